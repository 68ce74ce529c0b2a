// SPDX-License-Identifier: BSD-3-Clause
// The eucsbademo camera model (analytic Jacobians against finite differences, the rotation
// parametrization, held intrinsics) and its file readers and writers, including the initial
// errors sba 1.6 publishes for its demo data.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <random>
#include <regex>
#include <string>
#include <vector>

#include <unistd.h>

#include "cameras/euclidean.h"
#include "formats/eucsba_io.h"

namespace fs = std::filesystem;
using namespace sbacameras::euclidean;
using namespace sbaformats::eucsba;

namespace {

const CameraKind kAllKinds[] = {CameraKind::FixedIntrinsics, CameraKind::VaryingIntrinsics,
                                CameraKind::VaryingIntrinsicsDistortion};

const char *kind_name(CameraKind kind) {
  switch (kind) {
    case CameraKind::FixedIntrinsics: return "fixed K";
    case CameraKind::VaryingIntrinsics: return "varying K";
    case CameraKind::VaryingIntrinsicsDistortion: return "varying K + distortion";
  }
  return "";
}

// Offsets of the blocks inside a camera's parameter vector (the documented layout).
int intr_offset(CameraKind kind) { return kind == CameraKind::FixedIntrinsics ? -1 : 0; }
int dist_offset(CameraKind kind) { return kind == CameraKind::VaryingIntrinsicsDistortion ? 5 : -1; }
int rot_offset(CameraKind kind) { return camera_params(kind) - 6; }

// A random scene: m cameras about 6 units from points spread over [-2, 2]^3, so that
// projections reach a normalized radius of about 0.4 and distortion matters.
struct Scene {
  std::vector<Camera> cameras;
  std::vector<double> points;
};

Scene random_scene(int m, int n, std::mt19937 &rng) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  Scene s;
  for (int j = 0; j < m; ++j) {
    Camera c;
    c.k = {800 + 50 * u(rng), 320 + 10 * u(rng), 240 + 10 * u(rng), 1 + 0.05 * u(rng), 0.5 * u(rng)};
    c.kc = {-0.2 + 0.05 * u(rng), 0.05 * u(rng), 0.002 * u(rng), 0.002 * u(rng), 0.02 * u(rng)};
    // Not normalized and possibly with w < 0: the model must cope.
    c.q = {u(rng), u(rng), u(rng), u(rng)};
    c.q.w *= 3;
    c.t = {0.5 * u(rng), 0.5 * u(rng), 6 + 0.5 * u(rng)};
    s.cameras.push_back(c);
  }
  for (int i = 0; i < 3 * n; ++i) s.points.push_back(1.5 * u(rng));
  return s;
}

// Moves a camera away from its initial parameters, rotation included, so Jacobians are not
// only checked at v = 0.
std::vector<double> perturbed_cameras(const CameraModel &model, std::mt19937 &rng, double vnorm = 0.15) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<double> a = model.initial_camera_params();
  const int cnp = model.cnp();
  for (int j = 0; j < model.ncameras(); ++j) {
    double *aj = &a[j * cnp];
    for (int c = 0; c < cnp; ++c) aj[c] += 1e-3 * std::fabs(aj[c]) * u(rng);
    double v[3] = {u(rng), u(rng), u(rng)};
    const double norm = std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    for (int r = 0; r < 3; ++r) aj[rot_offset(model.kind()) + r] = vnorm * v[r] / norm;
  }
  return a;
}

double step_for(double value) { return 1e-6 * std::max(1.0, std::fabs(value)); }

// Central differences of model.project for one projection; A (2 x cnp) and B (2 x 3).
void numeric_jacobian(const CameraModel &model, int j, const double *a, const double *b,
                      std::vector<double> *A, std::vector<double> *B) {
  const int cnp = model.cnp();
  A->assign(2 * cnp, 0.0);
  B->assign(6, 0.0);
  std::vector<double> ap(a, a + cnp), bp(b, b + 3);
  double xp[2], xm[2];
  for (int c = 0; c < cnp; ++c) {
    const double h = step_for(ap[c]), saved = ap[c];
    ap[c] = saved + h;
    model.project(j, ap.data(), b, xp);
    ap[c] = saved - h;
    model.project(j, ap.data(), b, xm);
    ap[c] = saved;
    for (int r = 0; r < 2; ++r) (*A)[r * cnp + c] = (xp[r] - xm[r]) / (2 * h);
  }
  for (int c = 0; c < 3; ++c) {
    const double h = step_for(bp[c]), saved = bp[c];
    bp[c] = saved + h;
    model.project(j, a, bp.data(), xp);
    bp[c] = saved - h;
    model.project(j, a, bp.data(), xm);
    bp[c] = saved;
    for (int r = 0; r < 2; ++r) (*B)[r * 3 + c] = (xp[r] - xm[r]) / (2 * h);
  }
}

// Analytic against numeric, row by row, relative to the largest entry of the row.
void expect_jacobians_agree(const CameraModel &model, int j, const double *a, const double *b,
                            double rel_tol = 1e-6) {
  const int cnp = model.cnp();
  std::vector<double> A(2 * cnp), B(6), An, Bn;
  double x[2];
  model.project_jacobian(j, a, b, x, A.data(), B.data());
  numeric_jacobian(model, j, a, b, &An, &Bn);
  for (int r = 0; r < 2; ++r) {
    double scale = 0;
    for (int c = 0; c < cnp; ++c) scale = std::max(scale, std::fabs(An[r * cnp + c]));
    for (int c = 0; c < 3; ++c) scale = std::max(scale, std::fabs(Bn[r * 3 + c]));
    for (int c = 0; c < cnp; ++c)
      EXPECT_NEAR(A[r * cnp + c], An[r * cnp + c], rel_tol * scale)
          << kind_name(model.kind()) << " camera " << j << " dA row " << r << " col " << c;
    for (int c = 0; c < 3; ++c)
      EXPECT_NEAR(B[r * 3 + c], Bn[r * 3 + c], rel_tol * scale)
          << kind_name(model.kind()) << " camera " << j << " dB row " << r << " col " << c;
  }
}

// The row-compressed visibility index the drivers hand to the expert callbacks.
struct Index {
  std::vector<int> rowptr, colidx, val;
  sba_crsm crsm{};
  std::vector<int> scratch1, scratch2;
};

Index make_index(const std::vector<char> &vmask, int n, int m) {
  Index idx;
  idx.rowptr.push_back(0);
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < m; ++j)
      if (vmask[i * m + j]) {
        idx.colidx.push_back(j);
        idx.val.push_back(static_cast<int>(idx.val.size()));
      }
    idx.rowptr.push_back(static_cast<int>(idx.colidx.size()));
  }
  idx.crsm = {n, m, static_cast<int>(idx.val.size()), idx.val.data(), idx.colidx.data(), idx.rowptr.data()};
  idx.scratch1.assign(std::max(n, m), 0);
  idx.scratch2.assign(std::max(n, m), 0);
  return idx;
}

double sum_of_squares(const std::vector<double> &a, const std::vector<double> &b) {
  double s = 0;
  for (std::size_t k = 0; k < a.size(); ++k) s += (a[k] - b[k]) * (a[k] - b[k]);
  return s;
}

std::string shared_demo_dir() { return std::string(SBA_SHARED_DATA_DIR) + "/sba-demo"; }

}  // namespace

// ---------------------------------------------------------------------------------------------
// Quaternions and the local rotation parametrization

