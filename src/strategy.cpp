// SPDX-License-Identifier: BSD-3-Clause
// The LM strategies. "sba" is 1.6's algorithm exactly (its parity with 1.6 is tested down to
// stop reasons and counters); "sba-clean-retry" is the same but for what a retry damps.
// "trust-region" is Levenberg-Marquardt as Moré's
// trust-region account and Ceres's documentation describe it: the damping term is
// mu diag(J^T J) (Marquardt), so that it is as strong in every direction relative to the
// curvature there, with the diagonal kept within a floor and a ceiling; a trial point must
// win a minimum fraction of the predicted reduction; and the solve ends when a step, taken or
// not, changes the cost by less than a relative tolerance, the stopping rule its users expect.
#include "strategy.h"

#include <algorithm>
#include <cfloat>
#include <climits>
#include <cmath>

#include "kernels.h"
#include "named.h"

namespace sba {
namespace {

struct NamedStrategy {
  const char *name;
  StrategyKind value;
};
constexpr NamedStrategy kStrategies[] = {
    {"sba", StrategyKind::Sba},
    {"sba-clean-retry", StrategyKind::SbaCleanRetry},
    {"trust-region", StrategyKind::TrustRegion},
};
constexpr auto kStrategyNames = joined_names<joined_length(kStrategies)>(kStrategies);

// Nielsen's damping update after an accepted step (sba paper, Fig. 2): shrink by up to 3 when
// the linear model predicted the reduction well, keep it when it did not.
double nielsen(double mu, double rho) {
  const double t = 2.0 * rho - 1.0;
  return mu * std::max(1.0 / 3.0, 1.0 - t * t * t);
}

// The smallest initial damping relative to max diag(J^T J) (see Sba16::initial_damping).
constexpr double kMinRelativeDamping = 0x1p-400;

// d[a * (b + 1)] += mu for a < b: the diagonal of a b x b row-major block.
void add_to_diagonal(double *d, int b, double mu) {
  for (int a = 0; a < b; ++a) d[a * (b + 1)] += mu;
}

// What sba 1.6 retries on (its damping sequences show it: test_drivers.cpp, Retries). 1.6
// damps its blocks in place and does not restore them between the attempts of an iteration,
// so each attempt adds its mu to the diagonals as the previous attempt left them:
// - U_j: diag(U_j) + mu_1 + ... + mu_k on attempt k. The same for V_i where no camera is free
//   (the structure-only driver), which solves each block from a copy.
// - V_i where cameras and points are free (the motion-and-structure driver): 1.6 inverts each
//   V_i + mu I in place, in point order, with a Bunch-Kaufman inverse that reads the upper
//   triangle and writes the inverse into the lower triangle with the diagonal. The next
//   attempt damps and inverts a block with V_i's own entries off the diagonal and the
//   previous inverse's diagonal on it: indefinite while mu is small, inverted all the same,
//   and the S made from it usually fails its Cholesky, so that mu grows by nu until it
//   dominates. One rejected step thus restarts the damping high. The inversion stops at the
//   first singular block: the points before it hold their inverse's diagonal, that one its
//   damped diagonal, the later ones what they held.
// The gain ratio and info[4] still use the attempt's own mu, as in 1.6.
class Sba16Retry {
 public:
  explicit Sba16Retry(const Layout &lay) : lay_(lay) {
    if (schur()) diag_.resize(size_t(lay.n) * size_t(lay.pnp));
  }

  void operator()(ThreadPool &pool, const Kernels &kernels, double mu, double *U, double *V) {
    const Layout &lay = lay_;
    const int cnp = lay.cnp, pnp = lay.pnp;
    pool.for_range(lay.free_cams(), [&](i64 b, i64 e) {
      for (i64 j = b + lay.mcon; j < e + lay.mcon; ++j) add_to_diagonal(U + j * cnp * cnp, cnp, mu);
    });
    if (!schur()) {
      pool.for_range(lay.free_pts(), [&](i64 b, i64 e) {
        for (i64 i = b + lay.ncon; i < e + lay.ncon; ++i) add_to_diagonal(V + i * pnp * pnp, pnp, mu);
      });
      return;
    }
    double *d = diag_.data();
    kernels.damped_inverse_diagonals(pool, V, mu, d);
    i64 singular = lay.ncon;
    while (singular < lay.n && !std::isnan(d[singular * pnp])) ++singular;
    pool.for_range(singular - lay.ncon, [&](i64 b, i64 e) {
      for (i64 i = b + lay.ncon; i < e + lay.ncon; ++i)
        for (int a = 0; a < pnp; ++a) V[i * pnp * pnp + a * (pnp + 1)] = d[i * pnp + a];
    });
    if (singular < lay.n) add_to_diagonal(V + singular * pnp * pnp, pnp, mu);
  }

