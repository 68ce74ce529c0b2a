// SPDX-License-Identifier: BSD-3-Clause
// Implicit S: truncated preconditioned conjugate gradients on the reduced camera system
// S da = e_a - W V*^-1 e_b, with S = U* - W V*^-1 W^T never formed. For photo collections,
// where most camera pairs share points, S is dense and a factorization of it costs the cube
// of the cameras in time and their square in memory; a product S x costs instead a pass
// over the observations, and this solver's memory is proportional to the observations and
// the points.
//
// S x = U* x - W V*^-1 W^T x in one pass over the Jacobian by point: for each free point,
// t_i = V*_i^-1 sum_j W_ij^T x_j, then the terms -W_ij t_i of its cameras, while the point's
// Jacobian blocks are still in cache. W is applied from the Jacobian blocks rather than
// stored: W_ij^T x_j as B_ij^T (A_ij x_j) takes mnp (cnp + pnp) multiply-adds, as many as
// with the stored cnp x pnp W_ij (mnp = 2, pnp = 3), and reads as many doubles, so storing
// W would double the memory the Jacobian already takes for no gain. A pass by camera (each
// camera's sum computed whole by one thread) would read the point-major Jacobian in
// scattered order and wait for memory at every block; instead the points are cut into a
// fixed number of chunks, each adding its terms into partial sums of its own, which are then
// added in chunk order: every sum has the same order for any thread count, so any thread
// count gives the same bits.
//
// The preconditioner is S's block diagonal (Schur-Jacobi): D_j = U*_j - sum_i W_ij V*_i^-1
// W_ij^T, one Cholesky-factored cnp x cnp block per camera, made once per damped system in
// the same chunked pass by point.
//
// With shared unknowns, a camera's parameters fall into several blocks (camera_map.h), and
// S's diagonal blocks over them would leave out what a camera's own block preconditions
// without sharing: the coupling of its pose to its lens. The preconditioner is then S's
// principal submatrix over clusters of blocks, each factored whole: a shared block (a lens)
// with the own blocks (the poses) of the cameras that touch it and nothing else, up to
// kMaxCluster unknowns; every other block alone. A principal submatrix of an SPD S is SPD, so
// any clustering gives a valid PCG preconditioner; this one keeps each lens with the poses it
// moves with, as the camera block does without sharing.
//
// Memory: the point blocks' inverses (n pnp^2), kChunks (cnp + 1) doubles per unknown of S
// for the partial sums, and six vectors of S's order: no array of cameras x cameras or
// anything per observation beyond the Jacobian LM already holds. With shared unknowns, the
// clusters' matrices add at most kMaxCluster doubles per unknown.
//
// Stopping: an inexact Newton (truncated) step. CG stops when ||S da - rhs|| <= eta ||rhs||,
// with the forcing term eta = sqrt(||g|| / ||g_0||) within [kEtaMin, kEtaMax] (g = J^T e on
// the free parameters at this iteration, g_0 at the solve's first): loose far from the
// solution, where an exact step is wasted, and tightening as the gradient falls, which keeps
// LM's convergence superlinear (Eisenstat and Walker's choice 2 family; Dembo and Steihaug)
// until the floor, and linear at a rate of about kEtaMin beyond it.
// At most kMaxIterations iterations (and no more than twice S's order). The iterate CG stops
// at is used if it is a descent direction of the reduced problem (rhs^T da > 0), whether or
// not the tolerance was met; otherwise the solve fails and LM raises the damping.
//
// LM's gain ratio needs the model reduction of the step taken. Every CG iterate from zero
// satisfies da^T S da = da^T rhs (its residual is orthogonal to the Krylov space that holds
// it), and with the points' steps by exact back-substitution this gives
// dp^T (J^T J + mu I) dp = dp^T g: the reduction LM computes for an exact step,
// dp^T (mu dp + g), is then the model's reduction for this inexact one as well.
#include <algorithm>
#include <cmath>
#include <memory>
#include <vector>

