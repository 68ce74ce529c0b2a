// SPDX-License-Identifier: BSD-3-Clause
// The library's internal block kernels (linked from its objects, like bench/'s kernel
// benchmark): the sparse-S storage layout against the dense S, and the point-block inverses
// made on the fly against the precomputed ones.
#include <gtest/gtest.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <random>
#include <string>
#include <vector>

#if defined(__linux__)
#include <signal.h>
#include <sys/syscall.h>
#include <time.h>
#include <unistd.h>
#endif

#include "column_split.h"
#include "layout.h"
#include "dense.h"
#include "dense_factorization.h"
#include "kernels.h"
#include "lapack.h"
#include "step_solver.h"
#include "parallel.h"
#include "pool_parts.h"

namespace {

using sba::i64;

// Random normal equations on a visibility pattern where every point is seen by 2-5 cameras
// of 12, from a random Jacobian and residual: V_i and U_j positive semidefinite, as in LM.
struct Fixture {
  sba::Layout lay;
  std::vector<double> jac, e, U, V, ea, eb;

  Fixture(int n, int m, int cnp, unsigned seed) {
    std::mt19937 rng(seed);
    std::uniform_int_distribution<int> len(2, 5), cam(0, m - 1);
    std::normal_distribution<double> g(0.0, 1.0);
    std::vector<char> vmask(size_t(n) * size_t(m), 0);
    for (int i = 0; i < n; ++i)
      for (int l = len(rng); l > 0;) {
        char &c = vmask[size_t(i) * size_t(m) + size_t(cam(rng))];
        if (!c) c = 1, --l;
      }
    std::string msg;
    EXPECT_TRUE(sba::build_layout(lay, sba::Mode::MotStr, n, m, 0, 0, cnp, 3, 2, vmask.data(), &msg)) << msg;
    jac.resize(size_t(lay.nvis * lay.jblk()));
    e.resize(size_t(lay.nvis * 2));
    for (double &v : jac) v = g(rng);
    for (double &v : e) v = g(rng);
    U.resize(size_t(m * cnp * cnp));
    ea.resize(size_t(m * cnp));
    V.resize(size_t(n * 9));
    eb.resize(size_t(n * 3));
  }
  sba::NormalEquations ne() const { return {jac.data(), U.data(), V.data(), ea.data(), eb.data()}; }
};

// S over all of f's cameras at damping mu, from its normal equations: dense, with the stored
// inverses Vinv, and in the sparse layout with every camera pair stored under the camera order
// perm (block columns of the lower triangle of P S P^T), with sparse_Vinv (null: made on the
// fly). Pairs that share no point stay zero.
struct BothLayouts {
  std::vector<double> S, rhs, blocks, rhs2;
  std::vector<int> rows;
  std::vector<i64> colstart{0};
  sba::BlockMap sparse;

  BothLayouts(const Fixture &f, sba::ThreadPool &pool, const sba::Kernels &kernels, double mu,
              const double *Vinv, const double *sparse_Vinv, const std::vector<int> &perm) {
    const int m = f.lay.m, cnp = f.lay.cnp, nS = m * cnp;
    S.assign(size_t(nS) * size_t(nS), 0.0);
    rhs.assign(size_t(nS), 0.0);
    sba::BlockMap dense;
    dense.base = S.data();
    dense.ld = nS;
    dense.cnp = cnp;
    EXPECT_TRUE(kernels.assemble(pool, f.ne(), Vinv, mu, dense, rhs.data()));
    for (int c = 0; c < m; ++c) {
      for (int r = c; r < m; ++r) rows.push_back(r);
      colstart.push_back(i64(rows.size()));
    }
    blocks.assign(rows.size() * size_t(cnp) * size_t(cnp), 0.0);
    rhs2.assign(size_t(nS), 0.0);
    sparse.base = blocks.data();
    sparse.cnp = cnp;
    sparse.perm = perm.data();
    sparse.rows = rows.data();
    sparse.colstart = colstart.data();
    EXPECT_TRUE(kernels.assemble(pool, f.ne(), sparse_Vinv, mu, sparse, rhs2.data()));
  }
};

// The free cameras' dense S and right-hand side at damping mu from ne, with the stored point
// inverses Vinv (or null: made on the fly), and the back-substitution of a fixed camera step.
struct DenseStep {
  std::vector<double> S, rhs, dp;