 private:
  // Whether the blocks are those of the Schur complement (cameras and points free).
  bool schur() const { return lay_.free_cams() > 0 && lay_.free_pts() > 0; }

  const Layout &lay_;
  std::vector<double> diag_;  // the inverses' diagonals, pnp per point
};

class Sba16 final : public Strategy {
 public:
  // retry16: 1.6's retries (Sba16Retry); otherwise each attempt damps the undamped blocks.
  Sba16(const Layout &lay, double eps4, bool retry16) : Strategy(lay), eps4_(eps4) {
    if (retry16) retry_ = std::make_unique<Sba16Retry>(lay);
  }
  // tau > 0 (the drivers refuse 0), but tau * maxdiag can still be 0 or so small that the
  // growth a run of failed steps allows (mu *= nu, about 2^465 before reason 6) never makes
  // it count, and the solve would end at once with nothing refined. So the initial damping
  // is at least kMinRelativeDamping * maxdiag (a floor that only a tau below it meets) and
  // at least the smallest normal number, as after each accepted step.
  double initial_damping(double tau, double maxdiag) const override {
    return std::max({tau * maxdiag, kMinRelativeDamping * maxdiag, DBL_MIN});
  }
  void linearized(ThreadPool &, const Kernels &, JacobianBlocks, double *, double *, double *, double *) override {}
  double solved_max_diagonal(double maxdiag) const override { return maxdiag; }
  bool acceptable(double dF, double dL) const override { return dL > 0.0 && dF > 0.0; }
  double after_success(double mu, double rho) const override {
    return std::max(nielsen(mu, rho), DBL_MIN);
  }
  void before_retry(ThreadPool &pool, const Kernels &kernels, double mu, double *U, double *V) override {
    if (retry_) (*retry_)(pool, kernels, mu, U, V);
  }
  // 1.6's int nu would overflow on the next doubling.
  bool exhausted(double, int nu) const override { return nu > INT_MAX / 2; }
  bool converged(double e, double en) const override { return reduction_stalled(e, en, eps4_); }

 private:
  void to_parameters(ThreadPool &, double *) const override {}

  double eps4_;
  std::unique_ptr<Sba16Retry> retry_;
};

// The system is (J^T J + mu D) dp = J^T e, Marquardt's, with D = diag(J^T J) clamped to
// [kMinDiagonal, kMaxDiagonal]. A solver that takes a damping per parameter
// (StepSolver::takes_damping) is handed D and solves it as it stands. The others keep their
// mu I interface: they work in scaled variables q = D^(1/2) p, whose system (S J^T J S + mu I)
// dq = S J^T e with S = D^(-1/2) is the same one, at the cost of scaling the normal equations
// and every Jacobian block. The floor keeps a parameter the data hardly see (or a column held
// at zero) from being left undamped; the bounds are those Ceres documents for its LM
// diagonal.
constexpr double kMinDiagonal = 1e-6, kMaxDiagonal = 1e32;
// A trial point must achieve this fraction of the predicted reduction (Ceres's
// min_relative_decrease): a step that barely lowers the cost is a sign the region is too
// large, and taking it makes the next linearization no better.
constexpr double kMinGain = 1e-3;
// The damping moves within these bounds, the reciprocals of Ceres's default largest and
// smallest trust-region radii; on the scaled system they are relative to curvature 1.
constexpr double kMinDamping = 1e-16, kMaxDamping = 1e32;
// Relative cost change below which a step ends the solve (Ceres's default
// function_tolerance), used when opts[4] is 0.
constexpr double kDefaultCostTolerance = 1e-6;

class TrustRegion final : public Strategy {
 public:
  TrustRegion(const Layout &lay, double eps4, bool solver_damps)
      : Strategy(lay), ftol_(eps4 > 0.0 ? eps4 : kDefaultCostTolerance), damps_(solver_damps),
        s_(size_t(lay.nvars()), 1.0) {}

