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
// Memory: the point blocks' inverses (n pnp^2), kChunks doubles per free camera parameter for
// the products' partial sums, and six vectors of S's order; for S's diagonal blocks,
// kChunks + 1 blocks per camera (the chunks' partial sums and the factored block); with
// shared unknowns instead, the clusters' matrices (at most kMaxCluster doubles per unknown),
// two vectors over the cameras' parameters and one more of S's order. No array of cameras x
// cameras, or anything per observation beyond the Jacobian LM already holds. auto's estimate
// (solver_choice.cpp) counts these.
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

// The block sizes, compiled (M, C, P nonzero) or read from the layout.
template <int M, int C, int P>
class BlockSizes {
 protected:
  explicit BlockSizes(const Layout &lay) : lay_(lay) {}
  int mnp() const { return M ? M : lay_.mnp; }
  int cnp() const { return C ? C : lay_.cnp; }
  int pnp() const { return P ? P : lay_.pnp; }
  const Layout &lay_;
};

// The pass over the free points behind both products, S x and the right-hand side: the
// point blocks' inverses, and the points in kChunks chunks, each adding its terms into
// partial sums of its own over the free cameras' parameters.
template <int M, int C, int P>
class PointPass : BlockSizes<M, C, P> {
  using BlockSizes<M, C, P>::mnp;
  using BlockSizes<M, C, P>::cnp;
  using BlockSizes<M, C, P>::pnp;
  using BlockSizes<M, C, P>::lay_;

 public:
  explicit PointPass(const SolveContext &ctx)
      : BlockSizes<M, C, P>(ctx.lay), ctx_(ctx), nc_(ctx.lay.free_cams()), nC_(i64(nc_) * cnp()) {
    chunk_ = split_by_work(lay_.rowptr, lay_.ncon, lay_.free_pts(), kChunks);
    partial_.resize(size_t(kChunks) * size_t(nC_));
    Vinv_.resize(size_t(lay_.n) * size_t(pnp()) * size_t(pnp()));
    // Per thread: u, w and t_i of a point and a projection's widened blocks, when their sizes
    // are known only at run time.
    scratch_.resize(size_t(ctx.pool.size()) * size_t(mnp() + 2 * pnp() + lay_.jblk()));
  }

  // Every free point's (V_i + mu I)^-1; false if one is not positive definite.
  bool invert(const NormalEquations &ne, double mu) {
    return ctx_.kernels.invert_damped_V(ctx_.pool, ne.V, mu, Vinv_.data());
  }
  const double *Vinv() const { return Vinv_.data(); }
  // The chunks' ranges of free points: chunk c holds points [chunks[c], chunks[c + 1]).
  const std::vector<i64> &chunks() const { return chunk_; }

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
      double ul[M > 0 ? M : 1], wl[P > 0 ? P : 1], tl[P > 0 ? P : 1], jl[M > 0 ? M * (C + P) : 1];
      double *u = M > 0 ? ul : sc, *w = P > 0 ? wl : sc + mn, *ti = P > 0 ? tl : sc + mn + pn;
      double *wide = M > 0 ? jl : sc + mn + 2 * pn;
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
              const double *A = projection_blocks<M * (C + P)>(ne, k, jb, wide), *B = A + mn * cn;
              const double *xj = x + i64(j) * cn;
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
            const double *A = projection_blocks<M * (C + P)>(ne, k, jb, wide), *B = A + mn * cn;
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

 private:
  SolveContext ctx_;
  int nc_;                       // the free cameras
  i64 nC_;                       // and their parameters
  std::vector<i64> chunk_;       // the chunks' ranges of free points
  std::vector<double> partial_;  // the chunks' partial sums
  std::vector<double> Vinv_;     // (V_i + mu I)^-1
  std::vector<double> scratch_;  // per thread: run-time-sized vectors
};

// The preconditioner M of the conjugate gradients: made once per damped system, applied at
// every iteration.
class Preconditioner {
 public:
  virtual ~Preconditioner() = default;
  // M at damping mu, factored; Vinv: every free point's (V_i + mu I)^-1. False if M is not
  // positive definite (then neither is S at this damping, up to rounding).
  virtual bool make(const NormalEquations &ne, const double *Vinv, double mu) = 0;
  // z = M^-1 r over S's unknowns.
  virtual void apply(const double *r, double *z) const = 0;
  // The factored matrices (iterative_schur_preconditioner).
  virtual const std::vector<double> &factors() const = 0;
};

