// SPDX-License-Identifier: BSD-3-Clause
// Tests of the dense helpers in sba.h (src/dense.cpp) against known solutions.
//
// The small matrices have integer entries and the right-hand sides are formed in exact
// integer arithmetic from integer solutions, so every expected value is exact and the
// tolerances are only those of the solver. The nonsymmetric matrix is used in both storage
// orders: the same array read column-major is the transpose, so each order gets its own
// right-hand side for the same known x.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <string>
#include <thread>
#include <vector>

#include "sba.h"

namespace {

using Vec = std::vector<double>;
constexpr int kM = 4;
constexpr double kTol = 1e-12;

// Symmetric positive definite (strictly diagonally dominant), condition number about 4.
const Vec kSpd = {4, 1, 0, 1,  //
                  1, 5, 2, 0,  //
                  0, 2, 6, 1,  //
                  1, 0, 1, 3};
// Symmetric indefinite; leading minors 1, -7, -15, 118 (so unpivoted LDL^T exists).
const Vec kSymInd = {1, 2,  0, 1,   //
                     2, -3, 1, 0,   //
                     0, 1,  2, 4,   //
                     1, 0,  4, -1};
// Inverse of kSymInd, exact rationals.
const Vec kSymIndInv = {55.0 / 118, 16.0 / 59, -7.0 / 59, -1.0 / 118,  //
                        16.0 / 59,  -10.0 / 59, -3.0 / 59, 4.0 / 59,   //
                        -7.0 / 59,  -3.0 / 59, 5.0 / 59,  13.0 / 59,   //
                        -1.0 / 118, 4.0 / 59,  13.0 / 59, -15.0 / 118};
// General nonsymmetric, determinant -132.
const Vec kGen = {2, -1, 0,  3,   //
                  1, 3,  -2, 0,   //
                  0, 1,  4,  -1,  //
                  5, 0,  1,  2};
// Singular nonsymmetric: row 4 = row 1 + row 2.
const Vec kSingGen = {1, 2, 0, 1,  //
                      0, 1, 3, 2,  //
                      4, 0, 1, 1,  //
                      1, 3, 3, 3};
// Singular symmetric positive semidefinite: column 4 = column 1 + column 2, so the null
// space is spanned by (1, 1, 0, -1). The leading 3x3 block is SPD.
const Vec kSingSym = {2, 1, 0, 3,  //
                      1, 3, 1, 4,  //
                      0, 1, 2, 1,  //
                      3, 4, 1, 7};
// SPD with determinant 1: L L^T for the unit lower triangular integer L
// [1 0 0 0; 1 1 0 0; 0 1 1 0; 1 0 1 1], so its inverse is an integer matrix.
const Vec kUni = {1, 1, 0, 1,  //
                  1, 2, 1, 1,  //
                  0, 1, 2, 1,  //
                  1, 1, 1, 3};
const Vec kUniInv = {7,  -4, 3,  -2,  //
                     -4, 3,  -2, 1,   //
                     3,  -2, 2,  -1,  //
                     -2, 1,  -1, 1};

const Vec kXTrue = {1, -2, 3, -1};

double at(const Vec &a, int m, bool colmaj, int i, int j) {
  return colmaj ? a[std::size_t(i) + std::size_t(j) * m] : a[std::size_t(i) * m + j];
}

// Logical A x for the array a read in the given storage order; exact for small integers.
Vec apply(const Vec &a, int m, bool colmaj, const Vec &x) {
  Vec y(std::size_t(m), 0.0);
  for (int i = 0; i < m; ++i)
    for (int j = 0; j < m; ++j) y[i] += at(a, m, colmaj, i, j) * x[j];
  return y;
}

// Row-major C = A B.
Vec matmul(const Vec &a, const Vec &b, int m) {
  Vec c(std::size_t(m) * m, 0.0);
  for (int i = 0; i < m; ++i)
    for (int k = 0; k < m; ++k)
      for (int j = 0; j < m; ++j) c[i * m + j] += a[i * m + k] * b[k * m + j];
  return c;
}

double inf_norm(const Vec &v) {
  double s = 0.0;
  for (double e : v) s = std::max(s, std::fabs(e));
  return s;
}

void expect_vec_near(const Vec &got, const Vec &want, double reltol, const std::string &what) {
  ASSERT_EQ(got.size(), want.size()) << what;
  const double tol = reltol * std::max(1.0, inf_norm(want));
  for (std::size_t k = 0; k < got.size(); ++k)
    EXPECT_NEAR(got[k], want[k], tol) << what << " entry " << k;
}

void expect_identity(const Vec &p, int m, double tol, const std::string &what) {
  for (int i = 0; i < m; ++i)
    for (int j = 0; j < m; ++j)
      EXPECT_NEAR(p[i * m + j], i == j ? 1.0 : 0.0, tol) << what << " (" << i << "," << j << ")";
}

// The symmetric inverses write the inverse into the lower triangle with the diagonal and
// keep the strictly upper triangle: the full inverse, mirrored from what they wrote.
Vec inverse_from_lower(const Vec &a, int m) {
  Vec inv = a;
  for (int i = 0; i < m; ++i)
    for (int j = i + 1; j < m; ++j) inv[i * m + j] = a[j * m + i];
  return inv;
}

void expect_upper_kept(const Vec &got, const Vec &in, int m, const std::string &what) {
  for (int i = 0; i < m; ++i)
    for (int j = i + 1; j < m; ++j)
      EXPECT_EQ(got[i * m + j], in[i * m + j])
          << what << " upper triangle at (" << i << "," << j << ")";
}

// Deterministic SPD test matrix of order m: M^T M + m I with M's entries in [-1, 1).
Vec spd_matrix(int m, std::uint32_t seed) {
  Vec mm(std::size_t(m) * m);
  for (double &e : mm) {
    seed = seed * 1664525u + 1013904223u;
    e = double(seed >> 8) / double(1u << 23) - 1.0;
  }
  Vec a(std::size_t(m) * m, 0.0);
  for (int i = 0; i < m; ++i)
    for (int j = 0; j < m; ++j) {
      double s = i == j ? double(m) : 0.0;
      for (int k = 0; k < m; ++k) s += mm[k * m + i] * mm[k * m + j];
      a[i * m + j] = s;
    }
  return a;
}

using AxbFn = int (*)(double *, double *, double *, int, int);
using InvFn = int (*)(double *, int);

struct SolverCase {
  const char *name;
  AxbFn fn;
  bool spd_only;        // needs a symmetric positive definite A
  bool symmetric_only;  // reads only one triangle
  bool rank_revealing;  // succeeds on singular A (SVD)
};

const SolverCase kAllSolvers[] = {
    {"QR", sba_Axb_QR, false, false, false},     {"QRnoQ", sba_Axb_QRnoQ, false, false, false},
    {"Chol", sba_Axb_Chol, true, true, false},   {"LDLt", sba_Axb_LDLt, false, true, false},
    {"LU", sba_Axb_LU, false, false, false},     {"SVD", sba_Axb_SVD, false, false, true},
    {"BK", sba_Axb_BK, false, true, false},
};

std::string case_name(const testing::TestParamInfo<SolverCase> &info) { return info.param.name; }

// Runs fn on copies of A and B and checks that neither copy was written.
int solve_checked(AxbFn fn, const Vec &a, const Vec &b, Vec &x, bool colmaj) {
  Vec acopy = a, bcopy = b;
  const int ret = fn(acopy.data(), bcopy.data(), x.data(), int(b.size()), colmaj ? 1 : 0);
  EXPECT_EQ(acopy, a) << "A was modified";
  EXPECT_EQ(bcopy, b) << "B was modified";
  return ret;
}

class Solver : public testing::TestWithParam<SolverCase> {};

TEST_P(Solver, SolvesSpdInBothOrders) {
  for (bool colmaj : {false, true}) {
    const Vec b = apply(kSpd, kM, colmaj, kXTrue);
    Vec x(kM, 99.0);
    ASSERT_EQ(solve_checked(GetParam().fn, kSpd, b, x, colmaj), 1) << "colmaj " << colmaj;
    expect_vec_near(x, kXTrue, kTol, std::string("colmaj ") + (colmaj ? "1" : "0"));
  }
}

TEST_P(Solver, SymmetricIndefinite) {
  for (bool colmaj : {false, true}) {
    const Vec b = apply(kSymInd, kM, colmaj, kXTrue);
    Vec x(kM, 99.0);
    const int ret = solve_checked(GetParam().fn, kSymInd, b, x, colmaj);
    if (GetParam().spd_only) {
      EXPECT_EQ(ret, 0) << "Cholesky must reject an indefinite matrix";
      EXPECT_EQ(x, Vec(kM, 99.0)) << "x must be left alone on failure";
    } else {
      ASSERT_EQ(ret, 1);
      expect_vec_near(x, kXTrue, kTol, "indefinite");
    }
  }
}

TEST_P(Solver, XMayAliasB) {
  for (bool colmaj : {false, true}) {
    Vec bx = apply(kSpd, kM, colmaj, kXTrue);
    Vec a = kSpd;
    ASSERT_EQ(GetParam().fn(a.data(), bx.data(), bx.data(), kM, colmaj ? 1 : 0), 1);
    expect_vec_near(bx, kXTrue, kTol, "aliased");
    EXPECT_EQ(a, kSpd);
  }
}

TEST_P(Solver, SingularInput) {
  const SolverCase &c = GetParam();
  for (bool colmaj : {false, true}) {
    const Vec b = {1, 2, 3, 5};  // not in the range of kSingSym
    Vec x(kM, 99.0);
    const int ret = solve_checked(c.fn, kSingSym, b, x, colmaj);
    if (c.rank_revealing) {
      EXPECT_EQ(ret, 1);
    } else {
      EXPECT_EQ(ret, 0) << "singular symmetric, colmaj " << colmaj;
      EXPECT_EQ(x, Vec(kM, 99.0));
    }
    if (!c.symmetric_only && !c.rank_revealing) {
      Vec y(kM, 99.0);
      EXPECT_EQ(solve_checked(c.fn, kSingGen, b, y, colmaj), 0) << "singular general";
      EXPECT_EQ(y, Vec(kM, 99.0));
    }
  }
  Vec zero(kM * kM, 0.0), b = {1, 1, 1, 1}, x(kM, 99.0);
  EXPECT_EQ(c.fn(zero.data(), b.data(), x.data(), kM, 0), 0) << "zero matrix";
}

TEST_P(Solver, LargerSpdSystem) {
  // m = 70 goes through LAPACK's blocked code paths (block sizes 32 and 64).
  const int m = 70;
  const Vec a = spd_matrix(m, 12345u);
  Vec xt(m);
  for (int i = 0; i < m; ++i) xt[i] = double(i % 7) - 3.0;
  for (bool colmaj : {false, true}) {
    const Vec b = apply(a, m, colmaj, xt);
    Vec x(m, 0.0);
    ASSERT_EQ(solve_checked(GetParam().fn, a, b, x, colmaj), 1);
    expect_vec_near(x, xt, 1e-11, "m = 70");
  }
}

TEST_P(Solver, BadArguments) {
  const AxbFn fn = GetParam().fn;
  EXPECT_EQ(fn(nullptr, nullptr, nullptr, 0, 0), 1) << "A == NULL is the legacy no-op";
  EXPECT_EQ(fn(nullptr, nullptr, nullptr, 5, 1), 1);
  Vec a = kSpd, b = apply(kSpd, kM, false, kXTrue), x(kM, 99.0);
  EXPECT_EQ(fn(a.data(), b.data(), x.data(), 0, 0), 0);
  EXPECT_EQ(fn(a.data(), b.data(), x.data(), -3, 0), 0);
  EXPECT_EQ(fn(a.data(), nullptr, x.data(), kM, 0), 0);
  EXPECT_EQ(fn(a.data(), b.data(), nullptr, kM, 0), 0);
  a[5] = std::numeric_limits<double>::quiet_NaN();
  EXPECT_EQ(fn(a.data(), b.data(), x.data(), kM, 0), 0);
  a = kSpd;
  b[2] = std::numeric_limits<double>::infinity();
  EXPECT_EQ(fn(a.data(), b.data(), x.data(), kM, 0), 0);
  EXPECT_EQ(x, Vec(kM, 99.0));
}

TEST_P(Solver, OneByOne) {
  double a = 4.0, b = -2.0, x = 0.0;
  ASSERT_EQ(GetParam().fn(&a, &b, &x, 1, 0), 1);
  EXPECT_DOUBLE_EQ(x, -0.5);
}

INSTANTIATE_TEST_SUITE_P(Dense, Solver, testing::ValuesIn(kAllSolvers), case_name);

// Solvers that read all of A: the nonsymmetric matrix in both storage orders.
class GeneralSolver : public testing::TestWithParam<SolverCase> {};

TEST_P(GeneralSolver, NonsymmetricInBothOrders) {
  for (bool colmaj : {false, true}) {
    const Vec b = apply(kGen, kM, colmaj, kXTrue);
    Vec x(kM, 99.0);
    ASSERT_EQ(solve_checked(GetParam().fn, kGen, b, x, colmaj), 1);
    expect_vec_near(x, kXTrue, kTol, std::string("colmaj ") + (colmaj ? "1" : "0"));
  }
  // The two orders really are different systems: the row-major right-hand side read with
  // column-major A gives another solution, namely the one of A^T x = b.
  const Vec b = apply(kGen, kM, false, kXTrue);
  Vec x(kM, 0.0);
  ASSERT_EQ(solve_checked(GetParam().fn, kGen, b, x, true), 1);
  expect_vec_near(apply(kGen, kM, true, x), b, kTol, "A^T x = b");
  EXPECT_GT(inf_norm({x[0] - kXTrue[0], x[1] - kXTrue[1], x[2] - kXTrue[2], x[3] - kXTrue[3]}),
            0.1);
}

const SolverCase kGeneralSolvers[] = {
    {"QR", sba_Axb_QR, false, false, false},
    {"QRnoQ", sba_Axb_QRnoQ, false, false, false},
    {"LU", sba_Axb_LU, false, false, false},
    {"SVD", sba_Axb_SVD, false, false, true},
};
INSTANTIATE_TEST_SUITE_P(Dense, GeneralSolver, testing::ValuesIn(kGeneralSolvers), case_name);

TEST(DenseSvd, MinimumNormSolutionOfSingularConsistentSystem) {
  // x0 = (1, 2, 3, 4) solves it; the minimum-norm solution is x0 minus its component along
  // the null vector n = (1, 1, 0, -1): x0 + n/3.
  const Vec x0 = {1, 2, 3, 4};
  const Vec want = {4.0 / 3, 7.0 / 3, 3.0, 11.0 / 3};
  for (bool colmaj : {false, true}) {
    const Vec b = apply(kSingSym, kM, colmaj, x0);
    Vec x(kM, 99.0);
    ASSERT_EQ(solve_checked(sba_Axb_SVD, kSingSym, b, x, colmaj), 1);
    expect_vec_near(x, want, kTol, "minimum norm");
  }
}

TEST(DenseSvd, LeastSquaresOnInconsistentSingularSystem) {
  // b has a component along the left null vector (1, 1, 0, -1) as well: the answer is the
  // minimum-norm least-squares solution, so A^T (A x - b) = 0 and x is orthogonal to it.
  Vec b = {1, 2, 3, 5};
  Vec x(kM, 99.0);
  ASSERT_EQ(solve_checked(sba_Axb_SVD, kSingSym, b, x, false), 1);
  Vec res = apply(kSingSym, kM, false, x);
  for (int i = 0; i < kM; ++i) res[i] -= b[i];
  const Vec normal = apply(kSingSym, kM, true, res);
  for (double e : normal) EXPECT_NEAR(e, 0.0, 1e-12 * 20);
  EXPECT_NEAR(x[0] + x[1] - x[3], 0.0, 1e-12 * 5);
  // The exact answer, from the consistent part of b: b minus its projection on n,
  // b - (1+2-5)/3 n = (5/3, 8/3, 3, 13/3), then the same minimum-norm construction.
  const Vec bc = {5.0 / 3, 8.0 / 3, 3.0, 13.0 / 3};
  Vec xc(kM, 0.0);
  ASSERT_EQ(solve_checked(sba_Axb_SVD, kSingSym, bc, xc, false), 1);
  expect_vec_near(x, xc, kTol, "least squares = minimum norm on the consistent part");
}

TEST(DenseLdlt, ZeroLeadingPivotFailsWhereBunchKaufmanSucceeds) {
  // [0 1; 1 0] is nonsingular but has no unpivoted LDL^T.
  const Vec a = {0, 1, 1, 0};
  const Vec b = {3, -5};
  Vec x = {99, 99};
  EXPECT_EQ(solve_checked(sba_Axb_LDLt, a, b, x, false), 0);
  EXPECT_EQ(x, (Vec{99, 99}));
  ASSERT_EQ(solve_checked(sba_Axb_BK, a, b, x, false), 1);
  expect_vec_near(x, {-5, 3}, kTol, "BK 2x2 pivot");
}

TEST(DenseLdlt, ReadsOnlyTheUpperTriangle) {
  // Garbage below the diagonal (row-major) must not matter; column-major storage of the
  // same array puts the garbage above, so there the upper-triangle reader sees it.
  Vec a = kSpd;
  for (int i = 0; i < kM; ++i)
    for (int j = 0; j < i; ++j) a[i * kM + j] = 1000.0 + i + j;
  const Vec b = apply(kSpd, kM, false, kXTrue);
  for (AxbFn fn : {sba_Axb_LDLt, sba_Axb_Chol, sba_Axb_BK}) {
    Vec x(kM, 0.0);
    ASSERT_EQ(solve_checked(fn, a, b, x, false), 1);
    expect_vec_near(x, kXTrue, kTol, "upper triangle only");
  }
}

TEST(DenseThresholds, BadlyScaledButWellPosedSystem) {
  // D A D with D = diag(1, 1e6, 1e-6, 1e3): condition number about 1e24, yet the system is
  // just kSpd in other units. The singularity tests are built not to refuse it where the
  // method itself is accurate (Chol, LDLt, LU, BK: every entry of x to 1e-12 relative).
  const double d[kM] = {1, 1e6, 1e-6, 1e3};
  Vec a(kM * kM);
  for (int i = 0; i < kM; ++i)
    for (int j = 0; j < kM; ++j) a[i * kM + j] = d[i] * kSpd[i * kM + j] * d[j];
  Vec xt(kM), b(kM, 0.0);
  for (int i = 0; i < kM; ++i) xt[i] = kXTrue[i] / d[i];
  for (int i = 0; i < kM; ++i)  // b = D (A (D xt)) = D (A kXTrue), exact
    for (int j = 0; j < kM; ++j) b[i] += d[i] * kSpd[i * kM + j] * kXTrue[j];
  for (AxbFn fn : {sba_Axb_Chol, sba_Axb_LDLt, sba_Axb_LU, sba_Axb_BK}) {
    Vec x(kM, 0.0);
    ASSERT_EQ(solve_checked(fn, a, b, x, false), 1);
    for (int i = 0; i < kM; ++i) EXPECT_NEAR(x[i], xt[i], 1e-12 * std::fabs(xt[i])) << i;
  }
  // Householder QR is not invariant under row scaling, so it keeps fewer digits, but it
  // must not call this system singular.
  Vec x(kM, 0.0);
  ASSERT_EQ(solve_checked(sba_Axb_QR, a, b, x, false), 1);
  for (int i = 0; i < kM; ++i) EXPECT_NEAR(x[i], xt[i], 1e-6 * std::fabs(xt[i])) << i;
  // The normal equations (cond^2 ~ 1e48) provably carry no digits: QRnoQ refuses.
  Vec y(kM, 99.0);
  EXPECT_EQ(solve_checked(sba_Axb_QRnoQ, a, b, y, false), 0);
  // Inverses through Cholesky and Bunch-Kaufman are fine as well.
  for (InvFn fn : {sba_symat_invert_Chol, sba_symat_invert_BK}) {
    Vec lower = a;
    ASSERT_EQ(fn(lower.data(), kM), 1);
    const Vec inv = inverse_from_lower(lower, kM);
    // (D A D)^-1 = D^-1 A^-1 D^-1, so D (D A D)^-1 D must be A^-1; A * that = I.
    Vec scaled(kM * kM);
    for (int i = 0; i < kM; ++i)
      for (int j = 0; j < kM; ++j) scaled[i * kM + j] = d[i] * inv[i * kM + j] * d[j];
    expect_identity(matmul(kSpd, scaled, kM), kM, 1e-12, "scaled inverse");
  }
}

// ---- conjugate gradients ----

struct CgCase {
  const char *name;
  int prec;
};
const CgCase kCgCases[] = {
    {"NoPrec", SBA_CG_NOPREC}, {"Jacobi", SBA_CG_JACOBI}, {"SSOR", SBA_CG_SSOR}};

class Cg : public testing::TestWithParam<CgCase> {};

int cg_checked(const Vec &a, const Vec &b, Vec &x, int niter, double eps, int prec, bool colmaj) {
  Vec acopy = a, bcopy = b;
  const int ret = sba_Axb_CG(acopy.data(), bcopy.data(), x.data(), int(b.size()), niter, eps, prec,
                             colmaj ? 1 : 0);
  EXPECT_EQ(acopy, a);
  EXPECT_EQ(bcopy, b);
  return ret;
}

TEST_P(Cg, SmallSpdWithinMIterations) {
  // In exact arithmetic (P)CG terminates in at most m iterations; at m = 4 and condition 4
  // rounding does not cost an extra one, so niter = 0 (which means m) must be enough.
  for (bool colmaj : {false, true}) {
    const Vec b = apply(kSpd, kM, colmaj, kXTrue);
    Vec x(kM, 99.0);  // the starting point is x = 0 regardless of x's content
    const int it = cg_checked(kSpd, b, x, 0, 1e-13, GetParam().prec, colmaj);
    EXPECT_GE(it, 1);
    EXPECT_LE(it, kM);
    expect_vec_near(x, kXTrue, 1e-10, "CG");
    const Vec r = apply(kSpd, kM, colmaj, x);
    double rn = 0.0, bn = 0.0;
    for (int i = 0; i < kM; ++i) {
      rn += (b[i] - r[i]) * (b[i] - r[i]);
      bn += b[i] * b[i];
    }
    EXPECT_LE(std::sqrt(rn), 1e-13 * std::sqrt(bn)) << "stopping rule";
  }
}

TEST_P(Cg, AliasAndDefaults) {
  Vec bx = apply(kSpd, kM, false, kXTrue);
  Vec a = kSpd;
  // eps <= 0 selects the default tolerance 1e-12.
  const int it = sba_Axb_CG(a.data(), bx.data(), bx.data(), kM, 10, 0.0, GetParam().prec, 0);
  EXPECT_GE(it, 1);
  EXPECT_LE(it, kM + 1);
  expect_vec_near(bx, kXTrue, 1e-10, "aliased CG");
}

TEST_P(Cg, ZeroRightHandSide) {
  const Vec b(kM, 0.0);
  Vec x(kM, 99.0);
  EXPECT_EQ(cg_checked(kSpd, b, x, 0, 1e-12, GetParam().prec, false), 1);
  EXPECT_EQ(x, Vec(kM, 0.0));
  // From a starting point as well: x = 0 is the exact answer, whatever the start.
  x = Vec(kM, 99.0);
  EXPECT_EQ(cg_checked(kSpd, b, x, -5, 1e-12, GetParam().prec, false), 1);
  EXPECT_EQ(x, Vec(kM, 0.0));
}

TEST_P(Cg, FailsOnIndefiniteOrSingular) {
  // Breakdowns: the indefinite matrix gives a direction of non-positive curvature, and the
  // singular one, with b outside its range, has no solution to converge to and breaks down
  // as well. (Running out of iterations is not a failure: see
  // BudgetExhaustedReturnsTheLastIterate.)
  const int prec = GetParam().prec;
  const Vec b = {1, 2, 3, 5};
  Vec x(kM, 99.0);
  EXPECT_EQ(cg_checked(kSymInd, b, x, 50, 1e-12, prec, false), 0) << "indefinite";
  EXPECT_EQ(cg_checked(kSingSym, b, x, 50, 1e-12, prec, false), 0) << "singular";
  EXPECT_EQ(x, Vec(kM, 99.0)) << "x is left alone on failure";
}

TEST_P(Cg, LargerSpdSystem) {
  const int m = 70;
  const Vec a = spd_matrix(m, 777u);
  Vec xt(m);
  for (int i = 0; i < m; ++i) xt[i] = double(i % 5) - 2.0;
  for (bool colmaj : {false, true}) {
    const Vec b = apply(a, m, colmaj, xt);
    Vec x(m, 0.0);
    const int it = cg_checked(a, b, x, 0, 1e-12, GetParam().prec, colmaj);
    // Condition number about 5: far fewer than m iterations are needed.
    EXPECT_GE(it, 5);
    EXPECT_LE(it, 40);
    expect_vec_near(x, xt, 1e-10, "m = 70");
  }
}

INSTANTIATE_TEST_SUITE_P(Dense, Cg, testing::ValuesIn(kCgCases),
                         [](const testing::TestParamInfo<CgCase> &i) { return i.param.name; });

// 1-D Laplacian tridiag(-1, 2, -1): all m eigenvalues are distinct, so for a right-hand side
// with a component along every eigenvector, unpreconditioned CG needs m iterations, and
// symmetric Gauss-Seidel must cut that down.
Vec laplacian(int m) {
  Vec a(std::size_t(m) * m, 0.0);
  for (int i = 0; i < m; ++i) {
    a[i * m + i] = 2.0;
    if (i > 0) a[i * m + i - 1] = -1.0;
    if (i + 1 < m) a[i * m + i + 1] = -1.0;
  }
  return a;
}

TEST(DenseCg, SsorBeatsNoPreconditionerOnLaplacian) {
  const int m = 50;
  const Vec a = laplacian(m);
  // Pseudo-random integers in [-8, 7]: a periodic x would give a b that excites only a few
  // eigenvectors, and CG would finish early for that reason alone.
  Vec xt(m);
  std::uint32_t seed = 7u;
  for (double &e : xt) {
    seed = seed * 1664525u + 1013904223u;
    e = double(int(seed >> 28)) - 8.0;
  }
  const Vec b = apply(a, m, false, xt);
  Vec x0(m, 0.0), x2(m, 0.0);
  const int it0 = cg_checked(a, b, x0, 3 * m, 1e-12, SBA_CG_NOPREC, false);
  const int it2 = cg_checked(a, b, x2, 3 * m, 1e-12, SBA_CG_SSOR, false);
  expect_vec_near(x0, xt, 1e-10, "no preconditioner");
  expect_vec_near(x2, xt, 1e-10, "SSOR");
  // Exact arithmetic needs exactly m; rounding at condition ~1000 may shift that by a couple.
  EXPECT_GE(it0, m - 2);
  EXPECT_LE(it0, m + 2);
  // Symmetric Gauss-Seidel roughly halves the condition number here (30 iterations seen).
  EXPECT_GE(it2, m / 4);
  EXPECT_LE(it2, 2 * m / 3);
}

TEST(DenseCg, JacobiRemovesBadScaling) {
  // D A D with D = diag(1, 10, 100, 1000): condition about 4e6 unpreconditioned, but the
  // Jacobi-preconditioned system is the well-conditioned A again.
  const double d[kM] = {1, 10, 100, 1000};
  Vec a(kM * kM);
  for (int i = 0; i < kM; ++i)
    for (int j = 0; j < kM; ++j) a[i * kM + j] = d[i] * kSpd[i * kM + j] * d[j];
  Vec xt(kM);
  for (int i = 0; i < kM; ++i) xt[i] = kXTrue[i] / d[i];
  const Vec b = apply(a, kM, false, xt);
  Vec x(kM, 0.0);
  const int it = cg_checked(a, b, x, 0, 1e-13, SBA_CG_JACOBI, false);
  EXPECT_GE(it, 1);
  EXPECT_LE(it, kM);
  for (int i = 0; i < kM; ++i) EXPECT_NEAR(x[i], xt[i], 1e-12 * std::fabs(xt[i])) << i;
}

TEST(DenseCg, BadArguments) {
  Vec a = kSpd, b = apply(kSpd, kM, false, kXTrue), x(kM, 99.0);
  EXPECT_EQ(sba_Axb_CG(nullptr, nullptr, nullptr, 0, 0, 0.0, 0, 0), 1);
  EXPECT_EQ(sba_Axb_CG(a.data(), b.data(), x.data(), kM, 0, 1e-12, 3, 0), 0) << "unknown prec";
  EXPECT_EQ(sba_Axb_CG(a.data(), b.data(), x.data(), kM, 0, 1e-12, -1, 0), 0) << "unknown prec";
  EXPECT_EQ(sba_Axb_CG(a.data(), b.data(), x.data(), 0, 0, 1e-12, 0, 0), 0);
  EXPECT_EQ(sba_Axb_CG(a.data(), nullptr, x.data(), kM, 0, 1e-12, 0, 0), 0);
  EXPECT_EQ(sba_Axb_CG(a.data(), b.data(), nullptr, kM, 0, 1e-12, 0, 0), 0);
  EXPECT_EQ(x, Vec(kM, 99.0));
  EXPECT_EQ(a, kSpd);
}

// ---- inverses ----

TEST(DenseInverse, KnownInverses) {
  struct Case {
    const char *name;
    InvFn fn;
    const Vec &a;
    const Vec &inv;
  };
  const Case cases[] = {
      {"LU unimodular", sba_symat_invert_LU, kUni, kUniInv},
      {"Chol unimodular", sba_symat_invert_Chol, kUni, kUniInv},
      {"BK unimodular", sba_symat_invert_BK, kUni, kUniInv},
      {"LU indefinite", sba_symat_invert_LU, kSymInd, kSymIndInv},
      {"BK indefinite", sba_symat_invert_BK, kSymInd, kSymIndInv},
  };
  for (const Case &c : cases) {
    Vec a = c.a;
    ASSERT_EQ(c.fn(a.data(), kM), 1) << c.name;
    expect_upper_kept(a, c.a, kM, c.name);
    const Vec inv = inverse_from_lower(a, kM);
    expect_vec_near(inv, c.inv, 1e-12, c.name);
    expect_identity(matmul(c.a, inv, kM), kM, 1e-12 * 8, c.name);
  }
}

TEST(DenseInverse, SpdProductIsIdentity) {
  for (InvFn fn : {sba_symat_invert_LU, sba_symat_invert_Chol, sba_symat_invert_BK}) {
    Vec a = kSpd;
    ASSERT_EQ(fn(a.data(), kM), 1);
    expect_upper_kept(a, kSpd, kM, "kSpd");
    const Vec inv = inverse_from_lower(a, kM);
    expect_identity(matmul(kSpd, inv, kM), kM, 1e-12, "A * inv(A)");
    expect_identity(matmul(inv, kSpd, kM), kM, 1e-12, "inv(A) * A");
  }
  // m = 70 goes through LAPACK's blocked code paths.
  const int m = 70;
  const Vec big = spd_matrix(m, 4242u);
  for (InvFn fn : {sba_symat_invert_LU, sba_symat_invert_Chol, sba_symat_invert_BK}) {
    Vec a = big;
    ASSERT_EQ(fn(a.data(), m), 1);
    expect_upper_kept(a, big, m, "m = 70");
    expect_identity(matmul(big, inverse_from_lower(a, m), m), m, 1e-12, "m = 70");
  }
}

TEST(DenseInverse, FailuresLeaveAUnchanged) {
  for (InvFn fn : {sba_symat_invert_LU, sba_symat_invert_Chol, sba_symat_invert_BK}) {
    Vec a = kSingSym;
    EXPECT_EQ(fn(a.data(), kM), 0);
    EXPECT_EQ(a, kSingSym);
    Vec z(kM * kM, 0.0);
    EXPECT_EQ(fn(z.data(), kM), 0);
    EXPECT_EQ(fn(nullptr, 0), 1) << "A == NULL is the legacy no-op";
    EXPECT_EQ(fn(a.data(), 0), 0);
    a[3] = std::numeric_limits<double>::quiet_NaN();  // (0, 3): in the triangle that is read
    EXPECT_EQ(fn(a.data(), kM), 0);
  }
  Vec a = kSymInd;
  EXPECT_EQ(sba_symat_invert_Chol(a.data(), kM), 0) << "indefinite";
  EXPECT_EQ(a, kSymInd);
}

TEST(DenseCholinv, UpperFactorOfTheInverse) {
  for (const Vec *src : {&kSpd, &kUni}) {
    Vec a = *src, b(kM * kM, 99.0);
    ASSERT_EQ(sba_mat_cholinv(a.data(), b.data(), kM), 1);
    EXPECT_EQ(a, *src) << "A unchanged";
    for (int i = 0; i < kM; ++i) {
      EXPECT_GT(b[i * kM + i], 0.0);
      for (int j = 0; j < i; ++j) EXPECT_EQ(b[i * kM + j], 0.0) << "upper triangular";
    }
    Vec bt(kM * kM);
    for (int i = 0; i < kM; ++i)
      for (int j = 0; j < kM; ++j) bt[i * kM + j] = b[j * kM + i];
    const Vec btb = matmul(bt, b, kM);
    expect_identity(matmul(btb, *src, kM), kM, 1e-12 * 8, "B^T B A");
    if (src == &kUni) expect_vec_near(btb, kUniInv, 1e-12, "B^T B = inv(A)");
  }
}

TEST(DenseCholinv, Failures) {
  Vec a = kSymInd, b(kM * kM, 99.0);
  EXPECT_EQ(sba_mat_cholinv(a.data(), b.data(), kM), 0) << "indefinite";
  a = kSingSym;
  EXPECT_EQ(sba_mat_cholinv(a.data(), b.data(), kM), 0) << "singular";
  EXPECT_EQ(b, Vec(kM * kM, 99.0));
  EXPECT_EQ(sba_mat_cholinv(nullptr, nullptr, 0), 1);
  EXPECT_EQ(sba_mat_cholinv(a.data(), nullptr, kM), 0);
  EXPECT_EQ(sba_mat_cholinv(a.data(), b.data(), 0), 0);
}

// ---- no shared state: concurrent calls give the sequential answers bit for bit ----

TEST(DenseThreads, ConcurrentCallsMatchSequential) {
  const int m = 40;
  const Vec a = spd_matrix(m, 99u);
  Vec xt(m);
  for (int i = 0; i < m; ++i) xt[i] = double(i % 3) - 1.0;
  const Vec b = apply(a, m, false, xt);
  std::vector<Vec> want;
  for (const SolverCase &c : kAllSolvers) {
    Vec x(m), acopy = a, bcopy = b;
    ASSERT_EQ(c.fn(acopy.data(), bcopy.data(), x.data(), m, 0), 1) << c.name;
    want.push_back(x);
  }
  Vec xcg(m), acopy = a, bcopy = b;
  const int itcg = sba_Axb_CG(acopy.data(), bcopy.data(), xcg.data(), m, 0, 1e-12, SBA_CG_SSOR, 0);
  ASSERT_GT(itcg, 0);

  std::vector<int> mismatches(4, 0);
  std::vector<std::thread> pool;
  for (int t = 0; t < 4; ++t)
    pool.emplace_back([&, t] {
      for (int rep = 0; rep < 5; ++rep) {
        std::size_t k = 0;
        for (const SolverCase &c : kAllSolvers) {
          Vec x(m), ac = a, bc = b;
          if (c.fn(ac.data(), bc.data(), x.data(), m, 0) != 1 || x != want[k]) ++mismatches[t];
          ++k;
        }
        Vec x(m), ac = a, bc = b;
        if (sba_Axb_CG(ac.data(), bc.data(), x.data(), m, 0, 1e-12, SBA_CG_SSOR, 0) != itcg ||
            x != xcg)
          ++mismatches[t];
      }
    });
  for (std::thread &th : pool) th.join();
  for (int t = 0; t < 4; ++t) EXPECT_EQ(mismatches[t], 0) << "thread " << t;
}

// ---- the 1.6 contract of the symmetric inverses: upper triangle in, lower triangle out ----

// A = H diag(ev) H with the Householder reflection H = I - 2 v v^T / (v^T v): a dense
// symmetric matrix whose eigenvalues are ev (to rounding), so its definiteness and
// conditioning are known by construction.
Vec sym_with_eigenvalues(const Vec &ev, std::uint32_t seed) {
  const int m = int(ev.size());
  Vec v(static_cast<std::size_t>(m));
  double vv = 0.0;
  for (double &e : v) {
    seed = seed * 1664525u + 1013904223u;
    e = double(seed >> 8) / double(1u << 23) + 0.25;  // in [0.25, 2.25): never the zero vector
    vv += e * e;
  }
  Vec h(std::size_t(m) * m);
  for (int i = 0; i < m; ++i)
    for (int j = 0; j < m; ++j) h[i * m + j] = (i == j ? 1.0 : 0.0) - 2.0 * v[i] * v[j] / vv;
  Vec a(std::size_t(m) * m, 0.0);
  for (int i = 0; i < m; ++i)
    for (int j = 0; j < m; ++j) {
      double s = 0.0;
      for (int k = 0; k < m; ++k) s += h[i * m + k] * ev[k] * h[k * m + j];
      a[i * m + j] = s;
    }
  // Exactly symmetric, so that "the upper triangle" is the whole matrix.
  for (int i = 0; i < m; ++i)
    for (int j = 0; j < i; ++j) a[i * m + j] = a[j * m + i];
  return a;
}

// The inverse by Gauss-Jordan elimination with partial pivoting in long double: a reference
// that shares nothing with the library's LAPACK path.
Vec reference_inverse(const Vec &a, int m) {
  using LD = long double;
  std::vector<LD> w(std::size_t(m) * 2 * m, 0.0L);
  for (int i = 0; i < m; ++i) {
    for (int j = 0; j < m; ++j) w[i * 2 * m + j] = a[i * m + j];
    w[i * 2 * m + m + i] = 1.0L;
  }
  for (int c = 0; c < m; ++c) {
    int piv = c;
    for (int r = c + 1; r < m; ++r)
      if (std::fabs(w[r * 2 * m + c]) > std::fabs(w[piv * 2 * m + c])) piv = r;
    for (int j = 0; j < 2 * m; ++j) std::swap(w[c * 2 * m + j], w[piv * 2 * m + j]);
    const LD d = w[c * 2 * m + c];
    for (int j = 0; j < 2 * m; ++j) w[c * 2 * m + j] /= d;
    for (int r = 0; r < m; ++r) {
      if (r == c) continue;
      const LD f = w[r * 2 * m + c];
      for (int j = 0; j < 2 * m; ++j) w[r * 2 * m + j] -= f * w[c * 2 * m + j];
    }
  }
  Vec inv(std::size_t(m) * m);
  for (int i = 0; i < m; ++i)
    for (int j = 0; j < m; ++j) inv[i * m + j] = double(w[i * 2 * m + m + j]);
  return inv;
}

// The symmetric a with its strictly lower triangle overwritten by fill.
Vec upper_only(const Vec &a, int m, double fill) {
  Vec u = a;
  for (int i = 0; i < m; ++i)
    for (int j = 0; j < i; ++j) u[i * m + j] = fill;
  return u;
}

bool same_bits(double a, double b) { return std::memcmp(&a, &b, sizeof a) == 0; }

bool all_same_bits(const Vec &a, const Vec &b) {
  if (a.size() != b.size()) return false;
  for (std::size_t k = 0; k < a.size(); ++k)
    if (!same_bits(a[k], b[k])) return false;
  return true;
}

struct InvCase {
  const char *name;
  InvFn fn;
  bool spd_only;
};
const InvCase kInverses[] = {{"LU", sba_symat_invert_LU, false},
                             {"Chol", sba_symat_invert_Chol, true},
                             {"BK", sba_symat_invert_BK, false}};

class SymInverse : public testing::TestWithParam<InvCase> {};

// Runs the inverse on a's upper triangle, with the strictly lower triangle set to fill, and
// checks the 1.6 layout: the inverse in the lower triangle with the diagonal, the strictly
// upper triangle bit for bit as it was.
void check_upper_in_lower_out(InvFn fn, const Vec &a, int m, double fill, const std::string &what) {
  const Vec want = reference_inverse(a, m);
  const Vec in = upper_only(a, m, fill);
  Vec got = in;
  ASSERT_EQ(fn(got.data(), m), 1) << what;
  const double tol = 1e-12 * inf_norm(want);
  for (int i = 0; i < m; ++i)
    for (int j = 0; j < m; ++j) {
      const std::size_t k = std::size_t(i) * m + j;
      if (j <= i)
        EXPECT_NEAR(got[k], want[k], tol) << what << " inverse at (" << i << "," << j << ")";
      else
        EXPECT_TRUE(same_bits(got[k], in[k])) << what << " upper triangle written at (" << i
                                              << "," << j << ")";
    }
}

TEST_P(SymInverse, ReadsUpperWritesLowerSpd) {
  for (int m : {1, 3, 7, 12}) {
    const Vec a = spd_matrix(m, 31u + m);
    for (double fill : {std::numeric_limits<double>::quiet_NaN(), 1000.0, 0.0})
      check_upper_in_lower_out(GetParam().fn, a, m, fill,
                               std::string(GetParam().name) + " SPD m = " + std::to_string(m) +
                                   " fill " + std::to_string(fill));
  }
}

TEST_P(SymInverse, IndefiniteMatrix) {
  for (int m : {1, 3, 7, 12}) {
    Vec ev(static_cast<std::size_t>(m));
    for (int k = 0; k < m; ++k) ev[k] = (k % 2 ? -1.0 : 1.0) * (1.0 + double(k) / m);
    if (m == 1) ev[0] = -2.0;
    const Vec a = sym_with_eigenvalues(ev, 5u + m);
    const std::string what = std::string(GetParam().name) + " indefinite m = " + std::to_string(m);
    if (GetParam().spd_only) {
      const Vec in = upper_only(a, m, std::numeric_limits<double>::quiet_NaN());
      Vec got = in;
      EXPECT_EQ(GetParam().fn(got.data(), m), 0) << what;
      EXPECT_TRUE(all_same_bits(got, in)) << what << ": A must be left alone on failure";
    } else {
      check_upper_in_lower_out(GetParam().fn, a, m, std::numeric_limits<double>::quiet_NaN(), what);
    }
  }
}

TEST_P(SymInverse, SingularMatrixFails) {
  // B^T B for an integer (m-1) x m matrix B: symmetric, exactly of rank m - 1.
  for (int m : {1, 3, 7, 12}) {
    Vec a(std::size_t(m) * m, 0.0);
    for (int r = 0; r + 1 < m; ++r)
      for (int i = 0; i < m; ++i)
        for (int j = 0; j < m; ++j)
          a[i * m + j] += double((r + 2 * i) % 5 - 2) * double((r + 2 * j) % 5 - 2);
    const Vec in = upper_only(a, m, std::numeric_limits<double>::quiet_NaN());
    Vec got = in;
    EXPECT_EQ(GetParam().fn(got.data(), m), 0) << GetParam().name << " singular m = " << m;
    EXPECT_TRUE(all_same_bits(got, in)) << GetParam().name << ": A must be left alone on failure";
  }
}

INSTANTIATE_TEST_SUITE_P(Dense, SymInverse, testing::ValuesIn(kInverses),
                         [](const testing::TestParamInfo<InvCase> &i) { return i.param.name; });

// ---- the 1.6 contract of sba_Axb_CG: starting point, budget, iteration count ----

// (P)CG as the textbook writes it, in long double, from x0 for exactly k iterations: the
// reference for the iterate the library must return when its budget runs out. a is
// symmetric and row-major.
Vec reference_cg(const Vec &a, const Vec &b, const Vec &x0, int k, int prec) {
  using LD = long double;
  const int m = int(b.size());
  auto matvec = [&](const std::vector<LD> &p) {
    std::vector<LD> q(std::size_t(m), 0.0L);
    for (int i = 0; i < m; ++i)
      for (int j = 0; j < m; ++j) q[i] += LD(a[i * m + j]) * p[j];
    return q;
  };
  // z = M^-1 r; SSOR (omega = 1) is M = (D + L) D^-1 (D + L^T).
  auto apply_prec = [&](const std::vector<LD> &r) {
    std::vector<LD> z(r);
    if (prec == SBA_CG_JACOBI) {
      for (int i = 0; i < m; ++i) z[i] = r[i] / LD(a[i * m + i]);
    } else if (prec == SBA_CG_SSOR) {
      std::vector<LD> y(static_cast<std::size_t>(m));
      for (int i = 0; i < m; ++i) {  // (D + L) y = r
        LD s = r[i];
        for (int j = 0; j < i; ++j) s -= LD(a[i * m + j]) * y[j];
        y[i] = s / LD(a[i * m + i]);
      }
      for (int i = m - 1; i >= 0; --i) {  // (D + L^T) z = D y
        LD s = LD(a[i * m + i]) * y[i];
        for (int j = i + 1; j < m; ++j) s -= LD(a[i * m + j]) * z[j];
        z[i] = s / LD(a[i * m + i]);
      }
    }
    return z;
  };
  std::vector<LD> x(x0.begin(), x0.end()), r(static_cast<std::size_t>(m));
  const std::vector<LD> ax = matvec(x);
  for (int i = 0; i < m; ++i) r[i] = LD(b[i]) - ax[i];
  std::vector<LD> z = apply_prec(r), p = z;
  LD rz = 0.0L;
  for (int i = 0; i < m; ++i) rz += r[i] * z[i];
  for (int it = 0; it < k; ++it) {
    const std::vector<LD> q = matvec(p);
    LD pq = 0.0L;
    for (int i = 0; i < m; ++i) pq += p[i] * q[i];
    const LD alpha = rz / pq;
    for (int i = 0; i < m; ++i) {
      x[i] += alpha * p[i];
      r[i] -= alpha * q[i];
    }
    z = apply_prec(r);
    LD rz1 = 0.0L;
    for (int i = 0; i < m; ++i) rz1 += r[i] * z[i];
    for (int i = 0; i < m; ++i) p[i] = z[i] + (rz1 / rz) * p[i];
    rz = rz1;
  }
  return Vec(x.begin(), x.end());
}

double residual_norm(const Vec &a, const Vec &b, const Vec &x, bool colmaj) {
  const Vec ax = apply(a, int(b.size()), colmaj, x);
  double s = 0.0;
  for (std::size_t i = 0; i < b.size(); ++i) s += (b[i] - ax[i]) * (b[i] - ax[i]);
  return std::sqrt(s);
}

// diag(1, 1, 1, 2, 2, 2, 3, 3, 3): three distinct eigenvalues, so CG from any start whose
// residual touches all three eigenspaces ends in exactly three steps in exact arithmetic.
Vec three_eigenvalue_diagonal() {
  Vec a(81, 0.0);
  for (int i = 0; i < 9; ++i) a[i * 9 + i] = double(1 + i / 3);
  return a;
}
const Vec kX9 = {1, -2, 3, -1, 2, -3, 1, 1, -1};

// 1.6's count: k updates of x, then the iteration whose residual test sees convergence.
TEST_P(Cg, CountsIterationsAsSba16) {
  const int prec = GetParam().prec;
  // Jacobi and SSOR (which is Jacobi for a diagonal matrix) turn it into the identity:
  // one step. Without a preconditioner: one step per distinct eigenvalue.
  const int want = (prec == SBA_CG_NOPREC ? 3 : 1) + 1;
  const Vec a = three_eigenvalue_diagonal();
  for (bool colmaj : {false, true}) {
    const Vec b = apply(a, 9, colmaj, kX9);
    Vec x(9, 99.0);
    EXPECT_EQ(cg_checked(a, b, x, 20, 1e-10, prec, colmaj), want) << "colmaj " << colmaj;
    expect_vec_near(x, kX9, 1e-14, "diagonal");
  }
  // The same spectrum behind a dense matrix: only for the plain method, since the
  // preconditioners no longer whiten it.
  if (prec == SBA_CG_NOPREC) {
    const Vec d = sym_with_eigenvalues({1, 2, 3, 1, 2, 3, 1, 2, 3}, 11u);
    for (bool colmaj : {false, true}) {
      const Vec b = apply(d, 9, colmaj, kX9);
      Vec x(9, 0.0);
      EXPECT_EQ(cg_checked(d, b, x, 20, 1e-10, prec, colmaj), 4) << "dense, colmaj " << colmaj;
      // A budget of exactly the three updates does not reach the fourth iteration's test.
      x.assign(9, 0.0);
      EXPECT_EQ(cg_checked(d, b, x, 3, 1e-10, prec, colmaj), 3) << "budget 3, colmaj " << colmaj;
      expect_vec_near(x, kX9, 1e-12, "dense, budget of three");
      expect_vec_near(x, kX9, 1e-12, "dense, three eigenvalues");
    }
  }
}

TEST_P(Cg, NegativeNiterStartsFromX) {
  const int prec = GetParam().prec;
  for (bool colmaj : {false, true}) {
    // Starting at the exact solution (the residual is exactly zero in integer arithmetic):
    // nothing to do, reported as one iteration because 0 means failure, and x is kept.
    const Vec b = apply(kSpd, kM, colmaj, kXTrue);
    Vec x = kXTrue;
    EXPECT_EQ(cg_checked(kSpd, b, x, -10, 1e-12, prec, colmaj), 1) << "colmaj " << colmaj;
    EXPECT_TRUE(all_same_bits(x, kXTrue)) << "x must stay the exact solution";
    // From elsewhere: the same answer.
    x = {10, 20, -30, 40};
    const int it = cg_checked(kSpd, b, x, -10, 1e-13, prec, colmaj);
    EXPECT_GE(it, 2);
    EXPECT_LE(it, kM + 1);
    expect_vec_near(x, kXTrue, 1e-10, "from a starting point");
  }
}

TEST(DenseCg, NegativeNiterUsesTheStartingPoint) {
  // The error x0 - x* lies in the eigenspace of eigenvalue 2 alone: one step from x0, where
  // the zero start needs three.
  const Vec a = three_eigenvalue_diagonal();
  const Vec b = apply(a, 9, false, kX9);
  Vec x = kX9;
  x[3] += 5.0;
  x[4] -= 2.0;
  x[5] += 1.0;
  EXPECT_EQ(cg_checked(a, b, x, -9, 1e-12, SBA_CG_NOPREC, false), 2);
  expect_vec_near(x, kX9, 1e-14, "one step from x0");
  Vec y = x;
  y[3] += 5.0;
  EXPECT_EQ(cg_checked(a, b, y, 9, 1e-12, SBA_CG_NOPREC, false), 4) << "niter > 0 ignores x";
  // A non-finite starting point is refused and left as it was.
  Vec bad(9, 0.0);
  bad[2] = std::numeric_limits<double>::infinity();
  const Vec bad_in = bad;
  EXPECT_EQ(cg_checked(a, b, bad, -9, 1e-12, SBA_CG_NOPREC, false), 0);
  EXPECT_TRUE(all_same_bits(bad, bad_in));
}

// 20 x 20 SPD with eigenvalues from 1 to 1e6 (geometric): three iterations come nowhere
// near 1e-12.
Vec ill_conditioned_20() {
  Vec ev(20);
  for (int k = 0; k < 20; ++k) ev[k] = std::pow(10.0, 6.0 * k / 19.0);
  return sym_with_eigenvalues(ev, 2024u);
}

TEST_P(Cg, BudgetExhaustedReturnsTheLastIterate) {
  const int prec = GetParam().prec;
  const int m = 20;
  const Vec a = ill_conditioned_20();
  Vec xt(m);
  for (int i = 0; i < m; ++i) xt[i] = double(i % 7) - 3.0;
  for (bool colmaj : {false, true}) {
    const Vec b = apply(a, m, colmaj, xt);
    const double r0 = residual_norm(a, b, Vec(m, 0.0), colmaj);
    Vec x(m, 99.0);
    EXPECT_EQ(cg_checked(a, b, x, 3, 1e-12, prec, colmaj), 3) << "colmaj " << colmaj;
    const Vec want = reference_cg(a, b, Vec(m, 0.0), 3, prec);
    expect_vec_near(x, want, 1e-9, "third iterate from 0");
    EXPECT_LT(residual_norm(a, b, x, colmaj), r0);
    EXPECT_GT(residual_norm(a, b, x, colmaj), 1e-6 * r0) << "not converged";

    // The same from a starting point, with niter < 0.
    Vec x0(m);
    for (int i = 0; i < m; ++i) x0[i] = 0.5 * double(i % 3);
    Vec y = x0;
    EXPECT_EQ(cg_checked(a, b, y, -3, 1e-12, prec, colmaj), 3) << "colmaj " << colmaj;
    expect_vec_near(y, reference_cg(a, b, x0, 3, prec), 1e-9, "third iterate from x0");
    EXPECT_LT(residual_norm(a, b, y, colmaj), residual_norm(a, b, x0, colmaj));
  }
}

}  // namespace