#include "mapped_schur.h"
#include "small_dense.h"
#include "step_solver.h"

namespace sba {
namespace {

// Forcing term bounds and the iteration cap (see above). The upper bound is tight because on
// badly conditioned problems (BAL's, cnp 9) a looser inexact step is poor enough for LM to
// stall in their flat valleys short of the minimum an exact step reaches; on well
// conditioned ones it costs few CG iterations, since at the large early damping CG converges
// in a few anyway. The BAL runs of bench/run_suite.sh and the orbit series of
// bench/series.sh are the benchmarks behind it. The floor: once the gradient has fallen
// below 1e-8 of the first, the cost has stopped changing in any digit a caller reads, and a
// solve continued to the iteration limit (as COLMAP's defaults ask) meets a damping that
// has fallen to nothing and S's gauge freedom, where every further digit of the residual
// costs CG more iterations than the whole solve before it.
constexpr double kEtaMax = 1e-3;
constexpr double kEtaMin = 1e-4;
constexpr int kMaxIterations = 500;

// The largest order of a cluster of the preconditioner with shared unknowns (see the top):
// its factorization costs the cube and its storage the square, and a lens shared by a
// thousand images would otherwise make one dense block of S's whole order. 128 holds a lens
// of up to 8 unknowns with the poses of 20 images.
constexpr int kMaxCluster = 128;

// The point pass of S x runs in this many chunks of points, each with its own partial sums
// (kChunks x S's order doubles): a fixed number, so that the sums' order does not depend on
// the thread count, and a few per thread for the load balance of up to a few dozen threads.
constexpr int kChunks = 32;

// Free points [0, count) split into T chunks of about the same number of observations;
// ptr[q] .. ptr[q + 1] are point q's (first + q in the layout's numbering).
std::vector<i64> split_by_work(const std::vector<int> &ptr, int first, int count, int T) {
  std::vector<i64> cut(size_t(T) + 1, count);
  cut[0] = 0;
  if (count == 0) return cut;
  const double w0 = ptr[size_t(first)], total = double(ptr[size_t(first + count)]) - w0;
  i64 q = 0;
  for (int t = 1; t < T; ++t) {
    // A point's work: its observations plus one, so that points without any still spread.
    const double goal = (total + double(count)) * t / T;
    while (q < count && double(ptr[size_t(first + q)]) - w0 + double(q) < goal) ++q;
    cut[size_t(t)] = q;
  }
  return cut;
}

template <int M, int C, int P>
class IterativeSchurSolver final : public StepSolver {
 public:
  // max_cluster: the largest order of a cluster of the preconditioner (the tests compare
  // kMaxCluster with 0, S's diagonal blocks alone).
  explicit IterativeSchurSolver(const SolveContext &ctx, int max_cluster = kMaxCluster) : ctx_(ctx), lay_(ctx.lay) {
    const Layout &lay = lay_;
    nc_ = lay.free_cams();
    np_ = lay.free_pts();
    nC_ = i64(nc_) * cnp();
    nS_ = lay.camera_unknowns();
    const int T = ctx.pool.size();
    chunk_ = split_by_work(lay.rowptr, lay.ncon, np_, kChunks);
    partial_.resize(size_t(kChunks) * size_t(nC_));
    Vinv_.resize(size_t(lay.n) * size_t(pnp()) * size_t(pnp()));
    if (!lay.cams.per_camera()) {
      // Over shared unknowns the products run on the cameras' parameters (xc_, yc_, all m
      // cameras' as in p) and are reduced to the unknowns; the preconditioner is S over
      // clusters of the unknowns' blocks.
      schur_ = std::make_unique<MappedSchur>(lay, T);
      const CameraMap &map = lay.cams;
      find_clusters(map, max_cluster);
      xc_.resize(size_t(lay.m) * size_t(cnp()));
      yc_.resize(xc_.size());
    } else {
      Dpartial_.resize(partial_.size() * size_t(cnp()));
      D_.resize(size_t(nS_) * size_t(cnp()));
    }
    for (std::vector<double> *v : {&rhs_, &x_, &r_, &z_, &p_, &q_}) v->resize(size_t(nS_));
    // Per thread: the point pass's mnp + 2 pnp, or the preconditioner's mnp (pnp + mnp + cnp).
    const int mn = mnp(), cn = cnp(), pn = pnp();
    scratch_.resize(size_t(T) * size_t(std::max(mn + 2 * pn, mn * (pn + mn + cn))));
  }

