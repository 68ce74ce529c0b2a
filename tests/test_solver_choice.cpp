// SPDX-License-Identifier: BSD-3-Clause
// The choice behind the linear solver "auto" (src/solver_choice.h): the rule as a function of
// the shape numbers, the shape it reads from a layout (S's blocks, its factor's after AMD,
// holding and sharing), the memory budget it plans within, and its estimate of each solver's
// memory against what the solves allocate.
#include <gtest/gtest.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cstdint>
#include <string>
#include <vector>

#include "camera_unknowns.h"
#include "counting_malloc.h"
#include "layout.h"
#include "linear_solver.h"
#include "sba_ext.h"
#include "solver_choice.h"
#include "synth.h"

namespace {

using sba::i64;
using sba::LinSolver;
using sba::SolverShape;

constexpr double kGiB = 1024.0 * 1024.0 * 1024.0;

// A problem of `cameras` free cameras of 6 unknowns, 100 points each seen by 5 of them, pnp 3,
// mnp 2; S's blocks filling the given share of its upper triangle, its factor as many blocks
// again, and a factorization that costs `passes` passes over the Jacobian.
SolverShape shape(i64 cameras, double s_share, double passes, double budget = 0) {
  SolverShape s;
  s.unknowns = 6 * cameras;
  s.blocks = cameras;
  const i64 all = cameras * (cameras + 1) / 2;
  s.s_blocks = i64(s_share * double(all));
  s.factor_blocks = std::min(all, 2 * s.s_blocks);
  s.points = 100 * cameras;
  s.observations = 5 * s.points;
  s.cnp = 6;
  s.pnp = 3;
  s.mnp = 2;
  s.factor_flops = passes * sba::pass_flops(s);
  s.budget_bytes = budget;
  return s;
}

// The same with the factor of a dense S.
SolverShape dense(i64 cameras, double budget = 0) {
  SolverShape s = shape(cameras, 1, 0, budget);
  s.factor_flops = double(s.unknowns) * double(s.unknowns) * double(s.unknowns) / 3;
  return s;
}

TEST(SolverChoice, PassesOverTheJacobian) {
  // 50,000 projections of 2 x (6 + 3) entries.
  EXPECT_DOUBLE_EQ(sba::pass_flops(shape(100, 1, 0)), 2.0 * 50000 * 2 * 9);
}

TEST(SolverChoice, NoUnknownsNoChoice) {
  // The motion-only and structure-only drivers, or no free points: the system is block
  // diagonal and the name only reported.
  SolverShape s = dense(1000);
  s.unknowns = 0;
  EXPECT_EQ(sba::choose_linsolver(s), LinSolver::Chol);
}

TEST(SolverChoice, SmallProblemsTakeChol) {
  for (i64 cams : {i64(2), i64(10), i64(100), sba::kDenseMaxUnknowns / 6}) {
    EXPECT_EQ(sba::choose_linsolver(dense(cams)), LinSolver::Chol) << cams;
    EXPECT_EQ(sba::choose_linsolver(shape(cams, 0.01, 1)), LinSolver::Chol) << cams;
  }
  SolverShape edge = dense(200);
  edge.unknowns = sba::kDenseMaxUnknowns;
  EXPECT_EQ(sba::choose_linsolver(edge), LinSolver::Chol);
  edge.unknowns += 1;
  EXPECT_EQ(sba::choose_linsolver(edge), LinSolver::IterativeSchur);
}

TEST(SolverChoice, CheapSparseFactorTakesSparseChol) {
  EXPECT_EQ(sba::choose_linsolver(shape(1000, 0.005, 2)), LinSolver::SparseChol);
  EXPECT_EQ(sba::choose_linsolver(shape(10000, 0.0005, sba::kSparseMaxPasses)), LinSolver::SparseChol);
  // A few hundred cameras along a path: S a fifth full, but banded.
  EXPECT_EQ(sba::choose_linsolver(shape(200, 0.2, 10)), LinSolver::SparseChol);
  // Sparse S, but a factor that fills in: a costly factorization.
  EXPECT_EQ(sba::choose_linsolver(shape(1000, 0.02, 2 * sba::kSparseMaxPasses)), LinSolver::IterativeSchur);
}

TEST(SolverChoice, LargeDenseTakesIterativeSchur) {
  EXPECT_EQ(sba::choose_linsolver(dense(300)), LinSolver::IterativeSchur);
  EXPECT_EQ(sba::choose_linsolver(dense(10000, 20 * kGiB)), LinSolver::IterativeSchur);
}

TEST(SolverChoice, LongTracksTakeIterativeSchur) {
  // Forming S costs more than kAssemblyMaxPasses passes: not sparse-chol, whatever the factor
  // costs; at the bound, the choice is as before. A small S still takes chol.
  SolverShape small = dense(100);
  small.assembly_flops = 10 * sba::kAssemblyMaxPasses * sba::pass_flops(small);
  EXPECT_EQ(sba::choose_linsolver(small), LinSolver::Chol);
  SolverShape banded = shape(1000, 0.005, 2);
  banded.assembly_flops = sba::kAssemblyMaxPasses * sba::pass_flops(banded);
  EXPECT_EQ(sba::choose_linsolver(banded), LinSolver::SparseChol);
  banded.assembly_flops *= 1.01;
  EXPECT_EQ(sba::choose_linsolver(banded), LinSolver::IterativeSchur);
}

TEST(SolverChoice, NeverWhatDoesNotFit) {
  // chol would be the choice, but its S does not fit: the sparse factor does.
  SolverShape s = shape(150, 0.02, 5);
  const sba::SolverMemory m = sba::solver_memory(s);
  s.budget_bytes = m.common + (m.chol + m.sparse_chol) / 2;
  ASSERT_LT(m.sparse_chol, m.chol);
  EXPECT_EQ(sba::choose_linsolver(s), LinSolver::SparseChol);
  // A dense S that does not fit, whose factorization would cost too much anyway: iterative-schur.
  SolverShape big = dense(150);
  const sba::SolverMemory md = sba::solver_memory(big);
  ASSERT_LT(md.iterative_schur, md.chol);
  big.budget_bytes = md.common + (md.chol + md.iterative_schur) / 2;
  EXPECT_EQ(sba::choose_linsolver(big), LinSolver::IterativeSchur);
  // Nothing fits: the one that needs least, here chol's small S.
  SolverShape tiny = dense(4, 1.0);
  const sba::SolverMemory mt = sba::solver_memory(tiny);
  ASSERT_LT(mt.chol, mt.iterative_schur);
  EXPECT_EQ(sba::choose_linsolver(tiny), LinSolver::Chol);
  // 10,000 cameras of a photo collection: a dense S of 60,000 unknowns is 26.8 GiB.
  const SolverShape photo = dense(10000, 20 * kGiB);
  EXPECT_GT(sba::solver_memory(photo).chol, 20 * kGiB);
  EXPECT_EQ(sba::choose_linsolver(photo), LinSolver::IterativeSchur);
}

// A layout of m cameras whose points are each seen by `run` consecutive cameras (S banded),
// or by every camera (`run` 0: S dense); the first mcon cameras and ncon points fixed.
sba::Layout layout(int m, int n, int run, int mcon = 0, int ncon = 0) {
  std::vector<char> vmask(size_t(n) * size_t(m), 0);
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < m; ++j)
      if (run == 0 || (j >= i % (m - run + 1) && j < i % (m - run + 1) + run)) vmask[size_t(i) * size_t(m) + size_t(j)] = 1;
  sba::Layout lay;
  std::string msg;
  EXPECT_TRUE(sba::build_layout(lay, sba::Mode::MotStr, n, m, mcon, ncon, 6, 3, 2, vmask.data(), &msg)) << msg;
  return lay;
}