  DenseStep(sba::ThreadPool &pool, const sba::Kernels &kernels, const sba::Layout &lay, const sba::NormalEquations &ne,
            const double *Vinv, double mu) {
    const i64 nS = i64(lay.free_cams()) * lay.cnp;
    S.assign(size_t(nS * nS), 0.0);
    rhs.assign(size_t(nS), 0.0);
    sba::BlockMap dense;
    dense.base = S.data();
    dense.ld = nS;
    dense.cnp = lay.cnp;
    EXPECT_TRUE(kernels.assemble(pool, ne, Vinv, mu, dense, rhs.data()));
    dp.assign(size_t(lay.nvars()), 0.0);
    for (i64 q = 0; q < nS; ++q) dp[size_t(lay.a_off(lay.mcon) + q)] = std::cos(double(q) + 0.5);
    kernels.back_substitute(pool, ne, Vinv, mu, dp.data());
  }
};

class KernelsLayout : public ::testing::TestWithParam<int> {};

// Every stored block of the sparse layout, under a scrambled camera ordering (so that many
// blocks are stored transposed), equals the dense S's block to rounding, and the right-hand
// sides agree exactly; the inverses made on the fly give the same bits as precomputed ones.
TEST_P(KernelsLayout, SparseLayoutHoldsTheDenseBlocks) {
  const int cnp = GetParam(), n = 300, m = 12;
  Fixture f(n, m, cnp, 7u + unsigned(cnp));
  for (int threads : {1, 2}) {
    SCOPED_TRACE("threads " + std::to_string(threads));
    sba::ThreadPool pool(threads);
    const auto kernels = sba::make_kernels(f.lay, pool.size());
    kernels->normal_equations(pool, f.jac.data(), f.e.data(), f.U.data(), f.V.data(), f.ea.data(), f.eb.data());
    const double mu = 0.5;
    std::vector<double> Vinv(f.V.size());
    ASSERT_TRUE(kernels->invert_damped_V(pool, f.V.data(), mu, Vinv.data()));

    const int nS = m * cnp;
    std::vector<int> perm(static_cast<size_t>(m));
    for (int j = 0; j < m; ++j) perm[size_t(j)] = (j * 5 + 3) % m;  // 5 is prime to 12
    const BothLayouts both(f, pool, *kernels, mu, Vinv.data(), nullptr, perm);
    const std::vector<double> &S = both.S, &blocks = both.blocks;
    const std::vector<i64> &colstart = both.colstart;
    const sba::BlockMap &sparse = both.sparse;
    EXPECT_EQ(both.rhs, both.rhs2);

    int transposed = 0;
    for (int j = 0; j < m; ++j)
      for (int k = j; k < m; ++k) {
        const sba::BlockMap::Block b = sparse.block(j, k);
        transposed += b.transposed;
        // Column-major block (r, c) of the stored lower triangle, per the layout's contract.
        const int pc = std::min(perm[size_t(j)], perm[size_t(k)]), pr = std::max(perm[size_t(j)], perm[size_t(k)]);
        const i64 col0 = colstart[size_t(pc)] * cnp * cnp, len = (colstart[size_t(pc) + 1] - colstart[size_t(pc)]) * cnp;
        const i64 pos = (pr - pc) * cnp;  // every row r >= c is stored
        for (int a = 0; a < cnp; ++a)
          for (int c = 0; c < cnp; ++c) {
            if (j == k && c < a) continue;  // only the upper triangle of a diagonal block is meaningful
            const double want = S[size_t(j * cnp + a) * size_t(nS) + size_t(k * cnp + c)];
            // S_jk is block (perm j, perm k) of P S P^T. Stored is its lower triangle's block
            // (pr, pc), column by column: S_jk^T when perm j < perm k, S_jk itself otherwise.
            const bool swapped = perm[size_t(j)] > perm[size_t(k)];
            const int row = swapped ? a : c, col = swapped ? c : a;
            const double got = blocks[size_t(col0 + i64(col) * len + pos + row)];
            EXPECT_NEAR(got, want, 1e-12 * (1.0 + std::fabs(want))) << "S_" << j << k << "(" << a << "," << c << ")";
            // The map's own view of it: S_jk row-major, or S_jk^T where it says so.
            EXPECT_EQ(b.transposed ? b.p[c * b.ld + a] : b.p[a * b.ld + c], got);
          }
      }
    EXPECT_GT(transposed, 10);

    // The back-substitution with on-the-fly inverses: the same bits.
    std::vector<double> dp1(size_t(f.lay.nvars()), 0.0);
    for (int q = 0; q < nS; ++q) dp1[size_t(q)] = std::sin(q + 1.0);
    std::vector<double> dp2 = dp1;
    kernels->back_substitute(pool, f.ne(), Vinv.data(), mu, dp1.data());
    kernels->back_substitute(pool, f.ne(), nullptr, mu, dp2.data());
    EXPECT_EQ(dp1, dp2);
  }
}

// Every kernel gives the same bits for any number of threads, down to more threads than
// free cameras (ranges of S's columns left empty) and with leading fixed cameras.
TEST_P(KernelsLayout, ThreadCountsGiveTheSameBits) {
  const int cnp = GetParam(), n = 300, m = 12;
  Fixture f(n, m, cnp, 11u + unsigned(cnp));
  f.lay.mcon = 9;  // three free cameras
  struct Out {
    std::vector<double> U, V, ea, eb, Vinv;
    std::vector<DenseStep> steps;  // with the stored inverses, and made on the fly as the solvers do
  };
  auto run = [&](int threads) {
    Out o;
    sba::ThreadPool pool(threads);
    EXPECT_EQ(pool.size(), threads);
    const auto kernels = sba::make_kernels(f.lay, pool.size());
    o.U.assign(f.U.size(), 0.0), o.V.assign(f.V.size(), 0.0), o.ea.assign(f.ea.size(), 0.0), o.eb.assign(f.eb.size(), 0.0);
    kernels->normal_equations(pool, f.jac.data(), f.e.data(), o.U.data(), o.V.data(), o.ea.data(), o.eb.data());
    const double mu = 0.25;
    o.Vinv.assign(f.V.size(), 0.0);
    EXPECT_TRUE(kernels->invert_damped_V(pool, o.V.data(), mu, o.Vinv.data()));
    const sba::NormalEquations ne{f.jac.data(), o.U.data(), o.V.data(), o.ea.data(), o.eb.data()};
    o.steps.emplace_back(pool, *kernels, f.lay, ne, o.Vinv.data(), mu);
    o.steps.emplace_back(pool, *kernels, f.lay, ne, nullptr, mu);
    return o;
  };
  const Out one = run(1);
  const DenseStep &stored = one.steps[0], &fly = one.steps[1];
  EXPECT_NE(std::count(stored.S.begin(), stored.S.end(), 0.0), i64(stored.S.size()));
  EXPECT_TRUE(std::all_of(stored.dp.begin(), stored.dp.end(), [](double v) { return std::isfinite(v); }));
  for (int threads : {2, 3, 5}) {
    SCOPED_TRACE("threads " + std::to_string(threads));
    const Out o = run(threads);
    EXPECT_EQ(o.U, one.U);
    EXPECT_EQ(o.V, one.V);
    EXPECT_EQ(o.ea, one.ea);
    EXPECT_EQ(o.eb, one.eb);
    EXPECT_EQ(o.Vinv, one.Vinv);
    for (size_t k = 0; k < o.steps.size(); ++k) {
      EXPECT_EQ(o.steps[k].S, one.steps[k].S);
      EXPECT_EQ(o.steps[k].rhs, one.steps[k].rhs);
      EXPECT_EQ(o.steps[k].dp, one.steps[k].dp);
    }
  }
  // The 3x3 inverses made four at a time are the stored ones, bit for bit.
  EXPECT_EQ(fly.S, stored.S);
  EXPECT_EQ(fly.rhs, stored.rhs);
  EXPECT_EQ(fly.dp, stored.dp);
}

// A dense S is assembled through each thread's packed copy of its block columns, or, past
// max_packed, in S itself: every entry S holds, and the step, the same bits both ways, with
// every thread count. S starts as NaN, so that an entry one way writes and the other leaves
// shows.
TEST_P(KernelsLayout, PackedAssemblyGivesTheBitsOfTheAssemblyInPlace) {
  const int cnp = GetParam(), n = 600, m = 16;
  Fixture f(n, m, cnp, 31u + unsigned(cnp));
  f.lay.mcon = 2;
  const i64 nS = i64(m - f.lay.mcon) * cnp;
  const auto assemble = [&](int threads, i64 max_packed, std::vector<double> *S, std::vector<double> *rhs,
                            std::vector<double> *dp) {
    sba::ThreadPool pool(threads);
    const auto kernels = sba::make_kernels(f.lay, pool.size(), max_packed);
    std::vector<double> U(f.U.size()), V(f.V.size()), ea(f.ea.size()), eb(f.eb.size());
    kernels->normal_equations(pool, f.jac.data(), f.e.data(), U.data(), V.data(), ea.data(), eb.data());
    const sba::NormalEquations ne{f.jac.data(), U.data(), V.data(), ea.data(), eb.data()};
    const double mu = 0.125;
    S->assign(size_t(nS * nS), NAN);
    rhs->assign(size_t(nS), NAN);
    sba::BlockMap dense;
    dense.base = S->data();
    dense.ld = nS;
    dense.cnp = cnp;
    EXPECT_TRUE(kernels->assemble(pool, ne, nullptr, mu, dense, rhs->data()));
    dp->assign(size_t(f.lay.nvars()), 0.0);
    for (i64 q = 0; q < nS; ++q) (*dp)[size_t(f.lay.a_off(f.lay.mcon) + q)] = std::sin(double(q) + 0.25);
    kernels->back_substitute(pool, ne, nullptr, mu, dp->data());
  };
  const auto bits = [](const std::vector<double> &v) {
    std::vector<std::uint64_t> b(v.size());
    std::memcpy(b.data(), v.data(), v.size() * sizeof(double));
    return b;
  };
  for (int threads : {1, 2, 3}) {
    SCOPED_TRACE("threads " + std::to_string(threads));
    std::vector<double> S1, rhs1, dp1, S2, rhs2, dp2;
    assemble(threads, sba::kMaxPackedS, &S1, &rhs1, &dp1);
    assemble(threads, 0, &S2, &rhs2, &dp2);
    EXPECT_EQ(bits(S1), bits(S2));
    EXPECT_EQ(bits(rhs1), bits(rhs2));
    EXPECT_EQ(bits(dp1), bits(dp2));
    // The upper triangle is all written, and the points couple the cameras.
    i64 unwritten = 0, coupled = 0;
    for (i64 r = 0; r < nS; ++r)
      for (i64 c = r; c < nS; ++c) {
        unwritten += std::isnan(S1[size_t(r * nS + c)]);
        coupled += r / cnp != c / cnp && S1[size_t(r * nS + c)] != 0.0;
      }
    EXPECT_EQ(unwritten, 0);
    EXPECT_GT(coupled, nS * nS / 8);
  }
}

// A dense S takes a track's pairs a column at a time, W_ik^T held for the column; a sparse S a
// pair at a time, through the map. Where the sparse layout stores S_jk as it is (the identity
// order), both make each entry from the same products in the same order, point by point, and
// must give the same bits: the dense S, the default solver's, is what sba 1.6's results are
// compared with.
TEST_P(KernelsLayout, DenseAssemblyGivesTheSparseLayoutsBits) {
  const int cnp = GetParam(), n = 4000, m = 64;
  Fixture f(n, m, cnp, 23u + unsigned(cnp));
  for (int threads : {1, 2}) {
    SCOPED_TRACE("threads " + std::to_string(threads));
    sba::ThreadPool pool(threads);
    const auto kernels = sba::make_kernels(f.lay, pool.size());
    kernels->normal_equations(pool, f.jac.data(), f.e.data(), f.U.data(), f.V.data(), f.ea.data(), f.eb.data());
    const double mu = 0.5;
    std::vector<double> Vinv(f.V.size());
    ASSERT_TRUE(kernels->invert_damped_V(pool, f.V.data(), mu, Vinv.data()));
    const int nS = m * cnp;
    std::vector<int> perm(static_cast<size_t>(m));
    for (int c = 0; c < m; ++c) perm[size_t(c)] = c;
    const BothLayouts both(f, pool, *kernels, mu, Vinv.data(), Vinv.data(), perm);
    const std::vector<double> &S = both.S;
    const sba::BlockMap &sparse = both.sparse;
    EXPECT_EQ(both.rhs, both.rhs2);
    i64 differ = 0, coupled = 0;
    for (int j = 0; j < m; ++j)
      for (int k = j; k < m; ++k) {
        const sba::BlockMap::Block b = sparse.block(j, k);
        ASSERT_FALSE(b.transposed);
        for (int a = 0; a < cnp; ++a)
          for (int c = j == k ? a : 0; c < cnp; ++c) {
            const double want = b.p[a * b.ld + c], got = S[size_t(j * cnp + a) * size_t(nS) + size_t(k * cnp + c)];
            differ += got != want;
            coupled += j != k && want != 0.0;
          }
      }
    EXPECT_EQ(differ, 0);
    EXPECT_GT(coupled, i64(m) * (m - 1) / 4 * cnp * cnp);  // most camera pairs share points
  }
}

// Blocks stored in single precision are widened before any arithmetic: every kernel gives on
// them the bits it gives on double blocks holding the same (float) values, with free and
// fixed cameras, the inverses stored or made on the fly, and 1 and 2 threads. Against the
// unrounded Jacobian the results differ, so the single-precision blocks were read.
TEST_P(KernelsLayout, SinglePrecisionBlocksGiveTheBitsOfTheirWidenedValues) {
  const int cnp = GetParam(), n = 600, m = 12;
  Fixture f(n, m, cnp, 31u + unsigned(cnp));
  f.lay.mcon = 2;
  const std::vector<float> j32(f.jac.begin(), f.jac.end());
  const std::vector<double> widened(j32.begin(), j32.end());
  for (int threads : {1, 2}) {
    SCOPED_TRACE("threads " + std::to_string(threads));
    sba::ThreadPool pool(threads);
    const auto kernels = sba::make_kernels(f.lay, pool.size());
    // The normal equations and the step of mu 0.5, from jac or from jac32. From jac32 the
    // kernels make U and V alone; e_a and e_b are those of the widened blocks, as the solve
    // makes them from the blocks before rounding.
    const auto run = [&](const double *jac, const float *jac32, bool stored) {
      std::vector<double> U(f.U.size()), V(f.V.size()), ea(f.ea.size()), eb(f.eb.size()), Vinv(f.V.size());
      if (jac32) {
        std::vector<double> U2(U.size()), V2(V.size());
        kernels->normal_equations(pool, widened.data(), f.e.data(), U2.data(), V2.data(), ea.data(), eb.data());
        kernels->normal_matrices(pool, jac32, U.data(), V.data());
      } else {
        kernels->normal_equations(pool, jac, f.e.data(), U.data(), V.data(), ea.data(), eb.data());
      }
      EXPECT_TRUE(kernels->invert_damped_V(pool, V.data(), 0.5, Vinv.data()));
      const sba::NormalEquations ne{jac, U.data(), V.data(), ea.data(), eb.data(), jac32};
      const DenseStep step(pool, *kernels, f.lay, ne, stored ? Vinv.data() : nullptr, 0.5);
      return std::vector<std::vector<double>>{U, V, ea, eb, step.S, step.rhs, step.dp};
    };
    for (bool stored : {true, false}) {
      SCOPED_TRACE(stored ? "inverses stored" : "inverses on the fly");
      const auto single = run(nullptr, j32.data(), stored), wide = run(widened.data(), nullptr, stored);
      const auto full = run(f.jac.data(), nullptr, stored);
      for (size_t k = 0; k < single.size(); ++k) {
        EXPECT_EQ(single[k], wide[k]) << k;
        EXPECT_NE(single[k], full[k]) << k;
      }
    }
    // Scaling rounds each product to float.
    std::vector<double> s(size_t(f.lay.nvars()));
    for (size_t q = 0; q < s.size(); ++q) s[q] = 0.5 + std::sin(double(q));
    std::vector<float> scaled32 = j32;
    std::vector<double> scaled = widened;
    kernels->scale_jacobian(pool, s.data(), sba::JacobianBlocks{nullptr, scaled32.data()});
    kernels->scale_jacobian(pool, s.data(), sba::JacobianBlocks{scaled.data(), nullptr});
    i64 differ = 0;
    for (size_t q = 0; q < scaled.size(); ++q) differ += scaled32[q] != static_cast<float>(scaled[q]);
    EXPECT_EQ(differ, 0);
  }
}

// U_j is accumulated in its upper triangle and copied down: exactly symmetric, and the sum of
// its camera's A^T A to rounding, from double and from single-precision blocks, on 1 and 2
// threads, for the free cameras.
TEST_P(KernelsLayout, CameraBlocksAreExactlySymmetricSums) {
  const int cnp = GetParam(), n = 300, m = 12;
  Fixture f(n, m, cnp, 41u + unsigned(cnp));
  f.lay.mcon = 3;
  const std::vector<float> j32(f.jac.begin(), f.jac.end());
  // The sums in long double, from the blocks the kernels read.
  const auto sums = [&](const auto &jac) {
    std::vector<long double> want(f.U.size(), 0.0L);
    for (i64 k = 0; k < f.lay.nvis; ++k) {
      const i64 j = f.lay.colidx[size_t(k)];
      const auto *A = jac.data() + k * f.lay.jblk();
      for (int r = 0; r < 2; ++r)
        for (int a = 0; a < cnp; ++a)
          for (int c = 0; c < cnp; ++c)
            want[size_t((j * cnp + a) * cnp + c)] += (long double)A[r * cnp + a] * (long double)A[r * cnp + c];
    }
    return want;
  };
  const std::vector<long double> want = sums(f.jac), want32 = sums(j32);
  for (int threads : {1, 2}) {
    SCOPED_TRACE("threads " + std::to_string(threads));
    sba::ThreadPool pool(threads);
    const auto kernels = sba::make_kernels(f.lay, pool.size());
    std::vector<double> U(f.U.size(), 0.0), U32(f.U.size(), 0.0);
    kernels->normal_equations(pool, f.jac.data(), f.e.data(), U.data(), f.V.data(), f.ea.data(), f.eb.data());
    kernels->normal_matrices(pool, j32.data(), U32.data(), f.V.data());
    i64 asymmetric = 0, off = 0;
    for (const auto &[got, sum] : {std::pair{&U, &want}, std::pair{&U32, &want32}})
      for (int j = f.lay.mcon; j < m; ++j)
        for (int a = 0; a < cnp; ++a)
          for (int c = 0; c < cnp; ++c) {
            const size_t q = size_t((j * cnp + a) * cnp + c), t = size_t((j * cnp + c) * cnp + a);
            asymmetric += (*got)[q] != (*got)[t];
            off += std::fabs((long double)(*got)[q] - (*sum)[q]) > 1e-12L * (1.0L + std::fabs((*sum)[q]));
          }
    EXPECT_EQ(asymmetric, 0);
    EXPECT_EQ(off, 0);
  }
}

// A held parameter's Jacobian column is zero, and the assembly leaves its rows of S alone:
// they keep U_j + mu I's (zero off the diagonal block), and every other entry is, bit for bit,
// what the same Jacobian gives without held flags, in the dense S and in the sparse layout
// (under a scrambled order, so that transposed blocks take their rows from the other camera).
// Camera 3 holds everything, camera 5 nothing, the others their parameter j % cnp and the last.
TEST_P(KernelsLayout, HeldParametersRowsOfSAreUPlusTheDampingAlone) {
  const int cnp = GetParam(), n = 600, m = 12;
  Fixture f(n, m, cnp, 31u + unsigned(cnp));
  std::vector<char> held(size_t(m * cnp), 0);
  for (int j = 0; j < m; ++j)
    for (int c = 0; c < cnp; ++c)
      held[size_t(j * cnp + c)] = j == 3 || (j != 5 && (c == j % cnp || c == cnp - 1));
  for (i64 k = 0; k < f.lay.nvis; ++k)
    for (int r = 0; r < 2; ++r)
      for (int c = 0; c < cnp; ++c)
        if (held[size_t(f.lay.colidx[size_t(k)] * cnp + c)]) f.jac[size_t(k * f.lay.jblk() + r * cnp + c)] = 0.0;
  Fixture g = f;
  g.lay.cams = sba::CameraMap(m, 0, cnp, held, {});
  ASSERT_TRUE(g.lay.cams.any_held());
  std::vector<int> perm(static_cast<size_t>(m));
  for (int j = 0; j < m; ++j) perm[size_t(j)] = (j * 5 + 3) % m;
  const double mu = 0.5;
  const int nS = m * cnp;
  for (int threads : {1, 2}) {
    SCOPED_TRACE("threads " + std::to_string(threads));
    sba::ThreadPool pool(threads);
    const auto plain = sba::make_kernels(f.lay, pool.size()), masked = sba::make_kernels(g.lay, pool.size());
    plain->normal_equations(pool, f.jac.data(), f.e.data(), f.U.data(), f.V.data(), f.ea.data(), f.eb.data());
    masked->normal_equations(pool, g.jac.data(), g.e.data(), g.U.data(), g.V.data(), g.ea.data(), g.eb.data());
    std::vector<double> Vinv(f.V.size());
    ASSERT_TRUE(plain->invert_damped_V(pool, f.V.data(), mu, Vinv.data()));
    const BothLayouts want(f, pool, *plain, mu, Vinv.data(), Vinv.data(), perm);
    const BothLayouts got(g, pool, *masked, mu, Vinv.data(), nullptr, perm);
    EXPECT_EQ(got.rhs, want.rhs);
    EXPECT_EQ(got.rhs2, want.rhs2);
    i64 differ = 0, held_rows = 0, moved = 0;
    for (int j = 0; j < m; ++j)
      for (int k = j; k < m; ++k) {
        const sba::BlockMap::Block b = got.sparse.block(j, k), w = want.sparse.block(j, k);
        for (int a = 0; a < cnp; ++a)
          for (int c = j == k ? a : 0; c < cnp; ++c) {
            const size_t q = size_t(j * cnp + a) * size_t(nS) + size_t(k * cnp + c);
            const double sparse_got = b.transposed ? b.p[c * b.ld + a] : b.p[a * b.ld + c];
            const double sparse_want = w.transposed ? w.p[c * w.ld + a] : w.p[a * w.ld + c];
            differ += got.S[q] != want.S[q] || sparse_got != sparse_want;
            if (!held[size_t(j * cnp + a)] && !held[size_t(k * cnp + c)]) continue;
            // A held row (or column) of S: U_j's entry plus the damping, or zero.
            ++held_rows;
            const double start = j == k ? g.U[size_t((j * cnp + a) * cnp + c)] + (a == c ? mu : 0.0) : 0.0;
            moved += got.S[q] != start || sparse_got != start;
          }
      }
    EXPECT_EQ(differ, 0);
    EXPECT_EQ(moved, 0);
    EXPECT_GT(held_rows, i64(m) * m / 2 * 2 * cnp);
  }
}

// held_normal_equations zeroes the held columns of the cameras' blocks and gives the bits
// normal_equations gives on the Jacobian zeroed beforehand, for 1 and 2 threads; the rest of
// the Jacobian is untouched.
TEST_P(KernelsLayout, HeldNormalEquationsZeroTheHeldColumnsAsTheyRead) {
  const int cnp = GetParam(), n = 500, m = 12;
  Fixture f(n, m, cnp, 41u + unsigned(cnp));
  std::vector<char> held(size_t(m * cnp), 0);
  for (int j = 0; j < m; ++j) held[size_t(j * cnp + (j + 1) % cnp)] = held[size_t(j * cnp + cnp - 1)] = 1;
  f.lay.cams = sba::CameraMap(m, 0, cnp, held, {});
  std::vector<double> zeroed = f.jac;
  i64 nonzero = 0;
  for (i64 k = 0; k < f.lay.nvis; ++k)
    for (int r = 0; r < 2; ++r)
      for (int c = 0; c < cnp; ++c) {
        double &x = zeroed[size_t(k * f.lay.jblk() + r * cnp + c)];
        if (!held[size_t(f.lay.colidx[size_t(k)] * cnp + c)]) continue;
        nonzero += x != 0.0;
        x = 0.0;
      }
  ASSERT_GT(nonzero, f.lay.nvis);
  for (int threads : {1, 2}) {
    SCOPED_TRACE("threads " + std::to_string(threads));
    sba::ThreadPool pool(threads);
    const auto kernels = sba::make_kernels(f.lay, pool.size());
    std::vector<double> jac = f.jac, U(f.U.size()), V(f.V.size()), ea(f.ea.size()), eb(f.eb.size());
    kernels->held_normal_equations(pool, jac.data(), f.e.data(), U.data(), V.data(), ea.data(), eb.data());
    kernels->normal_equations(pool, zeroed.data(), f.e.data(), f.U.data(), f.V.data(), f.ea.data(), f.eb.data());
    EXPECT_EQ(jac, zeroed);
    EXPECT_EQ(U, f.U);
    EXPECT_EQ(V, f.V);
    EXPECT_EQ(ea, f.ea);
    EXPECT_EQ(eb, f.eb);
  }
}

// Every fixed width (the packed assembly splits the 9-wide blocks), and a run-time one.
INSTANTIATE_TEST_SUITE_P(Kernels, KernelsLayout, ::testing::Values(6, 7, 9, 11, 16, 5),
                         [](const ::testing::TestParamInfo<int> &p) { return "cnp" + std::to_string(p.param); });

// A damped point block that is indefinite is inverted (sba 1.6's retries make such blocks and
// invert them with Bunch-Kaufman), by every path the same; one that is singular fails the
// assembly when the inverses are made on the fly (and gives NaNs in the back-substitution and
// in the inverse diagonals), as invert_damped_V fails.
TEST(Kernels, IndefinitePointBlocksAreInvertedSingularOnesReported) {
  Fixture f(40, 6, 6, 3u);
  sba::ThreadPool pool(2);
  const auto kernels = sba::make_kernels(f.lay, pool.size());
  kernels->normal_equations(pool, f.jac.data(), f.e.data(), f.U.data(), f.V.data(), f.ea.data(), f.eb.data());
  const double mu = 0.1;
  double *V17 = f.V.data() + 17 * 9;
  V17[4] = -1.0;  // point 17's V_i[1][1]: V_i + mu I indefinite
  std::vector<double> Vinv(f.V.size()), diag(size_t(f.lay.n) * 3);
  ASSERT_TRUE(kernels->invert_damped_V(pool, f.V.data(), mu, Vinv.data()));
  const double *inv = Vinv.data() + 17 * 9;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) {
      double s = 0.0;
      for (int q = 0; q < 3; ++q) s += (V17[r * 3 + q] + (r == q ? mu : 0.0)) * inv[q * 3 + c];
      EXPECT_NEAR(s, r == c ? 1.0 : 0.0, 1e-12) << r << " " << c;
      EXPECT_EQ(inv[r * 3 + c], inv[c * 3 + r]);
    }
  kernels->damped_inverse_diagonals(pool, f.V.data(), mu, diag.data());
  for (int i = 0; i < f.lay.n; ++i)
    for (int a = 0; a < 3; ++a) ASSERT_EQ(diag[size_t(i) * 3 + a], Vinv[size_t(i) * 9 + a * 4]) << i;
  const int nS = 6 * 6;
  std::vector<double> S(size_t(nS) * size_t(nS), 0.0), rhs(static_cast<size_t>(nS));
  sba::BlockMap dense;
  dense.base = S.data();
  dense.ld = nS;
  dense.cnp = 6;
  EXPECT_TRUE(kernels->assemble(pool, f.ne(), nullptr, mu, dense, rhs.data()));

