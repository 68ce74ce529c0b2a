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
#include <cmath>
#include <cstdio>
#include <vector>

#include "finite.h"
#include "kernels.h"
#include "layout.h"
#include "linearization.h"
#include "lm.h"
#include "memory.h"
#include "model.h"
#include "options.h"
#include "parallel.h"
#include "priors.h"
#include "small_dense.h"
#include "step_solver.h"
#include "strategy.h"
#include "unknowns.h"

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
  // long as the measurements: beside the Jacobian they are the largest arrays of a solve,
  // so they bound the problem that fits in memory (bench/'s scaling series measures it).
  // The trial point's residual overwrites the current one: once e_a and e_b are formed,
  // the LM loop needs e(p) again only after a step is accepted, when e(p + dp) takes its
  // place anyway. A robust loss keeps both, since the outlier count is made from the
  // residual at the last accepted point.
  // single: the Jacobian in single precision (Options::single_jacobian). With the model's
  // Jacobian (not by differences) it is also `streamed`: nothing is kept per projection but
  // the blocks. An evaluation sums the cost point by point, and the linearization has the
  // model make f(p) again beside each point's blocks (one more projection per Jacobian block,
  // for the 16 bytes per observation of the residual; with a robust loss, 56).
  Workspace(const Layout &lay, bool weighted, bool robust, bool keep_hx, bool single)
      : streamed(single && !keep_hx) {
    const i64 nobs = lay.nvis * lay.mnp;
    const auto alloc = [](std::vector<double> &v, i64 n) { resize_prefaulted(v, size_t(n)); };
    if (!streamed) alloc(e, nobs);
    if (robust && !streamed) alloc(en, nobs);
    if (keep_hx) {
      alloc(hx, nobs);
      alloc(hxn, nobs);
    }
    if (streamed) {
      parts.resize(kGradientChunks);
      alloc(escratch, i64(kGradientChunks) * 2 * lay.mnp);
    }
    if (single) {
      resize_prefaulted(jac32, size_t(lay.nvis * lay.jblk()));
      // The gradient from the blocks in double: by chunks of points (their ranges set by the
      // observations, whatever the thread count), each chunk's share of e_a on its own.
      chunks.resize(kGradientChunks + 1);
      for (int c = 0; c <= kGradientChunks; ++c)
        chunks[size_t(c)] = std::lower_bound(lay.rowptr.begin(), lay.rowptr.end(), lay.nvis * c / kGradientChunks) -
                            lay.rowptr.begin();
      chunks[kGradientChunks] = lay.n;
      alloc(ga, i64(kGradientChunks) * lay.m * lay.cnp);
      alloc(gb, i64(lay.n) * lay.pnp);
      if (weighted) alloc(wscratch, i64(kGradientChunks) * lay.jblk());
    } else {
      alloc(jac, lay.nvis * lay.jblk());
    }
    if (weighted) alloc(wts, nobs * lay.mnp);
    alloc(U, i64(lay.m) * lay.cnp * lay.cnp);
    alloc(ea, i64(lay.m) * lay.cnp);
    alloc(V, i64(lay.n) * lay.pnp * lay.pnp);
    alloc(eb, i64(lay.n) * lay.pnp);
    alloc(dp, lay.nvars());
    if (robust && !streamed) {
      alloc(rw, lay.nvis);
      alloc(rwn, lay.nvis);
      alloc(er, nobs);
    }
  }
  NormalEquations view() const {
    return NormalEquations{jac32.empty() ? jac.data() : nullptr, U.data(), V.data(), ea.data(), eb.data(),
                           jac32.empty() ? nullptr : jac32.data()};
  }
  JacobianBlocks blocks() {
    return jac32.empty() ? JacobianBlocks{jac.data(), nullptr} : JacobianBlocks{nullptr, jac32.data()};
  }
  // Where f(p) and f(p + dp) are written.
  double *f_out() { return hx.empty() ? e.data() : hx.data(); }
  double *fn_out() { return hxn.empty() ? en_data() : hxn.data(); }
  double *en_data() { return en.empty() ? e.data() : en.data(); }
  // dp: the step, then (once it is in the units of p) the trial point p + dp.
  std::vector<double> hx, e, hxn, en, jac, wts, U, ea, V, eb, dp;
  // With the Jacobian in single precision: the blocks instead of jac, the chunks of points
  // of the gradient, their shares of e_a and e_b, and their scratch for the weighting.
  static constexpr int kGradientChunks = 32;
  std::vector<float> jac32;
  std::vector<i64> chunks;
  std::vector<double> ga, gb, wscratch;
  // Streamed: what an evaluation sums over each chunk of points (in the chunk's order, then
  // the chunks' in theirs, for the same sums on any number of threads), and each chunk's
  // scratch for a projection's residual.
  struct ChunkCost {
    double cost = 0, sq = 0, dist = 0;  // dist: the unweighted reprojection distances
    i64 outliers = 0;
    i64 bad = -1;  // the first coordinate of f that is not finite, or -1
  };
  const bool streamed;
  std::vector<ChunkCost> parts;
  std::vector<double> escratch;
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
  double cost = 0;  // sum rho(s_k) plus the priors' cost: what LM minimizes
  double sq = 0;    // sum s_k, of the projections
  double proj = 0, prior = 0;  // the cost's two parts (prior: 0 without priors)
  i64 outliers = 0;  // with a robust loss, s_k beyond its scale (counted by streamed evaluations)
};

