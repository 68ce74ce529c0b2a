/* SPDX-License-Identifier: BSD-3-Clause */
// How the LM loop damps, accepts a step and decides it has converged: sba 1.6's rules (with
// 1.6's retries, or with the paper's), or a trust-region Levenberg-Marquardt as the
// trust-region literature and Ceres run it. The loop (lm_core.cpp) is the same for all; a
// strategy is the handful of decisions in which they differ.
#ifndef SBA_SRC_STRATEGY_H
#define SBA_SRC_STRATEGY_H

#include <memory>
#include <string>
#include <vector>

#include "kernels.h"
#include "layout.h"
#include "parallel.h"

namespace sba {

enum class StrategyKind {
  Sba,            // sba 1.6: damping mu I, Nielsen's update, 1.6's stop tests as written, and
                  // 1.6's retries on the blocks as the previous attempt left them
  SbaCleanRetry,  // the same, but every attempt damps the undamped J^T J (the sba paper's)
  TrustRegion,    // Marquardt's damping mu diag(J^T J), Ceres-style acceptance and stopping
};

// "sba", "sba-clean-retry", "trust-region"; false for an unknown name.
bool strategy_from_name(const std::string &name, StrategyKind *out);
const char *strategy_name(StrategyKind s);
// Space-separated list of every name, for messages and the C API.
const char *strategy_names();

// sba 1.6's stop-4 test after an accepted step from cost e to cost en, as 1.6 writes it (see
// strategy.cpp): the "sba" strategies' convergence test.
bool reduction_stalled(double e, double en, double eps4);

class Strategy {
 public:
  explicit Strategy(const Layout &lay);
  virtual ~Strategy() = default;
  // Called once per iteration with the normal equations just formed (undamped U_j, V_i,
  // e_a, e_b, and the Jacobian blocks the solvers read). A strategy may change variables
  // here: the solver then works in its variables, and step_in_parameters maps its step back;
  // or, with damping(), set the damping of each parameter instead.
  virtual void linearized(ThreadPool &pool, const Kernels &kernels, JacobianBlocks jac, double *U,
                          double *V, double *ea, double *eb) = 0;
  // The damping of the first iteration, from opts[0] and the largest diagonal entry of
  // J^T J (of the system the solver sees).
  virtual double initial_damping(double tau, double maxdiag) const = 0;
  // The largest diagonal entry of the system the solver sees, from that of J^T J.
  virtual double solved_max_diagonal(double maxdiag) const = 0;
  // The step dp the solver returned at damping mu, given the gradient e_a, e_b it was handed:
  // returns the reduction its linear model predicts, dp^T (mu D dp + g) with g = J^T e (D:
  // damping(), or I), and
  // turns dp, in place, into the step in the units of p. The reduction is computed first, in
  // the solver's variables, where mu and g belong: after the change back they no longer apply.
  double step_in_parameters(ThreadPool &pool, const double *ea, const double *eb, double mu,
                            double *dp) const;
  // Whether a trial point is taken: dF the actual reduction of the cost, dL the linear
  // model's.
  virtual bool acceptable(double dF, double dL) const = 0;
  // The damping after an accepted step with gain ratio rho = dF / dL.
  virtual double after_success(double mu, double rho) const = 0;
  // After an attempt at damping mu that gave no accepted step (rejected, or its system could
  // not be solved), before the next attempt of the same iteration: the blocks U, V that it
  // will damp. The solvers add the next mu to their diagonals as they find them.
  virtual void before_retry(ThreadPool &pool, const Kernels &kernels, double mu, double *U,
                            double *V) = 0;
  // True when the damping reached after failures (mu, about to be multiplied by nu) means
  // there is nothing left to try: stop reason 6.
  virtual bool exhausted(double mu, int nu) const = 0;
  // Stop reason 4 after an accepted step from cost e to cost en.
  virtual bool converged(double e, double en) const = 0;
  // Stop reason 4 after a rejected step from cost e to cost en: no more to gain at any
  // damping. sba 1.6 has no such test: it damps on until one of its other tests fires.
  virtual bool converged_on_rejection(double, double) const { return false; }
  // Per parameter, the factor D_q of the damping mu D_q the solver is to apply
  // (NormalEquations::damping), set by each linearization; null for mu alone. Its address
  // does not change during a solve.
  virtual const double *damping() const { return nullptr; }

 protected:
  const Layout &lay_;

 private:
  // Per camera parameter, 1 / the copies of its unknown (shared parameters only).
  std::vector<double> share_;
  // dp, in place, from the solver's variables to the units of p.
  virtual void to_parameters(ThreadPool &pool, double *dp) const = 0;
};

// eps4 is opts[4]; the trust region reads 0 as its default relative cost tolerance.
// solver_damps: the solver takes a damping per parameter (StepSolver::takes_damping), which
// the trust region then uses rather than scaling the normal equations and the Jacobian.
std::unique_ptr<Strategy> make_strategy(StrategyKind kind, const Layout &lay, double eps4,
                                        bool solver_damps = false);

}  // namespace sba

#endif