TEST(Quaternion, ProductMatchesRotationComposition) {
  std::mt19937 rng(1);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (int trial = 0; trial < 20; ++trial) {
    const Quaternion a = normalized_rotation({u(rng), u(rng), u(rng), u(rng)});
    const Quaternion b = normalized_rotation({u(rng), u(rng), u(rng), u(rng)});
    double Ra[9], Rb[9], Rab[9];
    rotation_matrix(a, Ra);
    rotation_matrix(b, Rb);
    rotation_matrix(multiply(a, b), Rab);
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) {
        double expected = 0;
        for (int k = 0; k < 3; ++k) expected += Ra[r * 3 + k] * Rb[k * 3 + c];
        EXPECT_NEAR(Rab[r * 3 + c], expected, 1e-14);
      }
    // R is orthonormal with determinant +1.
    for (int r = 0; r < 3; ++r)
      for (int s = 0; s < 3; ++s) {
        double dot = 0;
        for (int k = 0; k < 3; ++k) dot += Ra[r * 3 + k] * Ra[s * 3 + k];
        EXPECT_NEAR(dot, r == s ? 1.0 : 0.0, 1e-14);
      }
  }
  const Quaternion id = multiply({1, 0, 0, 0}, {0.5, 0.5, 0.5, 0.5});
  EXPECT_DOUBLE_EQ(id.w, 0.5);
  EXPECT_DOUBLE_EQ(id.z, 0.5);
}

TEST(Quaternion, RotationMatrixIsTheStandardOne) {
  // 90 degrees about z takes x to y.
  const double h = std::sqrt(0.5);
  double R[9];
  rotation_matrix({h, 0, 0, h}, R);
  const double X[3] = {1, 0, 0};
  EXPECT_NEAR(R[0] * X[0] + R[1] * X[1] + R[2] * X[2], 0.0, 1e-15);
  EXPECT_NEAR(R[3] * X[0] + R[4] * X[1] + R[5] * X[2], 1.0, 1e-15);
  EXPECT_NEAR(R[6] * X[0] + R[7] * X[1] + R[8] * X[2], 0.0, 1e-15);
}

TEST(Quaternion, NormalizedRotationHasUnitNormAndNonNegativeScalar) {
  const Quaternion q = normalized_rotation({-2, 1, -1, 0.5});
  EXPECT_NEAR(q.w * q.w + q.x * q.x + q.y * q.y + q.z * q.z, 1.0, 1e-15);
  EXPECT_GE(q.w, 0.0);
  EXPECT_NEAR(q.x, -1 / std::sqrt(6.25), 1e-15);  // negated with the scalar part
}

// The squares of components near 1e308 overflow and those near 1e-200 underflow: neither may
// lose the rotation.
TEST(Quaternion, NormalizedRotationOfAnyNonzeroSize) {
  const double h = std::sqrt(0.5);
  const struct {
    Quaternion q, unit;
  } cases[] = {{{1e308, 1e308, 0, 0}, {h, h, 0, 0}},
               {{1.7e308, -1.7e308, 1.7e308, -1.7e308}, {0.5, -0.5, 0.5, -0.5}},
               {{-1e-200, 0, 0, 1e-200}, {h, 0, 0, -h}},
               {{0, 0, 4.9e-324, 0}, {0, 0, 1, 0}}};
  for (const auto &c : cases) {
    const Quaternion q = normalized_rotation(c.q);
    EXPECT_NEAR(q.w, c.unit.w, 1e-15) << c.q.w;
    EXPECT_NEAR(q.x, c.unit.x, 1e-15) << c.q.w;
    EXPECT_NEAR(q.y, c.unit.y, 1e-15) << c.q.w;
    EXPECT_NEAR(q.z, c.unit.z, 1e-15) << c.q.w;
  }
}

TEST(CameraModel, ZeroCorrectionGivesTheInputRotation) {
  std::mt19937 rng(2);
  for (CameraKind kind : kAllKinds) {
    const Scene scene = random_scene(4, 1, rng);
    const CameraModel model(kind, scene.cameras, scene.points, 0, 0);
    for (int j = 0; j < model.ncameras(); ++j) {
      const Camera c = model.camera(j, model.initial_camera(j));
      const Quaternion q0 = normalized_rotation(scene.cameras[j].q);
      EXPECT_NEAR(c.q.w, q0.w, 1e-15);
      EXPECT_NEAR(c.q.x, q0.x, 1e-15);
      EXPECT_NEAR(c.q.y, q0.y, 1e-15);
      EXPECT_NEAR(c.q.z, q0.z, 1e-15);
      for (int r = 0; r < 3; ++r) EXPECT_EQ(c.t[r], scene.cameras[j].t[r]);
      if (kind != CameraKind::FixedIntrinsics) EXPECT_EQ(c.k.fu, scene.cameras[j].k.fu);
    }
  }
}

TEST(CameraModel, CorrectedCameraIsUnitWithNonNegativeScalarAndProjectsTheSame) {
  std::mt19937 rng(3);
  for (CameraKind kind : kAllKinds) {
    const Scene scene = random_scene(5, 6, rng);
    const CameraModel model(kind, scene.cameras, scene.points, 0, 0);
    const std::vector<double> a = perturbed_cameras(model, rng, 0.4);
    std::vector<Camera> decoded;
    for (int j = 0; j < model.ncameras(); ++j) {
      const Camera c = model.camera(j, &a[j * model.cnp()]);
      EXPECT_NEAR(c.q.w * c.q.w + c.q.x * c.q.x + c.q.y * c.q.y + c.q.z * c.q.z, 1.0, 1e-14);
      EXPECT_GE(c.q.w, 0.0);
      decoded.push_back(c);
    }
    // A model started from the decoded cameras (v = 0) predicts what the corrected one did.
    const CameraModel restarted(kind, decoded, scene.points, 0, 0);
    for (int j = 0; j < model.ncameras(); ++j)
      for (int i = 0; i < model.npoints(); ++i) {
        double x1[2], x2[2];
        model.project(j, &a[j * model.cnp()], model.initial_point(i), x1);
        restarted.project(j, restarted.initial_camera(j), restarted.initial_point(i), x2);
        EXPECT_NEAR(x1[0], x2[0], 1e-9 * std::fabs(x1[0]));
        EXPECT_NEAR(x1[1], x2[1], 1e-9 * std::fabs(x1[1]));
      }
  }
}

TEST(CameraModel, ProjectionMatchesTheSpecFormula) {
  // One camera by hand: q0 = identity, v = 0, t = (0.1, -0.2, 5), X = (0.3, 0.4, 1).
  Camera c;
  c.k = {800, 320, 240, 1.1, 0.7};
  c.kc = {-0.2, 0.05, 0.001, -0.002, 0.01};
  c.t = {0.1, -0.2, 5};
  const std::vector<double> X = {0.3, 0.4, 1};
  const double xn = 0.4 / 6, yn = 0.2 / 6, r2 = xn * xn + yn * yn;
  const double radial = 1 + c.kc[0] * r2 + c.kc[1] * r2 * r2 + c.kc[4] * r2 * r2 * r2;
  const double xd = radial * xn + 2 * c.kc[2] * xn * yn + c.kc[3] * (r2 + 2 * xn * xn);
  const double yd = radial * yn + c.kc[2] * (r2 + 2 * yn * yn) + 2 * c.kc[3] * xn * yn;

  const CameraModel with(CameraKind::VaryingIntrinsicsDistortion, {c}, X, 0, 0);
  double x[2];
  with.project(0, with.initial_camera(0), with.initial_point(0), x);
  EXPECT_NEAR(x[0], 800 * xd + 0.7 * yd + 320, 1e-10);
  EXPECT_NEAR(x[1], 800 * 1.1 * yd + 240, 1e-10);

  const CameraModel without(CameraKind::VaryingIntrinsics, {c}, X, 0, 0);
  without.project(0, without.initial_camera(0), without.initial_point(0), x);
  EXPECT_NEAR(x[0], 800 * xn + 0.7 * yn + 320, 1e-10);
  EXPECT_NEAR(x[1], 800 * 1.1 * yn + 240, 1e-10);
}

// The C callbacks of the MATLAB/Octave interface (matlab/sbaeuc_proj.c), compiled into this test.
extern "C" {
void sbaeuc_proj(int j, int i, double *aj, double *bi, double *xij, double **adata);
void sbaeuc_projac(int j, int i, double *aj, double *bi, double *Aij, double *Bij, double **adata);
}

