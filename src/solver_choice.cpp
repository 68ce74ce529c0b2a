// SPDX-License-Identifier: BSD-3-Clause
#include "solver_choice.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <iterator>

#if defined(__unix__) || defined(__APPLE__)
#include <sys/resource.h>
#include <unistd.h>
#endif

#include "kernels.h"
#include "schur_pattern.h"
#include "step_solver.h"
#include "suitesparse_status.h"

namespace sba {
namespace {

i64 triangle(i64 b) { return b * (b + 1) / 2; }

// The mean order of S's blocks, and so the scalar entries a count of blocks stands for.
double block_order(const SolverShape &s) { return s.blocks > 0 ? double(s.unknowns) / double(s.blocks) : 0.0; }

// The free cameras' parameters: the unknowns, or with sharing the parameters they map to.
double camera_params(const SolverShape &s) {
  return double(s.shared_params > 0 ? s.shared_params : s.unknowns);
}

// What iterative-schur holds besides the point blocks' inverses (solver_iterative_schur.cpp):
// the point pass's partial sums, kChunks (32) per camera parameter, and CG's six vectors of
// S's order; without sharing, the preconditioner's partial sums (32 camera blocks per camera)
// and its factored blocks; with sharing, the clusters' matrices and their index (a 64-bit
// offset and four ints per block), the products' two vectors over the cameras' parameters,
// the gradient over the unknowns, and the assembly's list of each point's blocks (at least
// one int per projection).
double iterative_schur_doubles(const SolverShape &s) {
  const double n = double(s.unknowns), b = block_order(s);
  if (s.shared_params == 0) return n * (32 * (b + 1) + b + 6);
  return 34 * camera_params(s) + double(s.cluster_doubles) + 3 * double(s.blocks) + 7 * n +
         double(s.observations) * sizeof(int) / sizeof(double);
}

// Forming S once: a free point touching blocks of orders b_1 .. b_t adds a pnp-deep product
// of 2 pnp b_k b_l operations to each block pair k <= l, pnp ((sum b)^2 + sum b^2) in all.
double assembly_flops(const Layout &lay) {
  if (lay.pnp == 0) return 0;
  const CameraMap &cams = lay.cams;
  double flops = 0;
  for (int i = lay.ncon; i < lay.n; ++i) {
    double sum = 0, squares = 0;
    if (cams.per_camera()) {
      const double b = lay.cnp;
      for (int k = lay.rowptr[size_t(i)]; k < lay.rowptr[size_t(i) + 1]; ++k)
        if (lay.colidx[size_t(k)] >= lay.mcon) {
          sum += b;
          squares += b * b;
        }
    } else {
      const int *blocks = cams.point_blocks(i);
      for (int k = 0; k < cams.point_nblocks(i); ++k) {
        const double b = cams.block_size(blocks[k]);
        sum += b;
        squares += b * b;
      }
    }
    flops += lay.pnp * (sum * sum + squares);
  }
  return flops;
}

}  // namespace

double pass_flops(const SolverShape &s) {
  return 2.0 * double(s.observations) * s.mnp * (block_order(s) + s.pnp);
}

SolverMemory solver_memory(const SolverShape &s) {
  const double d = sizeof(double), b = block_order(s), n = double(s.unknowns);
  const double nobs = double(s.observations) * s.mnp, jblk = double(s.mnp) * (s.cnp + s.pnp);
  const double point_blocks = double(s.points) * s.pnp * s.pnp;
  SolverMemory m;
  // The Jacobian, the residual (unless streamed) and the measurements, the normal equations'
  // blocks (a camera's cnp x cnp, shared unknowns or not), p and the step, and the index
  // (three ints per projection, two without the expert callbacks' val); with sharing, the map
  // of each camera parameter to its unknown (an int and a flag) and the damping's share of
  // each (a double).
  const double params = camera_params(s);
  m.common = double(s.jacobian_entry_bytes) * double(s.observations) * jblk +
             d * ((s.residual_kept ? 2 : 1) * nobs + params * s.cnp + point_blocks +
                  2 * (params + double(s.points) * s.pnp)) +
             (s.expert_index ? 3.0 : 2.0) * sizeof(int) * double(s.observations);
  if (s.shared_params > 0) m.common += params * (d + sizeof(int) + 1);
  // S in full, and the point blocks' inverses where unknowns are shared; per camera, the
  // threads' packed copies of S's upper triangle that the assembly fills (kMaxPackedS).
  m.chol = d * (n * n + point_blocks);
  const double upper = n * (n + b) / 2;
  if (s.shared_params == 0 && upper <= double(kMaxPackedS)) m.chol += d * upper;
  // S's blocks and the factor's, the factor counted three times for the supernodes' padding
  // and CHOLMOD's workspace, which for a factor that fills in come near twice the factor.
  m.sparse_chol = d * ((double(s.s_blocks) + 3 * double(s.factor_blocks)) * b * b + point_blocks);
  m.iterative_schur = d * (point_blocks + iterative_schur_doubles(s));
  return m;
}

double solver_bytes(const SolverShape &s, LinSolver solver) {
  const SolverMemory m = solver_memory(s);
  switch (solver) {
    case LinSolver::SparseChol:
      return m.common + m.sparse_chol;
    case LinSolver::IterativeSchur:
      return m.common + m.iterative_schur;
    default:
      return m.common + m.chol;
  }
}

LinSolver choose_linsolver(const SolverShape &s) {
  if (s.unknowns <= 0) return LinSolver::Chol;
  const SolverMemory mem = solver_memory(s);
  const bool assembly_cheap = s.assembly_flops <= kAssemblyMaxPasses * pass_flops(s);
  const struct {
    LinSolver solver;
    double bytes;
    bool wanted;
  } candidates[] = {
      {LinSolver::Chol, mem.chol, s.unknowns <= kDenseMaxUnknowns},
      {LinSolver::SparseChol, mem.sparse_chol, s.factor_flops <= kSparseMaxPasses * pass_flops(s) && assembly_cheap},
      {LinSolver::IterativeSchur, mem.iterative_schur, true},
  };
  const auto fits = [&](double own) { return s.budget_bytes <= 0 || mem.common + own <= s.budget_bytes; };
  for (const auto &c : candidates)
    if (c.wanted && fits(c.bytes)) return c.solver;
  // Nothing fits: the least memory is the best chance.
  const auto *least = std::min_element(std::begin(candidates), std::end(candidates),
                                       [](const auto &a, const auto &b) { return a.bytes < b.bytes; });
  return least->solver;
}

std::string describe(const SolverShape &s) {
  const i64 all = triangle(s.blocks);
  const double pct = all > 0 ? 100.0 / double(all) : 0.0;
  const SolverMemory m = solver_memory(s);
  const auto mb = [](double bytes) { return bytes / (1024.0 * 1024.0); };
  char buf[640];
  std::snprintf(buf, sizeof buf,
                "S of %lld unknowns in %lld blocks, %s%.3g%% of them nonzero, %.3g%% in its factor, whose "
                "factorization costs %.3g passes over the Jacobian of %lld observations and forming it %.3g; MiB "
                "besides the common %.0f: chol %.0f, sparse-chol %.0f, iterative-schur %.0f; a budget of %.0f MiB",
                static_cast<long long>(s.unknowns), static_cast<long long>(s.blocks),
                s.s_partial ? "at least " : "", double(s.s_blocks) * pct,
                double(s.factor_blocks) * pct, s.factor_flops / std::max(1.0, pass_flops(s)),
                static_cast<long long>(s.observations), s.assembly_flops / std::max(1.0, pass_flops(s)),
                mb(m.common), mb(m.chol), mb(m.sparse_chol),
                mb(m.iterative_schur), mb(s.budget_bytes));
  return buf;
}

SolverShape shape_of(const Layout &lay, double budget_bytes) {
  SolverShape s;
  s.observations = lay.nvis;
  s.points = lay.free_pts();
  s.cnp = lay.cnp;
  s.pnp = lay.pnp;
  s.mnp = lay.mnp;
  s.budget_bytes = budget_bytes;
  if (lay.free_cams() == 0 || (lay.free_pts() == 0 && lay.cams.per_camera())) return s;
  s.unknowns = lay.camera_unknowns();
  s.blocks = lay.cams.nblocks();
  if (!lay.cams.per_camera()) {
    s.shared_params = i64(lay.free_cams()) * lay.cnp;
    s.cluster_doubles = iterative_schur_cluster_doubles(lay.cams);
  }
  // Every camera parameter held: S is empty, and its blocks have no order to divide by.
  if (s.unknowns <= 0 || s.blocks <= 0) {
    s.unknowns = s.blocks = 0;
    return s;
  }
  s.assembly_flops = assembly_flops(lay);
  const double b = block_order(s), nb = double(s.blocks);
  s.factor_blocks = triangle(s.blocks);
  s.factor_flops = double(s.unknowns) * double(s.unknowns) * double(s.unknowns) / 3;
  // A factor whose columns hold f_k blocks below the diagonal takes sum f_k (f_k + 1) / 2
  // block multiply-subtracts of 2 b^3 operations, at least (sum f_k)^2 / nb b^3, and sum f_k is
  // at least S's blocks off the diagonal: past this many blocks of S, sparse-chol is out.
  const double enough = nb + std::sqrt(kSparseMaxPasses * pass_flops(s) * nb / (b * b * b));
  auto analysis = std::make_shared<SchurAnalysis>();
  const bool counted = schur_pattern(lay, i64(std::min(enough, double(s.factor_blocks))), &analysis->pattern);
  s.s_blocks = analysis->pattern.nnz();
  s.s_partial = !counted;
  if (!counted) return s;
  double info[AMD_INFO];
  analysis->order = amd_block_order(analysis->pattern, info);
  s.analysis = std::move(analysis);
  s.factor_blocks = std::min(s.factor_blocks, i64(info[AMD_LNZ]) + s.blocks);
  // Each diagonal block's own Cholesky, b^3 / 3, and the updates.
  s.factor_flops = nb * b * b * b / 3 + 2 * b * b * b * info[AMD_NMULTSUBS_LDL];
  return s;
}

MemoryBudget memory_budget(double asked) {
  if (asked > 0) return {asked, "memory_budget"};
  MemoryBudget budget{0, "physical memory"};
#if defined(__unix__) || defined(__APPLE__)
#if defined(_SC_PHYS_PAGES)
  const long pages = sysconf(_SC_PHYS_PAGES), size = sysconf(_SC_PAGESIZE);
  if (pages > 0 && size > 0) budget.bytes = double(pages) * double(size);
#endif
  rlimit lim{};
  if (getrlimit(RLIMIT_AS, &lim) == 0 && lim.rlim_cur != RLIM_INFINITY &&
      (budget.bytes <= 0 || double(lim.rlim_cur) < budget.bytes))
    budget = {double(lim.rlim_cur), "address-space limit"};
#endif
  return budget;
}

}  // namespace sba
