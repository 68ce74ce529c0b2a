/* SPDX-License-Identifier: BSD-3-Clause */
// The normal equations at a point without iterating, formed as an LM iteration forms them
// (weights from covx, the loss's reweighting): what the covariance of a solution starts from.
// Implemented beside the LM loop (lm_core.cpp), whose steps it shares.
#ifndef SBA_SRC_LINEARIZATION_H
#define SBA_SRC_LINEARIZATION_H

#include <vector>

#include "layout.h"
#include "log.h"
#include "model.h"
#include "options.h"
#include "parallel.h"

namespace sba {

class Kernels;

// The normal equations at p, without iterating: for the covariance of the solution.
struct Linearization {
  std::vector<double> jac, U, V, ea, eb;  // as in an LM iteration (weighted, reweighted)
  double sq_err = 0;                      // squared error of the (re)weighted residual
};
bool linearize(const Layout &lay, Model &model, double *p, const double *x, const double *covx,
               const Options &opt, const Logger &log, ThreadPool &pool, const Kernels &kernels,
               Linearization *out);

}  // namespace sba

#endif
