// SPDX-License-Identifier: BSD-3-Clause
// The one Levenberg-Marquardt core behind all six drivers (sba paper, Fig. 2 and Fig. 4).
// Each iteration computes the Jacobian and the normal equations once; the damped system is
// solved by the chosen StepSolver (by default through the Schur complement on the cameras,
// S = U* - W V*^-1 W^T, factored densely) until a step is accepted or a stop test fires.
// Motion-only and structure-only problems fall out of the same code (no free points, or no
// free cameras: block diagonal systems).
#include <algorithm>
#include <cfloat>
#include <chrono>
#include <climits>
#include <cmath>
#include <cstdio>
#include <vector>

#include "finite.h"
#include "kernels.h"
#include "layout.h"
#include "linearization.h"
#include "lm.h"
#include "model.h"
#include "options.h"
#include "step_solver.h"
#include "strategy.h"
#include "memory.h"
#include "parallel.h"
#include "small_dense.h"

namespace sba {
namespace {

// sba 1.6's threshold for an "almost singular" augmented system: ||dp||^2 beyond
// (||p||^2 + eps2) / 1e-24 means the step is numerically meaningless.
constexpr double kSingularEpsSq = 1e-24;

double sqnorm(ThreadPool &pool, const double *v, i64 len) {
  return deterministic_sum(pool, len, [v](i64 k) { return v[k] * v[k]; });
}

using sba::all_finite;
bool all_finite(ThreadPool &pool, const double *v, i64 len) {
  return pool.all_ranges(len, [v](int, i64 b, i64 e) { return all_finite(v + b, e - b); });
}

// Everything the LM loop itself needs, sized once before iterating (the linear solver
// owns its own).
struct Workspace {
  // keep_hx: f(p) must outlive the residual (the finite-difference Jacobian needs it).
  // Otherwise each residual is made in place over f's output, which saves two vectors as
  // long as the measurements (7 MB at 225k projections).
  // The trial point's residual overwrites the current one: once e_a and e_b are formed,
  // the LM loop needs e(p) again only after a step is accepted, when e(p + dp) takes its
  // place anyway. A robust loss keeps both, since the outlier count is made from the
  // residual at the last accepted point.
  Workspace(const Layout &lay, bool weighted, bool robust, bool keep_hx) {
    const i64 nobs = lay.nvis * lay.mnp;
    const auto alloc = [](std::vector<double> &v, i64 n) { resize_prefaulted(v, size_t(n)); };
    alloc(e, nobs);
    if (robust) alloc(en, nobs);
    if (keep_hx) {
      alloc(hx, nobs);
      alloc(hxn, nobs);
    }
    alloc(jac, lay.nvis * lay.jblk());
    if (weighted) alloc(wts, nobs * lay.mnp);
    alloc(U, i64(lay.m) * lay.cnp * lay.cnp);
    alloc(ea, i64(lay.m) * lay.cnp);
    alloc(V, i64(lay.n) * lay.pnp * lay.pnp);
    alloc(eb, i64(lay.n) * lay.pnp);
    alloc(dp, lay.nvars());
    if (robust) {
      alloc(rw, lay.nvis);
      alloc(rwn, lay.nvis);
      alloc(er, nobs);
    }
  }
  NormalEquations view() const {
    return NormalEquations{jac.data(), U.data(), V.data(), ea.data(), eb.data()};
  }
  // Where f(p) and f(p + dp) are written.
  double *f_out() { return hx.empty() ? e.data() : hx.data(); }
  double *fn_out() { return hxn.empty() ? en_data() : hxn.data(); }
  double *en_data() { return en.empty() ? e.data() : en.data(); }
  // dp: the step, then (once the predicted reduction is known) the trial point p + dp.
  std::vector<double> hx, e, hxn, en, jac, wts, U, ea, V, eb, dp;
  // With a robust loss: sqrt(rho') per projection at p and at the trial point, and the
  // reweighted residual that the normal equations see.
  std::vector<double> rw, rwn, er;
};

// Weight matrices W_ij (upper triangular, W^T W = Sigma_ij^-1) from the covariances.
bool make_weights(const Layout &lay, const double *covx, std::vector<double> &wts,
                  const Logger &log) {
  const int mnp = lay.mnp, m2 = mnp * mnp;
  std::vector<double> a(static_cast<size_t>(m2)), tmp(static_cast<size_t>(m2));
  for (int i = 0; i < lay.n; ++i)
    for (int k = lay.rowptr[i]; k < lay.rowptr[i + 1]; ++k) {
      const double *c = covx + i64(k) * m2;
      std::copy(c, c + m2, a.begin());
      bool ok = all_finite(c, m2);
      for (int r = 0; ok && r < mnp; ++r)
        for (int s = r + 1; s < mnp; ++s)
          if (c[r * mnp + s] != c[s * mnp + r]) ok = false;
      if (ok) ok = small::cholinv_upper(a.data(), wts.data() + i64(k) * m2, tmp.data(), mnp);
      if (!ok) {
        log.error("sba: the covariance of measurement %d (point %d, camera %d) is not a finite "
                  "symmetric positive definite matrix",
                  k, i, lay.colidx[k]);
        return false;
      }
    }
  return true;
}

struct Cost {
  double cost = 0;  // sum rho(s_k): what LM minimizes
  double sq = 0;    // sum s_k
};

// e = W (x - hx), the (covariance-weighted) residual, and its cost; e may be hx itself. With
// a robust loss, rw gets sqrt(rho'(s_k)) of every projection k (s_k = ||e_k||^2), the IRLS
// weights.
Cost residual(ThreadPool &pool, const Layout &lay, const double *x, const double *hx,
              const double *wts, const Loss &loss, double *e, double *rw) {
  const int mnp = lay.mnp;
  pool.for_range(lay.nvis, [&](i64 b, i64 end) {
    for (i64 q = b * mnp; q < end * mnp; ++q) e[q] = x[q] - hx[q];
    if (wts) {
      std::vector<double> t(static_cast<size_t>(mnp));
      for (i64 k = b; k < end; ++k) {
        double *ek = e + k * mnp;
        const double *w = wts + k * mnp * mnp;
        for (int r = 0; r < mnp; ++r) {
          double s = 0.0;
          for (int c = r; c < mnp; ++c) s += w[r * mnp + c] * ek[c];
          t[size_t(r)] = s;
        }
        std::copy(t.begin(), t.end(), ek);
      }
    }
    if (loss.robust())
      for (i64 k = b; k < end; ++k) {
        double s = 0.0;
        for (int r = 0; r < mnp; ++r) s += e[k * mnp + r] * e[k * mnp + r];
        rw[k] = std::sqrt(loss.weight(s));
      }
  });
  Cost c;
  c.sq = sqnorm(pool, e, lay.nvis * mnp);
  c.cost = !loss.robust() ? c.sq : deterministic_sum(pool, lay.nvis, [&](i64 k) {
    double s = 0.0;
    for (int r = 0; r < mnp; ++r) s += e[k * mnp + r] * e[k * mnp + r];
    return loss.rho(s);
  });
  return c;
}

// The IRLS step: J_k <- sqrt(rho'_k) J_k and er_k = sqrt(rho'_k) e_k, so that the normal
// equations are those of sum rho'_k ||e_k - J_k dp||^2 (gradient exact, Hessian without the
// second-order term of rho, which can make the system indefinite for redescending losses).
void reweight(ThreadPool &pool, const Layout &lay, const double *rw, const double *e,
              double *jac, double *er) {
  const int mnp = lay.mnp, jb = lay.jblk();
  pool.for_range(lay.nvis, [&](i64 b, i64 end) {
    for (i64 k = b; k < end; ++k) {
      for (int q = 0; q < jb; ++q) jac[k * jb + q] *= rw[k];
      for (int r = 0; r < mnp; ++r) er[k * mnp + r] = rw[k] * e[k * mnp + r];
    }
  });
}

// Jacobian blocks A_ij, B_ij <- W_ij A_ij, W_ij B_ij.
void weight_jacobian(ThreadPool &pool, const Layout &lay, const double *wts, double *jac) {
  const int mnp = lay.mnp, cnp = lay.cnp, pnp = lay.pnp, ncol = cnp + pnp;
  pool.for_range(lay.nvis, [&](i64 b, i64 end) {
    std::vector<double> t(size_t(mnp) * size_t(ncol));
    for (i64 k = b; k < end; ++k) {
      double *J = jac + k * lay.jblk();
      const double *w = wts + k * mnp * mnp;
      // The A and B blocks lie one after the other, each row-major; row r of the
      // projection is A's row r followed by B's row r.
      auto at = [&](int r, int c) -> double & {
        return c < cnp ? J[r * cnp + c] : J[mnp * cnp + r * pnp + (c - cnp)];
      };
      for (int r = 0; r < mnp; ++r)
        for (int c = 0; c < ncol; ++c) {
          double s = 0.0;
          for (int q = r; q < mnp; ++q) s += w[r * mnp + q] * at(q, c);
          t[size_t(r) * ncol + c] = s;
        }
      for (int r = 0; r < mnp; ++r)
        for (int c = 0; c < ncol; ++c) at(r, c) = t[size_t(r) * ncol + c];
    }
  });
}

// A Jacobian entry that is not finite makes every later number meaningless. Rather than
// scanning the whole Jacobian, look at the normal equations: every entry of a free camera's
// or point's block appears squared on the diagonal of its U_j or V_i (fixed blocks are
// ignored by definition), so a NaN or Inf there always shows up in U, V, e_a or e_b.
bool normal_equations_finite(ThreadPool &pool, const Layout &lay, const Workspace &w) {
  const i64 c2 = i64(lay.cnp) * lay.cnp, p2 = i64(lay.pnp) * lay.pnp;
  const i64 fc = lay.free_cams(), fp = lay.free_pts();
  return all_finite(pool, w.U.data() + lay.mcon * c2, fc * c2) &&
         all_finite(pool, w.ea.data() + lay.mcon * i64(lay.cnp), fc * lay.cnp) &&
         all_finite(pool, w.V.data() + lay.ncon * p2, fp * p2) &&
         all_finite(pool, w.eb.data() + lay.ncon * i64(lay.pnp), fp * lay.pnp);
}

// What sba 1.6 prints at verbose > 1 after each trial point: the mean Euclidean distance
// between the first two coordinates of the measured and the predicted projections,
// unweighted.
double mean_reprojection_error(ThreadPool &pool, const Layout &lay, const double *x, const double *hx) {
  const int mnp = lay.mnp, d = std::min(mnp, 2);
  const double sum = deterministic_sum(pool, lay.nvis, [=](i64 k) {
    double s = 0.0;
    for (int r = 0; r < d; ++r) s += (x[k * mnp + r] - hx[k * mnp + r]) * (x[k * mnp + r] - hx[k * mnp + r]);
    return std::sqrt(s);
  });
  return sum / double(lay.nvis);
}

// 1.6's line at verbose > 0 naming the first projection that is NaN or Inf.
void report_invalid_projection(const Layout &lay, const double *hx, const Logger &log) {
  const i64 len = lay.nvis * lay.mnp;
  i64 q = 0;
  while (q < len && std::isfinite(hx[q])) ++q;
  if (q == len) return;
  const i64 k = q / lay.mnp;
  const int i = int(std::upper_bound(lay.rowptr.begin(), lay.rowptr.end(), k) - lay.rowptr.begin()) - 1;
  log.legacy(1, "SBA: component %d of the estimated projection of point %d on camera %d is invalid!\n",
             int(q % lay.mnp), i, lay.colidx[size_t(k)]);
}

// The driver's name in 1.6's lines.
const char *legacy_name(Mode mode) {
  return mode == Mode::Mot ? "mot" : mode == Mode::Str ? "str" : "motstr";
}

// max |g| and max diag(J^T J) over the free cameras and points.
void gradient_stats(const Layout &lay, const Workspace &w, double *ginf, double *maxdiag) {
  double g = 0.0, d = 0.0;
  const int cnp = lay.cnp, pnp = lay.pnp;
  for (int j = lay.mcon; j < lay.m && cnp; ++j)
    for (int a = 0; a < cnp; ++a) {
      g = std::max(g, std::fabs(w.ea[size_t(i64(j) * cnp + a)]));
      d = std::max(d, w.U[size_t(i64(j) * cnp * cnp + a * (cnp + 1))]);
    }
  for (int i = lay.ncon; i < lay.n && pnp; ++i)
    for (int a = 0; a < pnp; ++a) {
      g = std::max(g, std::fabs(w.eb[size_t(i64(i) * pnp + a)]));
      d = std::max(d, w.V[size_t(i64(i) * pnp * pnp + a * (pnp + 1))]);
    }
  *ginf = g;
  *maxdiag = d;
}

}  // namespace

// sba 1.6's relative-reduction test, evaluated as 1.6 writes it. Algebraically it is
// sqrt(e) - sqrt(en) < eps4 sqrt(e), but as written the left side cancels: with eps4 = 0 it
// fires once the relative decrease of the squared error falls to the rounding level of
// 2 sqrt(e en), and that is how 1.6 ends most runs. Legacy callers see its stop reasons and
// iteration counts, so the rounding is part of the contract.
bool reduction_stalled(double e, double en, double eps4) {
  return en - 2.0 * std::sqrt(e * en) < (eps4 * eps4 - 1.0) * e;
}

namespace {

// dp^T (mu dp + g) with g = J^T e: the reduction of the linear model. g is e_a over the
// camera part of p and e_b over the point part, laid out like p; fixed entries of dp are 0.
double predicted_reduction(ThreadPool &pool, const Layout &lay, const Workspace &w, double mu) {
  const i64 ncam = i64(lay.m) * lay.cnp;
  const double *dp = w.dp.data(), *ea = w.ea.data(), *eb = w.eb.data();
  return deterministic_sum(pool, lay.nvars(), [=](i64 q) {
    const double g = q < ncam ? ea[q] : eb[q - ncam];
    return dp[q] * (mu * dp[q] + g);
  });
}

}  // namespace

void Summary::to_info(double *info) const {
  if (!info) return;
  info[0] = err0;
  info[1] = err;
  info[2] = grad_inf;
  info[3] = dp2;
  info[4] = mu_ratio;
  info[5] = iterations;
  info[6] = reason;
  info[7] = double(nfev);
  info[8] = double(njev);
  info[9] = double(nlinsys);
}

namespace {

// The steps of an LM iteration over one problem: what the solve repeats and what the
// covariance needs once. Each step reports a failure through the log and returns false.
class Steps {
 public:
  Steps(const Layout &lay, Model &model, const double *x, const Loss &loss, const Logger &log,
        ThreadPool &pool, const Kernels &kernels, bool weighted)
      : lay_(lay), model_(model), x_(x), loss_(loss), log_(log), pool_(pool),
        kernels_(kernels), w(lay, weighted, loss.robust(), !model.has_jacobian()) {}

