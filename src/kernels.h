// The block kernels of an LM iteration (normal equations, damped point blocks, the Schur
// complement and the back-substitution), compiled for the common block sizes
// (mnp, cnp, pnp) = (2,6,3), (2,7,3), (2,9,3), (2,11,3), (2,16,3) with a run-time-sized
// fallback, and run on a thread pool. Every output entry is computed by one thread, adding
// its terms in a fixed order, so results do not depend on the number of threads.
#ifndef SBA_SRC_KERNELS_H
#define SBA_SRC_KERNELS_H

#include <algorithm>
#include <memory>
#include <vector>

#include "core.h"
#include "parallel.h"

namespace sba {

struct NormalEquations;

// Where the Schur assembly finds block S_jk (free-camera indices j <= k): row-major with
// row stride ld, inside a dense (nS x nS) matrix or a list of stored blocks.
struct BlockMap {
  double *base = nullptr;
  i64 ld = 0;  // dense: nS; blocks: cnp
  int cnp = 0;
  // Stored blocks (sparse S): block column k holds block rows rows[colstart[k] ..
  // colstart[k+1]), ascending; null for a dense S.
  const int *rows = nullptr;
  const i64 *colstart = nullptr;

  double *block(int j, int k) const {
    if (!rows) return base + i64(j) * cnp * ld + i64(k) * cnp;
    const int *first = rows + colstart[k], *last = rows + colstart[k + 1];
    return base + i64(std::lower_bound(first, last, j) - rows) * cnp * cnp;
  }
};

class Kernels {
 public:
  virtual ~Kernels() = default;
  // U_j, e_a,j over the free cameras, V_i, e_b,i over the free points, from the (weighted)
  // Jacobian and residual. U and V get their full (mirrored) blocks.
  virtual void normal_equations(ThreadPool &pool, const double *jac, const double *e, double *U,
                                double *V, double *ea, double *eb) const = 0;
  // Vinv_i = (V_i + mu I)^-1 for the free points; false if one is not positive definite.
  virtual bool invert_damped_V(ThreadPool &pool, const double *V, double mu,
                               double *Vinv) const = 0;
  // S = U* - W V*^-1 W^T into the upper block triangle of `S` (zeroed by the caller; the
  // strict lower triangle of the diagonal blocks is left meaningless) and
  // rhs = e_a - W V*^-1 e_b, over the free cameras.
  virtual void assemble(ThreadPool &pool, const NormalEquations &ne, const double *Vinv, double mu,
                        const BlockMap &S, double *rhs) const = 0;
  // db_i = Vinv_i (e_b,i - sum_j W_ij^T da_j) for the free points, with da already in dp.
  virtual void back_substitute(ThreadPool &pool, const NormalEquations &ne, const double *Vinv,
                               double *dp) const = 0;
};

// Kernels for the layout's block sizes, with the assembly split over `threads` threads.
std::unique_ptr<Kernels> make_kernels(const Layout &lay, int threads);

}  // namespace sba

#endif
