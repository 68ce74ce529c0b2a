// SPDX-License-Identifier: BSD-3-Clause
// Sparse S: the reduced camera system stored as blocks only for camera pairs that share a
// point, factored by CHOLMOD's supernodal Cholesky. For long sequences (each point seen by a
// few consecutive cameras) S is banded and this is far cheaper than the dense S, in time
// and in memory (the sba paper's proposed future work). The block pattern, the ordering and
// CHOLMOD's symbolic analysis depend only on the visibility, so they are done once per solve.
//
// Memory is what this solver is for, so S is assembled straight into the arrays that CHOLMOD
// factors, and in the form its supernodal factorization works on: the lower triangle of the
// permuted matrix P S P^T. Given S upper or unpermuted, cholmod_factorize would make that
// copy itself on every factorization. The fill-reducing ordering P is ours for the same
// reason: AMD on the camera graph (cnp times smaller than the scalar graph), after which
// CHOLMOD analyzes in natural order. CHOLMOD's int version is used while the matrix and its
// factor fit its indices (half the index memory of the long version), the long one beyond.
#include <algorithm>
#include <climits>
#include <cmath>
#include <limits>
#include <memory>
#include <vector>

#include "schur_assembly.h"
#include "schur_pattern.h"
#include "step_solver.h"
#include "suitesparse_status.h"

namespace sba {
namespace {

using sslong = SuiteSparse_long;

// Which blocks of S are stored, and where (kernels.h's BlockMap layout, or with shared
// unknowns mapped_schur.h's UnknownBlocks): blocks of the cameras, or of the unknowns.
struct Pattern {
  std::vector<int> perm;      // block -> block column of P S P^T
  std::vector<int> rows;      // block row of every stored block, block column by column
  std::vector<i64> colstart;  // block column c's blocks: [colstart[c], colstart[c+1])
  std::vector<int> size;      // per block column of P S P^T: its order
  std::vector<i64> start;     // per block column: its first scalar column; then the total
  // With shared unknowns, per block column: where its entries start and how many each scalar
  // column has; per stored block: its offset in its column.
  std::vector<i64> colbase, height, rowoff;