inline double squared(const double *v, int n) {
  double s = 0.0;
  for (int r = 0; r < n; ++r) s += v[r] * v[r];
  return s;
}

// e_k <- W_ij e_k (w: its upper triangular weight; t: mnp scratch).
inline void weigh_residual(int mnp, const double *w, double *ek, double *t) {
  for (int r = 0; r < mnp; ++r) {
    double s = 0.0;
    for (int c = r; c < mnp; ++c) s += w[r * mnp + c] * ek[c];
    t[r] = s;
  }
  std::copy(t, t + mnp, ek);
}

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
      for (i64 k = b; k < end; ++k) weigh_residual(mnp, wts + k * mnp * mnp, e + k * mnp, t.data());
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

// The IRLS step for projection k: J_k <- sqrt(rho'_k) J_k and er_k = sqrt(rho'_k) e_k, so
// that the normal equations are those of sum rho'_k ||e_k - J_k dp||^2 (gradient exact,
// Hessian without the second-order term of rho, which can make the system indefinite for
// redescending losses).
// r: sqrt(rho'_k); ek: e_k, erk: where er_k goes (may be ek).
inline void reweight_projection(const Layout &lay, double r, const double *ek, double *Jk, double *erk) {
  const int mnp = lay.mnp, jb = lay.jblk();
  for (int q = 0; q < jb; ++q) Jk[q] *= r;
  for (int c = 0; c < mnp; ++c) erk[c] = r * ek[c];
}

// Projection k's blocks A_ij, B_ij (at Jk) <- W_ij A_ij, W_ij B_ij; t: jblk() scratch.
inline void weigh_projection(const Layout &lay, i64 k, const double *wts, double *Jk, double *t) {
  const int mnp = lay.mnp, cnp = lay.cnp, pnp = lay.pnp, ncol = cnp + pnp;
  const double *w = wts + k * mnp * mnp;
  // The A and B blocks lie one after the other, each row-major; row r of the projection is
  // A's row r followed by B's row r.
  auto at = [&](int r, int c) -> double & {
    return c < cnp ? Jk[r * cnp + c] : Jk[mnp * cnp + r * pnp + (c - cnp)];
  };
  for (int r = 0; r < mnp; ++r)
    for (int c = 0; c < ncol; ++c) {
      double s = 0.0;
      for (int q = r; q < mnp; ++q) s += w[r * mnp + q] * at(q, c);
      t[r * ncol + c] = s;
    }
  for (int r = 0; r < mnp; ++r)
    for (int c = 0; c < ncol; ++c) at(r, c) = t[r * ncol + c];
}