// Without shared unknowns: S's block diagonal, D_j = U_j + mu I - sum_i W_ij V*_i^-1 W_ij^T,
// one cnp x cnp block per free camera, Cholesky-factored. The sums by chunk of points, for the
// reasons of PointPass::point_pass.
template <int M, int C, int P>
class BlockJacobi final : public Preconditioner, BlockSizes<M, C, P> {
  using BlockSizes<M, C, P>::mnp;
  using BlockSizes<M, C, P>::cnp;
  using BlockSizes<M, C, P>::pnp;
  using BlockSizes<M, C, P>::lay_;

 public:
  // chunks: the point pass's (PointPass::chunks), which outlive this.
  BlockJacobi(const SolveContext &ctx, const std::vector<i64> &chunks)
      : BlockSizes<M, C, P>(ctx.lay), ctx_(ctx), chunk_(chunks), nc_(ctx.lay.free_cams()) {
    const size_t blocks = size_t(nc_) * size_t(cnp()) * size_t(cnp());
    Dpartial_.resize(size_t(kChunks) * blocks);
    D_.resize(blocks);
    // Per thread: BV, Y and N (see add_chunks) and a projection's widened blocks, when their
    // sizes are known only at run time.
    scratch_.resize(size_t(ctx.pool.size()) * size_t(mnp() * (pnp() + mnp() + cnp()) + lay_.jblk()));
  }

  bool make(const NormalEquations &ne, const double *Vinv, double mu) override {
    add_chunks(ne, Vinv);
    return factor(ne, mu);
  }

  void apply(const double *r, double *z) const override {
    ctx_.pool.for_range(nc_, [&](i64 j0, i64 j1) {
      const int cn = cnp();
      for (i64 j = j0; j < j1; ++j) {
        double *zj = z + j * cn;
        std::copy_n(r + j * cn, cn, zj);
        small::chol_solve<C>(D_.data() + j * cn * cn, zj, cn);
      }
    });
  }

  const std::vector<double> &factors() const override { return D_; }