  StepStatus solve(const NormalEquations &ne, double mu, double *dp) override {
    const Layout &lay = lay_;
    ThreadPool &pool = ctx_.pool;
    std::fill(dp, dp + lay.a_off(lay.mcon), 0.0);
    std::fill(dp + lay.b_off(0), dp + lay.b_off(lay.ncon), 0.0);
    if (!ctx_.kernels.invert_damped_V(pool, ne.V, mu, Vinv_.data())) return StepStatus::SingularPointBlock;

    // rhs = e_a - W V*^-1 e_b, and the forcing term from the gradient's norm.
    const int pn = pnp();
    point_pass(ne, nullptr);
    const double *ga = ne.ea + lay.a_off(lay.mcon);
    if (schur_) {
      gather(ne, 0.0, nullptr, ga, yc_.data() + lay.a_off(lay.mcon));
      lay.cams.reduce(yc_.data(), rhs_.data());
      lay.cams.reduce(ne.ea, x_.data());  // the gradient over the unknowns, for its norm
      ga = x_.data();
    } else {
      gather(ne, 0.0, nullptr, ga, rhs_.data());
    }
    const double *eb_free = ne.eb + i64(lay.ncon) * pn;
    const double g2 = dot(ga, ga, nS_) + dot(eb_free, eb_free, i64(np_) * pn);
    if (!std::isfinite(g2)) return StepStatus::Failed;
    if (g0_ < 0.0) g0_ = std::sqrt(g2);
    const double eta = g0_ > 0.0 ? std::clamp(std::sqrt(std::sqrt(g2) / g0_), kEtaMin, kEtaMax) : kEtaMax;

    if (!make_preconditioner(ne, mu)) return StepStatus::Failed;
    double *da = schur_ ? q_.data() : dp + lay.a_off(lay.mcon);
    if (!conjugate_gradients(ne, mu, eta, da)) return StepStatus::Failed;
    if (schur_) lay.cams.expand(da, -0.0, dp);
    ctx_.kernels.back_substitute(pool, ne, Vinv_.data(), mu, dp);
    return StepStatus::Solved;
  }

  // y = S x on its own (iterative_schur_product).
  bool product(const NormalEquations &ne, double mu, const double *x, double *y) {
    if (!ctx_.kernels.invert_damped_V(ctx_.pool, ne.V, mu, Vinv_.data())) return false;
    multiply(ne, mu, x, y);
    return true;
  }

  // The factored preconditioner on its own (iterative_schur_preconditioner).
  bool preconditioner(const NormalEquations &ne, double mu, double *D) {
    if (!ctx_.kernels.invert_damped_V(ctx_.pool, ne.V, mu, Vinv_.data())) return false;
    if (!make_preconditioner(ne, mu)) return false;
    std::copy(D_.begin(), D_.end(), D);
    return true;
  }

  // z = M^-1 r, the preconditioner made at damping mu (iterative_schur_apply_preconditioner).
  bool apply_preconditioner(const NormalEquations &ne, double mu, const double *r, double *z) {
    if (!ctx_.kernels.invert_damped_V(ctx_.pool, ne.V, mu, Vinv_.data())) return false;
    if (!make_preconditioner(ne, mu)) return false;
    precondition(r, z);
    return true;
  }

  // The CG iterations of the last solve.
  int cg_iterations() const { return cg_iterations_; }