// Gives lay the camera map of o, checked as the drivers check it (every parameter 1.0).
testing::AssertionResult map_cameras(const sba::CameraParamOptions &o, sba::Layout *lay) {
  std::vector<double> p(size_t(lay->nvars()), 1.0);
  const std::string error = sba::check_camera_params(o, *lay, p.data());
  if (!error.empty()) return testing::AssertionFailure() << error;
  lay->cams = sba::make_camera_map(o, *lay);
  return testing::AssertionSuccess();
}

TEST(SolverChoice, ShapeOfABandedProblem) {
  const sba::Layout lay = layout(300, 3000, 3);
  const SolverShape s = sba::shape_of(lay, 5 * kGiB);
  EXPECT_EQ(s.unknowns, 1800);
  EXPECT_EQ(s.blocks, 300);
  EXPECT_EQ(s.observations, 9000);
  EXPECT_EQ(s.points, 3000);
  EXPECT_EQ(s.budget_bytes, 5 * kGiB);
  // Each camera with itself and the two before it.
  EXPECT_EQ(s.s_blocks, 300 + 299 + 298);
  EXPECT_FALSE(s.s_partial);
  // AMD keeps a band's factor within a few times the band, and its work to a few dozen block
  // operations of 2 * 6^3 per camera, where a dense S's would be 1800^3 / 3.
  EXPECT_GE(s.factor_blocks, s.s_blocks);
  EXPECT_LE(s.factor_blocks, 2 * s.s_blocks);
  EXPECT_GT(s.factor_flops, 300 * 216 / 3.0);
  EXPECT_LT(s.factor_flops, 300 * 216 * 20.0);
  EXPECT_EQ(sba::choose_linsolver(s), LinSolver::SparseChol);
}

