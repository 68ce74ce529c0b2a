// SPDX-License-Identifier: BSD-3-Clause
#include "linear_solver.h"

#include "named.h"

namespace sba {
namespace {

struct NamedSolver {
  const char *name;
  LinSolver value;
};
constexpr NamedSolver kSolvers[] = {
    {"chol", LinSolver::Chol}, {"ldlt", LinSolver::LDLt},     {"bk", LinSolver::BK},
    {"lu", LinSolver::LU},     {"qr", LinSolver::QR},         {"qrnoq", LinSolver::QRnoQ},
    {"svd", LinSolver::SVD},   {"cg", LinSolver::CG},         {"ldl-amd", LinSolver::LdlAmd},
    {"sparse-chol", LinSolver::SparseChol}, {"chol-lapack", LinSolver::CholLapack},
    {"iterative-schur", LinSolver::IterativeSchur}, {"auto", LinSolver::Auto},
};

constexpr auto kSolverNames = joined_names<joined_length(kSolvers)>(kSolvers);

}  // namespace

bool linsolver_from_name(const std::string &name, LinSolver *out) {
  return value_of(kSolvers, name, out);
}

const char *linsolver_name(LinSolver kind) {
  if (kind == LinSolver::BlockDiagonal) return "block-diagonal";
  for (const NamedSolver &s : kSolvers)
    if (s.value == kind) return s.name;
  return "?";
}

const char *linsolver_names() { return kSolverNames.text; }

}  // namespace sba