 private:
  int mnp() const { return M ? M : lay_.mnp; }
  int cnp() const { return C ? C : lay_.cnp; }
  int pnp() const { return P ? P : lay_.pnp; }

  double dot(const double *a, const double *b, i64 n) {
    return deterministic_sum(ctx_.pool, n, [=](i64 k) { return a[k] * b[k]; });
  }

  // The point pass of S x (x given) or of the right-hand side (x null): for each free point,
  // t_i = V*_i^-1 sum_j W_ij^T x_j (or V*_i^-1 e_b,i), and its terms -W_ij t_i, added into
  // its chunk's partial sums while the point's Jacobian blocks are still in cache. Done by
  // camera instead, the pass would read the Jacobian (laid out by point) in scattered order
  // and wait for memory at every block; the partial sums of fixed chunks of points keep the
  // order of every sum independent of the thread count.
  void point_pass(const NormalEquations &ne, const double *x) {
    const Layout &lay = lay_;
    const int jb = lay.jblk();
    const size_t per = scratch_.size() / size_t(ctx_.pool.size());
    ctx_.pool.for_range_t(kChunks, [&](int t, i64 c0, i64 c1) {
      // The block sizes are read here, inside the task, where they fold to constants in the
      // compiled sizes' instances: captured from outside, they would be loads through the
      // closure, and the small loops below would neither unroll nor vectorize.
      const int mn = mnp(), cn = cnp(), pn = pnp();
      double *sc = scratch_.data() + size_t(t) * per;
      double ul[M > 0 ? M : 1], wl[P > 0 ? P : 1], tl[P > 0 ? P : 1];
      double *u = M > 0 ? ul : sc, *w = P > 0 ? wl : sc + mn, *ti = P > 0 ? tl : sc + mn + pn;
      for (i64 c = c0; c < c1; ++c) {
        double *yc = partial_.data() + c * nC_;
        std::fill(yc, yc + nC_, 0.0);
        for (i64 q = chunk_[size_t(c)]; q < chunk_[size_t(c) + 1]; ++q) {
          const int i = int(q) + lay.ncon;
          const int k0 = lay.rowptr[i], k1 = lay.rowptr[i + 1];
          const double *Vi = Vinv_.data() + i64(i) * pn * pn;
          if (x) {
            for (int d = 0; d < pn; ++d) w[d] = 0.0;
            for (int k = k0; k < k1; ++k) {
              const int j = lay.colidx[k] - lay.mcon;
              if (j < 0) continue;
              const double *A = ne.jac + i64(k) * jb, *B = A + mn * cn, *xj = x + i64(j) * cn;
              for (int r = 0; r < mn; ++r) {
                double v = 0.0;
                for (int a = 0; a < cn; ++a) v += A[r * cn + a] * xj[a];
                u[r] = v;
              }
              for (int r = 0; r < mn; ++r)
                for (int d = 0; d < pn; ++d) w[d] += B[r * pn + d] * u[r];
            }
          } else {
            for (int d = 0; d < pn; ++d) w[d] = ne.eb[i64(i) * pn + d];
          }
          for (int a = 0; a < pn; ++a) {
            double v = 0.0;
            for (int d = 0; d < pn; ++d) v += Vi[a * pn + d] * w[d];
            ti[a] = v;
          }
          for (int k = k0; k < k1; ++k) {
            const int j = lay.colidx[k] - lay.mcon;
            if (j < 0) continue;
            const double *A = ne.jac + i64(k) * jb, *B = A + mn * cn;
            double *yj = yc + i64(j) * cn;
            for (int r = 0; r < mn; ++r) {
              double v = 0.0;
              for (int d = 0; d < pn; ++d) v += B[r * pn + d] * ti[d];
              u[r] = v;
            }
            for (int r = 0; r < mn; ++r)
              for (int a = 0; a < cn; ++a) yj[a] -= A[r * cn + a] * u[r];
          }
        }
      }
    });
  }