TEST(SolverChoice, ShapeOfADenseProblemStopsCounting) {
  const sba::Layout lay = layout(200, 400, 0);
  const SolverShape s = sba::shape_of(lay, 0);
  EXPECT_EQ(s.unknowns, 1200);
  // Counting stops where even the least fill-in would cost more than kSparseMaxPasses passes,
  // (s_blocks - 200)^2 / 200 * 6^3 flops > 50 passes of 2 * 80,000 * 2 * 9 flops, i.e. past
  // 11,747 blocks: at the end of the column that passes it, the 153rd.
  ASSERT_EQ(sba::kSparseMaxPasses, 50);
  EXPECT_TRUE(s.s_partial);
  EXPECT_EQ(s.s_blocks, 153 * 154 / 2);
  EXPECT_EQ(s.factor_blocks, 200 * 201 / 2);
  EXPECT_DOUBLE_EQ(s.factor_flops, 1200.0 * 1200 * 1200 / 3);
  EXPECT_EQ(sba::choose_linsolver(s), LinSolver::IterativeSchur);
}

TEST(SolverChoice, ShapeCountsFormingS) {
  // Every point seen by every camera: each of the n points adds 2 * 3 * 6 * 6 operations to
  // each of the m (m + 1) / 2 pairs of cameras. A pass over the Jacobian is 2 * n m * 2 * 9.
  ASSERT_EQ(sba::kAssemblyMaxPasses, 400);
  const SolverShape hundred = sba::shape_of(layout(100, 300, 0), 0);
  EXPECT_DOUBLE_EQ(hundred.assembly_flops, 300.0 * 3 * 36 * 100 * 101);
  EXPECT_DOUBLE_EQ(sba::pass_flops(hundred), 2.0 * 30000 * 2 * 9);
  EXPECT_EQ(sba::choose_linsolver(hundred), LinSolver::Chol);
  // 200 cameras seeing 2,000 points: S's 1,200 unknowns are too many for chol, and the points'
  // long tracks make a pass costly enough that S's dense factor costs 40 passes, which would
  // take sparse-chol; but forming S costs 603.
  const SolverShape longer = sba::shape_of(layout(200, 2000, 0), 0);
  EXPECT_EQ(longer.unknowns, 1200);
  EXPECT_FALSE(longer.s_partial);
  EXPECT_LE(longer.factor_flops, sba::kSparseMaxPasses * sba::pass_flops(longer));
  EXPECT_DOUBLE_EQ(longer.assembly_flops, 2000.0 * 3 * 36 * 200 * 201);
  EXPECT_EQ(sba::choose_linsolver(longer), LinSolver::IterativeSchur);
  // Fixed cameras and points add nothing: 6 free cameras, each point of the band seeing up to 3
  // of them, 20 free points.
  const sba::Layout fixed = layout(10, 50, 3, 4, 30);
  double flops = 0;
  for (int i = 30; i < 50; ++i) {
    int t = 0;
    for (int k = fixed.rowptr[size_t(i)]; k < fixed.rowptr[size_t(i) + 1]; ++k) t += fixed.colidx[size_t(k)] >= 4;
    flops += 3.0 * 36 * t * (t + 1);
  }
  EXPECT_GT(flops, 0);
  EXPECT_DOUBLE_EQ(sba::shape_of(fixed, 0).assembly_flops, flops);
}

TEST(SolverChoice, ShapeFollowsFixedCamerasAndPoints) {
  // Each layout built with its fixed cameras and points, whose camera map follows them.
  SolverShape s = sba::shape_of(layout(10, 50, 3, 4), 0);
  EXPECT_EQ(s.blocks, 6);
  EXPECT_EQ(s.unknowns, 36);
  // Points only: nothing to choose.
  EXPECT_EQ(sba::shape_of(layout(10, 50, 3, 10), 0).unknowns, 0);
  EXPECT_EQ(sba::shape_of(layout(10, 50, 3, 0, 50), 0).unknowns, 0);
}