TEST(CameraModel, MexCallbacksAreTheFixedIntrinsicsCamera) {
  // They take their rotation from the same code as the model (euclidean_rotation.h) but
  // compose the camera's two rotations in the other order, so they agree up to rounding:
  // inside the unit ball and outside it, where both use the boundary rotation.
  std::mt19937 rng(11);
  Scene scene = random_scene(5, 7, rng);
  const Intrinsics k = scene.cameras[0].k;
  for (Camera &c : scene.cameras) c.k = k;
  const CameraModel model(CameraKind::FixedIntrinsics, scene.cameras, scene.points);
  std::vector<double> q0, cal = {k.fu, k.u0, k.v0, k.ar, k.s};
  for (int j = 0; j < model.ncameras(); ++j) {
    const Quaternion &q = model.input_camera(j).q;
    q0.insert(q0.end(), {q.w, q.x, q.y, q.z});
  }
  double *adata[2] = {q0.data(), cal.data()};
  for (double vnorm : {0.15, 1.5}) {
    std::vector<double> a = perturbed_cameras(model, rng, vnorm);
    for (int j = 0; j < model.ncameras(); ++j)
      for (int i = 0; i < model.npoints(); ++i) {
        double *aj = &a[j * 6], b[3];
        std::copy(model.initial_point(i), model.initial_point(i) + 3, b);
        double x[2], A[12], B[6], xc[2], Ac[12], Bc[6];
        model.project_jacobian(j, aj, b, x, A, B);
        sbaeuc_proj(j, i, aj, b, xc, adata);
        sbaeuc_projac(j, i, aj, b, Ac, Bc, adata);
        for (int r = 0; r < 2; ++r) {
          EXPECT_NEAR(xc[r], x[r], 1e-10 * std::fabs(x[r])) << "camera " << j << " point " << i;
          double scale = 0;
          for (int c = 0; c < 6; ++c) scale = std::max(scale, std::fabs(A[r * 6 + c]));
          for (int c = 0; c < 3; ++c) scale = std::max(scale, std::fabs(B[r * 3 + c]));
          for (int c = 0; c < 6; ++c)
            EXPECT_NEAR(Ac[r * 6 + c], A[r * 6 + c], 1e-10 * scale) << "dA row " << r << " col " << c;
          for (int c = 0; c < 3; ++c)
            EXPECT_NEAR(Bc[r * 3 + c], B[r * 3 + c], 1e-10 * scale) << "dB row " << r << " col " << c;
        }
      }
  }
}

TEST(CameraModel, RejectsBadConstructorArguments) {
  Camera c;
  EXPECT_THROW(CameraModel(CameraKind::VaryingIntrinsics, {c}, {0, 0, 1}, 6, 3), std::invalid_argument);
  EXPECT_THROW(CameraModel(CameraKind::VaryingIntrinsics, {c}, {0, 0, 1}, 2, -1), std::invalid_argument);
  EXPECT_THROW(CameraModel(CameraKind::FixedIntrinsics, {c}, {0, 0}, 2, 3), std::invalid_argument);
  c.q = {0, 0, 0, 0};
  EXPECT_THROW(CameraModel(CameraKind::FixedIntrinsics, {c}, {0, 0, 1}, 2, 3), std::invalid_argument);
}

// ---------------------------------------------------------------------------------------------
// Jacobians against finite differences

TEST(Jacobian, AnalyticMatchesFiniteDifferencesForAllModels) {
  std::mt19937 rng(4);
  for (CameraKind kind : kAllKinds) {
    const Scene scene = random_scene(6, 8, rng);
    const CameraModel model(kind, scene.cameras, scene.points, 0, 0);
    for (double vnorm : {0.0, 0.15, 0.6}) {
      const std::vector<double> a = perturbed_cameras(model, rng, vnorm);
      for (int j = 0; j < model.ncameras(); ++j)
        for (int i = 0; i < model.npoints(); ++i)
          expect_jacobians_agree(model, j, &a[j * model.cnp()], model.initial_point(i));
    }
  }
}

TEST(Jacobian, StaysConsistentOutsideTheUnitBall) {
  // A wild trial step can give |v| > 1; the model then uses the boundary rotation and must
  // stay finite with a matching Jacobian.
  std::mt19937 rng(5);
  const Scene scene = random_scene(3, 4, rng);
  const CameraModel model(CameraKind::VaryingIntrinsics, scene.cameras, scene.points, 0, 0);
  const std::vector<double> a = perturbed_cameras(model, rng, 1.7);
  for (int j = 0; j < model.ncameras(); ++j)
    for (int i = 0; i < model.npoints(); ++i) {
      double x[2];
      model.project(j, &a[j * model.cnp()], model.initial_point(i), x);
      EXPECT_TRUE(std::isfinite(x[0]) && std::isfinite(x[1]));
      expect_jacobians_agree(model, j, &a[j * model.cnp()], model.initial_point(i));
    }
}

TEST(Jacobian, AtPointFormAgreesWithTheCallbacksForm) {
  // project_jacobian (the per-camera tensor of the callbacks) and project_jacobian_at_point
  // (the benchmark's Ceres cost) are the same derivative in another order of operations:
  // equal to rounding, inside the unit ball and on its boundary rotation (|v| > 1).
  std::mt19937 rng(12);
  for (CameraKind kind : kAllKinds) {
    const Scene scene = random_scene(4, 5, rng);
    const CameraModel model(kind, scene.cameras, scene.points, 1, 2);
    const int cnp = model.cnp();
    for (double vnorm : {0.0, 0.3, 1.7}) {
      const std::vector<double> a = perturbed_cameras(model, rng, vnorm);
      for (int j = 0; j < model.ncameras(); ++j)
        for (int i = 0; i < model.npoints(); ++i) {
          double x1[2], x2[2], A1[32], A2[32], B1[6], B2[6];
          model.project_jacobian(j, &a[j * cnp], model.initial_point(i), x1, A1, B1);
          model.project_jacobian_at_point(j, &a[j * cnp], model.initial_point(i), x2, A2, B2);
          double scale = 1.0;
          for (int c = 0; c < 2 * cnp; ++c) scale = std::max(scale, std::fabs(A1[c]));
          for (int c = 0; c < 6; ++c) scale = std::max(scale, std::fabs(B1[c]));
          for (int r = 0; r < 2; ++r) EXPECT_NEAR(x1[r], x2[r], 1e-12 * std::max(1.0, std::fabs(x1[r])));
          for (int c = 0; c < 2 * cnp; ++c) EXPECT_NEAR(A1[c], A2[c], 1e-12 * scale) << "A column " << c % cnp;
          for (int c = 0; c < 6; ++c) EXPECT_NEAR(B1[c], B2[c], 1e-12 * scale);
        }
    }
  }
}
TEST(Jacobian, HeldIntrinsicsHaveZeroColumnsForEveryNccalib) {
  std::mt19937 rng(6);
  for (CameraKind kind : {CameraKind::VaryingIntrinsics, CameraKind::VaryingIntrinsicsDistortion}) {
    const Scene scene = random_scene(2, 3, rng);
    for (int nccalib = 0; nccalib <= 5; ++nccalib) {
      const CameraModel model(kind, scene.cameras, scene.points, nccalib, 0);
      const std::vector<double> a = perturbed_cameras(model, rng);
      const int cnp = model.cnp();
      for (int j = 0; j < model.ncameras(); ++j)
        for (int i = 0; i < model.npoints(); ++i) {
          std::vector<double> A(2 * cnp), B(6);
          model.project_jacobian(j, &a[j * cnp], model.initial_point(i), nullptr, A.data(), B.data());
          for (int c = 0; c < kIntrinsicParams; ++c) {
            const bool held = c >= kIntrinsicParams - nccalib;
            const double col = std::fabs(A[c]) + std::fabs(A[cnp + c]);
            if (held) EXPECT_EQ(col, 0.0) << "nccalib " << nccalib << " intrinsic " << c;
            else EXPECT_GT(col, 0.0) << "nccalib " << nccalib << " intrinsic " << c;
          }
          // The distortion and pose columns are untouched.
          for (int c = kIntrinsicParams; c < cnp; ++c)
            EXPECT_GT(std::fabs(A[c]) + std::fabs(A[cnp + c]), 0.0) << "nccalib " << nccalib << " col " << c;
          // Held values are constants of the model, so finite differences agree too.
          expect_jacobians_agree(model, j, &a[j * cnp], model.initial_point(i));
        }
    }
  }
}

