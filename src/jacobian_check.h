/* SPDX-License-Identifier: BSD-3-Clause */
// The check of a caller's analytic Jacobian against central differences: the drivers' itmax
// == 0 mode, and sba_chkjac.h's functions (chkjac_driver.cpp).
#ifndef SBA_SRC_JACOBIAN_CHECK_H
#define SBA_SRC_JACOBIAN_CHECK_H

#include "layout.h"
#include "log.h"
#include "model.h"

namespace sba {

// The itmax == 0 check of an analytic Jacobian against central differences. Reports every
// suspicious entry and a one-line verdict through log. Returns the number of suspicious rows.
i64 check_jacobian(const Layout &lay, Model &model, double *p, const Logger &log);

}  // namespace sba

#endif