TEST(SolverChoice, ShapeCountsSharedUnknowns) {
  // A hundred cameras with a pose each and one shared intrinsic (parameter 5): 501 unknowns
  // in 101 blocks; the shared block couples every camera, so S's pattern is the band plus a
  // full row and column.
  sba::Layout lay = layout(100, 500, 3);
  std::vector<int> group(100, 0);
  const char shared[6] = {0, 0, 0, 0, 0, 1};
  sba::CameraParamOptions o;
  o.group = group.data();
  o.shared = shared;
  ASSERT_TRUE(map_cameras(o, &lay));
  const SolverShape s = sba::shape_of(lay, 0);
  EXPECT_EQ(s.unknowns, 501);
  EXPECT_EQ(s.blocks, 101);
  EXPECT_EQ(s.s_blocks, 100 + 99 + 98 + 101);
  // Each point touches its 3 cameras' own blocks of 5 and the shared one of 1: (3 * 5 + 1)^2
  // + 3 * 5^2 + 1^2 times pnp.
  EXPECT_DOUBLE_EQ(s.assembly_flops, 500.0 * 3 * (16 * 16 + 76));
}

TEST(SolverChoice, EveryCameraParameterHeldLeavesNothingToChoose) {
  // Free cameras and points, but no camera unknown: S is empty, and the shape says so
  // without dividing by its empty blocks (which made the pattern's bound a NaN).
  sba::Layout lay = layout(10, 50, 3);
  const char held[6] = {1, 1, 1, 1, 1, 1};
  const std::vector<int> one(10, 0);  // one group sharing everything: the mapped form
  sba::CameraParamOptions o;
  o.fixed = held;
  o.group = one.data();
  o.shared = held;
  ASSERT_TRUE(map_cameras(o, &lay));
  const SolverShape s = sba::shape_of(lay, 0);
  EXPECT_EQ(s.unknowns, 0);
  EXPECT_EQ(s.s_blocks, 0);
  EXPECT_FALSE(s.s_partial);
  EXPECT_EQ(s.factor_flops, 0.0);
  EXPECT_EQ(sba::choose_linsolver(s), LinSolver::Chol);
}

// The budget is a setting: the one asked for, else the physical memory, else (lower) the
// address-space limit; the same on every call, whatever the moment's free memory.
TEST(SolverChoice, BudgetIsASetting) {
  const double pages = double(sysconf(_SC_PHYS_PAGES)) * double(sysconf(_SC_PAGESIZE));
  const sba::MemoryBudget machine = sba::memory_budget(0);
  EXPECT_EQ(machine.bytes, pages);
  EXPECT_STREQ(machine.what, "physical memory");
  std::vector<char> held(64 << 20, 1);  // memory taken meanwhile changes nothing
  EXPECT_EQ(sba::memory_budget(0).bytes, machine.bytes);
  EXPECT_EQ(held[12345], 1);
  const sba::MemoryBudget asked = sba::memory_budget(3 * kGiB);
  EXPECT_EQ(asked.bytes, 3 * kGiB);
  EXPECT_STREQ(asked.what, "memory_budget");
  // In a child, under an address-space limit below the physical memory: the limit.
  const pid_t pid = fork();
  ASSERT_GE(pid, 0);
  if (pid == 0) {
    rlimit lim{};
    lim.rlim_cur = lim.rlim_max = rlim_t(8) << 30;
    if (pages <= double(lim.rlim_cur) || setrlimit(RLIMIT_AS, &lim) != 0) _exit(2);
    const sba::MemoryBudget limited = sba::memory_budget(0);
    _exit(limited.bytes == double(rlim_t(8) << 30) && std::string(limited.what) == "address-space limit" ? 0 : 1);
  }
  int status = 0;
  ASSERT_EQ(waitpid(pid, &status, 0), pid);
  ASSERT_TRUE(WIFEXITED(status));
  if (WEXITSTATUS(status) == 2) GTEST_SKIP() << "the physical memory is below 8 GiB, or no limit can be set";
  EXPECT_EQ(WEXITSTATUS(status), 0);
}

// ---- the memory the solves allocate ----