  // The entries of the stored blocks.
  i64 nnz() const {
    i64 n = 0;
    for (size_t c = 0; c < size.size(); ++c)
      for (i64 s = colstart[c]; s < colstart[c + 1]; ++s) n += i64(size[c]) * size[size_t(rows[size_t(s)])];
    return n;
  }
};

// The AMD ordering of the block graph (auto's when it made one: SolveContext::analysis),
// then the blocks of the lower triangle of P S P^T block column by block column: block
// (b, B) of S goes to column min(perm b, perm B), row max(perm b, perm B).
Pattern make_pattern(const Layout &lay, const SchurAnalysis *given) {
  SchurAnalysis made;
  if (!given) {
    schur_pattern(lay, std::numeric_limits<i64>::max(), &made.pattern);
    made.order = amd_block_order(made.pattern, nullptr);
  }
  const SchurAnalysis &analysis = given ? *given : made;
  const SchurPattern &blocks = analysis.pattern;
  const int nc = blocks.nblocks();
  const std::vector<int> &rows = blocks.rows;
  const std::vector<i64> &colstart = blocks.colstart;
  Pattern pat;
  pat.perm.resize(size_t(nc));
  for (int q = 0; q < nc; ++q) pat.perm[size_t(analysis.order[size_t(q)])] = q;
  const std::vector<int> &perm = pat.perm;
  pat.colstart.assign(size_t(nc) + 1, 0);
  for (int k = 0; k < nc; ++k)
    for (i64 s = colstart[size_t(k)]; s < colstart[size_t(k) + 1]; ++s)
      ++pat.colstart[size_t(std::min(perm[size_t(rows[size_t(s)])], perm[size_t(k)])) + 1];
  for (int c = 0; c < nc; ++c) pat.colstart[size_t(c) + 1] += pat.colstart[size_t(c)];
  pat.rows.resize(rows.size());
  std::vector<i64> fill(pat.colstart.begin(), pat.colstart.end() - 1);
  for (int k = 0; k < nc; ++k)
    for (i64 s = colstart[size_t(k)]; s < colstart[size_t(k) + 1]; ++s) {
      const int pj = perm[size_t(rows[size_t(s)])], pk = perm[size_t(k)];
      pat.rows[size_t(fill[size_t(std::min(pj, pk))]++)] = std::max(pj, pk);
    }
  for (int c = 0; c < nc; ++c)
    std::sort(pat.rows.begin() + long(pat.colstart[size_t(c)]), pat.rows.begin() + long(pat.colstart[size_t(c) + 1]));
  // Sizes and offsets in the permuted order.
  pat.size.resize(size_t(nc));
  for (int b = 0; b < nc; ++b) pat.size[size_t(perm[size_t(b)])] = lay.cams.block_size(b);
  pat.start.assign(size_t(nc) + 1, 0);
  for (int c = 0; c < nc; ++c) pat.start[size_t(c) + 1] = pat.start[size_t(c)] + pat.size[size_t(c)];
  // Offsets only with shared unknowns: with the cameras' blocks they follow from cnp, and
  // this solver's memory is what it is for.
  if (lay.cams.per_camera()) return pat;
  pat.colbase.assign(size_t(nc) + 1, 0);
  pat.height.assign(size_t(nc), 0);
  pat.rowoff.resize(pat.rows.size());
  for (int c = 0; c < nc; ++c) {
    i64 h = 0;
    for (i64 s = pat.colstart[size_t(c)]; s < pat.colstart[size_t(c) + 1]; ++s) {
      pat.rowoff[size_t(s)] = h;
      h += pat.size[size_t(pat.rows[size_t(s)])];
    }
    pat.height[size_t(c)] = h;
    pat.colbase[size_t(c) + 1] = pat.colbase[size_t(c)] + h * pat.size[size_t(c)];
  }
  return pat;
}

// CHOLMOD's int and long entry points.
struct IntApi {
  using Index = int;
  static constexpr auto start = &cholmod_start;
  static constexpr auto finish = &cholmod_finish;
  static constexpr auto allocate_sparse = &cholmod_allocate_sparse;
  static constexpr auto allocate_dense = &cholmod_allocate_dense;
  static constexpr auto analyze = &cholmod_analyze;
  static constexpr auto super_numeric = &cholmod_super_numeric;
  static constexpr auto factorize = &cholmod_factorize;
  static constexpr auto solve = &cholmod_solve;
  static constexpr auto free_sparse = &cholmod_free_sparse;
  static constexpr auto free_dense = &cholmod_free_dense;
  static constexpr auto free_factor = &cholmod_free_factor;
};
struct LongApi {
  using Index = sslong;
  static constexpr auto start = &cholmod_l_start;
  static constexpr auto finish = &cholmod_l_finish;
  static constexpr auto allocate_sparse = &cholmod_l_allocate_sparse;
  static constexpr auto allocate_dense = &cholmod_l_allocate_dense;
  static constexpr auto analyze = &cholmod_l_analyze;
  static constexpr auto super_numeric = &cholmod_l_super_numeric;
  static constexpr auto factorize = &cholmod_l_factorize;
  static constexpr auto solve = &cholmod_l_solve;
  static constexpr auto free_sparse = &cholmod_l_free_sparse;
  static constexpr auto free_dense = &cholmod_l_free_dense;
  static constexpr auto free_factor = &cholmod_l_free_factor;
};

// CHOLMOD's workspace and objects, released on every path (also when the solver's
// constructor throws part-way, since members are destroyed then).
template <class Api>
struct Cholmod {
  Cholmod() {
    Api::start(&cm);
    cm.print = 0;  // failures are reported by status, never printed
    cm.error_handler = nullptr;
    cm.supernodal = CHOLMOD_SUPERNODAL;
    cm.nmethods = 1;  // the matrix comes permuted already
    cm.method[0].ordering = CHOLMOD_NATURAL;
    cm.postorder = 0;
  }
  ~Cholmod() {
    Api::free_factor(&L, &cm);
    Api::free_sparse(&A, &cm);
    Api::free_dense(&B, &cm);
    Api::finish(&cm);
  }
  Cholmod(const Cholmod &) = delete;
  Cholmod &operator=(const Cholmod &) = delete;

  cholmod_common cm{};
  cholmod_sparse *A = nullptr;
  cholmod_factor *L = nullptr;
  cholmod_dense *B = nullptr;
};

// Below this many flops in the factorization (CHOLMOD's estimate after analysis), the
// simplicial factorization: it starts no OpenMP team and needs no BLAS buffers, so it holds
// less memory, and at that size the factorization is a small part of an iteration anyway.
// Above it the supernodal factorization is the faster one. sba_bench's scaling series and
// the sba-demo runs (bench/results) are the measurements behind the threshold.
constexpr double kSimplicialFlops = 1e6;

template <class Api>
class SparseSchurSolver final : public StepSolver {
  using Index = typename Api::Index;