  std::fill(V17, V17 + 9, 0.0);
  V17[0] = -mu;  // V_i + mu I has a zero row
  EXPECT_FALSE(kernels->invert_damped_V(pool, f.V.data(), mu, Vinv.data()));
  EXPECT_FALSE(kernels->assemble(pool, f.ne(), nullptr, mu, dense, rhs.data()));
  std::vector<double> dp(size_t(f.lay.nvars()), 0.0);
  kernels->back_substitute(pool, f.ne(), nullptr, mu, dp.data());
  const double *db = dp.data() + f.lay.b_off(17);
  EXPECT_TRUE(std::isnan(db[0]) && std::isnan(db[1]) && std::isnan(db[2]));
  EXPECT_TRUE(std::isfinite(dp[size_t(f.lay.b_off(16))]));
  kernels->damped_inverse_diagonals(pool, f.V.data(), mu, diag.data());
  for (int i = 0; i < f.lay.n; ++i) EXPECT_EQ(std::isnan(diag[size_t(i) * 3]), i == 17) << i;
}

// A random symmetric positive definite matrix of order n, row-major upper with row stride ld
// (the rest of each row, and the lower triangle, hold junk that must not be read), and its
// condition number kept moderate by the diagonal shift.
std::vector<double> random_spd(i64 n, i64 ld, unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> g(0.0, 1.0);
  std::vector<double> B(size_t(n * n)), S(size_t(ld * n), 0.0);
  for (double &b : B) b = g(rng);
  for (i64 r = 0; r < n; ++r)
    for (i64 c = 0; c < ld; ++c) {
      if (c < r || c >= n) {
        S[size_t(r * ld + c)] = 1e300;  // junk: a read of it would show in the factor
        continue;
      }
      double t = r == c ? double(n) : 0.0;
      for (i64 q = 0; q < n; ++q) t += B[size_t(r * n + q)] * B[size_t(c * n + q)];
      S[size_t(r * ld + c)] = t;
    }
  return S;
}

