// SPDX-License-Identifier: BSD-3-Clause
// The reduced camera system over shared unknowns' blocks (src/mapped_schur.h) against a dense
// reference computed here from a small random Jacobian: S = Ju^T Ju + mu I - sum_i Bi Ci^-1
// Bi^T and rhs = P^T e_a - sum_i Bi Ci^-1 e_b,i, where Ju = Jc P is the cameras' Jacobian over
// the unknowns, Bi = Ju^T Jp_i and Ci = Jp_i^T Jp_i + mu I; for any thread count.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "camera_unknowns.h"
#include "counting_malloc.h"
#include "kernels.h"
#include "layout.h"
#include "mapped_schur.h"
#include "parallel.h"

namespace {

using sba::i64;
constexpr int kM = 5, kN = 12, kPnp = 3, kMnp = 2;

// x = A^-1 b for a small SPD A (n x n, row-major), by Gauss-Jordan without pivoting.
std::vector<double> solve_small(std::vector<double> A, std::vector<double> b, int n) {
  for (int k = 0; k < n; ++k)
    for (int r = 0; r < n; ++r) {
      if (r == k) continue;
      const double f = A[size_t(r * n + k)] / A[size_t(k * n + k)];
      for (int c = 0; c < n; ++c) A[size_t(r * n + c)] -= f * A[size_t(k * n + c)];
      b[size_t(r)] -= f * b[size_t(k)];
    }
  for (int k = 0; k < n; ++k) b[size_t(k)] /= A[size_t(k * n + k)];
  return b;
}

// The cameras' parameters: cnp of them, `a` shared by cameras 1-2 and by cameras 3-4, `b` by
// cameras 1, 3 and 4, `held` (unless -1) held everywhere.
struct Sharing {
  int cnp, a, b, held;
};

struct Problem {
  sba::Layout lay;
  int cnp;
  std::vector<double> jac, e, U, V, ea, eb;