  // y = base + the chunks' partial sums in chunk order; base_j = U*_j x_j when x is given.
  void gather(const NormalEquations &ne, double mu, const double *x, const double *base, double *y) {
    const i64 mcon = lay_.mcon;
    ctx_.pool.for_range(nc_, [&](i64 j0, i64 j1) {
      const int cn = cnp();
      for (i64 j = j0; j < j1; ++j) {
        double *yj = y + j * cn;
        if (x) {
          const double *Uj = ne.U + (j + mcon) * cn * cn, *xj = x + j * cn;
          for (int a = 0; a < cn; ++a) {
            double v = mu * xj[a];
            for (int c = 0; c < cn; ++c) v += Uj[a * cn + c] * xj[c];
            yj[a] = v;
          }
        } else {
          std::copy_n(base + j * cn, cn, yj);
        }
        for (int c = 0; c < kChunks; ++c) {
          const double *pc = partial_.data() + c * nC_ + j * cn;
          for (int a = 0; a < cn; ++a) yj[a] += pc[a];
        }
      }
    });
  }

  // y = S x. Over shared unknowns, through the cameras' parameters: S = P^T (U - W V*^-1
  // W^T) P + mu I with P the map from the unknowns to the parameters.
  void multiply(const NormalEquations &ne, double mu, const double *x, double *y) {
    if (!schur_) {
      point_pass(ne, x);
      gather(ne, mu, x, nullptr, y);
      return;
    }
    const Layout &lay = lay_;
    lay.cams.expand(x, 0.0, xc_.data());
    point_pass(ne, xc_.data() + lay.a_off(lay.mcon));
    gather(ne, 0.0, xc_.data() + lay.a_off(lay.mcon), nullptr, yc_.data() + lay.a_off(lay.mcon));
    lay.cams.reduce(yc_.data(), y);
    ctx_.pool.for_range(nS_, [=](i64 e0, i64 e1) {
      for (i64 e = e0; e < e1; ++e) y[e] += mu * x[e];
    });
  }