// The library's Cholesky of S (the `chol` solver's, up to 2048 unknowns) is LAPACK's DPOTRF
// to rounding, on orders around every blocking boundary (the 48-row panels, the 4-row and
// 12-column tiles, the 384-column blocks, the serial path below 128), its two right-hand
// sides come out as U^-T b, and it gives the same bits on 1, 2, 3 and 5 threads.
TEST(DenseCholesky, MatchesLapackAndThreadCountsGiveTheSameBits) {
  constexpr i64 kRhs = 2;
  for (i64 n : {1, 2, 5, 47, 48, 49, 127, 128, 131, 324, 433, 800}) {
    SCOPED_TRACE("order " + std::to_string(n));
    const i64 ld = (n + kRhs + 7) / 8 * 8 + (n % 3 == 0 ? 8 : 0);
    std::vector<double> S = random_spd(n, ld, unsigned(n));
    for (i64 r = 0; r < n; ++r)
      for (i64 k = 0; k < kRhs; ++k) S[size_t(r * ld + n + k)] = std::cos(double(r * (k + 1)));
    std::vector<double> ref(S);
    int info = 0;
    const int ni = int(n), ldi = int(ld);
    SBA_F77(dpotrf, DPOTRF)("L", &ni, ref.data(), &ldi, &info, 1);
    ASSERT_EQ(info, 0);
    // U^-T b by forward substitution with LAPACK's factor.
    std::vector<double> yref(size_t(n * kRhs));
    for (i64 k = 0; k < kRhs; ++k)
      for (i64 r = 0; r < n; ++r) {
        double t = S[size_t(r * ld + n + k)];
        for (i64 p = 0; p < r; ++p) t -= ref[size_t(p * ld + r)] * yref[size_t(k * n + p)];
        yref[size_t(k * n + r)] = t / ref[size_t(r * ld + r)];
      }
    std::vector<double> one;
    for (int threads : {1, 2, 3, 5}) {
      SCOPED_TRACE("threads " + std::to_string(threads));
      sba::ThreadPool pool(threads);
      std::vector<double> U(S);
      ASSERT_TRUE(sba::own_dense_cholesky()(pool, U.data(), n, ld, kRhs));
      double worst = 0.0, worst_y = 0.0, ynorm = 0.0;
      for (i64 r = 0; r < n; ++r)
        for (i64 c = r; c < n; ++c) {
          const double d = std::fabs(U[size_t(r * ld + c)] - ref[size_t(r * ld + c)]);
          worst = std::max(worst, d / std::fabs(ref[size_t(r * ld + r)]));
        }
      for (i64 k = 0; k < kRhs; ++k)
        for (i64 r = 0; r < n; ++r) {
          worst_y = std::max(worst_y, std::fabs(U[size_t(r * ld + n + k)] - yref[size_t(k * n + r)]));
          ynorm = std::max(ynorm, std::fabs(yref[size_t(k * n + r)]));
        }
      EXPECT_LT(worst, 1e-12);
      EXPECT_LT(worst_y, 1e-12 * ynorm);
      // Only the upper triangle and the right-hand sides are the result; the junk elsewhere
      // may be overwritten.
      std::vector<double> result;
      for (i64 r = 0; r < n; ++r) result.insert(result.end(), U.begin() + r * ld + r, U.begin() + r * ld + n + kRhs);
      if (threads == 1)
        one = result;
      else
        EXPECT_EQ(result, one);
    }
  }
}