  explicit Problem(unsigned seed, Sharing sh = {4, 0, 1, 3}) : cnp(sh.cnp) {
    const int kCnp = cnp;
    std::mt19937 rng(seed);
    std::normal_distribution<double> g(0.0, 1.0);
    std::vector<char> vmask(size_t(kN) * kM, 0);
    for (int i = 0; i < kN; ++i)
      for (int j = 0; j < kM; ++j) vmask[size_t(i * kM + j)] = (i + 2 * j) % 3 != 0 || j == i % kM;
    std::string msg;
    // Camera 0 and point 0 fixed.
    EXPECT_TRUE(sba::build_layout(lay, sba::Mode::MotStr, kN, kM, 1, 1, kCnp, kPnp, kMnp, vmask.data(), &msg))
        << msg;
    std::vector<int> group(size_t(kM) * kCnp, -1);
    const int ga[kM] = {-1, 0, 0, 1, 1}, gb[kM] = {-1, 7, -1, 7, 7};
    for (int j = 0; j < kM; ++j) group[size_t(j * kCnp + sh.a)] = ga[j], group[size_t(j * kCnp + sh.b)] = gb[j];
    std::vector<char> held(size_t(kCnp), 0);
    if (sh.held >= 0) held[size_t(sh.held)] = 1;
    sba::CameraParamOptions o;
    o.param_group = group.data();
    o.fixed = held.data();
    lay.cams = sba::make_camera_map(o, lay);
    jac.resize(size_t(lay.nvis * lay.jblk()));
    for (double &v : jac) v = g(rng);
    // The held column zeroed, as the LM core does.
    for (i64 k = 0; k < lay.nvis && sh.held >= 0; ++k)
      for (int r = 0; r < kMnp; ++r) jac[size_t(k * lay.jblk() + r * kCnp + sh.held)] = 0.0;
    e.resize(size_t(lay.nvis * kMnp));
    for (double &v : e) v = g(rng);
    U.resize(size_t(kM * kCnp * kCnp));
    ea.resize(size_t(kM * kCnp));
    V.resize(size_t(kN * kPnp * kPnp));
    eb.resize(size_t(kN * kPnp));
    sba::ThreadPool pool(1);
    sba::make_kernels(lay, 1)->normal_equations(pool, jac.data(), e.data(), U.data(), V.data(), ea.data(), eb.data());
  }
  sba::NormalEquations ne() const { return {jac.data(), U.data(), V.data(), ea.data(), eb.data()}; }
};

// The reference S (nu x nu, full) and rhs, from the Jacobian blocks.
void reference(const Problem &pb, double mu, std::vector<double> *S, std::vector<double> *rhs) {
  const int kCnp = pb.cnp;
  const sba::Layout &lay = pb.lay;
  const sba::CameraMap &map = lay.cams;
  const int nu = map.unknowns();
  S->assign(size_t(nu) * nu, 0.0);
  rhs->assign(size_t(nu), 0.0);
  for (int j = 1; j < kM; ++j)
    for (int c = 0; c < kCnp; ++c)
      if (map.unknown(j, c) >= 0) (*rhs)[size_t(map.unknown(j, c))] += pb.ea[size_t(j * kCnp + c)];
  for (int u = 0; u < nu; ++u) (*S)[size_t(u * nu + u)] += mu;
  for (int i = 0; i < kN; ++i) {
    // Ju and Jp of point i's projections, stacked: rows 2 per projection.
    std::vector<double> Ju, Jp;
    for (int k = lay.rowptr[size_t(i)]; k < lay.rowptr[size_t(i) + 1]; ++k) {
      const int j = lay.colidx[size_t(k)];
      const double *A = pb.jac.data() + i64(k) * lay.jblk(), *B = A + kMnp * kCnp;
      for (int r = 0; r < kMnp; ++r) {
        std::vector<double> row(size_t(nu), 0.0);
        for (int c = 0; c < kCnp; ++c)
          if (map.unknown(j, c) >= 0) row[size_t(map.unknown(j, c))] += A[r * kCnp + c];
        Ju.insert(Ju.end(), row.begin(), row.end());
        Jp.insert(Jp.end(), B + r * kPnp, B + (r + 1) * kPnp);
      }
    }
    const int rows = int(Jp.size()) / kPnp;
    for (int a = 0; a < nu; ++a)
      for (int b = 0; b < nu; ++b)
        for (int r = 0; r < rows; ++r) (*S)[size_t(a * nu + b)] += Ju[size_t(r * nu + a)] * Ju[size_t(r * nu + b)];
    if (i < lay.ncon) continue;
    std::vector<double> C(size_t(kPnp * kPnp), 0.0), Bt(size_t(kPnp) * nu, 0.0);  // Bt = Jp^T Ju
    for (int d = 0; d < kPnp; ++d) {
      for (int f = 0; f < kPnp; ++f)
        for (int r = 0; r < rows; ++r) C[size_t(d * kPnp + f)] += Jp[size_t(r * kPnp + d)] * Jp[size_t(r * kPnp + f)];
      C[size_t(d * kPnp + d)] += mu;
      for (int a = 0; a < nu; ++a)
        for (int r = 0; r < rows; ++r) Bt[size_t(d * nu + a)] += Jp[size_t(r * kPnp + d)] * Ju[size_t(r * nu + a)];
    }
    const std::vector<double> y = solve_small(C, std::vector<double>(pb.eb.begin() + i * kPnp, pb.eb.begin() + (i + 1) * kPnp), kPnp);
    for (int a = 0; a < nu; ++a) {
      std::vector<double> col(static_cast<size_t>(kPnp));
      for (int d = 0; d < kPnp; ++d) col[size_t(d)] = Bt[size_t(d * nu + a)];
      const std::vector<double> z = solve_small(C, col, kPnp);  // Ci^-1 Bi^T's column a
      for (int b = 0; b < nu; ++b)
        for (int d = 0; d < kPnp; ++d) (*S)[size_t(b * nu + a)] -= Bt[size_t(d * nu + b)] * z[size_t(d)];
      for (int d = 0; d < kPnp; ++d) (*rhs)[size_t(a)] -= Bt[size_t(d * nu + a)] * y[size_t(d)];
    }
  }
}

// S's upper block triangle and diagonal blocks (the rest is the assembly's scratch), then rhs,
// as assembled into a dense S with `threads` threads, each compared with the reference.
std::vector<double> assembled(const Problem &pb, double mu, int threads, sba::MappedSchur::Assembly how, int tile,
                              int chunk = 512) {
  const sba::CameraMap &map = pb.lay.cams;
  const int nu = map.unknowns();
  std::vector<double> Sref, rref;
  reference(pb, mu, &Sref, &rref);
  sba::ThreadPool pool(threads);
  const auto kernels = sba::make_kernels(pb.lay, pool.size());
  std::vector<double> Vinv(pb.V.size());
  EXPECT_TRUE(kernels->invert_damped_V(pool, pb.V.data(), mu, Vinv.data()));
  std::vector<double> S(size_t(nu) * nu, 1e300), rhs(size_t(nu), 1e300);
  sba::UnknownBlocks blocks;
  blocks.base = S.data();
  blocks.ld = nu;
  blocks.start = map.block_starts();
  const sba::MappedSchur schur(pb.lay, pool.size(), how, tile, chunk);
  EXPECT_EQ(schur.tiled(), how == sba::MappedSchur::Assembly::Tiled);
  schur.assemble(pool, pb.ne(), Vinv.data(), mu, blocks, rhs.data());
  double scale = 0.0;
  for (double v : Sref) scale = std::max(scale, std::fabs(v));
  std::vector<double> held;
  for (int b = 0; b < map.nblocks(); ++b)
    for (int B = b; B < map.nblocks(); ++B)
      for (i64 r = map.block_start(b); r < map.block_start(b + 1); ++r)
        for (i64 c = map.block_start(B); c < map.block_start(B + 1); ++c) {
          EXPECT_NEAR(S[size_t(r * nu + c)], Sref[size_t(r * nu + c)], 1e-12 * scale) << r << ", " << c;
          held.push_back(S[size_t(r * nu + c)]);
        }
  for (int u = 0; u < nu; ++u) EXPECT_NEAR(rhs[size_t(u)], rref[size_t(u)], 1e-12 * scale) << u;
  held.insert(held.end(), rhs.begin(), rhs.end());
  return held;
}

TEST(MappedSchur, DenseAssemblyMatchesTheReferenceForAnyThreadCount) {
  const Problem pb(17u);
  const sba::CameraMap &map = pb.lay.cams;
  ASSERT_TRUE(map.shared());
  // Parameter 3 held: 4 cameras x 3 free parameters, less the 2 + 1 + 2 copies shared away.
  ASSERT_EQ(map.unknowns(), 12 - 1 - 1 - 2);
  std::vector<double> first;
  for (int threads : {1, 2, 3}) {
    SCOPED_TRACE("threads " + std::to_string(threads));
    const std::vector<double> held = assembled(pb, 0.7, threads, sba::MappedSchur::Assembly::PointByPoint, 24);
    if (first.empty())
      first = held;
    else
      EXPECT_EQ(held, first);  // the same bits for any thread count
  }
}

// Tile by tile, a chunk of points at a time, S takes each point's terms in the order point by
// point gives them: the same bits, for any tile width, chunk and thread count. With 8 parameters,
// cameras 1, 3 and 4's own 6 make blocks of 6 (the poses' case, which has a kernel of its own).
TEST(MappedSchur, TiledAssemblyGivesThePointByPointBits) {
  for (const Sharing sh : {Sharing{4, 0, 1, 3}, Sharing{8, 6, 7, -1}}) {
    SCOPED_TRACE("cnp " + std::to_string(sh.cnp));
    const Problem pb(23u, sh);
    const sba::CameraMap &map = pb.lay.cams;
    ASSERT_TRUE(map.shared());
    if (sh.cnp == 8) {
      // Cameras 1-4's own 6 (camera 2's with its own parameter 7) and the 2 + 1 shared.
      ASSERT_EQ(map.unknowns(), 4 * 6 + 1 + 2 + 1);
      int sixes = 0;
      for (int b = 0; b < map.nblocks(); ++b) sixes += map.block_size(b) == 6;
      EXPECT_EQ(sixes, 3);
    }
    const std::vector<double> want = assembled(pb, 0.3, 1, sba::MappedSchur::Assembly::PointByPoint, 24);
    for (int threads : {1, 2, 3})
      for (int tile : {1, 3, 7, 24})
        for (int chunk : {1, 5, 512}) {
          SCOPED_TRACE("threads " + std::to_string(threads) + ", tile " + std::to_string(tile) + ", chunk " +
                       std::to_string(chunk));
          EXPECT_EQ(assembled(pb, 0.3, threads, sba::MappedSchur::Assembly::Tiled, tile, chunk), want);
        }
  }
}

// A small problem's room for the tiled assembly is in proportion to its points, not a fixed
// 2 MB a thread: a mapper solves small problems hundreds of times over, each solve with its
// own.
TEST(MappedSchur, TiledAssemblyRoomOfASmallProblemIsInProportionToIt) {
#ifdef SBA_TEST_SANITIZED
  GTEST_SKIP() << "needs the counting malloc, which the sanitizers replace";
#else
  const Problem pb(23u);
  const long long before = malloc_count::live();
  const sba::MappedSchur schur(pb.lay, 2, sba::MappedSchur::Assembly::Tiled);
  ASSERT_TRUE(schur.tiled());
  const long long held = malloc_count::live() - before;
  EXPECT_GT(held, 0);
  EXPECT_LT(held, 64 * 1024) << "bytes held by a tiled assembly of " << kN << " points on 2 threads";
#endif
}

}  // namespace
