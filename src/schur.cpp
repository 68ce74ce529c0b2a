#include "schur.h"

#include <algorithm>
#include <cmath>
#include <cstring>

#include "small_dense.h"

namespace sba {

namespace schur {

void form_W(const Layout &lay, const double *jac, i64 k, double *W) {
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

Assembler::Assembler(const Layout &lay) : lay_(lay) {
  int maxtrack = 0;
  for (int i = 0; i < lay.n; ++i)
    maxtrack = std::max(maxtrack, lay.rowptr[i + 1] - lay.rowptr[i]);
  const size_t cp = size_t(lay.cnp) * size_t(lay.pnp);
  Vinv_.resize(size_t(i64(lay.n) * lay.pnp * lay.pnp));
  W_.resize(size_t(maxtrack) * cp);
  Y_.resize(W_.size());
  track_.resize(size_t(maxtrack));
  tmp_.resize(size_t(lay.pnp) * size_t(lay.pnp) + size_t(lay.pnp));
}

bool Assembler::invert_damped_V(const NormalEquations &ne, double mu) {
  const int pnp = lay_.pnp;
  double *blk = tmp_.data();
  for (int i = lay_.ncon; i < lay_.n; ++i) {
    const double *V = ne.V + i64(i) * pnp * pnp;
    std::copy(V, V + pnp * pnp, blk);
    for (int a = 0; a < pnp; ++a) blk[a * pnp + a] += mu;
    if (!small::spd_inverse(blk, Vinv_.data() + i64(i) * pnp * pnp, pnp)) return false;
  }
  return true;
}

void Assembler::back_substitute(const NormalEquations &ne, double *dp) {
  const Layout &lay = lay_;
  const int cnp = lay.cnp, pnp = lay.pnp;
  double *t = tmp_.data(), *W = W_.data();
  for (int i = lay.ncon; i < lay.n; ++i) {
    const double *ebi = ne.eb + i64(i) * pnp;
    std::copy(ebi, ebi + pnp, t);
    for (int k = lay.rowptr[i]; k < lay.rowptr[i + 1]; ++k) {
      const int j = lay.colidx[k];
      if (j < lay.mcon) continue;
      form_W(lay, ne.jac, k, W);
      const double *daj = dp + lay.a_off(j);
      for (int b = 0; b < pnp; ++b) {
        double s = 0.0;
        for (int a = 0; a < cnp; ++a) s += W[a * pnp + b] * daj[a];
        t[b] -= s;
      }
    }
    const double *Vi = Vinv_.data() + i64(i) * pnp * pnp;
    double *dbi = dp + lay.b_off(i);
    for (int a = 0; a < pnp; ++a) {
      double s = 0.0;
      for (int b = 0; b < pnp; ++b) s += Vi[a * pnp + b] * t[b];
      dbi[a] = s;
    }
  }
}

}  // namespace schur

namespace {

// No free points or no free cameras: (J^T J + mu I) is block diagonal, one small Cholesky
// per free camera or point (the 1.6 motion-only and structure-only drivers).
class BlockDiagonalSolver final : public StepSolver {
 public:
  explicit BlockDiagonalSolver(const Layout &lay)
      : lay_(lay), blk_(size_t(std::max(lay.cnp, lay.pnp)) * size_t(std::max(lay.cnp, lay.pnp))) {}

  bool solve(const NormalEquations &ne, double mu, double *dp) override {
    const Layout &lay = lay_;
    std::fill(dp, dp + lay.nvars(), 0.0);
    for (int j = lay.mcon; j < lay.m && lay.cnp; ++j)
      if (!one(ne.U + i64(j) * lay.cnp * lay.cnp, ne.ea + i64(j) * lay.cnp, lay.cnp, mu,
               dp + lay.a_off(j)))
        return false;
    for (int i = lay.ncon; i < lay.n && lay.pnp; ++i)
      if (!one(ne.V + i64(i) * lay.pnp * lay.pnp, ne.eb + i64(i) * lay.pnp, lay.pnp, mu,
               dp + lay.b_off(i)))
        return false;
    return true;
  }

 private:
  bool one(const double *M, const double *g, int d, double mu, double *x) {
    if (d <= 0) return true;  // never: cnp, pnp > 0 here; tells the optimizer so
    double *b = blk_.data();
    std::copy_n(M, size_t(d) * size_t(d), b);
    for (int a = 0; a < d; ++a) b[a * d + a] += mu;
    if (!small::chol(b, d)) return false;
    std::copy_n(g, size_t(d), x);
    small::chol_solve(b, x, d);
    for (int a = 0; a < d; ++a)
      if (!std::isfinite(x[a])) return false;
    return true;
  }

  const Layout &lay_;
  std::vector<double> blk_;
};

struct NamedSolver {
  const char *name;
  LinSolver kind;
};
constexpr NamedSolver kSolvers[] = {
    {"chol", LinSolver::Chol}, {"ldlt", LinSolver::LDLt},     {"bk", LinSolver::BK},
    {"lu", LinSolver::LU},     {"qr", LinSolver::QR},         {"qrnoq", LinSolver::QRnoQ},
    {"svd", LinSolver::SVD},   {"cg", LinSolver::CG},         {"ldl-amd", LinSolver::LdlAmd},
    {"sparse-chol", LinSolver::SparseChol},
};

}  // namespace

// Defined in solver_*.cpp.
std::unique_ptr<StepSolver> make_dense_schur_solver(LinSolver kind, const Layout &lay);
std::unique_ptr<StepSolver> make_ldl_amd_solver(const Layout &lay);
std::unique_ptr<StepSolver> make_sparse_schur_solver(const Layout &lay);

bool linsolver_from_name(const std::string &name, LinSolver *out) {
  for (const NamedSolver &s : kSolvers)
    if (name == s.name) {
      *out = s.kind;
      return true;
    }
  return false;
}

const char *linsolver_name(LinSolver kind) {
  for (const NamedSolver &s : kSolvers)
    if (s.kind == kind) return s.name;
  return "?";
}

const char *linsolver_names() {
  return "chol ldlt bk lu qr qrnoq svd cg ldl-amd sparse-chol";
}

std::unique_ptr<StepSolver> make_step_solver(LinSolver kind, const Layout &lay) {
  if (lay.free_cams() == 0 || lay.free_pts() == 0)
    return std::make_unique<BlockDiagonalSolver>(lay);
  switch (kind) {
    case LinSolver::LdlAmd:
      return make_ldl_amd_solver(lay);
    case LinSolver::SparseChol:
      return make_sparse_schur_solver(lay);
    default:
      return make_dense_schur_solver(kind, lay);
  }
}

}  // namespace sba