#if defined(__linux__)
// Holds the thread it interrupts for 10 ms, asleep: a member of the pool that the scheduler
// has set aside, as on a machine with more running threads than cores.
void held_for_a_while(int) {
  const int saved = errno;
  timespec left{0, 10000000};
  while (nanosleep(&left, &left) != 0 && errno == EINTR) {
  }
  errno = saved;
}

// While the pool's worker runs only now and then (held 10 ms of every 10.5 ms, from the
// start, by a timer whose signal goes to it alone), the factorization soon stops waiting for
// it at every barrier and runs on the calling thread, with the same bits. Before, every one
// of them ran on both members, at the held one's pace. The order is one whose factorization
// on both members outlasts the worker's free half millisecond.
TEST(DenseCholesky, RunsAloneWhileAMemberIsMostlyKeptFromRunning) {
  const i64 n = 512, ld = 520;
  const std::vector<double> S = random_spd(n, ld, 3u);
  sba::ThreadPool one(1), pool(2);
  ASSERT_EQ(pool.size(), 2);
  std::vector<double> U1(S);
  ASSERT_TRUE(sba::own_dense_cholesky()(one, U1.data(), n, ld, 0));
  pid_t worker = 0;
  on_worker(pool, [&] { worker = pid_t(syscall(SYS_gettid)); });
  struct sigaction held {}, old {};
  held.sa_handler = held_for_a_while;
  sigemptyset(&held.sa_mask);
  ASSERT_EQ(sigaction(SIGUSR2, &held, &old), 0);
  sigevent to_worker{};
  to_worker.sigev_notify = SIGEV_THREAD_ID;
  to_worker.sigev_signo = SIGUSR2;
  to_worker._sigev_un._tid = worker;  // sigev_notify_thread_id, which glibc's header lacks
  timer_t timer{};
  ASSERT_EQ(timer_create(CLOCK_MONOTONIC, &to_worker, &timer), 0);
  itimerspec every{};
  every.it_value.tv_nsec = 1;
  every.it_interval.tv_nsec = 10500000;
  ASSERT_EQ(timer_settime(timer, 0, &every, nullptr), 0);
  const int kFactorizations = 40;
  const std::uint64_t before = pool.jobs();
  bool same = true;
  for (int k = 0; k < kFactorizations && same; ++k) {
    std::vector<double> U(S);
    same = sba::own_dense_cholesky()(pool, U.data(), n, ld, 0);
    for (i64 r = 0; r < n && same; ++r)
      same = std::equal(U.begin() + r * ld + r, U.begin() + r * ld + n, U1.begin() + r * ld + r);
  }
  const std::uint64_t on_both = pool.jobs() - before;
  timer_delete(timer);
  on_worker(pool, [] {});  // the last signal handled
  sigaction(SIGUSR2, &old, nullptr);
  EXPECT_TRUE(same);
  // Two that waited, 16 alone, two again, then 32 alone: 4, if each job on both members
  // meets a hold.
  EXPECT_LE(on_both, 6u);
}
#endif