  // The weights from the measurement covariances (none without covx).
  bool weigh(const double *covx) {
    if (!covx) return true;
    if (!make_weights(lay_, covx, w.wts, log_)) return false;
    wts_ = w.wts.data();
    return true;
  }

  // f(p) and the residual at the starting point.
  bool start(double *p, const char *where, Cost *c) {
    model_.eval(p, w.f_out());
    if (!all_finite(pool_, w.f_out(), lay_.nvis * lay_.mnp)) {
      log_.error("sba: the projection function returned NaN or Inf%s", where);
      return false;
    }
    *c = residual(pool_, lay_, x_, w.f_out(), wts_, loss_, w.e.data(), w.rw.data());
    return true;
  }

  // J at p (the callback's or by differences), weighted and reweighted as the residual is,
  // and its normal equations U_j, V_i, e_a, e_b.
  bool linearize(double *p, const char *where) {
    if (model_.has_jacobian())
      model_.jacobian(p, w.jac.data());
    else
      model_.fd_jacobian(p, w.hx.data(), w.jac.data());
    if (wts_) weight_jacobian(pool_, lay_, wts_, w.jac.data());
    if (loss_.robust())
      reweight(pool_, lay_, w.rw.data(), w.e.data(), w.jac.data(), w.er.data());
    kernels_.normal_equations(pool_, w.jac.data(), loss_.robust() ? w.er.data() : w.e.data(),
                              w.U.data(), w.V.data(), w.ea.data(), w.eb.data());
    if (!normal_equations_finite(pool_, lay_, w)) {
      log_.error("sba: the Jacobian has a NaN or Inf entry (or overflows)%s", where);
      return false;
    }
    return true;
  }

