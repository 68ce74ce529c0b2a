/* SPDX-License-Identifier: BSD-3-Clause */
// The covariance of a solution's cameras and points, block by block (sba_ext.h's
// sba_motstr_covariance*): how it is computed is told in covariance.cpp.
#ifndef SBA_SRC_COVARIANCE_H
#define SBA_SRC_COVARIANCE_H

#include "layout.h"
#include "log.h"
#include "model.h"
#include "options.h"

namespace sba {

// What sba_motstr_covariance* computes (see sba_ext.h), with validated indices.
struct CovarianceRequest {
  int ncams = 0;
  const int *cams = nullptr;
  double *camcov = nullptr;
  int npts = 0;
  const int *pts = nullptr;
  double *ptcov = nullptr;
  double sigma2 = 0;
  int rank = 0, nfree = 0;
};
bool covariance(const Layout &lay, Model &model, double *p, const double *x, const double *covx,
                const Options &opt, const Logger &log, CovarianceRequest &req);

}  // namespace sba

#endif