// A matrix that is not positive definite, a zero pivot, a NaN or an Inf on the diagonal (in
// the first panel, a later one, or the serial path's last row) make the factorization fail on
// any thread count.
TEST(DenseCholesky, RefusesWhatIsNotPositiveDefinite) {
  const double nan = std::nan(""), inf = HUGE_VAL;
  for (i64 n : {100, 300})
    for (i64 bad : {i64(0), i64(60), n - 1})
      for (double v : {-1.0, 0.0, nan, inf}) {
        if (v == 0.0 && bad != 0) continue;  // elsewhere rounding decides the sign of a zero pivot
        SCOPED_TRACE("order " + std::to_string(n) + ", row " + std::to_string(bad) + ", value " + std::to_string(v));
        const i64 ld = (n + 7) / 8 * 8;
        std::vector<double> S = random_spd(n, ld, 5u);
        // Make the row's pivot at its own step v: remove what the earlier rows take away.
        std::vector<double> L(S);
        int info = 0;
        const int ni = int(n), ldi = int(ld);
        SBA_F77(dpotrf, DPOTRF)("L", &ni, L.data(), &ldi, &info, 1);
        ASSERT_EQ(info, 0);
        double taken = 0.0;
        for (i64 p = 0; p < bad; ++p) taken += L[size_t(p * ld + bad)] * L[size_t(p * ld + bad)];
        S[size_t(bad * ld + bad)] = std::isfinite(v) ? taken + v : v;
        for (int threads : {1, 2, 3}) {
          sba::ThreadPool pool(threads);
          std::vector<double> U(S);
          EXPECT_FALSE(sba::own_dense_cholesky()(pool, U.data(), n, ld, 0)) << "threads " << threads;
        }
      }
}