 public:
  // The int solver may turn out too small for the factor; the long one then shares the pattern.
  SparseSchurSolver(const SolveContext &ctx, std::shared_ptr<const Pattern> pat)
      : ctx_(ctx), lay_(ctx.lay), pat_(std::move(pat)), assembly_(ctx), rhs_(size_t(lay_.camera_unknowns())) {
    build_matrix();
  }
  // False when the factor is too large for this index type.
  bool analyzed() const { return chol_.L != nullptr; }

  StepStatus solve(const NormalEquations &ne, double mu, double *dp) override {
    std::fill(dp, dp + lay_.nvars(), 0.0);
    double *Ax = static_cast<double *>(chol_.A->x);
    std::fill(Ax, Ax + static_cast<const Index *>(chol_.A->p)[chol_.A->ncol], 0.0);
    if (!assemble(ne, mu, Ax)) return StepStatus::SingularPointBlock;

    const ThreadPool::ForeignThreads cholmod(ctx_.pool);  // CHOLMOD and its BLAS run their own
    double beta[2] = {0.0, 0.0};
    const int ok = direct_ ? Api::super_numeric(chol_.A, nullptr, beta, chol_.L, &chol_.cm)
                           : Api::factorize(chol_.A, chol_.L, &chol_.cm);
    // The matrix is valid by construction: short of a matrix that is not positive definite
    // at this damping (L->minor below), only memory should fail.
    if (chol_.cm.status == CHOLMOD_OUT_OF_MEMORY || (!ok && chol_.cm.status != CHOLMOD_NOT_POSDEF))
      throw_cholmod_failure(direct_ ? "cholmod_super_numeric" : "cholmod_factorize", chol_.cm.status);
    if (chol_.L->minor < chol_.L->n) return StepStatus::Failed;  // not positive definite at this damping
    if (!solve_factored(dp)) return StepStatus::Failed;
    assembly_.finish(ne, mu, dp);
    return StepStatus::Solved;
  }
  // As the dense solver: per-camera blocks only.
  bool takes_damping() const override { return lay_.cams.per_camera(); }

 private:
  // S into CHOLMOD's arrays (Ax, zeroed) and rhs_; false if some V_i + mu I is singular.
  bool assemble(const NormalEquations &ne, double mu, double *Ax) {
    BlockMap cams;
    cams.base = Ax;
    cams.cnp = lay_.cnp;
    cams.perm = pat_->perm.data();
    cams.rows = pat_->rows.data();
    cams.colstart = pat_->colstart.data();
    UnknownBlocks unknowns;
    unknowns.kind = UnknownBlocks::Kind::Sparse;
    unknowns.base = Ax;
    unknowns.start = lay_.cams.block_starts();
    unknowns.perm = pat_->perm.data();
    unknowns.rows = pat_->rows.data();
    unknowns.colstart = pat_->colstart.data();
    unknowns.colbase = pat_->colbase.data();
    unknowns.height = pat_->height.data();
    unknowns.rowoff = pat_->rowoff.data();
    return assembly_.assemble(ne, mu, cams, unknowns, rhs_.data());
  }

  // The cameras' steps (dp's free cameras) from the factor and rhs_, through CHOLMOD's
  // permuted order; false if they are not finite.
  bool solve_factored(double *dp) {
    const int nb = int(pat_->perm.size());
    const std::vector<int> &perm = pat_->perm;
    double *b = static_cast<double *>(chol_.B->x);
    for (int q = 0; q < nb; ++q)
      std::copy_n(rhs_.data() + lay_.cams.block_start(q), lay_.cams.block_size(q), b + pat_->start[size_t(perm[size_t(q)])]);
    cholmod_dense *X = Api::solve(CHOLMOD_A, chol_.L, chol_.B, &chol_.cm);
    if (!X) throw_cholmod_failure("cholmod_solve", chol_.cm.status);
    const double *x = static_cast<const double *>(X->x);
    double *da = assembly_.solution(dp);
    bool finite = true;
    for (int q = 0; q < nb; ++q) {
      const double *xq = x + pat_->start[size_t(perm[size_t(q)])];
      double *out = da + lay_.cams.block_start(q);
      for (int a = 0; a < lay_.cams.block_size(q); ++a) {
        out[a] = xq[a];
        finite = finite && std::isfinite(xq[a]);
      }
    }
    Api::free_dense(&X, &chol_.cm);
    return finite;
  }