TEST(Jacobian, HeldDistortionTermsHaveZeroColumnsForEveryNcdist) {
  std::mt19937 rng(7);
  const CameraKind kind = CameraKind::VaryingIntrinsicsDistortion;
  const Scene scene = random_scene(2, 3, rng);
  for (int ncdist = 0; ncdist <= 5; ++ncdist) {
    const CameraModel model(kind, scene.cameras, scene.points, 0, ncdist);
    const std::vector<double> a = perturbed_cameras(model, rng);
    const int cnp = model.cnp(), off = dist_offset(kind);
    for (int j = 0; j < model.ncameras(); ++j)
      for (int i = 0; i < model.npoints(); ++i) {
        std::vector<double> A(2 * cnp);
        model.project_jacobian(j, &a[j * cnp], model.initial_point(i), nullptr, A.data(), nullptr);
        for (int c = 0; c < kDistortionParams; ++c) {
          const bool held = c >= kDistortionParams - ncdist;
          const double col = std::fabs(A[off + c]) + std::fabs(A[cnp + off + c]);
          if (held) EXPECT_EQ(col, 0.0) << "ncdist " << ncdist << " kc" << c;
          else EXPECT_GT(col, 0.0) << "ncdist " << ncdist << " kc" << c;
        }
        for (int c = 0; c < kIntrinsicParams; ++c)  // nccalib 0: all intrinsics free
          EXPECT_GT(std::fabs(A[c]) + std::fabs(A[cnp + c]), 0.0) << "ncdist " << ncdist << " intrinsic " << c;
        expect_jacobians_agree(model, j, &a[j * cnp], model.initial_point(i));
      }
  }
}

TEST(Jacobian, HeldParametersKeepTheirInitialValuesWhateverPHolds) {
  std::mt19937 rng(8);
  const Scene scene = random_scene(1, 1, rng);
  const CameraModel model(CameraKind::VaryingIntrinsicsDistortion, scene.cameras, scene.points, 2, 3);
  std::vector<double> a = model.initial_camera_params();
  double x0[2], x1[2];
  model.project(0, a.data(), model.initial_point(0), x0);
  a[3] *= 1.5;  // ar, held by nccalib 2
  a[4] += 10;   // s
  a[7] += 0.1;  // kc2, held by ncdist 3
  a[9] += 0.1;  // kc4
  model.project(0, a.data(), model.initial_point(0), x1);
  EXPECT_EQ(x0[0], x1[0]);
  EXPECT_EQ(x0[1], x1[1]);
  const Camera c = model.camera(0, a.data());
  EXPECT_EQ(c.k.ar, scene.cameras[0].k.ar);
  EXPECT_EQ(c.kc[4], scene.cameras[0].kc[4]);
  a[0] += 1;  // fu is free
  EXPECT_EQ(model.camera(0, a.data()).k.fu, a[0]);
}

// ---------------------------------------------------------------------------------------------
// The sba callbacks

namespace {

// A small problem with a few holes in the visibility.
struct SmallProblem {
  int n = 7, m = 4;
  std::vector<char> vmask;
  Index idx;
  SmallProblem() {
    vmask.assign(n * m, 1);
    vmask[0 * m + 1] = 0;
    vmask[2 * m + 0] = 0;
    vmask[2 * m + 3] = 0;
    vmask[5 * m + 2] = 0;
    idx = make_index(vmask, n, m);
  }
  int nvis() const { return idx.crsm.nnz; }
};

// Central-difference Jacobian of an expert func over all of p (dense, nvis*2 x p.size()).
std::vector<double> dense_numeric(ExpertFn func, std::vector<double> p, Index &idx, void *adata) {
  const int rows = 2 * idx.crsm.nnz, cols = static_cast<int>(p.size());
  std::vector<double> J(static_cast<std::size_t>(rows) * cols), hp(rows), hm(rows);
  for (int c = 0; c < cols; ++c) {
    const double h = step_for(p[c]), saved = p[c];
    p[c] = saved + h;
    func(p.data(), &idx.crsm, idx.scratch1.data(), idx.scratch2.data(), hp.data(), adata);
    p[c] = saved - h;
    func(p.data(), &idx.crsm, idx.scratch1.data(), idx.scratch2.data(), hm.data(), adata);
    p[c] = saved;
    for (int r = 0; r < rows; ++r) J[static_cast<std::size_t>(r) * cols + c] = (hp[r] - hm[r]) / (2 * h);
  }
  return J;
}

// Checks fjac's blocks against the dense numeric Jacobian: the blocks where they belong, and
// zeros (in the numeric one) everywhere else.
void check_expert(const CameraModel &model, Refinement refinement, const std::vector<double> &p) {
  SmallProblem sp;
  Index &idx = sp.idx;
  const ExpertCallbacks cb = expert_callbacks(model.kind(), refinement);
  const int cnp = model.cnp(), m = model.ncameras();
  const int acols = refinement == Refinement::Structure ? 0 : cnp;
  const int bcols = refinement == Refinement::Motion ? 0 : 3;
  const int block = 2 * (acols + bcols);
  std::vector<double> jac(static_cast<std::size_t>(sp.nvis()) * block, -1.0);
  cb.fjac(const_cast<double *>(p.data()), &idx.crsm, idx.scratch1.data(), idx.scratch2.data(),
          jac.data(), as_adata(model));
  const std::vector<double> J = dense_numeric(cb.func, p, idx, as_adata(model));
  const int cols = static_cast<int>(p.size());

  for (int i = 0; i < sp.n; ++i)
    for (int e = idx.rowptr[i]; e < idx.rowptr[i + 1]; ++e) {
      const int j = idx.colidx[e], k = idx.val[e];
      const double *A = &jac[static_cast<std::size_t>(k) * block];
      const double *B = A + 2 * acols;
      for (int r = 0; r < 2; ++r) {
        const double *Jrow = &J[static_cast<std::size_t>(2 * k + r) * cols];
        double scale = 0;
        for (int c = 0; c < cols; ++c) scale = std::max(scale, std::fabs(Jrow[c]));
        const int acol0 = acols ? j * cnp : -1;
        const int bcol0 = bcols ? (refinement == Refinement::Structure ? 0 : m * cnp) + i * 3 : -1;
        for (int c = 0; c < cols; ++c) {
          double analytic = 0;
          if (acols && c >= acol0 && c < acol0 + cnp) analytic = A[r * cnp + c - acol0];
          if (bcols && c >= bcol0 && c < bcol0 + 3) analytic = B[r * 3 + c - bcol0];
          EXPECT_NEAR(analytic, Jrow[c], 1e-6 * scale)
              << kind_name(model.kind()) << " refinement " << static_cast<int>(refinement)
              << " point " << i << " camera " << j << " row " << r << " col " << c;
        }
      }
    }
}

}  // namespace

TEST(Callbacks, ExpertJacobiansMatchFiniteDifferencesInAllModes) {
  std::mt19937 rng(9);
  for (CameraKind kind : kAllKinds) {
    SmallProblem sp;
    const Scene scene = random_scene(sp.m, sp.n, rng);
    const CameraModel model(kind, scene.cameras, scene.points, 1, 2);
    const std::vector<double> a = perturbed_cameras(model, rng);
    std::vector<double> b = scene.points;
    for (double &v : b) v += 0.01;

    std::vector<double> p = a;
    p.insert(p.end(), b.begin(), b.end());
    check_expert(model, Refinement::MotionStructure, p);
    check_expert(model, Refinement::Motion, a);
    check_expert(model, Refinement::Structure, b);
  }
}