// A problem of synth.h whose points are each seen by `run` consecutive cameras: S banded.
synth::Problem banded(int n, int m, int run) {
  synth::Problem pb = synth::make(n, m, 0, 0.02, 7, 0.0);
  pb.x.clear();
  pb.nvis = 0;
  for (int i = 0; i < n; ++i) {
    const int first = int(i64(i) * (m - run + 1) / n);
    for (int j = 0; j < m; ++j) {
      const bool seen = j >= first && j < first + run;
      pb.vmask[size_t(i) * size_t(m) + size_t(j)] = seen;
      if (!seen) continue;
      double xij[2];
      synth::project(pb.truth.data() + j * synth::kCnp, pb.truth.data() + size_t(m) * synth::kCnp + size_t(i) * 3, xij,
                     nullptr, nullptr);
      pb.x.insert(pb.x.end(), {xij[0], xij[1]});
      ++pb.nvis;
    }
  }
  return pb;
}

struct Solved {
  int ret = 0;
  double info[SBA_INFOSZ] = {};
  double peak = 0;  // the most the call held beyond what was held before it, in bytes
  std::vector<double> p;
  std::string linsolver, log;
};

// param_group: sba_ext_options::cam_param_group (null: nothing shared).
Solved solve(const synth::Problem &pb, const char *solver, size_t budget = 0, const int *param_group = nullptr) {
  Solved r;
  r.p = pb.p0;
  sba_ext_result res;
  sba_ext_result_init(&res);
  sba_ext_options ext;
  sba_ext_options_init(&ext);
  ext.linsolver = solver;
  ext.nthreads = 1;
  ext.memory_budget = budget;
  ext.cam_param_group = param_group;
  ext.result = &res;
  ext.log_ctx = &r.log;
  ext.log = [](void *ctx, int, const char *line) { *static_cast<std::string *>(ctx) += std::string(line) + "\n"; };
  const long long before = malloc_count::live();
  malloc_count::reset_peak();
  r.ret = sba_motstr_levmar_x_ext(pb.n, 0, pb.m, 1, const_cast<char *>(pb.vmask.data()), r.p.data(), synth::kCnp,
                                  synth::kPnp, const_cast<double *>(pb.x.data()), nullptr, synth::kMnp, synth::func_motstr,
                                  synth::fjac_motstr, const_cast<synth::Problem *>(&pb), 3, 0, nullptr, r.info, &ext);
  r.peak = double(malloc_count::peak() - before);
  if (res.linsolver) r.linsolver = res.linsolver;
  return r;
}

SolverShape shape_of(const synth::Problem &pb, double budget = 0, const int *param_group = nullptr) {
  sba::Layout lay;
  std::string msg;
  EXPECT_TRUE(sba::build_layout(lay, sba::Mode::MotStr, pb.n, pb.m, 1, 0, synth::kCnp, synth::kPnp, synth::kMnp,
                                pb.vmask.data(), &msg))
      << msg;
  if (param_group) {
    sba::CameraParamOptions o;
    o.param_group = param_group;
    EXPECT_TRUE(map_cameras(o, &lay));
  }
  return sba::shape_of(lay, budget);
}

// What auto plans with is what the solves take: malloc's bytes at their peak (CHOLMOD's and the
// library's alike, counting_malloc.h) within 20% below and 10% above the estimate, for each
// of the three solvers on a dense S, an S whose factor fills in, and a banded S.
TEST(SolverMemory, EachSolverTakesAboutItsEstimate) {
#ifdef SBA_TEST_SANITIZED
  GTEST_SKIP() << "a sanitizer replaces malloc: nothing is counted";
#endif
  const struct {
    const char *what;
    synth::Problem pb;
  } problems[] = {{"dense", synth::make(4000, 60, 0.5, 0.02, 7, 0.5)},
                  {"filling in", synth::make(3000, 300, 0.5, 0.02, 7, 0.02)},
                  {"banded", banded(3000, 300, 4)}};
  for (const auto &[what, pb] : problems) {
    const SolverShape s = shape_of(pb);
    for (const LinSolver solver : {LinSolver::Chol, LinSolver::SparseChol, LinSolver::IterativeSchur}) {
      const char *name = sba::linsolver_name(solver);
      SCOPED_TRACE(std::string(what) + " " + name);
      const Solved r = solve(pb, name);
      ASSERT_EQ(r.ret, 3) << r.log;
      const double estimate = sba::solver_bytes(s, solver);
      EXPECT_GE(r.peak, 0.8 * estimate) << r.peak / estimate;
      EXPECT_LE(r.peak, 1.1 * estimate) << r.peak / estimate;
    }
  }
}

