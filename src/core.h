/* SPDX-License-Identifier: BSD-3-Clause */
// Everything the drivers' side of the library shares: the layout (layout.h), the callback
// models (model.h) and the LM core with what works beside it (lm.h).
#ifndef SBA_SRC_CORE_H
#define SBA_SRC_CORE_H

#include "layout.h"
#include "lm.h"
#include "model.h"

#endif