// Every dense factorization solves S x = rhs from the upper triangle in its own storage (the
// lower triangle and the padding hold junk that a read would show), with badly scaled
// unknowns as the camera parameters make them; and each refuses an S that is not positive
// definite, which LM answers with more damping.
TEST(DenseFactorization, EveryKindSolvesFromTheUpperTriangleAndRefusesAnIndefiniteS) {
  using sba::LinSolver;
  const i64 n = 120;
  const int cnp = 6;
  std::vector<double> scale(static_cast<size_t>(n)), xtrue(static_cast<size_t>(n));
  for (i64 r = 0; r < n; ++r) {
    scale[size_t(r)] = std::pow(10.0, double(r % cnp) - 2.0);
    xtrue[size_t(r)] = std::sin(double(r + 1)) / scale[size_t(r)];
  }
  sba::ThreadPool pool(2);
  for (LinSolver kind : {LinSolver::Chol, LinSolver::CholLapack, LinSolver::LDLt, LinSolver::BK,
                         LinSolver::LU, LinSolver::QR, LinSolver::QRnoQ, LinSolver::SVD,
                         LinSolver::CG}) {
    SCOPED_TRACE(sba::linsolver_name(kind));
    const auto f = sba::make_dense_factorization(kind, n, cnp, pool);
    ASSERT_TRUE(f);
    const i64 ld = f->ld();
    ASSERT_GE(ld, n);
    // D S0 D, S0 = random_spd: the upper triangle scaled, the rest junk.
    const std::vector<double> S0 = random_spd(n, ld, 11u);
    std::vector<double> S(S0), rhs(static_cast<size_t>(n), 0.0), x(static_cast<size_t>(n));
    for (i64 r = 0; r < n; ++r)
      for (i64 c = r; c < n; ++c) S[size_t(r * ld + c)] *= scale[size_t(r)] * scale[size_t(c)];
    for (i64 r = 0; r < n; ++r)
      for (i64 c = 0; c < n; ++c) {
        const i64 a = std::min(r, c), b = std::max(r, c);
        rhs[size_t(r)] += S[size_t(a * ld + b)] * xtrue[size_t(c)];
      }
    std::vector<double> work(S);
    ASSERT_TRUE(f->solve(work.data(), rhs.data(), x.data()));
    double worst = 0.0;
    for (i64 r = 0; r < n; ++r)
      worst = std::max(worst, std::fabs(x[size_t(r)] - xtrue[size_t(r)]) * scale[size_t(r)]);
    EXPECT_LT(worst, 1e-8);

    // A negative pivot halfway down.
    work = S;
    work[size_t((n / 2) * ld + n / 2)] = -1.0;
    EXPECT_FALSE(f->solve(work.data(), rhs.data(), x.data()));
  }
}