// The two over the whole Jacobian.
void reweight(ThreadPool &pool, const Layout &lay, const double *rw, const double *e, double *jac, double *er) {
  pool.for_range(lay.nvis, [&](i64 b, i64 end) {
    for (i64 k = b; k < end; ++k)
      reweight_projection(lay, rw[k], e + k * lay.mnp, jac + k * lay.jblk(), er + k * lay.mnp);
  });
}
void weight_jacobian(ThreadPool &pool, const Layout &lay, const double *wts, double *jac) {
  pool.for_range(lay.nvis, [&](i64 b, i64 end) {
    std::vector<double> t(size_t(lay.jblk()));
    for (i64 k = b; k < end; ++k) weigh_projection(lay, k, wts, jac + k * lay.jblk(), t.data());
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

// The Euclidean distance between the first two coordinates of a measured projection xk and
// the predicted fk, unweighted.
inline double reprojection_distance(const double *xk, const double *fk, int mnp) {
  double s = 0.0;
  for (int r = 0; r < std::min(mnp, 2); ++r) s += (xk[r] - fk[r]) * (xk[r] - fk[r]);
  return std::sqrt(s);
}
// What sba 1.6 prints at verbose > 1 after each trial point: the mean of those distances.
double mean_reprojection_error(ThreadPool &pool, const Layout &lay, const double *x, const double *hx) {
  const int mnp = lay.mnp;
  const double sum = deterministic_sum(
      pool, lay.nvis, [=](i64 k) { return reprojection_distance(x + k * mnp, hx + k * mnp, mnp); });
  return sum / double(lay.nvis);
}

// 1.6's line at verbose > 0 naming the projection of coordinate q of f, NaN or Inf.
void report_invalid_coordinate(const Layout &lay, i64 q, const Logger &log) {
  const i64 k = q / lay.mnp;
  const int i = int(std::upper_bound(lay.rowptr.begin(), lay.rowptr.end(), k) - lay.rowptr.begin()) - 1;
  log.legacy(1, "SBA: component %d of the estimated projection of point %d on camera %d is invalid!\n",
             int(q % lay.mnp), i, lay.colidx[size_t(k)]);
}
// The same for the first such coordinate of hx, if any.
void report_invalid_projection(const Layout &lay, const double *hx, const Logger &log) {
  const i64 len = lay.nvis * lay.mnp;
  i64 q = 0;
  while (q < len && std::isfinite(hx[q])) ++q;
  if (q < len) report_invalid_coordinate(lay, q, log);
}

// The driver's name in 1.6's lines.
const char *legacy_name(Mode mode) {
  return mode == Mode::Mot ? "mot" : mode == Mode::Str ? "str" : "motstr";
}

// max |g| and max diag(J^T J) over the unknowns: the free points and the camera side's (a
// shared unknown's gradient and diagonal entry are its copies' sums; a held parameter's are 0).
void gradient_stats(const Layout &lay, const Workspace &w, double *ginf, double *maxdiag) {
  double g = 0.0, d = 0.0;
  const int pnp = lay.pnp;
  if (lay.free_cams() > 0) {
    std::vector<double> gu(size_t(lay.camera_unknowns())), du(gu.size());
    lay.cams.reduce(w.ea.data(), gu.data());
    lay.cams.reduce_diagonal(w.U.data(), du.data());
    for (size_t u = 0; u < gu.size(); ++u) {
      g = std::max(g, std::fabs(gu[u]));
      d = std::max(d, du[u]);
    }
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
  // priors: null or empty for none.
  // single: the Jacobian in single precision (the model must be able to give it).
  Steps(const Layout &lay, Model &model, const double *x, const Loss &loss, const Logger &log,
        ThreadPool &pool, const Kernels &kernels, bool weighted, const PriorTerms *priors, bool single)
      : lay_(lay), model_(model), x_(x), loss_(loss), log_(log), pool_(pool),
        kernels_(kernels), w(lay, weighted, loss.robust(), !model.has_jacobian(), single && model.single()),
        priors_(priors && !priors->empty() ? priors : nullptr) {}

  // The weights from the measurement covariances (none without covx).
  bool weigh(const double *covx) {
    if (!covx) return true;
    if (!make_weights(lay_, covx, w.wts, log_)) return false;
    wts_ = w.wts.data();
    return true;
  }

  // f(p) and the residual at the starting point.
  bool start(double *p, const char *where, Cost *c) {
    if (w.streamed) {
      if (!stream_cost(p, false, c)) {
        log_.error("sba: the projection function returned NaN or Inf%s", where);
        return false;
      }
      outliers_ = c->outliers;
      return add_priors(p, where, c);
    }
    model_.eval(p, w.f_out());
    if (!all_finite(pool_, w.f_out(), lay_.nvis * lay_.mnp)) {
      log_.error("sba: the projection function returned NaN or Inf%s", where);
      return false;
    }
    *c = residual(pool_, lay_, x_, w.f_out(), wts_, loss_, w.e.data(), w.rw.data());
    return add_priors(p, where, c);
  }

  // The priors' cost at p into c, whose cost becomes the projections' plus the priors'; false
  // (said) if a prior's residual is not finite. Without priors c stays as it is.
  bool add_priors(const double *p, const char *where, Cost *c) const {
    c->proj = c->cost;
    if (!priors_) return true;
    PriorCost pc;
    if (!priors_->cost(p, log_, where, &pc)) return false;
    c->prior = pc.cost;
    c->cost = c->proj + pc.cost;
    return true;
  }

  // J at p (the callback's or by differences), weighted and reweighted as the residual is,
  // and its normal equations U_j, V_i, e_a, e_b.
  bool linearize(double *p, const char *where) {
    if (w.jac32.empty()) {
      if (model_.has_jacobian())
        model_.jacobian(p, w.jac.data());
      else
        model_.fd_jacobian(p, w.hx.data(), w.jac.data());
      if (wts_) weight_jacobian(pool_, lay_, wts_, w.jac.data());
      if (loss_.robust()) reweight(pool_, lay_, w.rw.data(), w.e.data(), w.jac.data(), w.er.data());
      // The held parameters' Jacobian columns are zeroed (as the kernels read them): nothing
      // of them reaches the normal equations, their rows of U_j and e_a come out zero, and
      // their step is pinned at -0.0 by the solvers.
      const double *e = loss_.robust() ? w.er.data() : w.e.data();
      if (lay_.cams.any_held())
        kernels_.held_normal_equations(pool_, w.jac.data(), e, w.U.data(), w.V.data(), w.ea.data(), w.eb.data());
      else
        kernels_.normal_equations(pool_, w.jac.data(), e, w.U.data(), w.V.data(), w.ea.data(), w.eb.data());
    } else {
      linearize_single(p);
    }
    if (priors_) prior_sq_ = priors_->add_normal_equations(p, w.U.data(), w.V.data(), w.ea.data(), w.eb.data());
    if (!normal_equations_finite(pool_, lay_, w)) {
      log_.error("sba: the Jacobian has a NaN or Inf entry (or overflows)%s", where);
      return false;
    }
    return true;
  }

  // linearize with the Jacobian stored in single precision. The model hands over each point's
  // blocks in double; they are weighted, reweighted and held there, give their terms of the
  // gradient, and only then are rounded to storage. U_j and V_i come from the rounded blocks,
  // but e_a and e_b, which say where the minimum is, from the blocks in double: the solve
  // then stops at the minimum of the problem, not of its rounded linearization.
  void linearize_single(double *p) {
    double *ga = w.ga.data();
    pool_.for_range(i64(w.ga.size()), [ga](i64 b, i64 e) { std::fill(ga + b, ga + e, 0.0); });
    model_.point_jacobians(p, w.streamed ? nullptr : w.hx.data(), w.chunks.data(), Workspace::kGradientChunks,
                           {take_point, this});
    kernels_.normal_matrices(pool_, w.jac32.data(), w.U.data(), w.V.data());
    const int cnp = lay_.cnp, pnp = lay_.pnp;
    const i64 stride = i64(lay_.m) * cnp;
    pool_.for_range(lay_.m - lay_.mcon, [&](i64 b, i64 e) {
      for (i64 q = (b + lay_.mcon) * cnp; q < (e + lay_.mcon) * cnp; ++q) {
        double s = 0.0;
        for (int c = 0; c < Workspace::kGradientChunks; ++c) s += w.ga[size_t(c * stride + q)];
        w.ea[size_t(q)] = s;
      }
    });
    std::copy(w.gb.begin() + i64(lay_.ncon) * pnp, w.gb.end(), w.eb.begin() + i64(lay_.ncon) * pnp);
  }
  static void take_point(void *ctx, int chunk, int i, double *blocks, const double *f) {
    static_cast<Steps *>(ctx)->take(chunk, i, blocks, f);
  }
  // Point i's blocks in double (chunk c's), and when streamed its projections f: see
  // linearize_single.
  void take(int c, int i, double *blocks, const double *f) {
    const int mnp = lay_.mnp, cnp = lay_.cnp, pnp = lay_.pnp, jb = lay_.jblk();
    const int r0 = lay_.rowptr[size_t(i)], r1 = lay_.rowptr[size_t(i) + 1];
    double *ga = w.ga.data() + i64(c) * lay_.m * cnp, *gbi = w.gb.data() + i64(i) * pnp;
    std::fill_n(gbi, pnp, 0.0);
    for (int k = r0; k < r1; ++k) {
      double *Jk = blocks + i64(k - r0) * jb;
      const int j = lay_.colidx[size_t(k)];
      if (wts_) weigh_projection(lay_, k, wts_, Jk, w.wscratch.data() + i64(c) * jb);
      const double *res = gradient_residual(c, k, f ? f + i64(k - r0) * mnp : nullptr, Jk);
      if (lay_.cams.any_held()) lay_.cams.zero_held(j, mnp, Jk);
      const double *A = Jk, *B = Jk + mnp * cnp;
      if (lay_.cam_free(j))
        for (int a = 0; a < cnp; ++a) {
          double s = 0.0;
          for (int r = 0; r < mnp; ++r) s += A[r * cnp + a] * res[r];
          ga[j * cnp + a] += s;
        }
      for (int d = 0; d < pnp; ++d) {
        double s = 0.0;
        for (int r = 0; r < mnp; ++r) s += B[r * pnp + d] * res[r];
        gbi[d] += s;
      }
      std::copy_n(Jk, jb, w.jac32.data() + i64(k) * jb);
    }
  }

  // The residual that projection k's weighted blocks Jk meet in the gradient, Jk reweighted
  // with a robust loss: e_k made from its projection fk (streamed, in chunk c's scratch), or
  // the stored one (fk null).
  const double *gradient_residual(int c, i64 k, const double *fk, double *Jk) {
    const int mnp = lay_.mnp;
    if (fk) {
      double *ek = w.escratch.data() + i64(c) * 2 * mnp;
      projection_residual(k, fk, ek, ek + mnp);
      if (loss_.robust()) reweight_projection(lay_, std::sqrt(loss_.weight(squared(ek, mnp))), ek, Jk, ek);
      return ek;
    }
    if (!loss_.robust()) return w.e.data() + k * mnp;
    reweight_projection(lay_, w.rw[size_t(k)], w.e.data() + k * mnp, Jk, w.er.data() + k * mnp);
    return w.er.data() + k * mnp;
  }

  // e_k = W_ij (x_k - f_k) of projection k into ek (t: mnp scratch).
  void projection_residual(i64 k, const double *fk, double *ek, double *t) const {
    const int mnp = lay_.mnp;
    for (int r = 0; r < mnp; ++r) ek[r] = x_[k * mnp + r] - fk[r];
    if (wts_) weigh_residual(mnp, wts_ + k * mnp * mnp, ek, t);
  }

  // Streamed: f at p and its cost, point by point, keeping nothing per projection. False if f
  // is not finite somewhere (said at verbose > 0, as report_invalid_projection does). A trial
  // point's evaluation says its mean reprojection error at verbose > 1, as evaluate_trial does.
  bool stream_cost(double *p, bool trial, Cost *c) {
    std::fill(w.parts.begin(), w.parts.end(), Workspace::ChunkCost{});
    model_.point_projections(p, w.chunks.data(), Workspace::kGradientChunks, {cost_point, this});
    Workspace::ChunkCost sum;
    for (const Workspace::ChunkCost &pc : w.parts) {
      if (pc.bad >= 0 && sum.bad < 0) sum.bad = pc.bad;
      sum.cost += pc.cost;
      sum.sq += pc.sq;
      sum.dist += pc.dist;
      sum.outliers += pc.outliers;
    }
    if (trial && log_.verbose() > 1) log_.legacy(2, "mean reprojection error %g\n", sum.dist / double(lay_.nvis));
    if (sum.bad >= 0) {
      if (trial && log_.verbose() > 0) report_invalid_coordinate(lay_, sum.bad, log_);
      return false;
    }
    *c = Cost{};
    c->cost = loss_.robust() ? sum.cost : sum.sq;
    c->sq = sum.sq;
    c->outliers = sum.outliers;
    return true;
  }
  static void cost_point(void *ctx, int chunk, int i, double *, const double *f) {
    static_cast<Steps *>(ctx)->add_cost(chunk, i, f);
  }
  // Point i's share of stream_cost, into chunk c's sums.
  void add_cost(int c, int i, const double *f) {
    Workspace::ChunkCost &pc = w.parts[size_t(c)];
    const int mnp = lay_.mnp, r0 = lay_.rowptr[size_t(i)];
    double *ek = w.escratch.data() + i64(c) * 2 * mnp;
    for (int k = r0; k < lay_.rowptr[size_t(i) + 1]; ++k) {
      const double *fk = f + i64(k - r0) * mnp;
      for (int r = 0; r < mnp && pc.bad < 0; ++r)
        if (!std::isfinite(fk[r])) pc.bad = i64(k) * mnp + r;
      if (log_.verbose() > 1) pc.dist += reprojection_distance(x_ + i64(k) * mnp, fk, mnp);
      projection_residual(k, fk, ek, ek + mnp);
      const double s = squared(ek, mnp);
      pc.sq += s;
      if (loss_.robust()) {
        pc.cost += loss_.rho(s);
        pc.outliers += s > loss_.scale2();
      }
    }
  }

  // f and the residual at the trial point w.dp (which holds p + dp); its cost in *c.
  bool evaluate_trial(int it, Cost *c) {
    if (w.streamed) {
      if (!stream_cost(w.dp.data(), true, c)) {
        log_.error("sba: the projection function returned NaN or Inf at iteration %d", it);
        return false;
      }
      return trial_priors(it, c);
    }
    model_.eval(w.dp.data(), w.fn_out());
    if (log_.verbose() > 1)
      log_.legacy(2, "mean reprojection error %g\n", mean_reprojection_error(pool_, lay_, x_, w.fn_out()));
    if (!all_finite(pool_, w.fn_out(), lay_.nvis * lay_.mnp)) {
      if (log_.verbose() > 0) report_invalid_projection(lay_, w.fn_out(), log_);
      log_.error("sba: the projection function returned NaN or Inf at iteration %d", it);
      return false;
    }
    *c = residual(pool_, lay_, x_, w.fn_out(), wts_, loss_, w.en_data(), w.rwn.data());
    return trial_priors(it, c);
  }
  bool trial_priors(int it, Cost *c) const {
    if (!priors_) return add_priors(w.dp.data(), "", c);  // no message to word on every trial
    char where[48];
    std::snprintf(where, sizeof where, " at iteration %d", it);
    return add_priors(w.dp.data(), where, c);
  }

  // The trial point, whose cost is c, becomes the current one.
  void accept(double *p, const Cost &c) {
    const double *pn = w.dp.data();
    pool_.for_range(lay_.nvars(), [&](i64 b, i64 e) { std::copy(pn + b, pn + e, p + b); });
    w.hx.swap(w.hxn);
    if (!w.en.empty()) w.e.swap(w.en);
    w.rw.swap(w.rwn);
    outliers_ = c.outliers;
  }

  // With a robust loss, the projections whose s_k at p is beyond the loss's scale.
  i64 outliers() const {
    if (w.streamed) return outliers_;
    i64 n = 0;
    for (i64 k = 0; k < lay_.nvis; ++k) n += squared(w.e.data() + k * lay_.mnp, lay_.mnp) > loss_.scale2();
    return n;
  }

  // The robustified residual's squared norm (the squared error the normal equations see).
  double reweighted_sq() const { return sqnorm(pool_, w.er.data(), lay_.nvis * lay_.mnp); }
  // The priors' share of it at the last linearization (0 without priors).
  double prior_sq() const { return prior_sq_; }

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
  const PriorTerms *priors_;
  double prior_sq_ = 0.0;
  i64 outliers_ = 0;  // streamed: outliers() at p
};

}  // namespace

bool linearize(const Layout &lay, Model &model, double *p, const double *x, const double *covx,
               const Options &opt, const Logger &log, ThreadPool &pool, const Kernels &kernels,
               Linearization *out) {
  const PriorTerms priors(opt.priors, lay);
  // The covariance is made from a Jacobian in double, whatever the solve stored.
  Steps st(lay, model, x, opt.loss, log, pool, kernels, covx != nullptr, &priors, false);
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
  if (opt.priors.any()) out->sq_err += st.prior_sq();
  return true;
}

namespace {

// The Levenberg-Marquardt iteration of one solve (sba paper, Fig. 2), as named steps: each
// outer iteration linearizes at p, computes a step (damped solves at growing mu, each
// candidate evaluated, then accepted or rejected) and reports its progress; each stop test
// sits where its quantities are known. Counters, log lines and callback calls come in sba
// 1.6's order, which the "sba" strategy's stop reasons and iteration counts depend on.
class LevenbergMarquardt {
 public:
  LevenbergMarquardt(const Layout &lay, Steps &st, StepSolver &solver, Strategy &strategy, const Options &opt, const Logger &log, Summary &sum,
                     std::chrono::steady_clock::time_point t0)
      : lay_(lay), st_(st), w_(st.w), ne_(damped(st.w.view(), strategy.damping())), pool_(st.pool_),
        kernels_(st.kernels_),
        solver_(solver), strategy_(strategy), opt_(opt), log_(log), sum_(sum),
        t0_(t0), nvars_(lay.nvars()) {}

  // Iterates from p (updated in place with the last accepted estimate). False on a failure,
  // with sum's reason and figures telling where the solve stood.
  bool run(double *p) {
    if (!start(p)) return false;
    for (it_ = 0; it_ < opt_.itmax && !stop_; ++it_) {
      if (!linearize(p)) return fail(kStopNonFinite, it_);
      if (!stop_ && !compute_step(p)) return false;
      if (!stop_ && eps_ <= opt_.eps3 * opt_.eps3) stop_ = kStopError;
      report_progress();
    }
    if (!stop_) stop_ = kStopItmax;
    finish();
    return true;
  }

 private:
  static NormalEquations damped(NormalEquations ne, const double *damping) {
    ne.damping = damping;
    return ne;
  }

  // What became of one damped solve.
  enum class Attempt {
    kAccepted,  // p moved to the candidate
    kRejected,  // no step, or one the strategy did not take: raise the damping and retry
    kStopped,   // a stop test fired
    kFailed,    // the solve cannot go on (sum says why)
  };

  // f(p) and the error at the starting point, and the first lines of the log.
  bool start(double *p) {
    Cost c0;
    sum_.nfev = 1;
    if (!st_.start(p, " at the initial estimate", &c0)) {
      log_.legacy(1, "initial %s-SBA error %g [%g]\n", legacy_name(lay_.mode), double(NAN), double(NAN));
      sum_.reason = kStopNonFinite;
      return false;
    }
    eps_ = c0.cost;
    sqe_ = c0.sq;
    proj_ = c0.proj;
    prior_ = c0.prior;
    sum_.proj_err0 = proj_;
    sum_.prior_err0 = prior_;
    log_.legacy(1, "initial %s-SBA error %g [%g]\n", legacy_name(lay_.mode), eps_, eps_ / double(lay_.nvis));
    sum_.err0 = sum_.err = eps_;
    sum_.sq_err0 = sum_.sq_err = sqe_;
    if (!std::isfinite(eps_)) {
      log_.error("sba: the initial error is not finite (check x and covx)");
      sum_.reason = kStopNonFinite;
      return false;
    }
    log_.info(1, "SBA: initial error %g, %g per measurement (%lld measurements, %lld variables)",
              eps_, eps_ / double(lay_.nvis), static_cast<long long>(lay_.nvis),
              static_cast<long long>(nvars_));
    return true;
  }

  // J and the normal equations at p, handed to the strategy; the first damping; stop 1.
  // False if they are not finite.
  bool linearize(double *p) {
    ++sum_.njev;
    char where[64];
    std::snprintf(where, sizeof where, " at iteration %d", it_);
    if (!st_.linearize(p, where)) return false;
    // Stop 1 looks at the gradient in the units of p, whatever the strategy solves in.
    gradient_stats(lay_, w_, &sum_.grad_inf, &maxdiag_);
    strategy_.linearized(pool_, kernels_, w_.blocks(), w_.U.data(), w_.V.data(), w_.ea.data(), w_.eb.data());
    maxdiag_ = strategy_.solved_max_diagonal(maxdiag_);
    if (it_ == 0) mu_ = strategy_.initial_damping(opt_.tau, maxdiag_);
    if (sum_.grad_inf <= opt_.eps1) {
      sum_.dp2 = 0.0;
      stop_ = kStopGradient;
    }
    return true;
  }

  // Damped solves at growing mu until a step is accepted or a stop test fires (2, 4, 6).
  // False on a failure (7, 8).
  bool compute_step(double *p) {
    p2_ = sqnorm(pool_, p, nvars_);
    for (;;) {
      switch (attempt(p)) {
        case Attempt::kAccepted:
        case Attempt::kStopped:
          return true;
        case Attempt::kFailed:
          return false;
        case Attempt::kRejected:
          break;
      }
      if (!raise_damping()) {
        stop_ = kStopDamping;
        return true;
      }
    }
  }

  // One damped solve at mu, its step tested (stops 2 and 8), the candidate evaluated.
  Attempt attempt(double *p) {
    double *dp = w_.dp.data();
    const StepStatus status = solver_.solve(ne_, mu_, dp);
    if (status != StepStatus::SingularPointBlock) ++sum_.nlinsys;
    if (status != StepStatus::Solved || !all_finite(pool_, dp, nvars_)) {
      log_.warning("sba: the damped system could not be factored (mu = %g); increasing damping", mu_);
      return Attempt::kRejected;
    }
    const double dL = strategy_.step_in_parameters(pool_, w_.ea.data(), w_.eb.data(), mu_, dp);
    const double dp2 = sqnorm(pool_, dp, nvars_);
    sum_.dp2 = dp2;
    if (dp2 <= opt_.eps2 * opt_.eps2 * p2_) {
      stop_ = kStopStep;
      return Attempt::kStopped;
    }
    if (dp2 >= (p2_ + opt_.eps2) / kSingularEpsSq) {
      log_.error("sba: the augmented normal equations are almost singular (||dp||^2 = %g); "
                 "the problem may be badly parametrized",
                 dp2);
      fail(kStopSingular, it_ + 1);
      return Attempt::kFailed;
    }
    Cost cn;
    if (!evaluate_candidate(p, &cn)) {
      fail(kStopNonFinite, it_ + 1);
      return Attempt::kFailed;
    }
    return accept_or_reject(p, dL, dp2, cn);
  }

  // The candidate p + dp, made in dp's place (one parameter vector fewer), and its cost.
  // False if f is not finite there.
  bool evaluate_candidate(const double *p, Cost *cn) {
    double *pn = w_.dp.data();
    pool_.for_range(nvars_, [&](i64 b, i64 e) {
      for (i64 q = b; q < e; ++q) pn[q] += p[q];
    });
    ++sum_.nfev;
    return st_.evaluate_trial(it_, cn);
  }

  // The strategy's verdict on the candidate, given the reduction dL the linear model
  // predicted; an accepted step moves p and lowers the damping (stop 4 may fire, and may on a
  // rejected one too).
  Attempt accept_or_reject(double *p, double dL, double dp2, const Cost &cn) {
    const double epsn = cn.cost, dF = eps_ - epsn, nvis = double(lay_.nvis);
    log_.legacy(2, "\ndamping term %8g, gain ratio %8g, errors %8g / %8g = %g\n", mu_,
                dF / (dL != 0.0 ? dL : DBL_EPSILON), eps_ / nvis, epsn / nvis, eps_ / epsn);
    log_.info(2, "SBA: iteration %d: mu %g, error %g -> %g, ||dp||^2 %g, gain ratio %g", it_, mu_,
              eps_, epsn, dp2, dL != 0.0 ? dF / dL : 0.0);
    if (!strategy_.acceptable(dF, dL)) {
      if (!strategy_.converged_on_rejection(eps_, epsn)) return Attempt::kRejected;
      stop_ = kStopReduction;
      return Attempt::kStopped;
    }
    if (strategy_.converged(eps_, epsn)) stop_ = kStopReduction;
    st_.accept(p, cn);
    sum_.moved = true;
    eps_ = epsn;
    sqe_ = cn.sq;
    proj_ = cn.proj;
    prior_ = cn.prior;
    mu_ = strategy_.after_success(mu_, dF / dL);
    nu_ = 2;
    return Attempt::kAccepted;
  }

  // After an attempt that gave no step: mu grows by nu and nu doubles, and the strategy
  // prepares the blocks of the next attempt. False when there is nothing left to try.
  bool raise_damping() {
    const double tried = mu_;
    mu_ *= nu_;
    if (strategy_.exhausted(mu_, nu_)) return false;
    nu_ *= 2;
    strategy_.before_retry(pool_, kernels_, tried, w_.U.data(), w_.V.data());
    return true;
  }

  // After every iteration, the last one too (whatever ended it); a request to stop after the
  // last one changes nothing: the solve ends with the reason it already has.
  void report_progress() {
    if (!opt_.progress) return;
    const sba_progress state{
        it_ + 1, eps_, mu_, std::sqrt(sum_.dp2),
        std::chrono::duration<double>(std::chrono::steady_clock::now() - t0_).count()};
    const bool last = stop_ || it_ + 1 >= opt_.itmax;
    if (opt_.progress(opt_.progress_ctx, &state) != 0 && !last) stop_ = kStopUser;
  }

  // Where the solve stands: p and eps_ are the last accepted, also after a failure.
  void record(StopReason reason, int iterations) {
    sum_.err = eps_;
    sum_.sq_err = sqe_;
    sum_.proj_err = proj_;
    sum_.prior_err = prior_;
    sum_.reason = reason;
    sum_.iterations = iterations;
    sum_.mu_ratio = maxdiag_ > 0 ? mu_ / maxdiag_ : 0.0;
  }

  bool fail(StopReason reason, int iterations) {
    record(reason, iterations);
    return false;
  }

  void finish() {
    record(stop_, it_);
    sum_.ok = true;
    if (opt_.loss.robust()) sum_.outliers += st_.outliers();
    log_.info(1, "SBA: %d iterations, stop reason %d, final error %g, %g per measurement", it_,
              int(stop_), eps_, eps_ / double(lay_.nvis));
  }

  const Layout &lay_;
  Steps &st_;
  Workspace &w_;
  const NormalEquations ne_;
  ThreadPool &pool_;
  const Kernels &kernels_;
  StepSolver &solver_;
  Strategy &strategy_;
  const Options &opt_;
  const Logger &log_;
  Summary &sum_;
  const std::chrono::steady_clock::time_point t0_;
  const i64 nvars_;

  int it_ = 0;
  StopReason stop_ = kStopNone;
  double eps_ = 0.0, sqe_ = 0.0;  // the cost and squared error at p
  double proj_ = 0.0, prior_ = 0.0;  // the cost's parts at p
  double mu_ = 0.0, maxdiag_ = 0.0;
  int nu_ = 2;      // the growth of mu at the next rejection
  double p2_ = 0.0;  // ||p||^2 at the start of the iteration
};

}  // namespace

bool solve(const Layout &lay, Model &model, double *p, const double *x, const double *covx,
           const Options &opt, const Logger &log, Summary &sum, const SolverWrap &wrap) {
  sum = Summary{};
  const auto t0 = std::chrono::steady_clock::now();
  ThreadPool pool(opt.nthreads, opt.avoid_shared_cores);
  const ModelThreads lend(model, &pool);
  const std::unique_ptr<Kernels> kernels = make_kernels(lay, pool.size());
  const PriorTerms priors(opt.priors, lay);
  Steps st(lay, model, x, opt.loss, log, pool, *kernels, covx != nullptr, &priors, opt.single_jacobian);
  std::unique_ptr<StepSolver> solver = make_step_solver(opt.solver, SolveContext{lay, pool, *kernels, opt.schur_analysis.get()});
  if (wrap) solver = wrap(std::move(solver));
  const std::unique_ptr<Strategy> strategy = make_strategy(opt.strategy, lay, opt.eps4, solver->takes_damping());
  if (!st.weigh(covx)) return false;
  // A solve that iterates starts with every shared parameter's copies equal; one that fails
  // before its first step, or only scores p (itmax 0), leaves p as the caller gave it.
  std::vector<double> given;
  if (opt.itmax > 0) given = tie_copies(lay, p);
  const bool ok = LevenbergMarquardt(lay, st, *solver, *strategy, opt, log, sum, t0).run(p);
  if (!ok && !sum.moved) restore_copies(lay, p, given);
  return ok;
}

}  // namespace sba