  // f and the residual at the trial point w.dp (which holds p + dp); its cost in *c.
  bool evaluate_trial(int it, Cost *c) {
    model_.eval(w.dp.data(), w.fn_out());
    if (log_.verbose() > 1)
      log_.legacy(2, "mean reprojection error %g\n", mean_reprojection_error(pool_, lay_, x_, w.fn_out()));
    if (!all_finite(pool_, w.fn_out(), lay_.nvis * lay_.mnp)) {
      if (log_.verbose() > 0) report_invalid_projection(lay_, w.fn_out(), log_);
      log_.error("sba: the projection function returned NaN or Inf at iteration %d", it);
      return false;
    }
    *c = residual(pool_, lay_, x_, w.fn_out(), wts_, loss_, w.en_data(), w.rwn.data());
    return true;
  }

  // The trial point becomes the current one.
  void accept(double *p) {
    const double *pn = w.dp.data();
    pool_.for_range(lay_.nvars(), [&](i64 b, i64 e) { std::copy(pn + b, pn + e, p + b); });
    w.hx.swap(w.hxn);
    if (!w.en.empty()) w.e.swap(w.en);
    w.rw.swap(w.rwn);
  }

  // The robustified residual's squared norm (the squared error the normal equations see).
  double reweighted_sq() const { return sqnorm(pool_, w.er.data(), lay_.nvis * lay_.mnp); }