TEST(Callbacks, SimpleCallbacksAgreeWithExpertOnes) {
  std::mt19937 rng(10);
  for (CameraKind kind : kAllKinds) {
    SmallProblem sp;
    const Scene scene = random_scene(sp.m, sp.n, rng);
    const CameraModel model(kind, scene.cameras, scene.points, 2, 3);
    void *adata = as_adata(model);
    const int cnp = model.cnp(), nvis = sp.nvis();
    std::vector<double> a = perturbed_cameras(model, rng), b = scene.points;
    for (double &v : b) v *= 1.01;
    std::vector<double> p = a;
    p.insert(p.end(), b.begin(), b.end());

    Index &idx = sp.idx;
    std::vector<double> hx(2 * nvis), hx_mot(2 * nvis), hx_str(2 * nvis);
    std::vector<double> jac(nvis * 2 * (cnp + 3)), jac_mot(nvis * 2 * cnp), jac_str(nvis * 6);
    const ExpertCallbacks ms = expert_callbacks(kind, Refinement::MotionStructure);
    const ExpertCallbacks mo = expert_callbacks(kind, Refinement::Motion);
    const ExpertCallbacks st = expert_callbacks(kind, Refinement::Structure);
    ms.func(p.data(), &idx.crsm, idx.scratch1.data(), idx.scratch2.data(), hx.data(), adata);
    ms.fjac(p.data(), &idx.crsm, idx.scratch1.data(), idx.scratch2.data(), jac.data(), adata);
    mo.func(a.data(), &idx.crsm, idx.scratch1.data(), idx.scratch2.data(), hx_mot.data(), adata);
    mo.fjac(a.data(), &idx.crsm, idx.scratch1.data(), idx.scratch2.data(), jac_mot.data(), adata);
    st.func(b.data(), &idx.crsm, idx.scratch1.data(), idx.scratch2.data(), hx_str.data(), adata);
    st.fjac(b.data(), &idx.crsm, idx.scratch1.data(), idx.scratch2.data(), jac_str.data(), adata);

    const MotStrCallbacks sms = motstr_callbacks(kind);
    const MotCallbacks smo = mot_callbacks(kind);
    const StrCallbacks sst = str_callbacks(kind);
    for (int i = 0; i < sp.n; ++i)
      for (int e = idx.rowptr[i]; e < idx.rowptr[i + 1]; ++e) {
        const int j = idx.colidx[e], k = idx.val[e];
        double *aj = &a[j * cnp], *bi = &b[i * 3];
        double x[2], A[32], B[6];
        sms.proj(j, i, aj, bi, x, adata);
        EXPECT_EQ(x[0], hx[2 * k]);
        EXPECT_EQ(x[1], hx[2 * k + 1]);
        sms.projac(j, i, aj, bi, A, B, adata);
        for (int c = 0; c < 2 * cnp; ++c) EXPECT_EQ(A[c], jac[k * 2 * (cnp + 3) + c]);
        for (int c = 0; c < 6; ++c) EXPECT_EQ(B[c], jac[k * 2 * (cnp + 3) + 2 * cnp + c]);

        // Motion only projects the model's points; structure only its cameras.
        smo.proj(j, i, aj, x, adata);
        EXPECT_EQ(x[0], hx_mot[2 * k]);
        smo.projac(j, i, aj, A, adata);
        for (int c = 0; c < 2 * cnp; ++c) EXPECT_EQ(A[c], jac_mot[k * 2 * cnp + c]);
        double xr[2];
        model.project(j, aj, model.initial_point(i), xr);
        EXPECT_EQ(xr[1], hx_mot[2 * k + 1]);

        sst.proj(j, i, bi, x, adata);
        EXPECT_EQ(x[0], hx_str[2 * k]);
        sst.projac(j, i, bi, B, adata);
        for (int c = 0; c < 6; ++c) EXPECT_EQ(B[c], jac_str[k * 6 + c]);
        model.project(j, model.initial_camera(j), bi, xr);
        EXPECT_EQ(xr[1], hx_str[2 * k + 1]);
      }
  }
}

TEST(Callbacks, WriteAtTheOrdinalTheIndexGives) {
  // val[k] is where projection k of the index goes; the callbacks must not assume val[k] == k.
  std::mt19937 rng(11);
  SmallProblem sp;
  const Scene scene = random_scene(sp.m, sp.n, rng);
  const CameraModel model(CameraKind::FixedIntrinsics, scene.cameras, scene.points);
  std::vector<double> p = model.initial_camera_params();
  p.insert(p.end(), scene.points.begin(), scene.points.end());
  const int nvis = sp.nvis();
  const ExpertCallbacks cb = expert_callbacks(model.kind(), Refinement::MotionStructure);
  std::vector<double> hx(2 * nvis), hx_rev(2 * nvis);
  cb.func(p.data(), &sp.idx.crsm, nullptr, nullptr, hx.data(), as_adata(model));
  Index rev = sp.idx;
  for (int k = 0; k < nvis; ++k) rev.val[k] = nvis - 1 - k;
  rev.crsm.val = rev.val.data();
  rev.crsm.colidx = rev.colidx.data();
  rev.crsm.rowptr = rev.rowptr.data();
  cb.func(p.data(), &rev.crsm, nullptr, nullptr, hx_rev.data(), as_adata(model));
  for (int k = 0; k < nvis; ++k) {
    EXPECT_EQ(hx[2 * k], hx_rev[2 * (nvis - 1 - k)]);
    EXPECT_EQ(hx[2 * k + 1], hx_rev[2 * (nvis - 1 - k) + 1]);
  }
}

// ---------------------------------------------------------------------------------------------
// The shared sba 1.6 demo data: counts and the initial errors 1.6 publishes

namespace {

struct DemoCase {
  const char *cams, *pts, *calib;
  CameraKind kind;
  int ncams, npoints, nprojs;
  const char *initial;  // info[0] / nprojs as eucsbademo prints it (%g)
};

const DemoCase kDemoCases[] = {
    {"7cams.txt", "7pts.txt", "calib.txt", CameraKind::FixedIntrinsics, 7, 465, 1916, "19.0947"},
    {"9cams.txt", "9pts.txt", "calib.txt", CameraKind::FixedIntrinsics, 9, 559, 2422, "8.17604"},
    {"54cams.txt", "54pts.txt", "calib.txt", CameraKind::FixedIntrinsics, 54, 5207, 24609, "2.14707"},
    {"7camsvarK.txt", "7pts.txt", "", CameraKind::VaryingIntrinsics, 7, 465, 1916, "19.0947"},
    {"54camsvarK.txt", "54pts.txt", "", CameraKind::VaryingIntrinsics, 54, 5207, 24609, "2.14707"},
    {"54camsvarKD.txt", "54pts.txt", "", CameraKind::VaryingIntrinsicsDistortion, 54, 5207, 24609,
     "2.14707"},
};

}  // namespace

