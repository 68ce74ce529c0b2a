/* SPDX-License-Identifier: BSD-3-Clause */
// What a solve is asked to do: the typed form of the drivers' itmax, opts[] and
// sba_ext_options, with one validity check. The C boundary translates into it
// (driver_options.cpp); the LM core, the covariance and the Jacobian check read it.
#ifndef SBA_SRC_OPTIONS_H
#define SBA_SRC_OPTIONS_H

#include <memory>
#include <string>

#include "camera_unknowns.h"
#include "linear_solver.h"
#include "loss.h"
#include "priors.h"
#include "sba_export.h"
#include "schur_pattern.h"
#include "strategy.h"

namespace sba {

struct Options {
  LinSolver solver = LinSolver::Chol;
  StrategyKind strategy = StrategyKind::Sba;
  double tau = SBA_INIT_MU;
  double eps1 = SBA_STOP_THRESH, eps2 = SBA_STOP_THRESH, eps3 = SBA_STOP_THRESH, eps4 = 0.0;
  int itmax = 0;
  int nthreads = 1;
  bool auto_threads = false;  // nthreads is the hardware's, not the caller's: see fit_threads
  bool parallel_callbacks = false;  // the caller's callbacks may run concurrently
  bool avoid_shared_cores = false;  // workers may narrow their own CPU mask (parallel.cpp)
  Loss loss;  // robust loss on each projection's squared residual (none: least squares)
  // Called after every outer iteration; nonzero stops with kStopUser.
  int (*progress)(void *ctx, const sba_progress *state) = nullptr;
  void *progress_ctx = nullptr;
  // Polled by the covariance computation; nonzero abandons it (sba_ext_options.cancel).
  int (*cancel)(void *ctx) = nullptr;
  void *cancel_ctx = nullptr;
  CameraParamOptions cams;
  PriorOptions priors;  // residuals beside the projections (priors.h); none by default
  double memory_budget = 0;  // bytes "auto" plans within; 0: the machine's (memory_budget())
  // The Jacobian blocks stored in single precision, every computation on them in double:
  // half the Jacobian's memory and bandwidth. Needs a model that makes the Jacobian
  // projection by projection (Model::single), one camera block per camera, and a solver that
  // reads the blocks through the kernels (not ldl-amd): check_single_jacobian.
  bool single_jacobian = false;
  // What auto measured of S to choose sparse-chol (its pattern and ordering), which that
  // solver then uses rather than compute again; null otherwise.
  std::shared_ptr<const SchurAnalysis> schur_analysis;

  // The one check of everything the options carry, for the problem lay and the initial
  // estimate p: false, with the first thing wrong in *error, when a value cannot be used. A
  // negative itmax, a tolerance or tau that is not finite, a zero tau (named as the opts[]
  // entries they come from: tau opts[0], eps1..eps4 opts[1..4]); a robust loss's scale out of
  // range; held and shared camera parameters that do not fit the problem
  // (check_camera_params); priors that do not fit the problem or cannot be used
  // (check_priors). The bindings pass their values through and report this message.
  bool is_valid(const Layout &lay, const double *p, std::string *error) const;
};

// Why single_jacobian cannot be honoured for the problem lay (its camera map made) with a
// model that makes the Jacobian projection by projection or not (per_projection); empty if
// it can, or if it is not asked for.
std::string check_single_jacobian(const Options &opt, const Layout &lay, bool per_projection);

}  // namespace sba

#endif
