/* SPDX-License-Identifier: BSD-3-Clause */
// The normal equations of an LM iteration, the vocabulary that the kernels, the linear solvers
// and the covariance share, and the block kernels over them (normal equations, damped point
// blocks, the Schur complement and the back-substitution), compiled for the common block sizes
// (mnp, cnp, pnp) = (2,6,3), (2,7,3), (2,9,3), (2,11,3), (2,16,3) with a run-time-sized
// fallback, and run on a thread pool. Every output entry is computed by one thread, adding
// its terms in a fixed order, so results do not depend on the number of threads.
#ifndef SBA_SRC_KERNELS_H
#define SBA_SRC_KERNELS_H

#include <algorithm>
#include <memory>
#include <vector>

#include "layout.h"
#include "parallel.h"

namespace sba {

// The normal equations of the current (weighted) Jacobian: the undamped U_j, V_i and
// e_a = A^T e, e_b = B^T e, formed from the Jacobian blocks A_ij, B_ij as U_j = sum_i A_ij^T
// A_ij, V_i = sum_j B_ij^T B_ij, W_ij = A_ij^T B_ij. Blocks of fixed cameras and points are
// not meaningful.
struct NormalEquations {
  const double *jac = nullptr;  // callback layout: A_ij then B_ij per projection
  const double *U = nullptr, *V = nullptr, *ea = nullptr, *eb = nullptr;
  // With single-precision storage (Options::single_jacobian) the blocks are here instead, and
  // jac is null. Every kernel widens them to double before it computes.
  const float *jac32 = nullptr;
  // Per parameter, in the layout's order, the factor D_q of a damping mu D_q where the kernels
  // damp a diagonal (Marquardt's, without scaling the Jacobian: strategy.cpp); null: mu.
  // Only the solvers whose StepSolver::takes_damping() says so are handed one.
  const double *damping = nullptr;
};

// The stored Jacobian blocks, to be changed in place: in double, or in single precision
// (NormalEquations::jac32); one of the two is set.
struct JacobianBlocks {
  double *jac = nullptr;
  float *jac32 = nullptr;
};

// n of one projection's Jacobian entries as doubles: the stored ones themselves, or, stored in
// single precision, widened into buf (exactly: every float is a double). The kernels then
// compute in double, and on widened blocks give the bits they give on double blocks of the
// same values. N > 0 fixes n at compile time. In an unnamed namespace: the kernels are
// compiled for several instruction sets, and each translation unit must keep its own copy.
namespace {
template <int N>
inline __attribute__((always_inline)) const double *widened(const double *x, int, double *) {
  return x;
}
template <int N>
inline __attribute__((always_inline)) const double *widened(const float *x, int n, double *buf) {
  if constexpr (N > 0) {
#pragma GCC unroll 8
    for (int c = 0; c < N; ++c) buf[c] = x[c];
  } else {
    for (int c = 0; c < n; ++c) buf[c] = x[c];
  }
  return buf;
}

// Projection k's blocks (jb entries) of ne as doubles, in buf where they are stored in single
// precision.
template <int N>
inline __attribute__((always_inline)) const double *projection_blocks(const NormalEquations &ne, i64 k, int jb,
                                                                      double *buf) {
  return ne.jac32 ? widened<N>(ne.jac32 + k * jb, jb, buf) : ne.jac + k * jb;
}

}  // namespace

// W_ij = A_ij^T B_ij (cnp x pnp, row-major) of projection k.
inline void form_W(const Layout &lay, const double *jac, i64 k, double *W) {
  const int mnp = lay.mnp, cnp = lay.cnp, pnp = lay.pnp;
  const double *A = jac + k * lay.jblk();
  const double *B = A + mnp * cnp;
  for (int a = 0; a < cnp; ++a)
    for (int b = 0; b < pnp; ++b) {
      double s = 0.0;
      for (int r = 0; r < mnp; ++r) s += A[r * cnp + a] * B[r * pnp + b];
      W[a * pnp + b] = s;
    }
}

// The largest upper triangle of a dense S, in doubles (32 MiB), whose assembly goes through
// each thread's packed copy of its block columns (kernels_impl.h, start_columns): that much
// memory besides S.
constexpr i64 kMaxPackedS = i64(1) << 22;

// Where the Schur assembly finds block S_jk (free-camera indices j <= k).
//  - Dense S: row-major inside an (nS x nS) matrix with row stride ld; the assembly zeroes
//    and fills the upper block triangle, each thread its own block columns (zeroed by
//    another thread, or by the caller, S's lines would move between the cores' caches).
//  - Sparse S: the blocks are the arrays of the matrix that CHOLMOD factors, the lower
//    triangle of P S P^T in compressed columns (P: the camera ordering, perm[j] is free camera
//    j's block column). Block column c holds full blocks for its block rows rows[colstart[c]
//    .. colstart[c+1]) (ascending, c itself first), its cnp scalar columns one after the
//    other, each nb_c * cnp entries long (nb_c blocks). Stored block (r, c), r >= c, read
//    row-major with row stride nb_c * cnp, is then block (c, r) of P S P^T: S_jk itself when
//    perm[j] <= perm[k], otherwise S_jk^T, which the assembly then computes in its place.
struct BlockMap {
  double *base = nullptr;
  i64 ld = 0;  // dense S: nS
  int cnp = 0;
  const int *perm = nullptr;  // null for a dense S
  const int *rows = nullptr;
  const i64 *colstart = nullptr;