TEST(SharedData, CountsAndInitialErrorsMatchSba16) {
  const std::string dir = shared_demo_dir();
  if (!fs::is_directory(dir)) GTEST_SKIP() << "no shared demo data at " << dir;
  for (const DemoCase &dc : kDemoCases) {
    SCOPED_TRACE(dc.cams);
    Problem problem;
    std::string err;
    ASSERT_TRUE(load_problem(dir + "/" + dc.cams, dir + "/" + dc.pts, *dc.calib ? dir + "/" + dc.calib : "",
                             &problem, &err))
        << err;
    const PointSet &pts = problem.points;
    EXPECT_EQ(problem.kind, dc.kind);
    EXPECT_EQ(static_cast<int>(problem.cameras.size()), dc.ncams);
    EXPECT_EQ(pts.ncameras, dc.ncams);
    EXPECT_EQ(pts.npoints(), dc.npoints);
    EXPECT_EQ(pts.nprojections(), dc.nprojs);
    EXPECT_FALSE(pts.has_covariances());
    EXPECT_EQ(static_cast<int>(std::count(pts.vmask.begin(), pts.vmask.end(), 1)), dc.nprojs);

    // The error at the start, through the expert motion+structure func as the driver calls it.
    const CameraModel model(problem.kind, problem.cameras, pts.xyz);
    Index idx = make_index(pts.vmask, pts.npoints(), pts.ncameras);
    std::vector<double> p = model.initial_camera_params();
    p.insert(p.end(), pts.xyz.begin(), pts.xyz.end());
    std::vector<double> hx(pts.x.size());
    expert_callbacks(problem.kind, Refinement::MotionStructure)
        .func(p.data(), &idx.crsm, idx.scratch1.data(), idx.scratch2.data(), hx.data(), as_adata(model));
    char printed[32];
    std::snprintf(printed, sizeof printed, "%g", sum_of_squares(hx, pts.x) / dc.nprojs);
    EXPECT_STREQ(printed, dc.initial);

    // Motion-only and structure-only start from the same error.
    std::vector<double> hx_mot(hx.size()), hx_str(hx.size());
    std::vector<double> a = model.initial_camera_params(), b = pts.xyz;
    expert_callbacks(problem.kind, Refinement::Motion)
        .func(a.data(), &idx.crsm, nullptr, nullptr, hx_mot.data(), as_adata(model));
    expert_callbacks(problem.kind, Refinement::Structure)
        .func(b.data(), &idx.crsm, nullptr, nullptr, hx_str.data(), as_adata(model));
    EXPECT_EQ(hx_mot, hx);
    EXPECT_EQ(hx_str, hx);
  }
}

TEST(SharedData, CalibrationGivesFixedIntrinsics) {
  const std::string dir = shared_demo_dir();
  if (!fs::is_directory(dir)) GTEST_SKIP() << "no shared demo data at " << dir;
  Intrinsics K;
  std::string err;
  ASSERT_TRUE(read_calibration(dir + "/calib.txt", &K, &err)) << err;
  EXPECT_DOUBLE_EQ(K.fu, 851.57945);
  EXPECT_DOUBLE_EQ(K.s, 0.0);
  EXPECT_DOUBLE_EQ(K.u0, 330.24755);
  EXPECT_DOUBLE_EQ(K.v0, 262.19500);
  EXPECT_DOUBLE_EQ(K.ar, 853.01905 / 851.57945);
}

// ---------------------------------------------------------------------------------------------
// Readers on small files, good and bad

class Files : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("eucsba_test_" + std::to_string(::getpid()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::create_directories(dir_);
  }
  void TearDown() override {
    std::error_code ec;
    fs::remove_all(dir_, ec);
  }
  std::string write(const std::string &name, const std::string &text) {
    const std::string path = (dir_ / name).string();
    std::ofstream(path, std::ios::binary) << text;
    return path;
  }
  std::string path(const std::string &name) const { return (dir_ / name).string(); }
  std::string err;  // what the last reader or writer that failed said

  fs::path dir_;
};

namespace {

const char *kTwoCams =
    "# q t\n"
    "1 0 0 0  0 0 0\n"
    "0.9 0.1 0 0  0.1 0 0\n";

// The error names the file and the line: "<path>:<line>: ...", or "<path>: ..." for line 0.
void expect_error(bool ok, const std::string &error, const std::string &path, int line, const std::string &fragment) {
  ASSERT_FALSE(ok) << "accepted a bad " << path;
  const std::string prefix = line > 0 ? path + ":" + std::to_string(line) + ": " : path + ": ";
  EXPECT_EQ(error.rfind(prefix, 0), 0u) << error;
  EXPECT_NE(error.find(fragment, prefix.size()), std::string::npos) << error;
  EXPECT_EQ(error.find('\n'), std::string::npos);
}

}  // namespace

TEST_F(Files, CameraFileKinds) {
  CameraFile cf;
  ASSERT_TRUE(read_cameras(write("c7.txt", kTwoCams), &cf, &err)) << err;
  EXPECT_EQ(cf.kind, CameraKind::FixedIntrinsics);
  ASSERT_EQ(cf.cameras.size(), 2u);
  EXPECT_EQ(cf.first_line, 2);
  EXPECT_EQ(cf.cameras[1].q.w, 0.9);
  EXPECT_EQ(cf.cameras[1].t[0], 0.1);

  ASSERT_TRUE(read_cameras(write("c12.txt", "\n  # c\n800 320 240 1.01 0.5  1 0 0 0  1 2 3\r\n"), &cf, &err)) << err;
  EXPECT_EQ(cf.kind, CameraKind::VaryingIntrinsics);
  EXPECT_EQ(cf.first_line, 3);
  EXPECT_EQ(cf.cameras[0].k.ar, 1.01);
  EXPECT_EQ(cf.cameras[0].k.s, 0.5);
  EXPECT_EQ(cf.cameras[0].t[2], 3);

  ASSERT_TRUE(read_cameras(write("c17.txt", "800 320 240 1 0 .1 .2 .3 .4 .5 1 0 0 0 1 2 3"), &cf, &err)) << err;
  EXPECT_EQ(cf.kind, CameraKind::VaryingIntrinsicsDistortion);
  EXPECT_EQ(cf.cameras[0].kc[4], 0.5);
  EXPECT_EQ(cf.cameras[0].q.w, 1);
}

TEST_F(Files, BadCameraFiles) {
  CameraFile cf;
  std::string p = path("missing.txt");
  expect_error(read_cameras(p, &cf, &err), err, p, 0, "cannot open");
  expect_error(read_cameras(dir_.string(), &cf, &err), err, dir_.string(), 0, "directory");
  p = write("empty.txt", "");
  expect_error(read_cameras(p, &cf, &err), err, p, 1, "no cameras");
  p = write("comments.txt", "# a\n\n# b\n");
  expect_error(read_cameras(p, &cf, &err), err, p, 3, "no cameras");
  p = write("six.txt", "1 0 0 0 0 0\n");
  expect_error(read_cameras(p, &cf, &err), err, p, 1, "7, 12 or 17");
  p = write("short.txt", std::string(kTwoCams) + "1 0 0 0 0 0\n");
  expect_error(read_cameras(p, &cf, &err), err, p, 4, "expected 7 values as on line 2, found 6");
  p = write("long.txt", std::string(kTwoCams) + "1 0 0 0 0 0 0 0\n");
  expect_error(read_cameras(p, &cf, &err), err, p, 4, "found 8");
  p = write("word.txt", std::string(kTwoCams) + "1 0 zero 0 0 0 0\n");
  expect_error(read_cameras(p, &cf, &err), err, p, 4, "'zero' is not a number");
  p = write("nan.txt", "1 0 0 0 0 nan 0\n");
  expect_error(read_cameras(p, &cf, &err), err, p, 1, "not a finite number");
  p = write("inf.txt", "1 0 0 0 0 0 -inf\n");
  expect_error(read_cameras(p, &cf, &err), err, p, 1, "not a finite number");
  p = write("overflow.txt", "1 0 0 0 1e999 0 0\n");
  expect_error(read_cameras(p, &cf, &err), err, p, 1, "not a finite number");
  p = write("zeroq.txt", std::string(kTwoCams) + "0 0 0 0 1 2 3\n");
  expect_error(read_cameras(p, &cf, &err), err, p, 4, "quaternion is zero");
  p = write("trailing.txt", "1 0 0 0 0 0 0x\n");
  expect_error(read_cameras(p, &cf, &err), err, p, 1, "'0x' is not a number");
  // strtod reads hexadecimal floats; no file of these formats is written with them.
  p = write("hex.txt", "1 0 0 0 0x1p-2 0 0\n");
  expect_error(read_cameras(p, &cf, &err), err, p, 1, "'0x1p-2' is not a number");
}

