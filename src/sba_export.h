/* SPDX-License-Identifier: BSD-3-Clause */
// The library is compiled with hidden visibility; sba.h's, sba_ext.h's and sba_chkjac.h's
// declarations get default visibility here, so that exactly their functions are exported (the
// version script src/sba.map agrees). Every source file of the library includes this instead
// of the public headers.
#ifndef SBA_SRC_SBA_EXPORT_H
#define SBA_SRC_SBA_EXPORT_H

#if defined(__GNUC__)
#pragma GCC visibility push(default)
#endif
#include "sba.h"
#include "sba_chkjac.h"
#include "sba_ext.h"
#if defined(__GNUC__)
#pragma GCC visibility pop
#endif

#endif