// The cg solver's truncated CG: any budget is a success (every iterate lowers the quadratic
// model), and a loss of curvature before the first update is a failure.
TEST(DenseFactorization, TruncatedCgTakesWhatItsBudgetAllows) {
  class Identity final : public sba::dense::Preconditioner {
   public:
    void apply(const std::vector<double> &r, std::vector<double> &z) const override { z = r; }
  };
  const int n = 40;
  std::vector<double> A(static_cast<size_t>(n * n), 0.0), b(static_cast<size_t>(n)), x(static_cast<size_t>(n));
  for (int r = 0; r < n; ++r) {
    A[size_t(r) * n + r] = 2.0 + 0.1 * r;
    if (r + 1 < n) A[size_t(r) * n + r + 1] = A[size_t(r + 1) * n + r] = -1.0;
    b[size_t(r)] = std::cos(double(r));
  }
  auto model = [&](const std::vector<double> &v) {  // v^T A v / 2 - b^T v
    double q = 0.0;
    for (int r = 0; r < n; ++r) {
      double t = 0.0;
      for (int c = 0; c < n; ++c) t += A[size_t(r) * n + c] * v[size_t(c)];
      q += v[size_t(r)] * (0.5 * t - b[size_t(r)]);
    }
    return q;
  };
  double last = 0.0;
  for (int budget : {1, 2, 4, 8}) {
    ASSERT_TRUE(sba::dense::truncated_cg(A.data(), b.data(), x.data(), n, budget, 1e-10, Identity()));
    const double q = model(x);
    EXPECT_LT(q, last) << "budget " << budget;
    last = q;
  }
  for (int r = 0; r < n; ++r) A[size_t(r) * n + r] = -A[size_t(r) * n + r];
  EXPECT_FALSE(sba::dense::truncated_cg(A.data(), b.data(), x.data(), n, n, 1e-10, Identity()));
}

}  // namespace

// The split of S's block columns among the assembling threads (column_split.cpp). Where every
// point sees every camera, the range [0, b) costs 54 b (b + 1) + 90 b multiply-adds per point
// (cnp 6, pnp 3, mnp 2: block products plus the W and Y products of the track) and [b, 40)
// costs 54 (40 * 41 - b (b + 1)) + 90 * 40 (the later thread recomputes the track's products
// from its start): equal at b = 28.3, so two threads meet at column 28 or 29, not at 20.
// The passes over the projections split cameras and points by their projections: with tracks
// growing from 2 to 40 cameras along the points, each seen by the last cameras (so that the
// later cameras make more projections), each range holds a T-th of them to within one
// camera's or point's.
TEST(ColumnSplit, ProjectionsSplitEvenly) {
  const int n = 400, m = 40;
  std::vector<char> vmask(size_t(n) * size_t(m), 0);
  for (int i = 0; i < n; ++i)
    for (int j = m - 2 - i * (m - 2) / n; j < m; ++j) vmask[size_t(i) * size_t(m) + size_t(j)] = 1;
  for (int mcon : {0, 5})
    for (int threads : {1, 2, 3, 7}) {
      SCOPED_TRACE(std::to_string(mcon) + " fixed, " + std::to_string(threads) + " threads");
      sba::Layout lay;
      std::string msg;
      ASSERT_TRUE(sba::build_layout(lay, sba::Mode::MotStr, n, m, mcon, 10, 6, 3, 2, vmask.data(), &msg)) << msg;
      std::vector<i64> per_camera(size_t(m), 0);
      for (i64 k = 0; k < lay.nvis; ++k) ++per_camera[size_t(lay.colidx[size_t(k)])];
      const auto track = [&](i64 i) { return i64(lay.rowptr[size_t(i) + 1] - lay.rowptr[size_t(i)]); };
      const auto camera = [&](i64 j) { return per_camera[size_t(j)]; };
      const auto check = [&](const std::vector<i64> &b, i64 lo, i64 hi, const auto &cost) {
        ASSERT_EQ(b.size(), size_t(threads) + 1);
        EXPECT_EQ(b.front(), lo);
        EXPECT_EQ(b.back(), hi);
        EXPECT_TRUE(std::is_sorted(b.begin(), b.end()));
        i64 total = 0, largest = 0;
        for (i64 x = lo; x < hi; ++x) total += cost(x), largest = std::max(largest, cost(x));
        for (int t = 0; t < threads; ++t) {
          i64 part = 0;
          for (i64 x = b[size_t(t)]; x < b[size_t(t) + 1]; ++x) part += cost(x);
          EXPECT_LE(std::abs(part * threads - total), threads * largest) << "range " << t;
        }
      };
      check(sba::split_cameras_by_projections(lay, threads), mcon, m, camera);
      check(sba::split_points_by_projections(lay, 10, threads), 10, n, track);
      check(sba::split_points_by_projections(lay, 0, threads), 0, n, track);
    }
}

TEST(ColumnSplit, BalancesTheCostOfTheAssembly) {
  const int n = 200, m = 40;
  std::vector<char> vmask(size_t(n) * size_t(m), 1);
  sba::Layout lay;
  std::string msg;
  ASSERT_TRUE(sba::build_layout(lay, sba::Mode::MotStr, n, m, 0, 0, 6, 3, 2, vmask.data(), &msg)) << msg;
  EXPECT_EQ(sba::split_schur_columns(lay, 1), (std::vector<int>{0, 40}));
  const std::vector<int> two = sba::split_schur_columns(lay, 2);
  ASSERT_EQ(two.size(), 3u);
  EXPECT_EQ(two[0], 0);
  EXPECT_GE(two[1], 28);
  EXPECT_LE(two[1], 29);
  EXPECT_EQ(two[2], 40);
  // Any thread count: boundaries from 0 to the free cameras, never decreasing, and with more
  // threads than columns some ranges are empty.
  for (int mcon : {0, 5})
    for (int threads : {3, 7, 64}) {
      sba::Layout fixed;
      ASSERT_TRUE(sba::build_layout(fixed, sba::Mode::MotStr, n, m, mcon, 0, 6, 3, 2, vmask.data(), &msg));
      const std::vector<int> s = sba::split_schur_columns(fixed, threads);
      ASSERT_EQ(s.size(), size_t(threads) + 1);
      EXPECT_EQ(s.front(), 0);
      EXPECT_EQ(s.back(), m - mcon);
      EXPECT_TRUE(std::is_sorted(s.begin(), s.end())) << threads;
      if (threads < m - mcon)
        for (int t = 0; t < threads; ++t) EXPECT_LT(s[size_t(t)], s[size_t(t) + 1]) << threads << " " << t;
    }
}
