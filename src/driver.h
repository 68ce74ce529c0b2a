/* SPDX-License-Identifier: BSD-3-Clause */
// How a driver call of the C API (sba.h's and sba_ext.h's levmar and covariance entry points)
// runs once parsed into DriverArgs (driver_args.h): validate (the problem, then the options,
// checked once), lay out, solve. c_api.cpp holds the entry points themselves.
#ifndef SBA_SRC_DRIVER_H
#define SBA_SRC_DRIVER_H

#include "driver_args.h"
#include "sba_export.h"

namespace sba {

// A levmar entry point: the number of iterations, or SBA_ERROR. info (when given) is filled
// on every path, and nothing is thrown but a forced unwind (log.h, catch_all).
int run_driver(const DriverArgs &a);
// A covariance entry point: 0, or SBA_ERROR; req gets the results.
int run_covariance(const DriverArgs &a, sba_covariance_request *req);

}  // namespace sba

#endif