  // D_j = U_j + mu I - sum_i W_ij V*_i^-1 W_ij^T, Cholesky-factored; false if one is not
  // positive definite (then neither is S at this damping, up to rounding). The sums by
  // chunk of points, for the reasons of point_pass.
  bool make_preconditioner(const NormalEquations &ne, double mu) {
    if (schur_) return make_mapped_preconditioner(ne, mu);
    const Layout &lay = lay_;
    const int jb = lay.jblk();
    const i64 blocks = i64(nc_) * cnp() * cnp();
    const size_t per = scratch_.size() / size_t(ctx_.pool.size());
    ctx_.pool.for_range_t(kChunks, [&](int t, i64 c0, i64 c1) {
      const int mn = mnp(), cn = cnp(), pn = pnp(), cc = cn * cn;  // constants: see point_pass
      // BV = B V*_i^-1 (mnp x pnp), Y = BV B^T (mnp x mnp), N = Y A (mnp x cnp), row-major; on
      // the stack when the sizes are compile-time, where the compiler can keep them in registers.
      double BVl[M > 0 ? M * P : 1], Yl[M > 0 ? M * M : 1], Nl[M > 0 ? M * C : 1];
      double *sc = scratch_.data() + size_t(t) * per;
      double *BV = M > 0 ? BVl : sc, *Y = M > 0 ? Yl : sc + mn * pn, *N = M > 0 ? Nl : sc + mn * (pn + mn);
      for (i64 c = c0; c < c1; ++c) {
        double *Dc = Dpartial_.data() + c * blocks;
        std::fill(Dc, Dc + blocks, 0.0);
        for (i64 q = chunk_[size_t(c)]; q < chunk_[size_t(c) + 1]; ++q) {
          const int i = int(q) + lay.ncon;
          const double *Vi = Vinv_.data() + i64(i) * pn * pn;
          for (int k = lay.rowptr[i]; k < lay.rowptr[i + 1]; ++k) {
            const int j = lay.colidx[k] - lay.mcon;
            if (j < 0) continue;
            const double *A = ne.jac + i64(k) * jb, *B = A + mn * cn;
            // W_ij V*_i^-1 W_ij^T = A^T (B V*_i^-1 B^T) A: through the mnp x mnp middle
            // factor, about 60% of the multiply-adds of forming W_ij = A^T B first.
            for (int r = 0; r < mn; ++r)
              for (int d = 0; d < pn; ++d) {
                double v = 0.0;
                for (int e = 0; e < pn; ++e) v += B[r * pn + e] * Vi[e * pn + d];
                BV[r * pn + d] = v;
              }
            for (int r = 0; r < mn; ++r)
              for (int s = 0; s <= r; ++s) {
                double v = 0.0;
                for (int d = 0; d < pn; ++d) v += BV[r * pn + d] * B[s * pn + d];
                Y[r * mn + s] = Y[s * mn + r] = v;
              }
            for (int r = 0; r < mn; ++r)
              for (int a = 0; a < cn; ++a) {
                double v = 0.0;
                for (int s = 0; s < mn; ++s) v += Y[r * mn + s] * A[s * cn + a];
                N[r * cn + a] = v;
              }
            // The lower triangle only: chol reads no more.
            double *Dj = Dc + i64(j) * cc;
            for (int a = 0; a < cn; ++a)
              for (int b = 0; b <= a; ++b) {
                double v = 0.0;
                for (int r = 0; r < mn; ++r) v += A[r * cn + a] * N[r * cn + b];
                Dj[a * cn + b] -= v;
              }
          }
        }
      }
    });
    std::vector<int> ok(size_t(nc_), 1);
    ctx_.pool.for_range(nc_, [&](i64 j0, i64 j1) {
      const int cn = cnp(), cc = cn * cn;
      for (i64 j = j0; j < j1; ++j) {
        double *Dj = D_.data() + j * cc;
        std::copy_n(ne.U + (j + lay.mcon) * cc, cc, Dj);
        for (int a = 0; a < cn; ++a) Dj[a * cn + a] += mu;
        for (int c = 0; c < kChunks; ++c) {
          const double *pc = Dpartial_.data() + c * blocks + j * cc;
          for (int a = 0; a < cn; ++a)
            for (int b = 0; b <= a; ++b) Dj[a * cn + b] += pc[a * cn + b];
        }
        ok[size_t(j)] = small::chol<C>(Dj, cn);
      }
    });
    return std::all_of(ok.begin(), ok.end(), [](int v) { return v != 0; });
  }

  // The clusters of the preconditioner (see the top of the file): a shared block K with the
  // own blocks of the cameras that touch K and nothing else, in ascending block order while
  // the cluster's order stays within max_cluster; every other block alone.
  void find_clusters(const CameraMap &map, int max_cluster) {
    const int nb = map.nblocks();
    const auto cams = [&](int b) { return map.block_ncams(b); };
    std::vector<int> root(static_cast<size_t>(nb));  // the block whose cluster b joins (b when alone)
    std::vector<int> size(static_cast<size_t>(nb));  // a root's cluster order so far
    for (int b = 0; b < nb; ++b) root[size_t(b)] = b, size[size_t(b)] = map.block_size(b);
    for (int b = 0; b < nb; ++b) {
      if (cams(b) != 1) continue;
      const int j = *map.block_cams_begin(b);
      const int *q0 = map.cam_blocks_begin(j);
      if (map.cam_blocks_end(j) - q0 != 2) continue;
      const int K = q0[0] == b ? q0[1] : q0[0];
      if (cams(K) < 2 || size[size_t(K)] + map.block_size(b) > max_cluster) continue;
      root[size_t(b)] = K;
      size[size_t(K)] += map.block_size(b);
    }
    // Each cluster's blocks ascending; the clusters in the order of their first blocks.
    std::vector<std::vector<int>> members(static_cast<size_t>(nb));
    for (int b = 0; b < nb; ++b) members[size_t(root[size_t(b)])].push_back(b);
    cluster_start_.assign(1, 0);
    cluster_blocks_.clear();
    origin_.assign(size_t(nb), 0);
    pos_.assign(size_t(nb), 0);
    order_.assign(size_t(nb), 0);
    i64 origin = 0;
    for (int f = 0; f < nb; ++f) {
      const std::vector<int> &c = members[size_t(root[size_t(f)])];
      if (c.front() != f) continue;
      int n = 0;
      for (int b : c) pos_[size_t(b)] = n, n += map.block_size(b);
      for (int b : c) origin_[size_t(b)] = origin, order_[size_t(b)] = n;
      cluster_blocks_.insert(cluster_blocks_.end(), c.begin(), c.end());
      cluster_start_.push_back(int(cluster_blocks_.size()));
      origin += i64(n) * n;
    }
    D_.resize(size_t(origin));
  }

