/* SPDX-License-Identifier: BSD-3-Clause */
// The covariance of a solution's cameras and points, block by block (sba_ext.h's
// sba_motstr_covariance*): how it is computed is told in covariance.cpp.
#ifndef SBA_SRC_COVARIANCE_H
#define SBA_SRC_COVARIANCE_H

#include <functional>
#include <vector>

#include "layout.h"
#include "log.h"
#include "model.h"
#include "options.h"

namespace sba {

// What sba_motstr_covariance* computes (see sba_ext.h), with validated indices. covariance()
// fills it, or returns false with the reason said through log.
struct CovarianceRequest {
  int ncams = 0;
  const int *cams = nullptr;
  double *camcov = nullptr;
  int npts = 0;
  const int *pts = nullptr;
  double *ptcov = nullptr;
  bool unscaled = false;     // blocks of (J^T J)^-1, not scaled by sigma2
  double point_damping = 0;  // added to every free point's V_i
  double sigma2 = 0;
  int rank = 0, nfree = 0;
};
bool covariance(const Layout &lay, Model &model, double *p, const double *x, const double *covx,
                const Options &opt, const Logger &log, CovarianceRequest &req);

// ---- the stages of covariance(), each for the tests as well ----

// The numerical rank of the symmetric positive semi-definite n x n block V (row-major); work
// is scratch. A free point whose V_i has rank < pnp has no covariance.
int block_rank(const double *V, int n, std::vector<double> &work);

// The symmetric n x n S (row-major, full) replaced by its pseudo-inverse Q diag(1/lambda) Q^T,
// from its eigendecomposition, eigenvalues at rounding level of the largest one counted as
// zero; *rank the others. stop is polled after the decomposition and at each eigenvector;
// true abandons it. False when it is abandoned or the decomposition fails (said through log).
bool pseudo_inverse(std::vector<double> &S, int n, const std::function<bool()> &stop, const Logger &log,
                    int *rank);

// The symmetric n x n S (row-major, full) replaced by its inverse through its Cholesky
// factor, when every pivot lies above the rounding level of S's largest diagonal entry
// (then S has full rank); false, S unchanged, when one does not or the factorization fails,
// for pseudo_inverse to decide the rank.
bool spd_inverse(std::vector<double> &S, int n);

// req's sigma2 = sq_err / (measurements - rank), rank and nfree, for nunknowns camera
// unknowns of which rank_S are determined and every free point's pnp; prior_rows are
// measurements beside the projections' (the priors' residual entries). False (said through
// log) when the measurements leave no redundancy.
bool residual_variance(const Layout &lay, double sq_err, int nunknowns, int rank_S, const Logger &log,
                       CovarianceRequest &req, i64 prior_rows = 0);

}  // namespace sba

#endif