  struct Block {
    double *p;
    i64 ld;
    bool transposed;  // holds S_jk^T
  };
  Block block(int j, int k) const {
    if (!perm) return {base + i64(j) * cnp * ld + i64(k) * cnp, ld, false};
    const int pj = perm[j], pk = perm[k], c = std::min(pj, pk), r = std::max(pj, pk);
    const int *first = rows + colstart[c], *last = rows + colstart[c + 1];
    return {base + colstart[c] * cnp * cnp + i64(std::lower_bound(first, last, r) - first) * cnp,
            (colstart[c + 1] - colstart[c]) * cnp, pj > pk};
  }
};

class Kernels {
 public:
  virtual ~Kernels() = default;
  // U_j, e_a,j over the free cameras, V_i, e_b,i over the free points, from the (weighted)
  // Jacobian and residual. U and V get their full (mirrored) blocks.
  virtual void normal_equations(ThreadPool &pool, const double *jac, const double *e, double *U,
                                double *V, double *ea, double *eb) const = 0;
  // The same, for a Jacobian whose columns of held camera parameters (the Layout's map) may
  // not be zero: each free camera's blocks have them zeroed as its U_j is summed, where they
  // are read anyway, rather than in a pass of their own over the Jacobian.
  virtual void held_normal_equations(ThreadPool &pool, double *jac, const double *e, double *U, double *V,
                                     double *ea, double *eb) const = 0;
  // U_j and V_i alone from single-precision blocks: the bits of the above on the blocks
  // widened. Their gradient is not formed here: it is made from the blocks in double, before
  // they were rounded (lm_core.cpp).
  virtual void normal_matrices(ThreadPool &pool, const float *jac, double *U, double *V) const = 0;
  // Vinv_i = (V_i + mu I)^-1 for the free points; false if one is singular. V_i + mu I is
  // positive definite but on the retries of sba 1.6's strategy (strategy.cpp), where it may be
  // indefinite and is inverted all the same, as 1.6 does.
  virtual bool invert_damped_V(ThreadPool &pool, const double *V, double mu,
                               double *Vinv) const = 0;
  // The diagonal of each free point's (V_i + mu I)^-1, made as the other kernels make the
  // inverse, into diag (pnp entries per point, by point); NaN where V_i + mu I is singular.
  virtual void damped_inverse_diagonals(ThreadPool &pool, const double *V, double mu,
                                        double *diag) const = 0;
  // S = U* - W V*^-1 W^T into the blocks of `S` (a sparse S zeroed by the caller;
  // of a diagonal block, only the upper triangle is meaningful) and rhs = e_a - W V*^-1 e_b,
  // over the free cameras. Vinv: invert_damped_V's blocks, or null to invert each
  // V_i + mu I where it is needed (no n pnp^2 array, for one more small inversion per point
  // in back_substitute); false if one of those is singular.
  virtual bool assemble(ThreadPool &pool, const NormalEquations &ne, const double *Vinv, double mu,
                        const BlockMap &S, double *rhs) const = 0;
  // db_i = Vinv_i (e_b,i - sum_j W_ij^T da_j) for the free points, with da already in dp;
  // Vinv as for assemble (with null, a block that cannot be inverted gives NaNs).
  virtual void back_substitute(ThreadPool &pool, const NormalEquations &ne, const double *Vinv,
                               double mu, double *dp) const = 0;
  // A_ij *= diag(s_j) and B_ij *= diag(s_i) for every projection (s: a scale per variable, in
  // the layout's order): the Jacobian in variables scaled by s. Single-precision blocks get
  // each product rounded to float.
  virtual void scale_jacobian(ThreadPool &pool, const double *s, JacobianBlocks jac) const = 0;
};

// Kernels for the layout's block sizes, with the assembly split over `threads` threads; a
// dense S whose upper triangle has at most max_packed doubles assembled through packed copies
// (kMaxPackedS; the tests compare both ways).
std::unique_ptr<Kernels> make_kernels(const Layout &lay, int threads, i64 max_packed = kMaxPackedS);

}  // namespace sba

#endif
