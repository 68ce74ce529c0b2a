// Implicit S: truncated preconditioned conjugate gradients on the reduced camera system
// S da = e_a - W V*^-1 e_b, with S = U* - W V*^-1 W^T never formed. For photo collections,
// where most camera pairs share points, S is dense and a factorization of it costs the cube
// of the cameras in time and their square in memory; a product S x costs instead a pass
// over the observations, and this solver's memory is proportional to the observations and
// the points (no camera x camera or point x point array anywhere).
//
// S x in two passes over the Jacobian, each output computed by one thread in a fixed order
// (so any thread count gives the same bits):
//   1. by point:  t_i = V*_i^-1 sum_j W_ij^T x_j, with W_ij^T x_j = B_ij^T (A_ij x_j);
//   2. by camera: (S x)_j = U*_j x_j - sum_i W_ij t_i, with W_ij t_i = A_ij^T (B_ij t_i).
// W is applied from the Jacobian blocks rather than stored: W_ij^T x_j as two thin
// products takes mnp (cnp + pnp) multiply-adds, as many as the stored cnp x pnp W_ij
// (mnp = 2, pnp = 3), and reads as many doubles, so storing W would double the memory
// that the Jacobian already takes for no gain.
//
// The preconditioner is S's block diagonal (Schur-Jacobi): D_j = U*_j - sum_i W_ij V*_i^-1
// W_ij^T, one Cholesky-factored cnp x cnp block per camera, made once per damped system.
//
// Stopping: an inexact Newton (truncated) step. CG stops when ||S da - rhs|| <= eta ||rhs||,
// with the forcing term eta = min(kEtaMax, sqrt(||g|| / ||g_0||)) (g = J^T e on the free
// parameters at this iteration, g_0 at the solve's first): loose far from the solution,
// where an exact step is wasted, and tightening as the gradient falls, which keeps LM's
// convergence superlinear (Eisenstat and Walker's choice 2 family; Dembo and Steihaug).
// At most kMaxIterations iterations (and no more than twice S's order). The iterate CG stops
// at is used if it is a descent direction (e_a^T da > 0 for the reduced problem), whether or
// not the tolerance was met; otherwise the solve fails and LM raises the damping.
//
// LM's gain ratio needs the model reduction of the step taken. Every CG iterate from zero
// satisfies da^T S da = da^T rhs (its residual is orthogonal to the Krylov space that holds
// it), and with the points' steps by exact back-substitution this gives
// dp^T (J^T J + mu I) dp = dp^T g: the reduction LM computes for an exact step,
// dp^T (mu dp + g), is then the model's reduction for this inexact one as well.
#include <algorithm>
#include <cmath>
#include <vector>

#include "small_dense.h"
#include "step_solver.h"

namespace sba {
namespace {

// Forcing term bounds and the iteration cap (see above).
constexpr double kEtaMax = 0.1;
constexpr int kMaxIterations = 500;

// Free items [0, count) split over T threads so that each gets about the same number of
// observations; ptr[q] .. ptr[q + 1] are item q's (first + q in the layout's numbering).
std::vector<i64> split_by_work(const std::vector<int> &ptr, int first, int count, int T) {
  std::vector<i64> cut(size_t(T) + 1, count);
  cut[0] = 0;
  if (count == 0) return cut;
  const double w0 = ptr[size_t(first)], total = double(ptr[size_t(first + count)]) - w0;
  i64 q = 0;
  for (int t = 1; t < T; ++t) {
    // Work of an item: its observations plus one, so that items without any still spread.
    const double goal = (total + double(count)) * t / T;
    while (q < count && double(ptr[size_t(first + q)]) - w0 + double(q) < goal) ++q;
    cut[size_t(t)] = q;
  }
  return cut;
}

template <int M, int C, int P>
class IterativeSchurSolver final : public StepSolver {
 public:
  explicit IterativeSchurSolver(const SolveContext &ctx) : ctx_(ctx), lay_(ctx.lay) {
    const Layout &lay = lay_;
    nc_ = lay.free_cams();
    np_ = lay.free_pts();
    nS_ = i64(nc_) * cnp();
    by_camera(lay, &cam_pt_, &cam_k_);
    const int T = ctx.pool.size();
    cam_cut_ = split_by_work(lay.colptr, lay.mcon, nc_, T);
    pt_cut_ = split_by_work(lay.rowptr, lay.ncon, np_, T);
    Vinv_.resize(size_t(lay.n) * size_t(pnp()) * size_t(pnp()));
    t_.resize(size_t(lay.n) * size_t(pnp()));
    D_.resize(size_t(nS_) * size_t(cnp()));
    for (std::vector<double> *v : {&rhs_, &x_, &r_, &z_, &p_, &q_}) v->resize(size_t(nS_));
    scratch_.resize(size_t(T) * size_t(2 * cnp() * pnp() + mnp() + cnp() + pnp()));
  }