 private:
  // Each chunk's sums -sum_i W_ij V*_i^-1 W_ij^T over its points, the lower triangles.
  void add_chunks(const NormalEquations &ne, const double *Vinv) {
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
      double jl[M > 0 ? M * (C + P) : 1];
      double *wide = M > 0 ? jl : sc + mn * (pn + mn + cn);
      for (i64 c = c0; c < c1; ++c) {
        double *Dc = Dpartial_.data() + c * blocks;
        std::fill(Dc, Dc + blocks, 0.0);
        for (i64 q = chunk_[size_t(c)]; q < chunk_[size_t(c) + 1]; ++q) {
          const int i = int(q) + lay.ncon;
          const double *Vi = Vinv + i64(i) * pn * pn;
          for (int k = lay.rowptr[i]; k < lay.rowptr[i + 1]; ++k) {
            const int j = lay.colidx[k] - lay.mcon;
            if (j < 0) continue;
            const double *A = projection_blocks<M * (C + P)>(ne, k, jb, wide), *B = A + mn * cn;
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
  }

  // D_j = U_j + mu I + the chunks' sums in chunk order, factored.
  bool factor(const NormalEquations &ne, double mu) {
    const i64 blocks = i64(nc_) * cnp() * cnp(), mcon = lay_.mcon;
    std::vector<int> ok(size_t(nc_), 1);
    ctx_.pool.for_range(nc_, [&](i64 j0, i64 j1) {
      const int cn = cnp(), cc = cn * cn;
      for (i64 j = j0; j < j1; ++j) {
        double *Dj = D_.data() + j * cc;
        std::copy_n(ne.U + (j + mcon) * cc, cc, Dj);
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

  SolveContext ctx_;
  const std::vector<i64> &chunk_;
  int nc_;                        // the free cameras
  std::vector<double> Dpartial_;  // the chunks' partial sums of the blocks
  std::vector<double> D_;         // the factored blocks
  std::vector<double> scratch_;   // per thread: run-time-sized blocks
};

// The clusters of the preconditioner over shared unknowns (see the top of the file): a shared
// block K with the own blocks of the cameras that touch K and nothing else, in ascending block
// order while the cluster's order stays within max_cluster; every other block alone.
struct Clusters {
  std::vector<int> start, blocks;  // cluster k's blocks: blocks[start[k] .. start[k + 1]), ascending
  std::vector<i64> origin;         // per block, its cluster's matrix (order x order) from there
  std::vector<int> pos, order;     // its first row in that matrix, and the cluster's order
  i64 doubles = 0;                 // the matrices' doubles: their orders squared, summed

  int count() const { return int(start.size()) - 1; }
  int order_of(int k) const { return order[size_t(blocks[size_t(start[size_t(k)])])]; }
  i64 origin_of(int k) const { return origin[size_t(blocks[size_t(start[size_t(k)])])]; }
};

Clusters find_clusters(const CameraMap &map, int max_cluster) {
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
  Clusters cl;
  cl.start.assign(1, 0);
  cl.origin.assign(size_t(nb), 0);
  cl.pos.assign(size_t(nb), 0);
  cl.order.assign(size_t(nb), 0);
  for (int f = 0; f < nb; ++f) {
    const std::vector<int> &c = members[size_t(root[size_t(f)])];
    if (c.front() != f) continue;
    int n = 0;
    for (int b : c) cl.pos[size_t(b)] = n, n += map.block_size(b);
    for (int b : c) cl.origin[size_t(b)] = cl.doubles, cl.order[size_t(b)] = n;
    cl.blocks.insert(cl.blocks.end(), c.begin(), c.end());
    cl.start.push_back(int(cl.blocks.size()));
    cl.doubles += i64(n) * n;
  }
  return cl;
}

// With shared unknowns: S's principal submatrix over each cluster of its blocks, assembled
// by the reduced camera system's assembly (mapped_schur.h), Cholesky-factored.
class ClusterJacobi final : public Preconditioner {
 public:
  // schur: the assembly, which outlives this.
  ClusterJacobi(const SolveContext &ctx, const MappedSchur &schur, int max_cluster)
      : ctx_(ctx), schur_(schur), clusters_(find_clusters(ctx.lay.cams, max_cluster)) {
    D_.resize(size_t(clusters_.doubles));
  }

  bool make(const NormalEquations &ne, const double *Vinv, double mu) override {
    UnknownBlocks D;
    D.kind = UnknownBlocks::Kind::Clusters;
    D.base = D_.data();
    D.start = ctx_.lay.cams.block_starts();
    D.origin = clusters_.origin.data();
    D.pos = clusters_.pos.data();
    D.order = clusters_.order.data();
    std::fill(D_.begin(), D_.end(), 0.0);
    schur_.assemble(ctx_.pool, ne, Vinv, mu, D, nullptr);
    return ctx_.pool.all_ranges(clusters_.count(), [&](int, i64 k0, i64 k1) {
      for (i64 k = k0; k < k1; ++k) {
        const int n = clusters_.order_of(int(k));
        double *A = D_.data() + clusters_.origin_of(int(k));
        // The assembly fills the upper block triangle; chol reads the lower.
        for (int r = 0; r < n; ++r)
          for (int c = 0; c < r; ++c) A[r * n + c] = A[c * n + r];
        if (!small::chol(A, n)) return false;
      }
      return true;
    });
  }

  void apply(const double *r, double *z) const override {
    const CameraMap &map = ctx_.lay.cams;
    ctx_.pool.for_range(clusters_.count(), [&](i64 k0, i64 k1) {
      std::vector<double> v;
      for (i64 k = k0; k < k1; ++k) {
        const int *c0 = clusters_.blocks.data() + clusters_.start[size_t(k)];
        const int *c1 = clusters_.blocks.data() + clusters_.start[size_t(k) + 1];
        v.resize(size_t(clusters_.order_of(int(k))));
        for (const int *b = c0; b < c1; ++b)
          std::copy_n(r + map.block_start(*b), map.block_size(*b), v.data() + clusters_.pos[size_t(*b)]);
        small::chol_solve(D_.data() + clusters_.origin_of(int(k)), v.data(), int(v.size()));
        for (const int *b = c0; b < c1; ++b)
          std::copy_n(v.data() + clusters_.pos[size_t(*b)], map.block_size(*b), z + map.block_start(*b));
      }
    });
  }

  const std::vector<double> &factors() const override { return D_; }

 private:
  SolveContext ctx_;
  const MappedSchur &schur_;
  Clusters clusters_;
  std::vector<double> D_;  // the clusters' matrices, factored
};

// The solver, whatever the form of S: the right-hand side, the forcing term, truncated PCG on
// S da = rhs and the points' steps by back-substitution. S's form (its products, its
// preconditioner, its unknowns' map onto the cameras) is the subclass's.
template <int M, int C, int P>
class IterativeSchurSolver : public StepSolver {
 public:
  StepStatus solve(const NormalEquations &ne, double mu, double *dp) final {
    const Layout &lay = lay_;
    std::fill(dp, dp + lay.a_off(lay.mcon), 0.0);
    std::fill(dp + lay.b_off(0), dp + lay.b_off(lay.ncon), 0.0);
    if (!pass_.invert(ne, mu)) return StepStatus::SingularPointBlock;

    // rhs = e_a - W V*^-1 e_b, and the forcing term from the gradient's norm.
    const int pn = P ? P : lay.pnp;
    const double ga2 = right_hand_side(ne, rhs_.data());
    const double *eb_free = ne.eb + i64(lay.ncon) * pn;
    const double g2 = ga2 + dot(eb_free, eb_free, i64(lay.free_pts()) * pn);
    if (!std::isfinite(g2)) return StepStatus::Failed;
    if (g0_ < 0.0) g0_ = std::sqrt(g2);
    const double eta = g0_ > 0.0 ? std::clamp(std::sqrt(std::sqrt(g2) / g0_), kEtaMin, kEtaMax) : kEtaMax;

    if (!preconditioner().make(ne, pass_.Vinv(), mu)) return StepStatus::Failed;
    if (!conjugate_gradients(ne, mu, eta)) return StepStatus::Failed;
    camera_step(x_.data(), dp);
    ctx_.kernels.back_substitute(ctx_.pool, ne, pass_.Vinv(), mu, dp);
    return StepStatus::Solved;
  }

  // y = S x on its own (iterative_schur_product).
  bool product(const NormalEquations &ne, double mu, const double *x, double *y) {
    if (!pass_.invert(ne, mu)) return false;
    multiply(ne, mu, x, y);
    return true;
  }

  // The factored preconditioner on its own (iterative_schur_preconditioner).
  bool factored_preconditioner(const NormalEquations &ne, double mu, double *D) {
    if (!pass_.invert(ne, mu) || !preconditioner().make(ne, pass_.Vinv(), mu)) return false;
    const std::vector<double> &factors = preconditioner().factors();
    std::copy(factors.begin(), factors.end(), D);
    return true;
  }

  // z = M^-1 r, the preconditioner made at damping mu (iterative_schur_apply_preconditioner).
  bool apply_preconditioner(const NormalEquations &ne, double mu, const double *r, double *z) {
    if (!pass_.invert(ne, mu) || !preconditioner().make(ne, pass_.Vinv(), mu)) return false;
    preconditioner().apply(r, z);
    return true;
  }

  // The CG iterations of the last solve.
  int cg_iterations() const { return cg_iterations_; }

 protected:
  // unknowns: S's order.
  IterativeSchurSolver(const SolveContext &ctx, i64 unknowns) : ctx_(ctx), lay_(ctx.lay), pass_(ctx), nS_(unknowns) {
    for (std::vector<double> *v : {&rhs_, &x_, &r_, &z_, &p_, &q_}) v->resize(size_t(nS_));
  }

  virtual Preconditioner &preconditioner() = 0;
  // rhs = e_a - W V*^-1 e_b over S's unknowns, the point pass's sums added to the gradient's
  // camera part; returns that part's squared norm over the unknowns.
  virtual double right_hand_side(const NormalEquations &ne, double *rhs) = 0;
  // y = S x.
  virtual void multiply(const NormalEquations &ne, double mu, const double *x, double *y) = 0;
  // The free cameras' part of dp from S's solution da.
  virtual void camera_step(const double *da, double *dp) = 0;

  double dot(const double *a, const double *b, i64 n) {
    return deterministic_sum(ctx_.pool, n, [=](i64 k) { return a[k] * b[k]; });
  }

  SolveContext ctx_;
  const Layout &lay_;
  PointPass<M, C, P> pass_;

 private:
  // Truncated PCG from x = 0 on S x = rhs_, leaving x in x_; false when no descent direction
  // came out.
  bool conjugate_gradients(const NormalEquations &ne, double mu, double eta) {
    const i64 n = nS_;
    double *x = x_.data(), *r = r_.data(), *z = z_.data(), *p = p_.data(), *q = q_.data();
    const double *b = rhs_.data();
    const Preconditioner &M_inv = preconditioner();
    int &iterations = cg_iterations_;
    iterations = 0;
    std::fill(x, x + n, 0.0);
    std::copy_n(b, n, r);
    const double bb = dot(b, b, n);
    if (!std::isfinite(bb)) return false;
    if (bb == 0.0) return true;  // x = 0
    const double tol2 = eta * eta * bb;
    M_inv.apply(r, z);
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
      M_inv.apply(r, z);
      const double rz_next = dot(r, z, n);
      if (!(rz_next > 0.0)) break;
      const double beta = rz_next / rz;
      rz = rz_next;
      ctx_.pool.for_range(n, [=](i64 e0, i64 e1) {
        for (i64 e = e0; e < e1; ++e) p[e] = z[e] + beta * p[e];
      });
    }
    return iterations > 0 && dot(b, x, n) > 0.0;
  }

  i64 nS_;  // S's order: the camera unknowns
  std::vector<double> rhs_, x_, r_, z_, p_, q_;
  double g0_ = -1.0;        // ||g|| at the first solve
  int cg_iterations_ = 0;  // CG's iterations in the last solve
};

// S over the free cameras' parameters, one block per camera: sba 1.6's layout.
template <int M, int C, int P>
class CameraIterativeSchur final : public IterativeSchurSolver<M, C, P> {
  using Base = IterativeSchurSolver<M, C, P>;

 public:
  explicit CameraIterativeSchur(const SolveContext &ctx)
      : Base(ctx, ctx.lay.camera_unknowns()), jacobi_(ctx, this->pass_.chunks()) {}

 private:
  Preconditioner &preconditioner() override { return jacobi_; }

  double right_hand_side(const NormalEquations &ne, double *rhs) override {
    const Layout &lay = this->lay_;
    const double *ga = ne.ea + lay.a_off(lay.mcon);
    this->pass_.point_pass(ne, nullptr);
    this->pass_.gather(ne, 0.0, nullptr, ga, rhs);
    return this->dot(ga, ga, lay.camera_unknowns());
  }

  void multiply(const NormalEquations &ne, double mu, const double *x, double *y) override {
    this->pass_.point_pass(ne, x);
    this->pass_.gather(ne, mu, x, nullptr, y);
  }

  void camera_step(const double *da, double *dp) override {
    const Layout &lay = this->lay_;
    std::copy_n(da, lay.camera_unknowns(), dp + lay.a_off(lay.mcon));
  }

  BlockJacobi<M, C, P> jacobi_;
};

// S over shared unknowns: the products run on the cameras' parameters (xc_, yc_, all m
// cameras' as in p) and are reduced to the unknowns, S = P^T (U - W V*^-1 W^T) P + mu I with
// P the map from the unknowns to the parameters; the preconditioner is S over clusters of the
// unknowns' blocks.
template <int M, int C, int P>
class SharedIterativeSchur final : public IterativeSchurSolver<M, C, P> {
  using Base = IterativeSchurSolver<M, C, P>;

 public:
  SharedIterativeSchur(const SolveContext &ctx, int max_cluster)
      : Base(ctx, ctx.lay.camera_unknowns()),
        schur_(ctx.lay, ctx.pool.size()),
        clusters_(ctx, schur_, max_cluster),
        xc_(size_t(ctx.lay.m) * size_t(ctx.lay.cnp)),
        yc_(xc_.size()),
        g_(size_t(ctx.lay.camera_unknowns())) {}

 private:
  Preconditioner &preconditioner() override { return clusters_; }

  double right_hand_side(const NormalEquations &ne, double *rhs) override {
    const Layout &lay = this->lay_;
    this->pass_.point_pass(ne, nullptr);
    this->pass_.gather(ne, 0.0, nullptr, ne.ea + lay.a_off(lay.mcon), yc_.data() + lay.a_off(lay.mcon));
    lay.cams.reduce(yc_.data(), rhs);
    lay.cams.reduce(ne.ea, g_.data());
    return this->dot(g_.data(), g_.data(), i64(g_.size()));
  }

  void multiply(const NormalEquations &ne, double mu, const double *x, double *y) override {
    const Layout &lay = this->lay_;
    lay.cams.expand(x, 0.0, xc_.data());
    this->pass_.point_pass(ne, xc_.data() + lay.a_off(lay.mcon));
    this->pass_.gather(ne, 0.0, xc_.data() + lay.a_off(lay.mcon), nullptr, yc_.data() + lay.a_off(lay.mcon));
    lay.cams.reduce(yc_.data(), y);
    this->ctx_.pool.for_range(i64(g_.size()), [=](i64 e0, i64 e1) {
      for (i64 e = e0; e < e1; ++e) y[e] += mu * x[e];
    });
  }

  void camera_step(const double *da, double *dp) override { this->lay_.cams.expand(da, -0.0, dp); }

  MappedSchur schur_;
  ClusterJacobi clusters_;
  std::vector<double> xc_, yc_;  // the products' vectors over the cameras' parameters
  std::vector<double> g_;        // the gradient's camera part over the unknowns, for its norm
};

template <int M, int C, int P>
std::unique_ptr<IterativeSchurSolver<M, C, P>> make_solver(const SolveContext &ctx, int max_cluster) {
  if (!ctx.lay.cams.per_camera()) return std::make_unique<SharedIterativeSchur<M, C, P>>(ctx, max_cluster);
  return std::make_unique<CameraIterativeSchur<M, C, P>>(ctx);
}

// fn(solver) with the solver compiled for the layout's block sizes: those make_kernels has (6, 7,
// 9, 11, 16: the quaternion camera with fixed and varying intrinsics, BAL's, COLMAP's cameras of
// four parameters), since the generic instance's point pass, its loops of run-time length
// neither unrolled nor folded, takes several times as long.
template <class Fn>
auto with_solver(const SolveContext &ctx, Fn fn, int max_cluster = kMaxCluster) {
  const Layout &lay = ctx.lay;
  if (lay.mnp == 2 && lay.pnp == 3) {
    if (lay.cnp == 6) return fn(make_solver<2, 6, 3>(ctx, max_cluster));
    if (lay.cnp == 7) return fn(make_solver<2, 7, 3>(ctx, max_cluster));
    if (lay.cnp == 9) return fn(make_solver<2, 9, 3>(ctx, max_cluster));
    if (lay.cnp == 11) return fn(make_solver<2, 11, 3>(ctx, max_cluster));
    if (lay.cnp == 16) return fn(make_solver<2, 16, 3>(ctx, max_cluster));
  }
  return fn(make_solver<0, 0, 0>(ctx, max_cluster));
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
  return with_solver(ctx, [&](auto s) { return s->factored_preconditioner(ne, mu, D); });
}

bool iterative_schur_apply_preconditioner(const SolveContext &ctx, const NormalEquations &ne, double mu,
                                          const double *r, double *z) {
  return with_solver(ctx, [&](auto s) { return s->apply_preconditioner(ne, mu, r, z); });
}

i64 iterative_schur_cluster_doubles(const CameraMap &map) { return find_clusters(map, kMaxCluster).doubles; }

int iterative_schur_cg_iterations(const SolveContext &ctx, const NormalEquations &ne, double mu, double *dp,
                                  bool clusters) {
  return with_solver(
      ctx, [&](auto s) { return s->solve(ne, mu, dp) == StepStatus::Solved ? s->cg_iterations() : -1; },
      clusters ? kMaxCluster : 0);
}

}  // namespace sba