// iterative-schur's preconditioner is what it allocates most of where cameras are many and
// see few points each: S's diagonal blocks without sharing, and with shared unknowns the
// matrices of the clusters of S's blocks (a shared block with the own blocks of the cameras
// that touch only it), or S's blocks alone where no cluster forms. Each within 20% below and
// 10% above the estimate, on 1,200 cameras of 10 observations each.
TEST(SolverMemory, IterativeSchurTakesAboutItsEstimate) {
#ifdef SBA_TEST_SANITIZED
  GTEST_SKIP() << "a sanitizer replaces malloc: nothing is counted";
#endif
  // Camera 0 held (mcon 1), 1,200 free.
  const int m = 1201, cnp = synth::kCnp;
  const synth::Problem pb = banded(3000, m, 4);
  // Clusters: parameters 3-5 shared by groups of 40 cameras, 3 shared and 40 x 3 own
  // unknowns in each of the 30 clusters.
  std::vector<int> clustered(size_t(m) * cnp, -1), alone(clustered);
  for (int j = 1; j < m; ++j)
    for (int c = 3; c < 6; ++c) clustered[size_t(j * cnp + c)] = (j - 1) / 40;
  // No cluster: parameter 5 shared by all free cameras and 3-4 by pairs, so that every
  // camera touches two shared blocks.
  for (int j = 1; j < m; ++j) {
    alone[size_t(j * cnp + 3)] = alone[size_t(j * cnp + 4)] = (j - 1) / 2;
    alone[size_t(j * cnp + 5)] = 0;
  }
  const struct {
    const char *what;
    const int *group;
    i64 cluster_doubles;
  } cases[] = {{"own", nullptr, 0},
               {"clusters", clustered.data(), 30 * 123 * 123},
               {"blocks alone", alone.data(), 1200 * 9 + 600 * 4 + 1}};
  for (const auto &c : cases) {
    SCOPED_TRACE(c.what);
    const SolverShape s = shape_of(pb, 0, c.group);
    EXPECT_EQ(s.cluster_doubles, c.cluster_doubles);
    EXPECT_EQ(s.shared_params, c.group ? i64(1200) * cnp : 0);
    const Solved r = solve(pb, "iterative-schur", 0, c.group);
    ASSERT_EQ(r.ret, 3) << r.log;
    const double estimate = sba::solver_bytes(s, LinSolver::IterativeSchur);
    EXPECT_GE(r.peak, 0.8 * estimate) << r.peak / estimate;
    EXPECT_LE(r.peak, 1.1 * estimate) << r.peak / estimate;
  }
}

// auto within a budget given in the options: the first solver of its order that fits, the same
// solve, bit for bit, as that solver named; below what even the leanest needs, a clear refusal.
TEST(SolverMemory, AutoPlansWithinTheBudget) {
  const synth::Problem pb = synth::make(4000, 60, 0.5, 0.02, 7, 0.5);
  const SolverShape s = shape_of(pb);
  const double chol = sba::solver_bytes(s, LinSolver::Chol), iterative = sba::solver_bytes(s, LinSolver::IterativeSchur);
  ASSERT_LT(iterative, chol);
  ASSERT_GT(sba::solver_bytes(s, LinSolver::SparseChol), chol);
  EXPECT_EQ(solve(pb, "auto", size_t(chol)).linsolver, "chol");
  const Solved tight = solve(pb, "auto", size_t((chol + iterative) / 2));
  EXPECT_EQ(tight.linsolver, "iterative-schur");
  const Solved named = solve(pb, "iterative-schur");
  EXPECT_EQ(tight.ret, named.ret);
  EXPECT_EQ(tight.p, named.p);
  const Solved refused = solve(pb, "auto", size_t(iterative / 2));
  EXPECT_EQ(refused.ret, SBA_ERROR);
  EXPECT_EQ(refused.info[6], SBA_STOP_NONE);
  EXPECT_EQ(refused.p, pb.p0);
  const auto mib = [](double b) { return std::to_string(long(b / (1024 * 1024) + 0.5)); };
  EXPECT_EQ(refused.log, "sba_motstr_levmar_x: linear solver auto: the leanest solver for this problem, "
                         "iterative-schur, needs about " + mib(iterative) + " MiB, more than the budget of " +
                             mib(double(size_t(iterative / 2))) + " MiB (memory_budget)\n");
}

}  // namespace