  bool solve(const NormalEquations &ne, double mu, double *dp) override {
    const Layout &lay = lay_;
    ThreadPool &pool = ctx_.pool;
    std::fill(dp, dp + lay.a_off(lay.mcon), 0.0);
    std::fill(dp + lay.b_off(0), dp + lay.b_off(lay.ncon), 0.0);
    if (!ctx_.kernels.invert_damped_V(pool, ne.V, mu, Vinv_.data())) return false;

    // rhs = e_a - W V*^-1 e_b, and the forcing term from the gradient's norm.
    const int pn = pnp();
    for_points([&](int i, double *) {
      const double *Vi = Vinv_.data() + i64(i) * pn * pn, *ebi = ne.eb + i64(i) * pn;
      double *ti = t_.data() + i64(i) * pn;
      for (int a = 0; a < pn; ++a) {
        double s = 0.0;
        for (int c = 0; c < pn; ++c) s += Vi[a * pn + c] * ebi[c];
        ti[a] = s;
      }
    });
    subtract_W_t(ne, ne.ea + lay.a_off(lay.mcon), 0.0, nullptr, rhs_.data());
    const double *eb_free = ne.eb + i64(lay.ncon) * pn;
    const double g2 =
        dot(ne.ea + lay.a_off(lay.mcon), ne.ea + lay.a_off(lay.mcon), nS_) + dot(eb_free, eb_free, i64(np_) * pn);
    if (!std::isfinite(g2)) return false;
    if (g0_ < 0.0) g0_ = std::sqrt(g2);
    const double eta = g0_ > 0.0 ? std::min(kEtaMax, std::sqrt(std::sqrt(g2) / g0_)) : kEtaMax;

    if (!make_preconditioner(ne, mu)) return false;
    double *da = dp + lay.a_off(lay.mcon);
    if (!conjugate_gradients(ne, mu, eta, da)) return false;
    ctx_.kernels.back_substitute(pool, ne, Vinv_.data(), mu, dp);
    return true;
  }

  // y = S x on its own (iterative_schur_product).
  bool product(const NormalEquations &ne, double mu, const double *x, double *y) {
    if (!ctx_.kernels.invert_damped_V(ctx_.pool, ne.V, mu, Vinv_.data())) return false;
    multiply(ne, mu, x, y);
    return true;
  }

 private:
  int mnp() const { return M ? M : lay_.mnp; }
  int cnp() const { return C ? C : lay_.cnp; }
  int pnp() const { return P ? P : lay_.pnp; }

  // fn(i, scratch) for every free point i, over the threads.
  template <class Fn>
  void for_points(Fn fn) {
    const size_t per = scratch_.size() / size_t(ctx_.pool.size());
    run_cut(pt_cut_, [&](int t, i64 b, i64 e) {
      for (i64 q = b; q < e; ++q) fn(int(q) + lay_.ncon, scratch_.data() + size_t(t) * per);
    });
  }
  // fn(j, scratch) for every free camera j (free-camera numbering), over the threads.
  template <class Fn>
  void for_cameras(Fn fn) {
    const size_t per = scratch_.size() / size_t(ctx_.pool.size());
    run_cut(cam_cut_, [&](int t, i64 b, i64 e) {
      for (i64 q = b; q < e; ++q) fn(int(q), scratch_.data() + size_t(t) * per);
    });
  }
  template <class Fn>
  void run_cut(const std::vector<i64> &cut, Fn fn) {
    if (ctx_.pool.size() == 1) {
      fn(0, cut[0], cut[1]);
      return;
    }
    ctx_.pool.run([&](int t) {
      if (cut[size_t(t)] < cut[size_t(t) + 1]) fn(t, cut[size_t(t)], cut[size_t(t) + 1]);
    });
  }

  double dot(const double *a, const double *b, i64 n) {
    return deterministic_sum(ctx_.pool, n, [=](i64 k) { return a[k] * b[k]; });
  }