TEST_F(Files, BadCalibrationFiles) {
  Intrinsics K;
  std::string p = path("missing.txt");
  expect_error(read_calibration(p, &K, &err), err, p, 0, "cannot open");
  p = write("two.txt", "800 0 320\n0 810 240\n");
  expect_error(read_calibration(p, &K, &err), err, p, 2, "K has 2 rows, expected 3");
  p = write("empty.txt", "");
  expect_error(read_calibration(p, &K, &err), err, p, 1, "K has 0 rows");
  p = write("word.txt", "800 0 320\n0 eight 240\n0 0 1\n");
  expect_error(read_calibration(p, &K, &err), err, p, 2, "'eight' is not a number");
  p = write("hex.txt", "0x1p9 0 320\n0 800 240\n0 0 1\n");
  expect_error(read_calibration(p, &K, &err), err, p, 1, "'0x1p9' is not a number");
  p = write("nan.txt", "800 0 320\n0 800 240\n0 0 NaN\n");
  expect_error(read_calibration(p, &K, &err), err, p, 3, "not a finite number");
  p = write("short.txt", "800 0 320\n0 800\n0 0 1\n");
  expect_error(read_calibration(p, &K, &err), err, p, 2, "expected 3 values in row 2");
  p = write("four.txt", "800 0 320\n0 800 240\n0 0 1\n0 0 1\n");
  expect_error(read_calibration(p, &K, &err), err, p, 4, "4th row");
  p = write("lower.txt", "800 0 320\n0 800 240\n0 0 2\n");
  expect_error(read_calibration(p, &K, &err), err, p, 3, "last row");
  p = write("fu.txt", "# K\n0 0 320\n0 800 240\n0 0 1\n");
  expect_error(read_calibration(p, &K, &err), err, p, 2, "fu");

  p = write("good.txt", "# K\n800 0.5 320\n\n0 808 240\n0 0 1\n");
  ASSERT_TRUE(read_calibration(p, &K, &err)) << err;
  EXPECT_EQ(K.fu, 800);
  EXPECT_EQ(K.s, 0.5);
  EXPECT_EQ(K.u0, 320);
  EXPECT_EQ(K.v0, 240);
  EXPECT_DOUBLE_EQ(K.ar, 1.01);
}

TEST_F(Files, PointsAreSortedByCameraWithinATrack) {
  PointSet ps;
  const std::string p = write("pts.txt",
                              "# X Y Z n ...\n"
                              "1 2 3  2  2 10 20  0 30 40\n"
                              "\n"
                              "4 5 6  3  1 1 2  0 3 4  2 5 6\n");
  ASSERT_TRUE(read_points(p, 3, &ps, &err)) << err;
  EXPECT_EQ(ps.npoints(), 2);
  EXPECT_EQ(ps.nprojections(), 5);
  EXPECT_EQ(ps.vmask, (std::vector<char>{1, 0, 1, 1, 1, 1}));
  EXPECT_EQ(ps.x, (std::vector<double>{30, 40, 10, 20, 3, 4, 1, 2, 5, 6}));
  EXPECT_EQ(ps.xyz, (std::vector<double>{1, 2, 3, 4, 5, 6}));
  EXPECT_FALSE(ps.has_covariances());
}

TEST_F(Files, CovarianceFormsGiveTheSameCovx) {
  PointSet full, upper;
  const std::string pf = write("full.txt",
                               "1 2 3  2  1 10 20 4 1 1 9  0 30 40 2 -0.5 -0.5 3\n"
                               "4 5 6  1  2 1 2 1 0 0 1\n");
  const std::string pu = write("upper.txt",
                               "1 2 3  2  1 10 20 4 1 9  0 30 40 2 -0.5 3\n"
                               "4 5 6  1  2 1 2 1 0 1\n");
  ASSERT_TRUE(read_points(pf, 3, &full, &err)) << err;
  ASSERT_TRUE(read_points(pu, 3, &upper, &err)) << err;
  EXPECT_EQ(full.form, CovarianceForm::Full);
  EXPECT_EQ(upper.form, CovarianceForm::UpperTriangular);
  ASSERT_TRUE(full.has_covariances());
  // Sorted with their projections: camera 0's covariance comes first.
  const std::vector<double> expected = {2, -0.5, -0.5, 3, 4, 1, 1, 9, 1, 0, 0, 1};
  EXPECT_EQ(full.covx, expected);
  EXPECT_EQ(upper.covx, expected);
  EXPECT_EQ(full.x, upper.x);
}

TEST_F(Files, BadPointFiles) {
  PointSet ps;
  const int m = 3;
  const std::string good = "# header\n1 2 3  2  0 10 20  1 30 40\n\n";  // data on line 2, next is 4
  struct Case {
    const char *name, *line;
    const char *fragment;
  };
  const Case cases[] = {
      {"frame_too_big", "1 2 3  2  0 10 20  3 30 40", "frame index 3 out of range [0, 3)"},
      {"frame_negative", "1 2 3  2  -1 10 20  1 30 40", "frame index -1 out of range"},
      {"frame_twice", "1 2 3  3  1 10 20  0 1 1  1 30 40", "frame 1 appears twice"},
      {"frame_not_int", "1 2 3  2  0.5 10 20  1 30 40", "frame index: '0.5' is not an integer"},
      {"frame_word", "1 2 3  2  a 10 20  1 30 40", "frame index: 'a' is not a number"},
      {"nframes_negative", "1 2 3  -2  0 10 20  1 30 40", "nframes is -2"},
      {"nframes_zero", "1 2 3  0", "nframes is 0"},
      {"nframes_huge", "1 2 3  99999999999999999999999  0 10 20", "out of range"},
      {"nframes_too_many", "1 2 3  4  0 10 20  1 30 40", "more than the 3 cameras"},
      {"nframes_not_int", "1 2 3  2.5  0 10 20  1 30 40", "nframes: '2.5' is not an integer"},
      {"nframes_disagrees", "1 2 3  2  0 10 20  1 30 40  2 50 60", "nframes is 2 but 9 values"},
      {"truncated_triple", "1 2 3  2  0 10 20  1 30", "nframes is 2 but 5 values"},
      {"truncated_head", "1 2 3", "expected X Y Z nframes"},
      {"coordinate_word", "1 two 3  1  0 10 20", "'two' is not a number"},
      {"coordinate_hex", "1 -0X2 3  1  0 10 20", "'-0X2' is not a number"},
      {"coordinate_nan", "1 2 nan  1  0 10 20", "not a finite number"},
      {"measurement_inf", "1 2 3  1  0 inf 20", "not a finite number"},
      {"cov_form_changes", "1 2 3  1  0 10 20 1 0 1", "inconsistent covariance form"},
  };
  for (const Case &c : cases) {
    SCOPED_TRACE(c.name);
    const std::string p = write(std::string(c.name) + ".txt", good + c.line + "\n");
    expect_error(read_points(p, m, &ps, &err), err, p, 4, c.fragment);
  }

  std::string p = path("missing.txt");
  expect_error(read_points(p, m, &ps, &err), err, p, 0, "cannot open");
  p = write("empty.txt", "");
  expect_error(read_points(p, m, &ps, &err), err, p, 1, "no points");
  p = write("comments.txt", "# X Y Z\n# nothing else\n");
  expect_error(read_points(p, m, &ps, &err), err, p, 2, "no points");
  p = write("cov_then_none.txt", "1 2 3  1  0 10 20 1 0 0 1\n1 2 3  1  0 10 20\n");
  expect_error(read_points(p, m, &ps, &err), err, p, 2, "inconsistent covariance form");
  p = write("cov_not_pd.txt", "1 2 3  1  0 10 20 1 2 1\n");
  expect_error(read_points(p, m, &ps, &err), err, p, 1, "not positive definite");
  p = write("cov_not_sym.txt", "1 2 3  1  0 10 20 1 0.1 0.2 1\n");
  expect_error(read_points(p, m, &ps, &err), err, p, 1, "not symmetric");
  p = write("bad_first.txt", "1 2 3  2  0 10 20  1 30 40 5\n");
  expect_error(read_points(p, m, &ps, &err), err, p, 1, "expected 6 (f x y per frame), 12 or 14");
}