  // CHOLMOD's matrix on the stored blocks and its symbolic factorization. The diagonal blocks
  // are stored whole (CHOLMOD ignores the part above the diagonal), so that every scalar
  // column of a block column has the same rows, as the BlockMap layout needs.
  void build_matrix() {
    const Pattern &pat = *pat_;
    const int nc = int(pat.perm.size());
    const Index N = Index(pat.start[size_t(nc)]);
    const i64 nnz = pat.nnz();
    // Each call starts by resetting the status, so each is checked before the next.
    chol_.A = Api::allocate_sparse(size_t(N), size_t(N), size_t(nnz), 1, 1, -1, CHOLMOD_REAL, &chol_.cm);
    if (!chol_.A) throw_cholmod_failure("cholmod_allocate_sparse", chol_.cm.status);
    chol_.B = Api::allocate_dense(size_t(N), 1, size_t(N), CHOLMOD_REAL, &chol_.cm);
    if (!chol_.B) throw_cholmod_failure("cholmod_allocate_dense", chol_.cm.status);
    Index *Ap = static_cast<Index *>(chol_.A->p), *Ai = static_cast<Index *>(chol_.A->i);
    Index q = 0;
    for (int c = 0; c < nc; ++c)
      for (int b = 0; b < pat.size[size_t(c)]; ++b) {
        Ap[pat.start[size_t(c)] + b] = q;
        for (i64 s = pat.colstart[size_t(c)]; s < pat.colstart[size_t(c) + 1]; ++s) {
          const int r = pat.rows[size_t(s)];
          for (int a = 0; a < pat.size[size_t(r)]; ++a) Ai[q++] = Index(pat.start[size_t(r)] + a);
        }
      }
    Ap[N] = q;
    std::fill(static_cast<double *>(chol_.A->x), static_cast<double *>(chol_.A->x) + q, 0.0);
    chol_.L = Api::analyze(chol_.A, &chol_.cm);
    if (!chol_.L) {
      if (chol_.cm.status == CHOLMOD_TOO_LARGE) return;
      throw_cholmod_failure("cholmod_analyze", chol_.cm.status);
    }
    // A small factor is made column by column instead: the supernodal one would start an
    // OpenMP team of CHOLMOD's fixed size and touch the BLAS's buffers, which for S of a few
    // cameras cost more memory than S and its factor, and save no time. Left in LL' form,
    // so that a pivot that is not positive stops the factorization as the supernodal one does.
    if (chol_.cm.fl < kSimplicialFlops) {
      Api::free_factor(&chol_.L, &chol_.cm);
      chol_.cm.supernodal = CHOLMOD_SIMPLICIAL;
      chol_.cm.final_ll = 1;
      chol_.L = Api::analyze(chol_.A, &chol_.cm);
      // Smaller than the supernodal analysis that fit: not expected to fail.
      if (!chol_.L) throw_cholmod_failure("cholmod_analyze", chol_.cm.status);
    }
    // Natural ordering without postordering leaves L unpermuted; should CHOLMOD permute all
    // the same, cholmod_factorize applies its permutation (at the cost of a copy of A).
    const Index *lperm = static_cast<const Index *>(chol_.L->Perm);
    direct_ = chol_.L->is_super;
    for (Index c = 0; c < N && direct_; ++c) direct_ = !lperm || lperm[c] == c;
  }

  SolveContext ctx_;
  const Layout &lay_;
  std::shared_ptr<const Pattern> pat_;
  SchurAssembly assembly_;
  std::vector<double> rhs_;
  Cholmod<Api> chol_;
  bool direct_ = false;  // L is unpermuted: factor A itself (no copy)
};

}  // namespace

std::unique_ptr<StepSolver> make_sparse_schur_solver(const SolveContext &ctx) {
  auto pat = std::make_shared<const Pattern>(make_pattern(ctx.lay, ctx.analysis));
  if (pat->nnz() <= INT_MAX) {
    auto s = std::make_unique<SparseSchurSolver<IntApi>>(ctx, pat);
    if (s->analyzed()) return s;
  }
  return std::make_unique<SparseSchurSolver<LongApi>>(ctx, pat);
}

}  // namespace sba