  const Layout &lay_;
  Model &model_;
  const double *x_;
  const Loss &loss_;
  const Logger &log_;
  ThreadPool &pool_;
  const Kernels &kernels_;
  Workspace w;

 private:
  const double *wts_ = nullptr;
};

}  // namespace

bool linearize(const Layout &lay, Model &model, double *p, const double *x, const double *covx,
               const Options &opt, const Logger &log, ThreadPool &pool, const Kernels &kernels,
               Linearization *out) {
  Steps st(lay, model, x, opt.loss, log, pool, kernels, covx != nullptr);
  Cost c;
  if (!st.weigh(covx) || !st.start(p, "", &c) || !st.linearize(p, "")) return false;
  Workspace &w = st.w;
  out->jac.swap(w.jac);
  out->U.swap(w.U);
  out->V.swap(w.V);
  out->ea.swap(w.ea);
  out->eb.swap(w.eb);
  // With a loss, the IRLS weights make sum rho' s the squared error the model sees.
  out->sq_err = opt.loss.robust() ? st.reweighted_sq() : c.sq;
  return true;
}

bool solve(const Layout &lay, Model &model, double *p, const double *x, const double *covx,
           const Options &opt, const Logger &log, Summary &sum, const SolverWrap &wrap) {
  sum = Summary{};
  const auto t0 = std::chrono::steady_clock::now();
  ThreadPool pool(opt.nthreads, opt.avoid_shared_cores);
  const ModelThreads lend(model, &pool);
  const std::unique_ptr<Kernels> kernels = make_kernels(lay, pool.size());
  Steps st(lay, model, x, opt.loss, log, pool, *kernels, covx != nullptr);
  Workspace &w = st.w;
  std::unique_ptr<StepSolver> solver = make_step_solver(opt.solver, SolveContext{lay, pool, *kernels});
  if (wrap) solver = wrap(std::move(solver));
  const std::unique_ptr<Strategy> strategy = make_strategy(opt.strategy, lay, opt.eps4);
  const NormalEquations ne = w.view();
  const i64 nvars = lay.nvars();
  const double eps1 = opt.eps1, eps2sq = opt.eps2 * opt.eps2, eps3sq = opt.eps3 * opt.eps3;

  if (!st.weigh(covx)) return false;
  Cost c0;
  sum.nfev = 1;
  const double nvis = double(lay.nvis);
  if (!st.start(p, " at the initial estimate", &c0)) {
    log.legacy(1, "initial %s-SBA error %g [%g]\n", legacy_name(lay.mode), double(NAN), double(NAN));
    sum.reason = kStopNonFinite;
    return false;
  }
  double eps = c0.cost, sqe = c0.sq;
  log.legacy(1, "initial %s-SBA error %g [%g]\n", legacy_name(lay.mode), eps, eps / nvis);
  sum.err0 = sum.err = eps;
  sum.sq_err0 = sum.sq_err = sqe;
  if (!std::isfinite(eps)) {
    log.error("sba: the initial error is not finite (check x and covx)");
    sum.reason = kStopNonFinite;
    return false;
  }
  log.info(1, "SBA: initial error %g, %g per measurement (%lld measurements, %lld variables)",
           eps, eps / double(lay.nvis), static_cast<long long>(lay.nvis),
           static_cast<long long>(nvars));

  double mu = 0.0, maxdiag = 0.0;
  int nu = 2, stop = kStopNone, it = 0;
  // Failures mid-way still report where the solve stood: p and eps are the last accepted.
  auto record = [&](int reason, int iterations) {
    sum.err = eps;
    sum.sq_err = sqe;
    sum.reason = reason;
    sum.iterations = iterations;
    sum.mu_ratio = maxdiag > 0 ? mu / maxdiag : 0.0;
  };
  char where[64];
  for (it = 0; it < opt.itmax && !stop; ++it) {
    ++sum.njev;
    std::snprintf(where, sizeof where, " at iteration %d", it);
    if (!st.linearize(p, where)) {
      record(kStopNonFinite, it);
      return false;
    }
    // Stop 1 looks at the gradient in the units of p, whatever the strategy solves in.
    gradient_stats(lay, w, &sum.grad_inf, &maxdiag);
    strategy->linearized(pool, w.jac.data(), w.U.data(), w.V.data(), w.ea.data(), w.eb.data());
    maxdiag = strategy->solved_max_diagonal(maxdiag);
    if (it == 0) mu = strategy->initial_damping(opt.tau, maxdiag);

    if (sum.grad_inf <= eps1) {
      sum.dp2 = 0.0;
      stop = kStopGradient;
    }
    const double p2 = stop ? 0.0 : sqnorm(pool, p, nvars);
    for (; !stop;) {
      const StepStatus status = solver->solve(ne, mu, w.dp.data());
      if (status != StepStatus::SingularPointBlock) ++sum.nlinsys;
      if (status == StepStatus::Solved && all_finite(pool, w.dp.data(), nvars)) {
        // The linear model's reduction in the solver's variables, where mu and the
        // gradient it sees belong; then the step in the units of p.
        const double dL = predicted_reduction(pool, lay, w, mu);
        strategy->to_parameters(pool, w.dp.data());
        const double dp2 = sqnorm(pool, w.dp.data(), nvars);
        sum.dp2 = dp2;
        if (dp2 <= eps2sq * p2) {
          stop = kStopStep;
          break;
        }
        if (dp2 >= (p2 + opt.eps2) / kSingularEpsSq) {
          log.error("sba: the augmented normal equations are almost singular (||dp||^2 = %g); "
                    "the problem may be badly parametrized",
                    dp2);
          record(kStopSingular, it + 1);
          return false;
        }
        double *pn = w.dp.data();  // dp becomes p + dp: one parameter vector fewer
        pool.for_range(nvars, [&](i64 b, i64 e) {
          for (i64 q = b; q < e; ++q) pn[q] += p[q];
        });
        Cost cn;
        ++sum.nfev;
        if (!st.evaluate_trial(it, &cn)) {
          record(kStopNonFinite, it + 1);
          return false;
        }
        const double epsn = cn.cost;
        const double dF = eps - epsn;
        log.legacy(2, "\ndamping term %8g, gain ratio %8g, errors %8g / %8g = %g\n", mu,
                   dF / (dL != 0.0 ? dL : DBL_EPSILON), eps / nvis, epsn / nvis, eps / epsn);
        log.info(2, "SBA: iteration %d: mu %g, error %g -> %g, ||dp||^2 %g, gain ratio %g", it, mu,
                 eps, epsn, dp2, dL != 0.0 ? dF / dL : 0.0);
        if (strategy->acceptable(dF, dL)) {
          if (strategy->converged(eps, epsn)) stop = kStopReduction;
          st.accept(p);
          eps = epsn;
          sqe = cn.sq;
          mu = strategy->after_success(mu, dF / dL);
          nu = 2;
          break;
        }
      } else {
        log.warning("sba: the damped system could not be factored (mu = %g); increasing damping",
                    mu);
      }
      const double tried = mu;
      mu *= nu;
      if (strategy->exhausted(mu, nu)) {
        stop = kStopDamping;
        break;
      }
      nu *= 2;
      strategy->before_retry(pool, *kernels, tried, w.U.data(), w.V.data());
    }
    if (!stop && eps <= eps3sq) stop = kStopError;
    // After every iteration, the last one too (whatever ended it); a request to stop after
    // the last one changes nothing: the solve ends with the reason it already has.
    if (opt.progress) {
      const sba_progress state{
          it + 1, eps, mu, std::sqrt(sum.dp2),
          std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count()};
      const bool last = stop || it + 1 >= opt.itmax;
      if (opt.progress(opt.progress_ctx, &state) != 0 && !last) stop = kStopUser;
    }
  }
  if (!stop) stop = kStopItmax;

  record(stop, it);
  sum.ok = true;
  if (opt.loss.robust())
    for (i64 k = 0; k < lay.nvis; ++k) {
      double sk = 0.0;
      for (int r = 0; r < lay.mnp; ++r) sk += w.e[size_t(k * lay.mnp + r)] * w.e[size_t(k * lay.mnp + r)];
      sum.outliers += sk > opt.loss.scale2();
    }
  log.info(1, "SBA: %d iterations, stop reason %d, final error %g, %g per measurement", it, stop,
           eps, eps / double(lay.nvis));
  return true;
}

}  // namespace sba