TEST_F(Files, LoadProblemMatchesCalibrationToCameraKind) {
  const std::string cams7 = write("c7.txt", kTwoCams);
  const std::string cams12 = write("c12.txt", "800 320 240 1 0 1 0 0 0 0 0 0\n800 320 240 1 0 1 0 0 0 0 0 1\n");
  const std::string pts = write("p.txt", "0 0 5 2 0 1 2 1 3 4\n");
  const std::string calib = write("k.txt", "800 0 320\n0 800 240\n0 0 1\n");
  Problem pr;
  expect_error(load_problem(cams7, pts, "", &pr, &err), err, cams7, 2, "calibration file is needed");
  expect_error(load_problem(cams12, pts, calib, &pr, &err), err, cams12, 1, "does not apply");
  ASSERT_TRUE(load_problem(cams7, pts, calib, &pr, &err)) << err;
  EXPECT_EQ(pr.cameras[1].k.fu, 800);
  EXPECT_EQ(pr.cameras[1].k.u0, 320);
  ASSERT_TRUE(load_problem(cams12, pts, "", &pr, &err)) << err;
  EXPECT_EQ(pr.kind, CameraKind::VaryingIntrinsics);
  // A frame index is checked against the cameras actually read.
  const std::string pts_far = write("p2.txt", "0 0 5 1 2 1 2\n");
  expect_error(load_problem(cams7, pts_far, calib, &pr, &err), err, pts_far, 1, "out of range [0, 2)");
}

// ---------------------------------------------------------------------------------------------
// Writers

TEST_F(Files, CameraWriterRoundTrip) {
  std::mt19937 rng(12);
  for (CameraKind kind : kAllKinds) {
    SCOPED_TRACE(kind_name(kind));
    const Scene scene = random_scene(5, 4, rng);
    const CameraModel model(kind, scene.cameras, scene.points, 0, 0);
    const std::vector<double> a = perturbed_cameras(model, rng, 0.3);
    std::vector<Camera> refined;
    for (int j = 0; j < model.ncameras(); ++j) refined.push_back(model.camera(j, &a[j * model.cnp()]));
    const std::string p = path("cams.txt");
    ASSERT_TRUE(write_cameras(p, kind, refined, &err)) << err;

    CameraFile back;
    ASSERT_TRUE(read_cameras(p, &back, &err)) << err;
    EXPECT_EQ(back.kind, kind);
    ASSERT_EQ(back.cameras.size(), refined.size());
    auto close = [](double x, double y) { return std::fabs(x - y) <= 1e-9 * std::max(1.0, std::fabs(y)); };
    for (std::size_t j = 0; j < refined.size(); ++j) {
      const Camera &c = back.cameras[j], &r = refined[j];
      EXPECT_GE(c.q.w, 0.0);
      EXPECT_TRUE(close(c.q.w, r.q.w) && close(c.q.x, r.q.x) && close(c.q.y, r.q.y) && close(c.q.z, r.q.z));
      for (int k = 0; k < 3; ++k) EXPECT_TRUE(close(c.t[k], r.t[k]));
      if (kind != CameraKind::FixedIntrinsics) {
        EXPECT_TRUE(close(c.k.fu, r.k.fu) && close(c.k.u0, r.k.u0) && close(c.k.v0, r.k.v0) &&
                    close(c.k.ar, r.k.ar) && close(c.k.s, r.k.s));
      }
      if (kind == CameraKind::VaryingIntrinsicsDistortion)
        for (int k = 0; k < 5; ++k) EXPECT_TRUE(close(c.kc[k], r.kc[k]));
    }
    // The written numbers use %.10e.
    std::ifstream in(p);
    std::string header, first;
    std::getline(in, header);
    in >> first;
    EXPECT_EQ(header[0], '#');
    EXPECT_TRUE(std::regex_match(first, std::regex(R"(-?[0-9]\.[0-9]{10}e[+-][0-9]{2,3})"))) << first;
  }
}

TEST_F(Files, PointWritersRoundTrip) {
  PointSet tracks;
  const std::string in = write("in.txt",
                               "1 2 3  2  2 10 20 4 1 9  0 30 40 2 -0.5 3\n"
                               "4 5 6  1  1 1 2 1 0 1\n");
  ASSERT_TRUE(read_points(in, 3, &tracks, &err)) << err;
  const std::vector<double> xyz = {0.123456789012345, -2.5e-7, 3e5, 1.0 / 3, 2.0 / 3, -1};

  const std::string pxyz = path("xyz.txt");
  ASSERT_TRUE(write_points_xyz(pxyz, xyz, &err)) << err;
  std::vector<double> back;
  ASSERT_TRUE(read_points_xyz(pxyz, &back, &err)) << err;
  ASSERT_EQ(back.size(), xyz.size());
  for (std::size_t k = 0; k < xyz.size(); ++k) EXPECT_NEAR(back[k], xyz[k], 1e-9 * std::fabs(xyz[k]));

  const std::string ptracks = path("tracks.txt");
  ASSERT_TRUE(write_points(ptracks, tracks, xyz, &err)) << err;
  PointSet again;
  ASSERT_TRUE(read_points(ptracks, 3, &again, &err)) << err;
  EXPECT_EQ(again.form, tracks.form);
  EXPECT_EQ(again.vmask, tracks.vmask);
  EXPECT_EQ(again.x, tracks.x);
  EXPECT_EQ(again.covx, tracks.covx);
  for (std::size_t k = 0; k < xyz.size(); ++k) EXPECT_NEAR(again.xyz[k], xyz[k], 1e-9 * std::fabs(xyz[k]));
}

TEST_F(Files, WritersReportUnwritablePaths) {
  const std::string p = (dir_ / "no" / "such" / "dir.txt").string();
  expect_error(write_cameras(p, CameraKind::FixedIntrinsics, {Camera{}}, &err), err, p, 0,
               "cannot open for writing");
  expect_error(write_points_xyz(p, {1, 2, 3}, &err), err, p, 0, "cannot open for writing");
}

TEST_F(Files, SharedProblemRoundTripKeepsTheError) {
  // Writing the cameras of a corrected model and reading them back as a new problem gives the
  // corrected model's error as the new initial error.
  const std::string dir = shared_demo_dir();
  if (!fs::is_directory(dir)) GTEST_SKIP() << "no shared demo data at " << dir;
  Problem pr;
  ASSERT_TRUE(load_problem(dir + "/54camsvarKD.txt", dir + "/7pts.txt", "", &pr, &err)) << err;
  const CameraModel model(pr.kind, pr.cameras, pr.points.xyz, 2, 3);
  std::mt19937 rng(13);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<double> a = model.initial_camera_params();
  for (int j = 0; j < model.ncameras(); ++j)
    for (int r = 0; r < 3; ++r) a[j * model.cnp() + rot_offset(model.kind()) + r] = 1e-3 * u(rng);
  for (int j = 0; j < model.ncameras(); ++j) a[j * model.cnp() + 5] = 1e-2 * u(rng);  // kc0

  std::vector<Camera> refined;
  for (int j = 0; j < model.ncameras(); ++j) refined.push_back(model.camera(j, &a[j * model.cnp()]));
  const std::string pc = path("cams.txt"), pp = path("pts.txt");
  ASSERT_TRUE(write_cameras(pc, pr.kind, refined, &err)) << err;
  ASSERT_TRUE(write_points(pp, pr.points, pr.points.xyz, &err)) << err;
  Problem again;
  ASSERT_TRUE(load_problem(pc, pp, "", &again, &err)) << err;
  const CameraModel model2(again.kind, again.cameras, again.points.xyz, 2, 3);

  Index idx = make_index(pr.points.vmask, pr.points.npoints(), pr.points.ncameras);
  std::vector<double> hx1(pr.points.x.size()), hx2(hx1.size());
  const ExpertCallbacks cb = expert_callbacks(pr.kind, Refinement::Motion);
  cb.func(a.data(), &idx.crsm, nullptr, nullptr, hx1.data(), as_adata(model));
  std::vector<double> a2 = model2.initial_camera_params();
  cb.func(a2.data(), &idx.crsm, nullptr, nullptr, hx2.data(), as_adata(model2));
  const double e1 = sum_of_squares(hx1, pr.points.x), e2 = sum_of_squares(hx2, again.points.x);
  EXPECT_NEAR(e1, e2, 1e-8 * e1);
}