  void linearized(ThreadPool &pool, const Kernels &kernels, JacobianBlocks jac, double *U, double *V, double *ea,
                  double *eb) override {
    if (damps_) {
      set_damping(pool, U, V);
      return;
    }
    const int cnp = lay_.cnp, pnp = lay_.pnp;
    double *s = s_.data();
    const auto scale = [](double d) { return 1.0 / std::sqrt(std::clamp(d, kMinDiagonal, kMaxDiagonal)); };
    // Each row of S is scaled by its own diagonal entry: a shared unknown by its copies' sum,
    // and every copy by that one scale, so that the copies' steps, mapped back, are the same
    // number. Blocks of fixed cameras and points keep scale 1: nothing reads them.
    if (lay_.free_cams() > 0) camera_scales(U);
    pool.for_range(lay_.m, [&](i64 b, i64 e) {
      for (i64 j = b; j < e; ++j) {
        if (!lay_.cam_free(int(j))) continue;
        double *u = U + j * cnp * cnp;
        const double *sj = s + lay_.a_off(int(j));
        for (int a = 0; a < cnp; ++a) {
          for (int c = 0; c < cnp; ++c) u[a * cnp + c] *= sj[a] * sj[c];
          ea[j * cnp + a] *= sj[a];
        }
      }
    });
    pool.for_range(lay_.n, [&](i64 b, i64 e) {
      for (i64 i = b; i < e; ++i) {
        if (!lay_.pt_free(int(i))) continue;
        double *v = V + i * pnp * pnp, *si = s + lay_.b_off(int(i));
        for (int a = 0; a < pnp; ++a) si[a] = scale(v[a * (pnp + 1)]);
        for (int a = 0; a < pnp; ++a) {
          for (int c = 0; c < pnp; ++c) v[a * pnp + c] *= si[a] * si[c];
          eb[i * pnp + a] *= si[a];
        }
      }
    });
    // The Jacobian blocks the solvers read (W_ij = A_ij^T B_ij).
    kernels.scale_jacobian(pool, s, jac);
  }

  // On the scaled system the curvature is 1 in every well-seen direction, and 1.6's rule
  // would start at tau; a tenth of it, 1e-4 for the default tau (Ceres's initial trust
  // radius of 1e4), takes fewer iterations on the BAL problems of bench/ and reaches the
  // same minimum.
  double initial_damping(double tau, double maxdiag) const override {
    return std::clamp(0.1 * tau * maxdiag, kMinDamping, kMaxDamping);
  }

  // Each diagonal entry d becomes d / clamp(d), which grows with d: the largest stays the
  // largest, and no second pass over the blocks is needed.
  double solved_max_diagonal(double maxdiag) const override {
    return maxdiag / std::clamp(maxdiag, kMinDiagonal, kMaxDiagonal);
  }

  bool acceptable(double dF, double dL) const override { return dL > 0.0 && dF > kMinGain * dL; }
  double after_success(double mu, double rho) const override {
    return std::clamp(nielsen(mu, rho), kMinDamping, kMaxDamping);
  }
  void before_retry(ThreadPool &, const Kernels &, double, double *, double *) override {}
  bool exhausted(double mu, int nu) const override {
    return mu > kMaxDamping || nu > INT_MAX / 2;
  }
  bool converged(double e, double en) const override { return e - en <= ftol_ * e; }
  // Ceres's function tolerance bounds the change of the cost up or down. At a minimum, where a
  // step moves the cost by rounding only, a rejected step then ends the solve instead of a
  // run of smaller and smaller steps (each a factorization) ending on eps2 at the same point.
  bool converged_on_rejection(double e, double en) const override { return std::fabs(e - en) <= ftol_ * e; }
  const double *damping() const override { return damps_ ? s_.data() : nullptr; }

 private:
  // s_ = D over the free cameras and points (held ones: 1), without a change of variables.
  // The solvers that take it have a block per camera: no unknown is shared.
  void set_damping(ThreadPool &pool, const double *U, const double *V) {
    const int cnp = lay_.cnp, pnp = lay_.pnp;
    double *d = s_.data();
    const auto clamped = [](double x) { return std::clamp(x, kMinDiagonal, kMaxDiagonal); };
    pool.for_range(lay_.m, [&](i64 b, i64 e) {
      for (i64 j = b; j < e; ++j)
        if (lay_.cam_free(int(j)))
          for (int a = 0; a < cnp; ++a) d[lay_.a_off(int(j)) + a] = clamped(U[(j * cnp + a) * cnp + a]);
    });
    pool.for_range(lay_.n, [&](i64 b, i64 e) {
      for (i64 i = b; i < e; ++i)
        if (lay_.pt_free(int(i)))
          for (int a = 0; a < pnp; ++a) d[lay_.b_off(int(i)) + a] = clamped(V[(i * pnp + a) * pnp + a]);
    });
  }