  // y_j = base_j + mu x_j ... : y_j = U_j x_j + mu x_j - sum_i W_ij t_i when U is given,
  // else y_j = base_j - sum_i W_ij t_i, over the free cameras, t_ from the point pass.
  void subtract_W_t(const NormalEquations &ne, const double *base, double mu, const double *x, double *y) {
    const Layout &lay = lay_;
    const int mn = mnp(), cn = cnp(), pn = pnp(), jb = lay.jblk();
    for_cameras([&](int j, double *sc) {
      const int cam = j + lay.mcon;
      double *yj = y + i64(j) * cn;
      if (x) {
        const double *Uj = ne.U + i64(cam) * cn * cn, *xj = x + i64(j) * cn;
        for (int a = 0; a < cn; ++a) {
          double s = mu * xj[a];
          for (int c = 0; c < cn; ++c) s += Uj[a * cn + c] * xj[c];
          yj[a] = s;
        }
      } else {
        std::copy_n(base + i64(j) * cn, cn, yj);
      }
      double ul[M > 0 ? M : 1];
      double *u = M > 0 ? ul : sc;
      for (int s = lay.colptr[cam]; s < lay.colptr[cam + 1]; ++s) {
        const int i = cam_pt_[size_t(s)];
        if (i < lay.ncon) continue;
        const double *A = ne.jac + i64(cam_k_[size_t(s)]) * jb, *B = A + mn * cn;
        const double *ti = t_.data() + i64(i) * pn;
        for (int r = 0; r < mn; ++r) {
          double v = 0.0;
          for (int c = 0; c < pn; ++c) v += B[r * pn + c] * ti[c];
          u[r] = v;
        }
        for (int r = 0; r < mn; ++r)
          for (int a = 0; a < cn; ++a) yj[a] -= A[r * cn + a] * u[r];
      }
    });
  }

  // y = S x.
  void multiply(const NormalEquations &ne, double mu, const double *x, double *y) {
    const Layout &lay = lay_;
    const int mn = mnp(), cn = cnp(), pn = pnp(), jb = lay.jblk();
    for_points([&](int i, double *sc) {
      double ul[M > 0 ? M : 1], wl[P > 0 ? P : 1];
      double *u = M > 0 ? ul : sc, *w = P > 0 ? wl : sc + mn;
      for (int c = 0; c < pn; ++c) w[c] = 0.0;
      for (int k = lay.rowptr[i]; k < lay.rowptr[i + 1]; ++k) {
        const int j = lay.colidx[k] - lay.mcon;
        if (j < 0) continue;
        const double *A = ne.jac + i64(k) * jb, *B = A + mn * cn;
        const double *xj = x + i64(j) * cn;
        for (int r = 0; r < mn; ++r) {
          double v = 0.0;
          for (int a = 0; a < cn; ++a) v += A[r * cn + a] * xj[a];
          u[r] = v;
        }
        for (int r = 0; r < mn; ++r)
          for (int c = 0; c < pn; ++c) w[c] += B[r * pn + c] * u[r];
      }
      const double *Vi = Vinv_.data() + i64(i) * pn * pn;
      double *ti = t_.data() + i64(i) * pn;
      for (int a = 0; a < pn; ++a) {
        double v = 0.0;
        for (int c = 0; c < pn; ++c) v += Vi[a * pn + c] * w[c];
        ti[a] = v;
      }
    });
    subtract_W_t(ne, nullptr, mu, x, y);
  }

  // D_j = U_j + mu I - sum_i W_ij V*_i^-1 W_ij^T, Cholesky-factored; false if one is not
  // positive definite (then neither is S at this damping, up to rounding).
  bool make_preconditioner(const NormalEquations &ne, double mu) {
    const Layout &lay = lay_;
    const int mn = mnp(), cn = cnp(), pn = pnp(), jb = lay.jblk();
    std::vector<int> ok(size_t(nc_), 1);
    for_cameras([&](int j, double *sc) {
      const int cam = j + lay.mcon;
      double *Dj = D_.data() + i64(j) * cn * cn;
      std::copy_n(ne.U + i64(cam) * cn * cn, cn * cn, Dj);
      for (int a = 0; a < cn; ++a) Dj[a * cn + a] += mu;
      double *W = sc, *Y = sc + cn * pn;  // cnp x pnp each, row-major
      for (int s = lay.colptr[cam]; s < lay.colptr[cam + 1]; ++s) {
        const int i = cam_pt_[size_t(s)];
        if (i < lay.ncon) continue;
        const double *A = ne.jac + i64(cam_k_[size_t(s)]) * jb, *B = A + mn * cn;
        const double *Vi = Vinv_.data() + i64(i) * pn * pn;
        for (int a = 0; a < cn; ++a)
          for (int c = 0; c < pn; ++c) {
            double v = 0.0;
            for (int r = 0; r < mn; ++r) v += A[r * cn + a] * B[r * pn + c];
            W[a * pn + c] = v;
          }
        for (int a = 0; a < cn; ++a)
          for (int c = 0; c < pn; ++c) {
            double v = 0.0;
            for (int d = 0; d < pn; ++d) v += W[a * pn + d] * Vi[d * pn + c];
            Y[a * pn + c] = v;
          }
        // Only the lower triangle: chol reads no more.
        for (int a = 0; a < cn; ++a)
          for (int b = 0; b <= a; ++b) {
            double v = 0.0;
            for (int c = 0; c < pn; ++c) v += Y[a * pn + c] * W[b * pn + c];
            Dj[a * cn + b] -= v;
          }
      }
      ok[size_t(j)] = small::chol<C>(Dj, cn);
    });
    return std::all_of(ok.begin(), ok.end(), [](int v) { return v != 0; });
  }

