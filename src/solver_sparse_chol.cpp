// Sparse S: the reduced camera system stored as blocks only for camera pairs that share a
// point, factored by CHOLMOD's supernodal Cholesky. For long sequences (each point seen by a
// few consecutive cameras) S is banded and this is far cheaper than the dense S, in time
// and in memory (the sba paper's proposed future work). The block pattern and CHOLMOD's
// symbolic analysis depend only on the visibility, so they are done once per solve.
#include <algorithm>
#include <cmath>
#include <new>
#include <vector>

#include "linsolve.h"

extern "C" {
#include <suitesparse/cholmod.h>
}

namespace sba {
namespace {

using sslong = SuiteSparse_long;

// CHOLMOD's workspace and objects, released on every path (also when the solver's
// constructor throws part-way, since members are destroyed then).
struct Cholmod {
  Cholmod() {
    cholmod_l_start(&cm);
    cm.print = 0;  // failures are reported by status, never printed
    cm.error_handler = nullptr;
    cm.supernodal = CHOLMOD_SUPERNODAL;
  }
  ~Cholmod() {
    cholmod_l_free_factor(&L, &cm);
    cholmod_l_free_sparse(&A, &cm);
    cholmod_l_free_dense(&B, &cm);
    cholmod_l_finish(&cm);
  }
  Cholmod(const Cholmod &) = delete;
  Cholmod &operator=(const Cholmod &) = delete;

  cholmod_common cm{};
  cholmod_sparse *A = nullptr;
  cholmod_factor *L = nullptr;
  cholmod_dense *B = nullptr;
};

class SparseSchurSolver final : public StepSolver {
 public:
  explicit SparseSchurSolver(const SolveContext &ctx)
      : ctx_(ctx), lay_(ctx.lay), Vinv_(size_t(i64(lay_.n) * lay_.pnp * lay_.pnp)) {
    build_pattern();
  }

  bool solve(const NormalEquations &ne, double mu, double *dp) override {
    const int cnp = lay_.cnp;
    std::fill(dp, dp + lay_.nvars(), 0.0);
    if (!ctx_.kernels.invert_damped_V(ctx_.pool, ne.V, mu, Vinv_.data())) return false;
    std::fill(blocks_.begin(), blocks_.end(), 0.0);
    BlockMap map;
    map.base = blocks_.data();
    map.ld = cnp;
    map.cnp = cnp;
    map.rows = rows_.data();
    map.colstart = colstart_.data();
    ctx_.kernels.assemble(ctx_.pool, ne, Vinv_.data(), mu, map, rhs_.data());

    // Blocks (row-major) into CHOLMOD's upper-triangular compressed columns.
    const int nc = lay_.free_cams();
    double *Ax = static_cast<double *>(chol_.A->x);
    const sslong *Ap = static_cast<const sslong *>(chol_.A->p);
    for (int k = 0; k < nc; ++k)
      for (int b = 0; b < cnp; ++b) {
        double *col = Ax + Ap[i64(k) * cnp + b];
        for (i64 s = colstart_[size_t(k)]; s < colstart_[size_t(k) + 1]; ++s) {
          const double *blk = blocks_.data() + s * cnp * cnp;
          const int rows = (s + 1 == colstart_[size_t(k) + 1]) ? b + 1 : cnp;  // diagonal last
          for (int a = 0; a < rows; ++a) *col++ = blk[a * cnp + b];
        }
      }
    ctx_.pool.rest();  // CHOLMOD and its BLAS have their own threads
    if (!cholmod_l_factorize(chol_.A, chol_.L, &chol_.cm) || chol_.cm.status == CHOLMOD_OUT_OF_MEMORY)
      throw std::bad_alloc();
    if (chol_.L->minor < chol_.L->n) return false;  // not positive definite at this damping
    std::copy(rhs_.begin(), rhs_.end(), static_cast<double *>(chol_.B->x));
    cholmod_dense *X = cholmod_l_solve(CHOLMOD_A, chol_.L, chol_.B, &chol_.cm);
    if (!X) throw std::bad_alloc();
    const double *x = static_cast<const double *>(X->x);
    double *da = dp + lay_.a_off(lay_.mcon);
    bool finite = true;
    for (size_t q = 0; q < rhs_.size(); ++q) {
      da[q] = x[q];
      finite = finite && std::isfinite(x[q]);
    }
    cholmod_l_free_dense(&X, &chol_.cm);
    if (!finite) return false;
    ctx_.kernels.back_substitute(ctx_.pool, ne, Vinv_.data(), dp);
    return true;
  }