  // s_ over the free cameras from the diagonal entries of S's rows (held parameters: 1).
  void camera_scales(const double *U) {
    std::vector<double> d(size_t(lay_.camera_unknowns()));
    lay_.cams.reduce_diagonal(U, d.data());
    for (double &x : d) x = 1.0 / std::sqrt(std::clamp(x, kMinDiagonal, kMaxDiagonal));
    lay_.cams.expand(d.data(), 1.0, s_.data());
  }

  void to_parameters(ThreadPool &pool, double *dp) const override {
    if (damps_) return;  // the solver's step is in the units of p
    const double *s = s_.data();
    pool.for_range(lay_.nvars(), [&](i64 b, i64 e) {
      for (i64 q = b; q < e; ++q) dp[q] *= s[q];
    });
  }

  double ftol_;
  bool damps_;             // the solver damps by s_ (D) rather than working in scaled variables
  std::vector<double> s_;  // per parameter: D, or D^(-1/2), of its latest linearization
};

}  // namespace

// sba 1.6's relative-reduction test, evaluated as 1.6 writes it. Algebraically it is
// sqrt(e) - sqrt(en) < eps4 sqrt(e), but as written the left side cancels: with eps4 = 0 it
// fires once the relative decrease of the squared error falls to the rounding level of
// 2 sqrt(e en), and that is how 1.6 ends most runs. Legacy callers see its stop reasons and
// iteration counts, so the rounding is part of the contract.
bool reduction_stalled(double e, double en, double eps4) {
  return en - 2.0 * std::sqrt(e * en) < (eps4 * eps4 - 1.0) * e;
}

Strategy::Strategy(const Layout &lay) : lay_(lay) {
  const CameraMap &map = lay.cams;
  if (!map.shared()) return;  // every unknown is one parameter: no share to weigh
  share_.assign(size_t(lay.m) * size_t(lay.cnp), 0.0);
  for (int j = lay.mcon; j < lay.m; ++j)
    for (int c = 0; c < lay.cnp; ++c) {
      const int u = map.unknown(j, c);
      if (u >= 0) share_[size_t(lay.a_off(j) + c)] = 1.0 / map.copies(u);
    }
}

// g is e_a over the camera part of dp and e_b over the point part; fixed entries of dp are 0.
// A shared unknown's step is in dp once per copy, and its gradient is the copies' sum: each
// copy brings its part of the gradient term and 1 / copies of the damping term.
double Strategy::step_in_parameters(ThreadPool &pool, const double *ea, const double *eb,
                                    double mu, double *dp) const {
  const i64 ncam = i64(lay_.m) * lay_.cnp;
  const double *share = share_.empty() ? nullptr : share_.data();
  const double *d = damping();
  const double predicted = deterministic_sum(pool, lay_.nvars(), [=](i64 q) {
    const double g = q < ncam ? ea[q] : eb[q - ncam];
    const double w = share && q < ncam ? share[q] : 1.0;
    return dp[q] * ((d ? mu * d[q] : mu) * dp[q] * w + g);
  });
  to_parameters(pool, dp);
  return predicted;
}

bool strategy_from_name(const std::string &name, StrategyKind *out) {
  return value_of(kStrategies, name, out);
}

const char *strategy_name(StrategyKind kind) {
  for (const NamedStrategy &s : kStrategies)
    if (s.value == kind) return s.name;
  return "?";
}

const char *strategy_names() { return kStrategyNames.text; }

std::unique_ptr<Strategy> make_strategy(StrategyKind kind, const Layout &lay, double eps4, bool solver_damps) {
  if (kind == StrategyKind::TrustRegion) return std::make_unique<TrustRegion>(lay, eps4, solver_damps);
  return std::make_unique<Sba16>(lay, eps4, kind == StrategyKind::Sba);
}

}  // namespace sba