  // z = D^-1 r.
  void precondition(const double *r, double *z) {
    const int cn = cnp();
    for_cameras([&](int j, double *) {
      double *zj = z + i64(j) * cn;
      std::copy_n(r + i64(j) * cn, cn, zj);
      small::chol_solve<C>(D_.data() + i64(j) * cn * cn, zj, cn);
    });
  }

  // Truncated PCG from x = 0 on S da = rhs_; false when no descent direction came out.
  bool conjugate_gradients(const NormalEquations &ne, double mu, double eta, double *da) {
    const i64 n = nS_;
    double *x = x_.data(), *r = r_.data(), *z = z_.data(), *p = p_.data(), *q = q_.data();
    const double *b = rhs_.data();
    iterations_ = 0;
    std::fill(x, x + n, 0.0);
    std::copy_n(b, n, r);
    const double bb = dot(b, b, n);
    if (!std::isfinite(bb)) return false;
    if (bb == 0.0) {
      std::fill(da, da + n, 0.0);
      return true;
    }
    const double tol2 = eta * eta * bb;
    precondition(r, z);
    double rz = dot(r, z, n);
    if (!(rz > 0.0)) return false;
    std::copy_n(z, n, p);
    const int maxit = int(std::min<i64>(kMaxIterations, std::max<i64>(2 * n, 1)));
    for (int k = 0; k < maxit; ++k) {
      multiply(ne, mu, p, q);
      const double pq = dot(p, q, n);
      if (!(pq > 0.0)) break;  // S not positive definite along p: keep the iterate reached
      const double alpha = rz / pq;
      const double rr = deterministic_sum(ctx_.pool, n, [=](i64 e) {
        x[e] += alpha * p[e];
        r[e] -= alpha * q[e];
        return r[e] * r[e];
      });
      ++iterations_;
      if (!std::isfinite(rr)) return false;
      if (rr <= tol2) break;
      precondition(r, z);
      const double rz_next = dot(r, z, n);
      if (!(rz_next > 0.0)) break;
      const double beta = rz_next / rz;
      rz = rz_next;
      ctx_.pool.for_range(n, [=](i64 e0, i64 e1) {
        for (i64 e = e0; e < e1; ++e) p[e] = z[e] + beta * p[e];
      });
    }
    if (iterations_ == 0 || !(dot(b, x, n) > 0.0)) return false;
    std::copy_n(x, n, da);
    return true;
  }

  SolveContext ctx_;
  const Layout &lay_;
  int nc_ = 0, np_ = 0;
  i64 nS_ = 0;
  std::vector<int> cam_pt_, cam_k_;       // by_camera: point and measurement of each slot
  std::vector<i64> cam_cut_, pt_cut_;     // the threads' ranges of free cameras / points
  std::vector<double> Vinv_, t_, D_;      // (V_i + mu I)^-1, the point pass, the preconditioner
  std::vector<double> rhs_, x_, r_, z_, p_, q_;
  std::vector<double> scratch_;           // per thread: run-time-sized blocks
  double g0_ = -1.0;                      // ||g|| at the first solve
  int iterations_ = 0;
};

// fn(solver) with the solver compiled for the layout's block sizes.
template <class Fn>
auto with_solver(const SolveContext &ctx, Fn fn) {
  const Layout &lay = ctx.lay;
  if (lay.mnp == 2 && lay.pnp == 3) {
    if (lay.cnp == 6) return fn(std::make_unique<IterativeSchurSolver<2, 6, 3>>(ctx));
    if (lay.cnp == 9) return fn(std::make_unique<IterativeSchurSolver<2, 9, 3>>(ctx));
  }
  return fn(std::make_unique<IterativeSchurSolver<0, 0, 0>>(ctx));
}

}  // namespace

std::unique_ptr<StepSolver> make_iterative_schur_solver(const SolveContext &ctx) {
  return with_solver(ctx, [](auto s) -> std::unique_ptr<StepSolver> { return s; });
}

bool iterative_schur_product(const SolveContext &ctx, const NormalEquations &ne, double mu,
                             const double *x, double *y) {
  return with_solver(ctx, [&](auto s) { return s->product(ne, mu, x, y); });
}

}  // namespace sba