 private:
  // Which block rows j <= k each block column k of S has: camera pairs sharing a free point.
  void build_pattern() {
    const Layout &lay = lay_;
    const int nc = lay.free_cams(), cnp = lay.cnp;
    std::vector<int> mark(size_t(nc), -1);
    colstart_.assign(size_t(nc) + 1, 0);
    for (int k = 0; k < nc; ++k) {
      const int cam = k + lay.mcon;
      const size_t first = rows_.size();
      for (int s = lay.colptr[cam]; s < lay.colptr[cam + 1]; ++s) {
        const int i = lay.colrow[s];
        if (i < lay.ncon) continue;
        for (int q = lay.rowptr[i]; q < lay.rowptr[i + 1]; ++q) {
          const int j = lay.colidx[q] - lay.mcon;
          if (j < 0) continue;
          if (j > k) break;  // cameras ascend along a track
          if (mark[size_t(j)] != k) {
            mark[size_t(j)] = k;
            rows_.push_back(j);
          }
        }
      }
      if (mark[size_t(k)] != k) rows_.push_back(k);  // a camera without free points
      std::sort(rows_.begin() + long(first), rows_.end());
      colstart_[size_t(k) + 1] = i64(rows_.size());
    }
    blocks_.resize(rows_.size() * size_t(cnp) * size_t(cnp));
    rhs_.resize(size_t(nc) * size_t(cnp));

    const sslong N = sslong(nc) * cnp;
    i64 nnz = 0;
    for (int k = 0; k < nc; ++k) {
      const i64 nb = colstart_[size_t(k) + 1] - colstart_[size_t(k)];
      nnz += (nb - 1) * cnp * cnp + i64(cnp) * (cnp + 1) / 2;
    }
    chol_.A = cholmod_l_allocate_sparse(size_t(N), size_t(N), size_t(nnz), 1, 1, 1, CHOLMOD_REAL, &chol_.cm);
    chol_.B = cholmod_l_allocate_dense(size_t(N), 1, size_t(N), CHOLMOD_REAL, &chol_.cm);
    if (!chol_.A || !chol_.B) throw std::bad_alloc();
    sslong *Ap = static_cast<sslong *>(chol_.A->p), *Ai = static_cast<sslong *>(chol_.A->i);
    sslong q = 0;
    for (int k = 0; k < nc; ++k)
      for (int b = 0; b < cnp; ++b) {
        Ap[i64(k) * cnp + b] = q;
        for (i64 s = colstart_[size_t(k)]; s < colstart_[size_t(k) + 1]; ++s) {
          const int rows = (s + 1 == colstart_[size_t(k) + 1]) ? b + 1 : cnp;
          for (int a = 0; a < rows; ++a) Ai[q++] = sslong(rows_[size_t(s)]) * cnp + a;
        }
      }
    Ap[N] = q;
    std::fill(static_cast<double *>(chol_.A->x), static_cast<double *>(chol_.A->x) + q, 0.0);
    chol_.L = cholmod_l_analyze(chol_.A, &chol_.cm);
    if (!chol_.L) throw std::bad_alloc();
  }

  SolveContext ctx_;
  const Layout &lay_;
  std::vector<double> Vinv_;
  Cholmod chol_;
  std::vector<int> rows_;      // block row of every stored block, column by column
  std::vector<i64> colstart_;  // block column k's blocks: [colstart_[k], colstart_[k+1])
  std::vector<double> blocks_, rhs_;
};

}  // namespace

std::unique_ptr<StepSolver> make_sparse_schur_solver(const SolveContext &ctx) {
  return std::make_unique<SparseSchurSolver>(ctx);
}

}  // namespace sba