  // Cluster k's order and matrix.
  int cluster_order(int k) const { return order_[size_t(cluster_blocks_[size_t(cluster_start_[size_t(k)])])]; }
  double *cluster_matrix(int k) { return D_.data() + origin_[size_t(cluster_blocks_[size_t(cluster_start_[size_t(k)])])]; }
  int nclusters() const { return int(cluster_start_.size()) - 1; }

  // S's principal submatrix over each cluster, Cholesky-factored.
  bool make_mapped_preconditioner(const NormalEquations &ne, double mu) {
    const CameraMap &map = lay_.cams;
    UnknownBlocks D;
    D.kind = UnknownBlocks::Kind::Clusters;
    D.base = D_.data();
    D.start = map.block_starts();
    D.origin = origin_.data();
    D.pos = pos_.data();
    D.order = order_.data();
    std::fill(D_.begin(), D_.end(), 0.0);
    schur_->assemble(ctx_.pool, ne, Vinv_.data(), mu, D, nullptr);
    return ctx_.pool.all_ranges(nclusters(), [&](int, i64 k0, i64 k1) {
      for (i64 k = k0; k < k1; ++k) {
        const int n = cluster_order(int(k));
        double *A = cluster_matrix(int(k));
        // The assembly fills the upper block triangle; chol reads the lower.
        for (int r = 0; r < n; ++r)
          for (int c = 0; c < r; ++c) A[r * n + c] = A[c * n + r];
        if (!small::chol(A, n)) return false;
      }
      return true;
    });
  }

  // z = M^-1 r over the clusters.
  void precondition_mapped(const double *r, double *z) {
    const CameraMap &map = lay_.cams;
    ctx_.pool.for_range(nclusters(), [&](i64 k0, i64 k1) {
      std::vector<double> v;
      for (i64 k = k0; k < k1; ++k) {
        const int *c0 = cluster_blocks_.data() + cluster_start_[size_t(k)];
        const int *c1 = cluster_blocks_.data() + cluster_start_[size_t(k) + 1];
        v.resize(size_t(cluster_order(int(k))));
        for (const int *b = c0; b < c1; ++b)
          std::copy_n(r + map.block_start(*b), map.block_size(*b), v.data() + pos_[size_t(*b)]);
        small::chol_solve(cluster_matrix(int(k)), v.data(), int(v.size()));
        for (const int *b = c0; b < c1; ++b)
          std::copy_n(v.data() + pos_[size_t(*b)], map.block_size(*b), z + map.block_start(*b));
      }
    });
  }

  // z = D^-1 r.
  void precondition(const double *r, double *z) {
    if (schur_) return precondition_mapped(r, z);
    ctx_.pool.for_range(nc_, [&](i64 j0, i64 j1) {
      const int cn = cnp();
      for (i64 j = j0; j < j1; ++j) {
        double *zj = z + j * cn;
        std::copy_n(r + j * cn, cn, zj);
        small::chol_solve<C>(D_.data() + j * cn * cn, zj, cn);
      }
    });
  }

  // Truncated PCG from x = 0 on S da = rhs_; false when no descent direction came out.
  bool conjugate_gradients(const NormalEquations &ne, double mu, double eta, double *da) {
    const i64 n = nS_;
    double *x = x_.data(), *r = r_.data(), *z = z_.data(), *p = p_.data(), *q = q_.data();
    const double *b = rhs_.data();
    int &iterations = cg_iterations_;
    iterations = 0;
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
      ++iterations;
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
    if (iterations == 0 || !(dot(b, x, n) > 0.0)) return false;
    std::copy_n(x, n, da);
    return true;
  }

  SolveContext ctx_;
  const Layout &lay_;
  int nc_ = 0, np_ = 0;
  i64 nC_ = 0;  // the free cameras' parameters
  i64 nS_ = 0;  // S's order: the camera unknowns
  std::vector<i64> chunk_;                // the chunks' ranges of free points
  std::vector<double> partial_;           // the chunks' partial sums of the point pass
  std::vector<double> Dpartial_;          // and of the preconditioner's blocks
  std::vector<double> Vinv_, D_;          // (V_i + mu I)^-1, the preconditioner
  std::vector<double> rhs_, x_, r_, z_, p_, q_;
  std::vector<double> scratch_;           // per thread: run-time-sized blocks
  double g0_ = -1.0;                      // ||g|| at the first solve
  int cg_iterations_ = 0;                 // CG's iterations in the last solve
  std::unique_ptr<MappedSchur> schur_;    // with shared unknowns (else null)
  std::vector<int> cluster_start_, cluster_blocks_;  // and the preconditioner's clusters' blocks
  std::vector<i64> origin_;               // and per block, its cluster's matrix in D_
  std::vector<int> pos_, order_;          // its first row there, and the cluster's order
  std::vector<double> xc_, yc_;           // and the products' vectors over the parameters
};

// fn(solver) with the solver compiled for the layout's block sizes.
template <class Fn>
auto with_solver(const SolveContext &ctx, Fn fn, int max_cluster = kMaxCluster) {
  const Layout &lay = ctx.lay;
  if (lay.mnp == 2 && lay.pnp == 3) {
    if (lay.cnp == 6) return fn(std::make_unique<IterativeSchurSolver<2, 6, 3>>(ctx, max_cluster));
    if (lay.cnp == 9) return fn(std::make_unique<IterativeSchurSolver<2, 9, 3>>(ctx, max_cluster));
  }
  return fn(std::make_unique<IterativeSchurSolver<0, 0, 0>>(ctx, max_cluster));
}

}  // namespace

std::unique_ptr<StepSolver> make_iterative_schur_solver(const SolveContext &ctx) {
  return with_solver(ctx, [](auto s) -> std::unique_ptr<StepSolver> { return s; });
}

bool iterative_schur_product(const SolveContext &ctx, const NormalEquations &ne, double mu,
                             const double *x, double *y) {
  return with_solver(ctx, [&](auto s) { return s->product(ne, mu, x, y); });
}

bool iterative_schur_preconditioner(const SolveContext &ctx, const NormalEquations &ne, double mu, double *D) {
  return with_solver(ctx, [&](auto s) { return s->preconditioner(ne, mu, D); });
}

bool iterative_schur_apply_preconditioner(const SolveContext &ctx, const NormalEquations &ne, double mu,
                                          const double *r, double *z) {
  return with_solver(ctx, [&](auto s) { return s->apply_preconditioner(ne, mu, r, z); });
}

int iterative_schur_cg_iterations(const SolveContext &ctx, const NormalEquations &ne, double mu, double *dp,
                                  bool clusters) {
  return with_solver(
      ctx, [&](auto s) { return s->solve(ne, mu, dp) == StepStatus::Solved ? s->cg_iterations() : -1; },
      clusters ? kMaxCluster : 0);
}

}  // namespace sba
