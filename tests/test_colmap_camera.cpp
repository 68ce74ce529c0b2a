// SPDX-License-Identifier: BSD-3-Clause
// COLMAP's camera models (lib/cameras/colmap_camera.h): projections against numbers worked
// out by hand from the documented formulas and against COLMAP's own (pycolmap's), analytic
// derivatives against central differences (r = 0 and FOV's omega = 0 included), and the sba
// camera model's pose part and callbacks.
#include "cameras/colmap_camera.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cfloat>
#include <cmath>
#include <cstring>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "cameras/euclidean_rotation.h"
#include "colmap_tangent.h"
#include "sba.h"

namespace cc = sbacameras::colmap_camera;

namespace {

// Parameters of each model with distortion strong enough that every term shows.
std::vector<double> sample_params(int model) {
  switch (model) {
    case cc::kSimplePinhole: return {500, 320, 240};
    case cc::kPinhole: return {500, 530, 320, 240};
    case cc::kSimpleRadial: return {500, 320, 240, -0.12};
    case cc::kRadial: return {500, 320, 240, -0.12, 0.03};
    case cc::kOpenCV: return {500, 520, 320, 240, 0.1, -0.05, 0.01, -0.02};
    case cc::kOpenCVFisheye: return {350, 355, 320, 240, 0.1, -0.02, 0.003, -0.0004};
    case cc::kFullOpenCV: return {600, 610, 300, 200, 0.1, -0.05, 0.001, -0.002, 0.02, 0.03, -0.01, 0.005};
    case cc::kFov: return {400, 410, 320, 240, 0.9};
    case cc::kSimpleRadialFisheye: return {300, 320, 240, 0.05};
    case cc::kRadialFisheye: return {300, 320, 240, 0.05, -0.01};
    case cc::kThinPrismFisheye:
      return {300, 305, 320, 240, 0.05, -0.01, 0.001, -0.0015, 0.002, -0.0005, 0.0007, -0.0004};
    case cc::kRadTanThinPrismFisheye:
      return {300,   305,     320,   240,     0.05,    -0.01,  0.002,  -0.0005,
              1e-4,  -2e-5,   0.001, -0.0015, 0.0007,  -0.0004, 0.0003, 0.0002};
    case cc::kSimpleDivision: return {500, 320, 240, -0.1};
    case cc::kDivision: return {500, 510, 320, 240, 0.05};
    case cc::kSimpleFisheye: return {300, 320, 240};
    case cc::kFisheye: return {300, 310, 320, 240};
    case cc::kEucm: return {400, 410, 320, 240, 0.6, 1.1};
    case cc::kEquirectangular: return {1000, 500};
  }
  return {};
}

std::vector<double> pixels(int model, const std::vector<double> &params, const double Xc[3]) {
  std::vector<double> x(2);
  cc::project(model, params.data(), Xc, x.data(), nullptr, nullptr);
  return x;
}

// Central differences with a step relative to the value; compared with a tolerance relative
// to the column's size (1e-6), absolute for columns that are zero (1e-7 pixels).
void expect_derivatives(int model, const std::vector<double> &params, const double Xc[3], const std::string &what) {
  const int np = cc::param_count(model);
  std::vector<double> Jp(2 * static_cast<std::size_t>(np));
  double Jx[6], x[2];
  cc::project(model, params.data(), Xc, x, Jp.data(), Jx);
  const auto check = [&](double analytic, double numeric, const std::string &name) {
    EXPECT_NEAR(analytic, numeric, 1e-6 * std::max(1.0, std::fabs(numeric)))
        << cc::model_name(model) << " " << what << " d/d" << name;
    EXPECT_TRUE(std::isfinite(analytic)) << cc::model_name(model) << " " << what << " d/d" << name;
  };
  for (int k = 0; k < np; ++k) {
    const double h = 1e-6 * std::max(1.0, std::fabs(params[static_cast<std::size_t>(k)]));
    std::vector<double> lo = params, hi = params;
    lo[static_cast<std::size_t>(k)] -= h;
    hi[static_cast<std::size_t>(k)] += h;
    const std::vector<double> xl = pixels(model, lo, Xc), xh = pixels(model, hi, Xc);
    for (int r = 0; r < 2; ++r)
      check(Jp[static_cast<std::size_t>(r * np + k)], (xh[static_cast<std::size_t>(r)] - xl[static_cast<std::size_t>(r)]) / (2 * h),
            "param" + std::to_string(k) + " row " + std::to_string(r));
  }
  for (int c = 0; c < 3; ++c) {
    const double h = 1e-6 * std::max(1.0, std::fabs(Xc[c]));
    double lo[3] = {Xc[0], Xc[1], Xc[2]}, hi[3] = {Xc[0], Xc[1], Xc[2]};
    lo[c] -= h;
    hi[c] += h;
    const std::vector<double> xl = pixels(model, params, lo), xh = pixels(model, params, hi);
    for (int r = 0; r < 2; ++r)
      check(Jx[r * 3 + c], (xh[static_cast<std::size_t>(r)] - xl[static_cast<std::size_t>(r)]) / (2 * h),
            "X" + std::to_string(c) + " row " + std::to_string(r));
  }
}

}  // namespace

TEST(ColmapCamera, ModelTable) {
  // COLMAP's names and parameter counts (pycolmap's CameraModelId and Camera.params_info).
  const char *names[] = {"SIMPLE_PINHOLE",  "PINHOLE",        "SIMPLE_RADIAL",         "RADIAL",
                         "OPENCV",          "OPENCV_FISHEYE", "FULL_OPENCV",           "FOV",
                         "SIMPLE_RADIAL_FISHEYE", "RADIAL_FISHEYE", "THIN_PRISM_FISHEYE",
                         "RAD_TAN_THIN_PRISM_FISHEYE", "SIMPLE_DIVISION", "DIVISION", "SIMPLE_FISHEYE",
                         "FISHEYE",         "EUCM",           "EQUIRECTANGULAR"};
  const int counts[] = {3, 4, 4, 5, 8, 8, 12, 5, 4, 5, 12, 16, 4, 5, 3, 4, 6, 2};
  ASSERT_EQ(cc::kNumModels, 18);
  for (int m = 0; m < cc::kNumModels; ++m) {
    EXPECT_STREQ(cc::model_name(m), names[m]);
    EXPECT_EQ(cc::param_count(m), counts[m]);
    EXPECT_EQ(sample_params(m).size(), static_cast<std::size_t>(counts[m]));
  }
  EXPECT_EQ(cc::model_name(18), nullptr);
  // 6 + the parameters, rounded up to the library's fixed-size kernels (9, 11, 16).
  EXPECT_EQ(cc::camera_params(3), 9);
  EXPECT_EQ(cc::camera_params(4), 11);
  EXPECT_EQ(cc::camera_params(5), 11);
  EXPECT_EQ(cc::camera_params(8), 16);
  EXPECT_EQ(cc::camera_params(12), 18);
  EXPECT_EQ(cc::camera_params(16), 22);
  EXPECT_EQ(cc::param_count(-1), 0);
  EXPECT_EQ(cc::param_kind(cc::kRadial, 0), cc::ParamKind::Focal);
  EXPECT_EQ(cc::param_kind(cc::kRadial, 2), cc::ParamKind::Principal);
  EXPECT_EQ(cc::param_kind(cc::kRadial, 3), cc::ParamKind::Extra);
  EXPECT_EQ(cc::param_kind(cc::kPinhole, 1), cc::ParamKind::Focal);
  EXPECT_EQ(cc::param_kind(cc::kPinhole, 3), cc::ParamKind::Principal);
  EXPECT_EQ(cc::param_kind(cc::kFov, 4), cc::ParamKind::Extra);
  // pycolmap's focal_length_idxs, principal_point_idxs and extra_params_idxs; EQUIRECTANGULAR's
  // w and h are none of them (metadata_params_idxs).
  EXPECT_EQ(cc::param_kind(cc::kSimpleDivision, 0), cc::ParamKind::Focal);
  EXPECT_EQ(cc::param_kind(cc::kSimpleDivision, 3), cc::ParamKind::Extra);
  EXPECT_EQ(cc::param_kind(cc::kFisheye, 1), cc::ParamKind::Focal);
  EXPECT_EQ(cc::param_kind(cc::kFisheye, 3), cc::ParamKind::Principal);
  EXPECT_EQ(cc::param_kind(cc::kEucm, 5), cc::ParamKind::Extra);
  EXPECT_EQ(cc::param_kind(cc::kRadTanThinPrismFisheye, 15), cc::ParamKind::Extra);
  EXPECT_EQ(cc::focal_count(cc::kEquirectangular), 0);
  EXPECT_EQ(cc::param_kind(cc::kEquirectangular, 0), cc::ParamKind::Size);
  EXPECT_EQ(cc::param_kind(cc::kEquirectangular, 1), cc::ParamKind::Size);
}

// The numbers below were worked out from the formulas in colmap_camera.h, independently of
// the code (python, double precision).
TEST(ColmapCamera, ProjectionsByHand) {
  struct Case {
    int model;
    std::vector<double> params;
    double Xc[3];
    double x, y;
  } cases[] = {
      // u = 0.2, v = -0.1: r^2 = 0.05, R = 1.004875, ud = 0.197975, vd = -0.0989875.
      {cc::kOpenCV, {500, 520, 320, 240, 0.1, -0.05, 0.01, -0.02}, {0.2, -0.1, 1}, 418.9875, 188.5265},
      {cc::kFullOpenCV,
       {600, 610, 300, 200, 0.1, -0.05, 0.001, -0.002, 0.02, 0.03, -0.01, 0.005},
       {0.3, 0.25, 1.5},
       420.40942260530278,
       302.12379044801116},
      // r = 1: F = atan(2 tan(0.25)) / 0.5 = 0.94431621335235505.
      {cc::kFov, {400, 410, 320, 240, 0.5}, {0.6, 0.8, 1}, 546.63589120456527, 549.73571797957243},
      {cc::kThinPrismFisheye,
       {300, 305, 320, 240, 0.05, -0.01, 0.001, -0.0015, 0.002, -0.0005, 0.0007, -0.0004},
       {-0.4, 0.3, 1},
       207.34053926646936,
       325.90283880931713},
      {cc::kOpenCVFisheye,
       {350, 355, 320, 240, 0.1, -0.02, 0.003, -0.0004},
       {0.5, -0.6, 1},
       474.56214092259609,
       51.875794191354515},
      // SIMPLE_RADIAL: u = 0.25, v = 0.5, r^2 = 0.3125, 1 + k r^2 = 0.9625.
      {cc::kSimpleRadial, {500, 320, 240, -0.12}, {0.5, 1, 2}, 320 + 500 * 0.25 * 0.9625, 240 + 500 * 0.5 * 0.9625},
      // PINHOLE with fx != fy.
      {cc::kPinhole, {500, 530, 320, 240}, {0.5, 1, 2}, 445, 505},
  };
  for (const Case &c : cases) {
    double x[2];
    cc::project(c.model, c.params.data(), c.Xc, x, nullptr, nullptr);
    EXPECT_NEAR(x[0], c.x, 1e-9) << cc::model_name(c.model);
    EXPECT_NEAR(x[1], c.y, 1e-9) << cc::model_name(c.model);
  }
}

// SIMPLE_RADIAL and RADIAL are OPENCV with the terms they lack at zero: their pixels and
// derivatives are OPENCV's, bit for bit, at points on and off the axis, with distortion of
// either sign (their own code writes out only the terms that are not zero).
TEST(ColmapCamera, RadialModelsAreOpenCVWithoutTheirTerms) {
  const double ks[][2] = {{0, 0}, {-0.21, 0.07}, {0.13, -0.011}, {3e-4, 2e-6}};
  std::vector<std::array<double, 3>> points = {{0, 0, 2}, {2e-9, -3e-9, 1}, {0.8, 0.8, 0.4}};
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(-1, 1);
  // Many points: another order of the same operations rounds differently at a few of them.
  for (int i = 0; i < 200; ++i) points.push_back({u(rng), u(rng), 1.5 + u(rng)});
  for (const auto &k : ks)
    for (const auto &point : points)
      for (const int model : {cc::kSimpleRadial, cc::kRadial}) {
        const double *X = point.data();
        const double k2 = model == cc::kRadial ? k[1] : 0.0;
        const std::vector<double> own = model == cc::kRadial ? std::vector<double>{612.5, 320.5, 240.25, k[0], k2}
                                                              : std::vector<double>{612.5, 320.5, 240.25, k[0]};
        const std::vector<double> opencv = {612.5, 612.5, 320.5, 240.25, k[0], k2, 0, 0};
        const int np = cc::param_count(model);
        double x[2], xo[2], Jp[2 * cc::kMaxParams], Jo[2 * cc::kMaxParams], Jx[6], Jxo[6];
        cc::project(model, own.data(), X, x, Jp, Jx);
        cc::project(cc::kOpenCV, opencv.data(), X, xo, Jo, Jxo);
        const std::string at = std::to_string(model) + " k1 " + std::to_string(k[0]) + " X " + std::to_string(X[0]);
        EXPECT_EQ(x[0], xo[0]) << at;
        EXPECT_EQ(x[1], xo[1]) << at;
        for (int c = 0; c < 6; ++c) EXPECT_EQ(Jx[c], Jxo[c]) << at << " Jx " << c;
        // f against fx and fy; k1 (and k2) against OPENCV's, whose parameters come 3 later.
        EXPECT_EQ(Jp[0], Jo[0]) << at;
        EXPECT_EQ(Jp[np], Jo[8 + 1]) << at;
        for (int e = 3; e < np; ++e) {
          EXPECT_EQ(Jp[e], Jo[e + 1]) << at << " " << e;
          EXPECT_EQ(Jp[np + e], Jo[8 + e + 1]) << at << " " << e;
        }
      }
}

// COLMAP's own projections: recorded from pycolmap 4.2.1 (tests/colmap_real/pycolmap_models.py
// --cpp prints them: Camera(model, params=the sample parameters above).img_from_cam(points,
// check_cheirality=False)), at points in front of the camera, on its axis, far off it, behind
// it, and one outside DIVISION's field of view, where COLMAP has no pixel either.
TEST(ColmapCamera, ProjectionsAsPycolmap) {
  const double points[6][3] = {{0.3, -0.45, 1.0}, {-0.8, 0.6, 1.2}, {0.0, 0.0, 2.0},
                               {1.5, 0.4, 1.0},   {0.2, -0.1, -1.0}, {3.0, 2.0, 1.0}};
  struct Case {
    int model;
    double x[6][2];
  } cases[] = {
      {0,  // SIMPLE_PINHOLE
       {{470, 15}, {-13.333333333333371, 490},
        {320, 240}, {1070, 440},
        {220, 290}, {1820, 1240}}},
      {1,  // PINHOLE
       {{470, 1.5}, {-13.333333333333371, 505},
        {320, 240}, {1070, 452},
        {220, 293}, {1820, 1300}}},
      {2,  // SIMPLE_RADIAL
       {{464.73500000000001, 22.897500000000008}, {14.4444444444444, 469.16666666666663},
        {320, 240}, {853.10000000000002, 382.15999999999997},
        {220.59999999999999, 289.69999999999999}, {-519.99999999999989, -320}}},
      {3,  // RADIAL
       {{465.12000312500004, 22.319995312499998}, {9.6219135802468827, 472.78356481481484},
        {320, 240}, {983.78224999999998, 417.0086},
        {220.59249999999997, 289.70375000000001}, {7085.0000000000009, 4750}}},
      {4,  // OPENCV
       {{467.67082812499996, 6.5915081249999901}, {-47.610596707818956, 524.93070987654323},
        {320, 240}, {969.84624999999994, 439.43976000000004},
        {218.01249999999999, 293.0335}, {-9155.0000000000018, -6171.6000000000013}}},
      {5,  // OPENCV_FISHEYE
       {{418.50649824635389, 90.12939909661867}, {116.929181807954, 394.47887241037785},
        {320, 240}, {685.51506061620898, 338.86312115714611},
        {250.80279202029988, 275.09286976113361}, {745.2776065164021, 527.56866726347198}}},
      {6,  // FULL_OPENCV
       {{482.38302814039963, -78.490967914109433}, {-115.79904830603738, 516.83496877779794},
        {300, 200}, {1313.9038634494764, 477.1347563129691},
        {179.41237649942804, 261.29870861279073}, {6636.1207299953221, 4512.9851614412728}}},
      {7,  // FOV
       {{438.7029473987966, 57.494218374350197}, {78.990939956427809, 425.27571490849607},
        {320, 240}, {742.02312213712889, 355.35298671748194},
        {235.4232471497391, 283.3455858357587}, {797.49896278926951, 566.29095790600081}}},
      {8,  // SIMPLE_RADIAL_FISHEYE
       {{403.51633854797831, 114.72549217803255}, {149.23893458819578, 368.07079905885314},
        {320, 240}, {623.87737283407603, 321.03396608908696},
        {260.82819690588559, 269.58590154705723}, {671.9969831731305, 474.66465544875371}}},
      {9,  // RADIAL_FISHEYE
       {{403.46649434267817, 114.80025848598277}, {149.62736871185822, 367.77947346610631},
        {320, 240}, {620.99976829911668, 320.26660487976449},
        {260.82957939264952, 269.58521030367524}, {662.72015725698043, 468.48010483798691}}},
      {10,  // THIN_PRISM_FISHEYE
       {{403.27367020841172, 112.96267234395185}, {149.06153876308863, 370.34057669314495},
        {320, 240}, {620.50241302604172, 321.71688587842175},
        {260.77149252129453, 270.11077671233073}, {663.54015567838292, 473.42828157592771}}},
      {11,  // RAD_TAN_THIN_PRISM_FISHEYE
       {{403.74046776913536, 112.39165568929755}, {150.23198755328335, 369.45188993590989},
        {320, 240}, {622.22811280805172, 321.50143119132991},
        {260.89492880186378, 270.03988693237824}, {665.36408197874994, 473.24033675986436}}},
      {12,  // SIMPLE_DIVISION
       {{465.8518134595588, 21.222279810661746}, {7.0680067498927315, 474.69899493758044},
        {320, 240}, {944.6283868906454, 406.56756983750546},
        {20419.50493836201, -9809.7524691810049}, {1179.6037997679307, 813.06919984528713}}},
      {13,  // DIVISION
       {{472.2603637922598, 7.041643397842563}, {-25.788509735982473, 504.52820994802659},
        {320, 240}, {1192.2339150896373, 477.24762490438138},
        {-39579.748742132484, 20588.871858487568}, {NAN, NAN}}},
      {14,  // SIMPLE_FISHEYE
       {{402.50240232228327, 116.24639651657513}, {153.2628137127912, 365.05288971540659},
        {320, 240}, {609.4472420620657, 317.18593121655084},
        {260.97103139732786, 269.5144843013361}, {644.56116084054258, 456.37410722702839}}},
      {15,  // FISHEYE
       {{402.50240232228327, 112.12127640046097}, {153.2628137127912, 369.22131937258678},
        {320, 240}, {609.4472420620657, 319.75879559043585},
        {260.97103139732786, 270.49830044471395}, {644.56116084054258, 463.58657746792937}}},
      {16,  // EUCM
       {{430.11151065291557, 70.703552371142308}, {97.196422441846209, 411.28025024783074},
        {320, 240}, {707.98402936459968, 346.04896802632391},
        {689.89232303010897, 50.430184447069166}, {756.85404619437998, 538.51693156615966}}},
      {17,  // EQUIRECTANGULAR
       {{546.3867895388712, 185.23028627702283}, {406.41647909450057, 312.74594107773578},
        {500, 250}, {656.41647909450057, 284.75034854703017},
        {968.58352090549954, 234.44330781995384}, {698.79180882521666, 339.75425899284403}}},
  };
  ASSERT_EQ(sizeof cases / sizeof cases[0], static_cast<std::size_t>(cc::kNumModels));
  for (const Case &c : cases) {
    const std::vector<double> params = sample_params(c.model);
    for (int i = 0; i < 6; ++i)
      for (int r = 0; r < 2; ++r) {
        const double want = c.x[i][r], got = pixels(c.model, params, points[i])[static_cast<std::size_t>(r)];
        if (std::isnan(want))
          EXPECT_TRUE(std::isnan(got)) << cc::model_name(c.model) << " point " << i << ": " << got;
        else
          EXPECT_NEAR(got, want, 1e-10 * std::max(1.0, std::fabs(want)))
              << cc::model_name(c.model) << " point " << i;
      }
  }
}

// project gives the formula's pixels behind the camera too (`refused` says where COLMAP's
// projection gives none). The models of u = X/Z see -X_c where they see X_c; the division
// models, EUCM and the panorama, functions of the point itself, do not.
TEST(ColmapCamera, PointsBehindTheCamera) {
  const double front[3] = {0.2, -0.1, 1.5}, behind[3] = {-0.2, 0.1, -1.5};
  for (int m = 0; m < cc::kNumModels; ++m) {
    const std::vector<double> params = sample_params(m);
    const std::vector<double> a = pixels(m, params, front), b = pixels(m, params, behind);
    const bool of_the_point = m == cc::kSimpleDivision || m == cc::kDivision || m == cc::kEucm ||
                              m == cc::kEquirectangular;
    EXPECT_TRUE(std::isfinite(b[0]) && std::isfinite(b[1])) << cc::model_name(m);
    if (of_the_point)
      EXPECT_GT(std::hypot(a[0] - b[0], a[1] - b[1]), 10.0) << cc::model_name(m);
    else
      EXPECT_EQ(a, b) << cc::model_name(m);
  }
}

// Where COLMAP 4's projection (pycolmap 4.2.1's Camera.img_from_cam) gives no pixel: every
// model below the epsilon of doubles in depth (2.2e-16 refused, 2.220446049250313e-16 not),
// but the division models, which refuse only where Z^2 < 4 k rho (k = 0.1 at (0.1, 0.2, 1e-20)
// refused, k = -0.1 at (0.1, 0.2, 0) and at (0.1, 0.2, -1) not), and EQUIRECTANGULAR, which
// refuses none.
TEST(ColmapCamera, RefusedWhereColmapGivesNoPixel) {
  for (int m = 0; m < cc::kNumModels; ++m) {
    std::vector<double> params = sample_params(m);
    const bool division = m == cc::kSimpleDivision || m == cc::kDivision;
    const bool by_depth = !division && m != cc::kEquirectangular;
    const double at_epsilon[3] = {0.1, 0.2, 2.220446049250313e-16}, below[3] = {0.1, 0.2, 2.2e-16},
                 behind[3] = {0.1, 0.2, -0.5}, front[3] = {0.1, 0.2, 1.0};
    const auto expected = [&](const double *X) {
      if (division) return X[2] * X[2] - 4 * params.back() * (X[0] * X[0] + X[1] * X[1]) < 0;
      return by_depth && X[2] < DBL_EPSILON;
    };
    EXPECT_FALSE(cc::refused(m, params.data(), front)) << cc::model_name(m);
    for (const double *X : {at_epsilon, below, behind})
      EXPECT_EQ(cc::refused(m, params.data(), X), expected(X)) << cc::model_name(m) << " " << X[2];
    if (by_depth) {
      EXPECT_FALSE(cc::refused(m, params.data(), at_epsilon)) << cc::model_name(m);
      EXPECT_TRUE(cc::refused(m, params.data(), below)) << cc::model_name(m);
    }
    if (!division) continue;
    const double tiny[3] = {0.1, 0.2, 1e-20}, plane[3] = {0.1, 0.2, 0.0}, back[3] = {0.1, 0.2, -1.0};
    params.back() = 0.1;
    EXPECT_TRUE(cc::refused(m, params.data(), tiny)) << cc::model_name(m);
    EXPECT_FALSE(cc::refused(m, params.data(), back)) << cc::model_name(m);
    params.back() = -0.1;
    EXPECT_FALSE(cc::refused(m, params.data(), tiny)) << cc::model_name(m);
    EXPECT_FALSE(cc::refused(m, params.data(), plane)) << cc::model_name(m);
  }
}

// The panorama's seam is straight behind the camera (atan2's branch cut): a point just to the
// right of it is at the left edge, x near 0, one just to the left at the right edge, x near w;
// on either side the derivatives are the same finite numbers.
TEST(ColmapCamera, EquirectangularSeam) {
  const std::vector<double> params = sample_params(cc::kEquirectangular);  // 1000 x 500
  const double left[3] = {-1e-9, 0.5, -2}, right[3] = {1e-9, 0.5, -2};
  const std::vector<double> xl = pixels(cc::kEquirectangular, params, left);
  const std::vector<double> xr = pixels(cc::kEquirectangular, params, right);
  EXPECT_NEAR(xl[0], 0, 1e-6);
  EXPECT_NEAR(xr[0], 1000, 1e-6);
  EXPECT_EQ(xl[1], xr[1]);
  EXPECT_NEAR(xl[1], 250 + 500 / M_PI * std::atan2(0.5, 2), 1e-12);
  double Jl[6], Jr[6], Pl[4], Pr[4];  // dx/dXc, and dx/d(w, h)
  cc::project(cc::kEquirectangular, params.data(), left, nullptr, Pl, Jl);
  cc::project(cc::kEquirectangular, params.data(), right, nullptr, Pr, Jr);
  for (int k = 0; k < 6; ++k) {
    EXPECT_TRUE(std::isfinite(Jl[k])) << k;
    EXPECT_NEAR(Jl[k], Jr[k], 1e-6) << k;
  }
  const double near_left[3] = {-1e-3, 0.5, -2};  // a difference step away from the seam
  expect_derivatives(cc::kEquirectangular, params, near_left, "left of the seam");
}

TEST(ColmapCamera, OpticalAxisProjectsToThePrincipalPoint) {
  const double Xc[3] = {0, 0, 3};
  for (int m = 0; m < cc::kNumModels; ++m) {
    const std::vector<double> params = sample_params(m);
    double x[2];
    cc::project(m, params.data(), Xc, x, nullptr, nullptr);
    const int nf = cc::focal_count(m);
    if (m == cc::kEquirectangular) {  // the panorama's centre
      EXPECT_EQ(x[0], params[0] / 2);
      EXPECT_EQ(x[1], params[1] / 2);
      continue;
    }
    EXPECT_EQ(x[0], params[static_cast<std::size_t>(nf)]) << cc::model_name(m);
    EXPECT_EQ(x[1], params[static_cast<std::size_t>(nf) + 1]) << cc::model_name(m);
  }
}

TEST(ColmapCamera, DerivativesMatchCentralDifferences) {
  const double points[][3] = {{0, 0, 2},        {1e-9, -2e-9, 1}, {0.003, 0.002, 1}, {0.3, -0.2, 1.5},
                              {-0.8, 0.6, 1.2}, {1.5, 0.4, 1},    {-0.02, 0.9, 0.7}, {0.2, -0.1, -1}};
  for (int m = 0; m < cc::kNumModels; ++m)
    for (const auto &X : points) expect_derivatives(m, sample_params(m), X, "at (" + std::to_string(X[0]) + "," + std::to_string(X[1]) + "," + std::to_string(X[2]) + ")");
}

// FOV's omega -> 0 is the pinhole; near it and at it the value and the derivatives stay finite
// and continuous.
TEST(ColmapCamera, FovNearZeroOmega) {
  const double Xc[3] = {0.4, -0.3, 1};
  for (double omega : {0.0, 1e-12, 1e-6, 9.99e-4, 1.001e-3, 1e-2}) {
    const std::vector<double> params = {400, 410, 320, 240, omega};
    expect_derivatives(cc::kFov, params, Xc, "omega " + std::to_string(omega));
  }
  double x0[2], x1[2];
  const std::vector<double> at0 = {400, 410, 320, 240, 0.0}, near0 = {400, 410, 320, 240, 1e-4};
  cc::project(cc::kFov, at0.data(), Xc, x0, nullptr, nullptr);
  EXPECT_EQ(x0[0], 320 + 400 * 0.4);
  EXPECT_EQ(x0[1], 240 - 410 * 0.3);
  cc::project(cc::kFov, near0.data(), Xc, x1, nullptr, nullptr);
  // d x / d omega is 0 at omega = 0: the change is second order, (omega^2 / 12)(1 - 4 r^2) u fx.
  EXPECT_NEAR(x1[0] - x0[0], 1e-8 / 12 * (1 - 4 * 0.25) * 0.4 * 400, 1e-12);
  // The two branches of omega / tan agree at the switch.
  double xa[2], xb[2];
  const std::vector<double> below = {400, 410, 320, 240, 1e-3 - 1e-15}, above = {400, 410, 320, 240, 1e-3 + 1e-15};
  cc::project(cc::kFov, below.data(), Xc, xa, nullptr, nullptr);
  cc::project(cc::kFov, above.data(), Xc, xb, nullptr, nullptr);
  EXPECT_NEAR(xa[0], xb[0], 1e-11);
  EXPECT_NEAR(xa[1], xb[1], 1e-11);
}

// The fisheye models' theta / r: the series below the switch and atan above agree.
TEST(ColmapCamera, FisheyeSeriesMeetsClosedForm) {
  const std::vector<double> params = sample_params(cc::kOpenCVFisheye);
  const double r = 1e-2;  // r^2 = 1e-4, the switch
  double xa[2], xb[2];
  const double below[3] = {r * (1 - 1e-9), 0, 1}, above[3] = {r * (1 + 1e-9), 0, 1};
  cc::project(cc::kOpenCVFisheye, params.data(), below, xa, nullptr, nullptr);
  cc::project(cc::kOpenCVFisheye, params.data(), above, xb, nullptr, nullptr);
  // The difference is the slope (about fx) times the step 2e-11, not a jump.
  EXPECT_NEAR(xb[0] - xa[0], 350 * 2e-11, 1e-11);
}

namespace {

std::vector<cc::Camera> sample_cameras() {
  std::vector<cc::Camera> cams;
  for (int m = 0; m < cc::kNumModels; ++m) {
    cc::Camera c;
    c.model = m;
    c.params = sample_params(m);
    c.q = {0.9 + 0.01 * m, 0.1, -0.2 + 0.03 * m, 0.05};  // not unit: the model normalizes it
    c.t = {0.1 * m, -0.2, 3 + 0.1 * m};
    cams.push_back(c);
  }
  return cams;
}


// Camera j's dx/da at a and dx/db at each point of `points` against central differences; the
// parameters from pose_params + its model's count on are padding, which moves nothing. Camera
// j is of COLMAP model j.
template <class Model>
void expect_sba_derivatives(const Model &model, int j, const std::vector<double> &a,
                            const std::vector<double> &points, int pose_params) {
  const int cnp = model.cnp();
  for (std::size_t i = 0; i < points.size() / 3; ++i) {
    const double *b = points.data() + 3 * i;
    std::vector<double> A(2 * static_cast<std::size_t>(cnp));
    double B[6], x[2];
    model.project_jacobian(j, a.data(), b, x, A.data(), B);
    for (int c = 0; c < cnp; ++c) {
      const double h = 1e-6 * std::max(1.0, std::fabs(a[static_cast<std::size_t>(c)]));
      std::vector<double> lo = a, hi = a;
      lo[static_cast<std::size_t>(c)] -= h;
      hi[static_cast<std::size_t>(c)] += h;
      double xl[2], xh[2];
      model.project(j, lo.data(), b, xl);
      model.project(j, hi.data(), b, xh);
      for (int r = 0; r < 2; ++r) {
        const double num = (xh[r] - xl[r]) / (2 * h);
        EXPECT_NEAR(A[static_cast<std::size_t>(r * cnp + c)], num, 1e-6 * std::max(1.0, std::fabs(num)))
            << cc::model_name(j) << " a" << c << " row " << r;
      }
      if (c >= pose_params + cc::param_count(j)) {  // padding: no effect at all
        EXPECT_EQ(A[static_cast<std::size_t>(c)], 0.0);
        EXPECT_EQ(A[static_cast<std::size_t>(cnp + c)], 0.0);
      }
    }
    for (int c = 0; c < 3; ++c) {
      double lo[3] = {b[0], b[1], b[2]}, hi[3] = {b[0], b[1], b[2]};
      lo[c] -= 1e-6;
      hi[c] += 1e-6;
      double xl[2], xh[2];
      model.project(j, a.data(), lo, xl);
      model.project(j, a.data(), hi, xh);
      for (int r = 0; r < 2; ++r) {
        const double num = (xh[r] - xl[r]) / 2e-6;
        EXPECT_NEAR(B[r * 3 + c], num, 1e-6 * std::max(1.0, std::fabs(num))) << cc::model_name(j) << " b" << c;
      }
    }
  }
}
using Callback = void (*)(double *, struct sba_crsm *, int *, int *, double *, void *);

// The expert callbacks func and fjac of `model` at p (m cameras, then the points), over the
// index of rowptr, colidx and val (the ordinals), give project_jacobian's numbers bit for bit
// at the ordinals the index names. Returns func's projections.
template <class Model>
std::vector<double> expect_callbacks_agree(const Model &model, Callback func, Callback fjac, std::vector<double> &p,
                                           std::vector<int> &rowptr, std::vector<int> &colidx,
                                           std::vector<int> &val) {
  const int m = model.ncameras(), n = model.npoints(), cnp = model.cnp();
  const int nvis = static_cast<int>(val.size());
  sba_crsm idx{n, m, nvis, val.data(), colidx.data(), rowptr.data()};
  std::vector<double> hx(2 * static_cast<std::size_t>(nvis)), jac(static_cast<std::size_t>(nvis) * 2 * (cnp + 3));
  func(p.data(), &idx, nullptr, nullptr, hx.data(), cc::as_adata(model));
  fjac(p.data(), &idx, nullptr, nullptr, jac.data(), cc::as_adata(model));
  for (int i = 0; i < n; ++i)
    for (int e = rowptr[i]; e < rowptr[i + 1]; ++e) {
      const int j = colidx[e], k = val[e];
      double x[2], B[6];
      std::vector<double> A(2 * static_cast<std::size_t>(cnp));
      model.project_jacobian(j, p.data() + j * cnp, p.data() + m * cnp + 3 * i, x, A.data(), B);
      EXPECT_EQ(hx[2 * k], x[0]);
      EXPECT_EQ(hx[2 * k + 1], x[1]);
      const double *blk = jac.data() + static_cast<std::size_t>(k) * 2 * (cnp + 3);
      for (int c = 0; c < 2 * cnp; ++c) EXPECT_EQ(blk[c], A[static_cast<std::size_t>(c)]);
      for (int c = 0; c < 6; ++c) EXPECT_EQ(blk[2 * cnp + c], B[c]);
    }
  return hx;
}

}  // namespace

// The pose part: dx/da (rotation v, translation, parameters, padding) and dx/db by differences.
TEST(ColmapCamera, SbaModelDerivatives) {
  const std::vector<double> points = {0.2, -0.1, 0.3, -0.5, 0.4, -0.2};
  const cc::CameraModel model(sample_cameras(), points);
  const int cnp = model.cnp();
  ASSERT_EQ(cnp, 6 + 16);
  for (int j = 0; j < model.ncameras(); ++j) {
    std::vector<double> a(model.initial_camera_params().begin() + j * cnp,
                          model.initial_camera_params().begin() + (j + 1) * cnp);
    a[0] = 0.01;  // off v = 0, so the rotation derivative is not only the one at the identity
    a[1] = -0.02;
    a[2] = 0.015;
    expect_sba_derivatives(model, j, a, points, cc::kPoseParams);
  }
}

// At v = 0 the camera is the input one: the projection is the model's of R(q0) X + t.
TEST(ColmapCamera, SbaModelStartsAtTheInputPose) {
  const std::vector<cc::Camera> cams = sample_cameras();
  const std::vector<double> points = {0.2, -0.1, 0.3};
  const cc::CameraModel model(cams, points);
  for (int j = 0; j < model.ncameras(); ++j) {
    const cc::Camera &c = model.input_camera(j);
    double R[9];
    sbacameras::euclidean::rotation_matrix(c.q, R);
    double Xc[3];
    for (int r = 0; r < 3; ++r)
      Xc[r] = R[3 * r] * points[0] + R[3 * r + 1] * points[1] + R[3 * r + 2] * points[2] + c.t[static_cast<std::size_t>(r)];
    double want[2], got[2];
    cc::project(c.model, c.params.data(), Xc, want, nullptr, nullptr);
    model.project(j, model.initial_camera_params().data() + j * model.cnp(), points.data(), got);
    EXPECT_NEAR(got[0], want[0], 1e-9);
    EXPECT_NEAR(got[1], want[1], 1e-9);
    const cc::Camera back = model.camera(j, model.initial_camera_params().data() + j * model.cnp());
    EXPECT_EQ(back.params, cams[static_cast<std::size_t>(j)].params);
    EXPECT_EQ(back.t, cams[static_cast<std::size_t>(j)].t);
  }
}

// The expert callbacks give project_jacobian's numbers, at the ordinals the index names,
// also when called on a part of the rows (parallel_callbacks). One camera of each model: the
// callbacks' code for the common models gives the bits of project_jacobian's code for any.
TEST(ColmapCamera, ExpertCallbacksAgreeWithTheModel) {
  const std::vector<cc::Camera> cams = sample_cameras();
  const std::vector<double> points = {0.2, -0.1, 0.3, -0.5, 0.4, -0.2, 0.1, 0.1, 0.1, -0.1, 0.2, 0.0};
  const cc::CameraModel model(cams, points);
  const int m = model.ncameras(), n = model.npoints(), cnp = model.cnp();
  std::vector<double> p = model.initial_camera_params();
  for (int j = 0; j < m; ++j) p[static_cast<std::size_t>(j * cnp)] = 0.01 * j;
  p.insert(p.end(), points.begin(), points.end());
  // Point i < 3 sees cameras i, i+3, i+6, ..., the last point every camera (each camera's
  // per-call set-up is then used again after the others'): ordinals in row order.
  std::vector<int> rowptr{0}, colidx, val;
  for (int i = 0; i < n; ++i) {
    for (int j = i < 3 ? i : 0; j < m; j += i < 3 ? 3 : 1) {
      colidx.push_back(j);
      val.push_back(static_cast<int>(val.size()));
    }
    rowptr.push_back(static_cast<int>(colidx.size()));
  }
  const int nvis = static_cast<int>(val.size());
  const std::vector<double> hx =
      expect_callbacks_agree(model, cc::motstr_func, cc::motstr_fjac, p, rowptr, colidx, val);
  // The index a thread is given under parallel_callbacks: every row, only the last one not
  // empty. Only that row's slots are written.
  std::vector<double> part(hx.size(), -1.0);
  std::vector<int> lastptr(static_cast<std::size_t>(n) + 1, rowptr[n - 1]);
  lastptr[static_cast<std::size_t>(n)] = rowptr[n];
  sba_crsm last{n, m, nvis, val.data(), colidx.data(), lastptr.data()};
  cc::motstr_func(p.data(), &last, nullptr, nullptr, part.data(), cc::as_adata(model));
  for (int k = 0; k < nvis; ++k) {
    const bool mine = k >= rowptr[n - 1];
    EXPECT_EQ(part[2 * static_cast<std::size_t>(k)], mine ? hx[2 * static_cast<std::size_t>(k)] : -1.0) << k;
  }
}

// Given the measurements, the callbacks cost a projection COLMAP refuses nothing, as COLMAP 4's
// cost does: hx is its measurement and its Jacobian zero. The others, and every projection
// without measurements, are project_jacobian's.
TEST(ColmapCamera, RefusedProjectionsCostNothingGivenTheMeasurements) {
  const std::vector<double> points = {0.2, -0.1, 0.3, 0.1, 0.2, -12.0, -0.3, 0.1, 0.2};  // the second behind
  cc::CameraModel model(sample_cameras(), points);
  const int m = model.ncameras(), n = model.npoints(), cnp = model.cnp();
  std::vector<double> p = model.initial_camera_params();
  p.insert(p.end(), points.begin(), points.end());
  std::vector<int> rowptr{0}, colidx, val;  // every point in every camera
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < m; ++j) {
      colidx.push_back(j);
      val.push_back(static_cast<int>(val.size()));
    }
    rowptr.push_back(static_cast<int>(colidx.size()));
  }
  const int nvis = static_cast<int>(val.size());
  std::vector<double> x(2 * static_cast<std::size_t>(nvis));
  for (std::size_t k = 0; k < x.size(); ++k) x[k] = 100.0 + static_cast<double>(k);
  sba_crsm idx{n, m, nvis, val.data(), colidx.data(), rowptr.data()};
  const std::size_t block = 2 * static_cast<std::size_t>(cnp + 3);
  std::vector<double> hx_free(x.size()), jac_free(static_cast<std::size_t>(nvis) * block);
  cc::motstr_func(p.data(), &idx, nullptr, nullptr, hx_free.data(), cc::as_adata(model));
  cc::motstr_fjac(p.data(), &idx, nullptr, nullptr, jac_free.data(), cc::as_adata(model));
  model.set_measurements(x.data());
  std::vector<double> hx(x.size()), jac(jac_free.size());
  cc::motstr_func(p.data(), &idx, nullptr, nullptr, hx.data(), cc::as_adata(model));
  cc::motstr_fjac(p.data(), &idx, nullptr, nullptr, jac.data(), cc::as_adata(model));
  int refused = 0, shown = 0;
  for (int i = 0; i < n; ++i)
    for (int e = rowptr[i]; e < rowptr[i + 1]; ++e) {
      const int j = colidx[e];
      const std::size_t k = static_cast<std::size_t>(val[e]);
      double px[2];
      const bool ok = model.project(j, p.data() + static_cast<std::size_t>(j) * cnp, points.data() + 3 * i, px);
      EXPECT_EQ(hx_free[2 * k], px[0]);
      EXPECT_EQ(hx_free[2 * k + 1], px[1]);
      const double *J = jac.data() + k * block;
      if (ok) {
        ++shown;
        EXPECT_EQ(hx[2 * k], px[0]) << j << " " << i;
        EXPECT_TRUE(std::equal(J, J + block, jac_free.data() + k * block)) << j << " " << i;
      } else {
        ++refused;
        EXPECT_EQ(hx[2 * k], x[2 * k]) << j << " " << i;
        EXPECT_EQ(hx[2 * k + 1], x[2 * k + 1]) << j << " " << i;
        EXPECT_TRUE(std::all_of(J, J + block, [](double v) { return v == 0.0; })) << j << " " << i;
      }
    }
  // The point behind: refused by every camera but the two division models and the panorama.
  EXPECT_EQ(refused, cc::kNumModels - 3);
  EXPECT_EQ(shown, 3 * cc::kNumModels - refused);
}

TEST(ColmapCamera, RefusesBadCameras) {
  std::vector<cc::Camera> cams(1);
  cams[0].model = 18;
  EXPECT_THROW(cc::CameraModel(cams, {}), std::invalid_argument);
  cams[0].model = cc::kOpenCV;
  cams[0].params = {1, 2, 3};
  EXPECT_THROW(cc::CameraModel(cams, {}), std::invalid_argument);
  cams[0].params = sample_params(cc::kOpenCV);
  cams[0].q = {0, 0, 0, 0};
  EXPECT_THROW(cc::CameraModel(cams, {}), std::invalid_argument);
  cams[0].q = {1, 0, 0, 0};
  EXPECT_THROW(cc::CameraModel(cams, {1, 2}), std::invalid_argument);
}

// A held parameter is read from the initial camera whatever a holds, and its column is zero.
TEST(ColmapCamera, HeldParametersAreConstants) {
  const std::vector<cc::Camera> cams = sample_cameras();
  const std::vector<double> points = {0.2, -0.1, 0.3};
  const cc::CameraModel free_model(cams, points);
  const int cnp = free_model.cnp(), m = free_model.ncameras();
  std::vector<char> held(static_cast<std::size_t>(m * cnp), 0);
  for (int j = 0; j < m; ++j) {
    held[static_cast<std::size_t>(j * cnp + 1)] = 1;  // v2
    held[static_cast<std::size_t>(j * cnp + 6)] = 1;  // f or fx
    held[static_cast<std::size_t>(j * cnp + cnp - 1)] = 1;  // the last slot
  }
  const cc::CameraModel model(cams, points, held);
  for (int j = 0; j < m; ++j) {
    std::vector<double> a(free_model.initial_camera(j), free_model.initial_camera(j) + cnp);
    std::vector<double> moved = a;
    moved[1] = 0.3;
    moved[6] *= 2;
    moved[static_cast<std::size_t>(cnp - 1)] += 1;
    double x0[2], x1[2];
    free_model.project(j, a.data(), points.data(), x0);
    model.project(j, moved.data(), points.data(), x1);
    EXPECT_EQ(x0[0], x1[0]) << j;
    EXPECT_EQ(x0[1], x1[1]) << j;
    std::vector<double> A(2 * static_cast<std::size_t>(cnp)), Af(A.size());
    model.project_jacobian(j, a.data(), points.data(), nullptr, A.data(), nullptr);
    free_model.project_jacobian(j, a.data(), points.data(), nullptr, Af.data(), nullptr);
    for (int r = 0; r < 2; ++r)
      for (int c = 0; c < cnp; ++c) {
        const double want = held[static_cast<std::size_t>(j * cnp + c)] ? 0.0 : Af[static_cast<std::size_t>(r * cnp + c)];
        EXPECT_EQ(A[static_cast<std::size_t>(r * cnp + c)], want) << j << " " << c;
      }
    EXPECT_NE(Af[6], 0.0);  // the held column is not zero by itself
    const cc::Camera back = model.camera(j, moved.data());
    EXPECT_EQ(back.params, cams[static_cast<std::size_t>(j)].params);
  }
  EXPECT_THROW(cc::CameraModel(cams, points, std::vector<char>(3, 0)), std::invalid_argument);
}

// A camera that carries only some of its model's parameters (kept) projects as the full model
// with the others at their given values, its columns are the full model's columns of those
// parameters, and camera() gives the others back as given; cnp is that of the count kept.
TEST(ColmapCamera, KeptParametersAreTheFullModelsColumns) {
  const std::vector<cc::Camera> cams = sample_cameras();
  const std::vector<double> points = {0.2, -0.1, 0.3};
  const cc::CameraModel full(cams, points);
  const int m = full.ncameras(), cnp = full.cnp();
  std::vector<std::vector<int>> kept(static_cast<std::size_t>(m));
  int most = 0;
  for (int j = 0; j < m; ++j) {  // every other parameter, from the second: the first held
    for (int k = 1; k < cc::param_count(cams[static_cast<std::size_t>(j)].model); k += 2)
      kept[static_cast<std::size_t>(j)].push_back(k);
    most = std::max(most, static_cast<int>(kept[static_cast<std::size_t>(j)].size()));
  }
  const cc::CameraModel model(cams, points, {}, kept);
  const int kn = model.cnp();
  EXPECT_EQ(kn, cc::camera_params(most));
  EXPECT_LT(kn, cnp);
  for (int j = 0; j < m; ++j) {
    const std::vector<int> &kj = kept[static_cast<std::size_t>(j)];
    // The full model's parameters, moved; the compact vector carries the pose and the kept ones.
    std::vector<double> a(full.initial_camera(j), full.initial_camera(j) + cnp), b(static_cast<std::size_t>(kn), 0.0);
    a[0] = 0.01;
    a[5] += 0.2;
    for (std::size_t s = 0; s < kj.size(); ++s) a[static_cast<std::size_t>(6 + kj[s])] *= 1.01;
    std::copy(a.begin(), a.begin() + 6, b.begin());
    for (std::size_t s = 0; s < kj.size(); ++s) b[6 + s] = a[static_cast<std::size_t>(6 + kj[s])];
    for (int k = 0; k < cc::param_count(cams[static_cast<std::size_t>(j)].model); ++k) {
      const auto it = std::find(kj.begin(), kj.end(), k);
      EXPECT_EQ(model.param_column(j, k), it == kj.end() ? -1 : 6 + static_cast<int>(it - kj.begin())) << j << " " << k;
    }
    double x0[2], x1[2];
    std::vector<double> A(2 * static_cast<std::size_t>(cnp)), Ak(2 * static_cast<std::size_t>(kn)), B(6), Bk(6);
    full.project_jacobian(j, a.data(), points.data(), x0, A.data(), B.data());
    model.project_jacobian(j, b.data(), points.data(), x1, Ak.data(), Bk.data());
    EXPECT_EQ(x0[0], x1[0]) << j;
    EXPECT_EQ(x0[1], x1[1]) << j;
    EXPECT_EQ(B, Bk) << j;
    for (int r = 0; r < 2; ++r)
      for (int c = 0; c < kn; ++c) {
        const std::size_t s = static_cast<std::size_t>(c - 6);
        const double want = c < 6 ? A[static_cast<std::size_t>(r * cnp + c)]
                            : s < kj.size() ? A[static_cast<std::size_t>(r * cnp + 6 + kj[s])]
                                            : 0.0;  // padding
        EXPECT_EQ(Ak[static_cast<std::size_t>(r * kn + c)], want) << j << " " << r << " " << c;
      }
    const cc::Camera back = model.camera(j, b.data()), want = full.camera(j, a.data());
    EXPECT_EQ(back.params, want.params) << j;
    EXPECT_EQ(back.t, want.t) << j;
  }
  const std::vector<std::vector<int>> unordered(static_cast<std::size_t>(m), std::vector<int>{1, 0});
  EXPECT_THROW(cc::CameraModel(cams, points, {}, unordered), std::invalid_argument);
  const std::vector<std::vector<int>> beyond(static_cast<std::size_t>(m), std::vector<int>{cc::kMaxParams});
  EXPECT_THROW(cc::CameraModel(cams, points, {}, beyond), std::invalid_argument);
  EXPECT_THROW(cc::CameraModel(cams, points, {}, std::vector<std::vector<int>>(2)), std::invalid_argument);
}

// ---- the rig camera model ----

namespace {

// An image of every model: a frame pose, and a camera pose in the rig that is not the
// identity (the reference camera's is checked apart).
std::vector<cc::RigImage> sample_rig_images() {
  std::vector<cc::RigImage> images;
  for (int m = 0; m < cc::kNumModels; ++m) {
    cc::RigImage im;
    im.model = m;
    im.params = sample_params(m);
    im.q_frame = {0.9 + 0.01 * m, 0.1, -0.2 + 0.03 * m, 0.05};  // not unit: the model normalizes it
    im.t_frame = {0.1 * m, -0.2, 3 + 0.1 * m};
    im.q_sensor = {2.0, -0.1 * (m % 3), 0.15, 0.02 * m};
    im.t_sensor = {-0.3, 0.05 * m, 0.2};
    images.push_back(im);
  }
  return images;
}

// a_j moved off v_f = v_s = 0, so that neither rotation derivative is only the one at the
// identity.
std::vector<double> moved_rig_params(const cc::RigCameraModel &model, int j) {
  std::vector<double> a(model.initial_camera(j), model.initial_camera(j) + model.cnp());
  const double v[6] = {0.01, -0.02, 0.015, -0.012, 0.008, 0.02};
  for (int k = 0; k < 3; ++k) {
    a[static_cast<std::size_t>(k)] = v[k];
    a[static_cast<std::size_t>(6 + k)] = v[3 + k];
  }
  return a;
}

// R(q) X + t with R from the quaternion q (not necessarily unit).
std::array<double, 3> transformed(const sbacameras::euclidean::Quaternion &q, const std::array<double, 3> &t,
                                  const double X[3]) {
  double R[9];
  sbacameras::euclidean::rotation_matrix(sbacameras::euclidean::normalized_rotation(q), R);
  std::array<double, 3> out;
  for (int r = 0; r < 3; ++r)
    out[static_cast<std::size_t>(r)] = R[3 * r] * X[0] + R[3 * r + 1] * X[1] + R[3 * r + 2] * X[2] + t[static_cast<std::size_t>(r)];
  return out;
}

}  // namespace

TEST(ColmapRigCamera, ParameterCount) {
  // 12 pose parameters and the model's, at least the library's 16-wide kernel.
  EXPECT_EQ(cc::rig_camera_params(2), 16);
  EXPECT_EQ(cc::rig_camera_params(4), 16);
  EXPECT_EQ(cc::rig_camera_params(5), 17);
  EXPECT_EQ(cc::rig_camera_params(16), 28);
  const cc::RigCameraModel model(sample_rig_images(), {0.1, 0.2, 0.3});
  EXPECT_EQ(model.cnp(), 28);
  EXPECT_EQ(model.ncameras(), cc::kNumModels);
}

// dx/da (frame pose, sensor pose, parameters, padding) and dx/db against central differences.
TEST(ColmapRigCamera, DerivativesMatchCentralDifferences) {
  const std::vector<double> points = {0.2, -0.1, 0.3, -0.5, 0.4, -0.2};
  const cc::RigCameraModel model(sample_rig_images(), points);
  for (int j = 0; j < model.ncameras(); ++j)
    expect_sba_derivatives(model, j, moved_rig_params(model, j), points, cc::kRigPoseParams);
}

// At the start the projection is the model's of R_s (R_f X + t_f) + t_s; the image and its
// composed camera come back as given.
TEST(ColmapRigCamera, StartsAtTheComposedPose) {
  const std::vector<cc::RigImage> images = sample_rig_images();
  const std::vector<double> points = {0.2, -0.1, 0.3};
  const cc::RigCameraModel model(images, points);
  for (int j = 0; j < model.ncameras(); ++j) {
    const cc::RigImage &in = images[static_cast<std::size_t>(j)];
    const std::array<double, 3> Xr = transformed(in.q_frame, in.t_frame, points.data());
    const std::array<double, 3> Xc = transformed(in.q_sensor, in.t_sensor, Xr.data());
    double want[2], got[2];
    cc::project(in.model, in.params.data(), Xc.data(), want, nullptr, nullptr);
    model.project(j, model.initial_camera(j), points.data(), got);
    EXPECT_NEAR(got[0], want[0], 1e-9) << j;
    EXPECT_NEAR(got[1], want[1], 1e-9) << j;
    const cc::RigImage back = model.image(j, model.initial_camera(j));
    EXPECT_EQ(back.params, in.params);
    EXPECT_EQ(back.t_frame, in.t_frame);
    EXPECT_EQ(back.t_sensor, in.t_sensor);
    // The composed camera projects the point where the rig does.
    const cc::Camera c = model.camera(j, model.initial_camera(j));
    const std::array<double, 3> Xc2 = transformed(c.q, c.t, points.data());
    for (int k = 0; k < 3; ++k) EXPECT_NEAR(Xc2[static_cast<std::size_t>(k)], Xc[static_cast<std::size_t>(k)], 1e-12) << j;
    EXPECT_NEAR(c.q.w * c.q.w + c.q.x * c.q.x + c.q.y * c.q.y + c.q.z * c.q.z, 1.0, 1e-15);
  }
}

// A rig's reference camera (the identity in the rig) is the single-camera model with the
// frame's pose, bit for bit: its pixels and its frame's columns are CameraModel's, and its
// translation in the rig moves it as its translation in the world does.
TEST(ColmapRigCamera, ReferenceCameraIsTheFramesPose) {
  std::vector<cc::RigImage> images = sample_rig_images();
  std::vector<cc::Camera> cameras;
  for (cc::RigImage &im : images) {
    im.q_sensor = {};
    im.t_sensor = {};
    cameras.push_back({im.model, im.params, im.q_frame, im.t_frame});
  }
  const std::vector<double> points = {0.2, -0.1, 0.3, -0.5, 0.4, -0.2};
  const cc::RigCameraModel rig(images, points);
  const cc::CameraModel single(cameras, points);
  const int cr = rig.cnp(), cs = single.cnp();
  for (int j = 0; j < rig.ncameras(); ++j) {
    std::vector<double> a = moved_rig_params(rig, j);
    for (int k = 6; k < 12; ++k) a[static_cast<std::size_t>(k)] = 0;  // the identity
    std::vector<double> s(single.initial_camera(j), single.initial_camera(j) + cs);
    std::copy(a.begin(), a.begin() + 3, s.begin());
    for (int i = 0; i < 2; ++i) {
      const double *b = points.data() + 3 * i;
      std::vector<double> A(2 * static_cast<std::size_t>(cr)), As(2 * static_cast<std::size_t>(cs));
      double x[2], xs[2], B[6], Bs[6];
      rig.project_jacobian(j, a.data(), b, x, A.data(), B);
      single.project_jacobian(j, s.data(), b, xs, As.data(), Bs);
      EXPECT_EQ(x[0], xs[0]) << j;
      EXPECT_EQ(x[1], xs[1]) << j;
      for (int r = 0; r < 2; ++r) {
        for (int c = 0; c < 6; ++c) {
          EXPECT_EQ(A[static_cast<std::size_t>(r * cr + c)], As[static_cast<std::size_t>(r * cs + c)]) << j << " " << c;
          EXPECT_EQ(A[static_cast<std::size_t>(r * cr + 9 + c % 3)], As[static_cast<std::size_t>(r * cs + 3 + c % 3)]);
        }
        for (int c = 0; c < cc::param_count(j); ++c)
          EXPECT_EQ(A[static_cast<std::size_t>(r * cr + 12 + c)], As[static_cast<std::size_t>(r * cs + 6 + c)]);
      }
      for (int c = 0; c < 6; ++c) EXPECT_EQ(B[c], Bs[c]);
    }
  }
}

// The expert callbacks give project_jacobian's numbers at the ordinals the index names.
TEST(ColmapRigCamera, ExpertCallbacksAgreeWithTheModel) {
  const std::vector<double> points = {0.2, -0.1, 0.3, -0.5, 0.4, -0.2, 0.1, 0.1, 0.1};
  const cc::RigCameraModel model(sample_rig_images(), points);
  const int m = model.ncameras(), n = model.npoints();
  std::vector<double> p;
  for (int j = 0; j < m; ++j) {
    const std::vector<double> a = moved_rig_params(model, j);
    p.insert(p.end(), a.begin(), a.end());
  }
  p.insert(p.end(), points.begin(), points.end());
  std::vector<int> rowptr{0}, colidx, val;  // point i sees cameras i, i+3, ...
  for (int i = 0; i < n; ++i) {
    for (int j = i; j < m; j += 3) {
      colidx.push_back(j);
      val.push_back(static_cast<int>(val.size()));
    }
    rowptr.push_back(static_cast<int>(colidx.size()));
  }
  expect_callbacks_agree(model, cc::rig_motstr_func, cc::rig_motstr_fjac, p, rowptr, colidx, val);
}

// A held parameter (a frame rotation, a sensor translation, a focal length) is read from the
// initial image whatever a holds, and its column is zero.
TEST(ColmapRigCamera, HeldParametersAreConstants) {
  const std::vector<cc::RigImage> images = sample_rig_images();
  const std::vector<double> points = {0.2, -0.1, 0.3};
  const cc::RigCameraModel free_model(images, points);
  const int cnp = free_model.cnp(), m = free_model.ncameras();
  std::vector<char> held(static_cast<std::size_t>(m * cnp), 0);
  for (int j = 0; j < m; ++j)
    for (int c : {1, 10, 12}) held[static_cast<std::size_t>(j * cnp + c)] = 1;  // v_f2, t_s2, f or fx
  const cc::RigCameraModel model(images, points, held);
  for (int j = 0; j < m; ++j) {
    const std::vector<double> a = moved_rig_params(free_model, j);
    std::vector<double> moved = a;
    moved[1] = 0.3;
    moved[10] += 1;
    moved[12] *= 2;
    std::vector<double> a_held = a;  // what the held model reads
    for (int c : {1, 10, 12}) a_held[static_cast<std::size_t>(c)] = free_model.initial_camera(j)[c];
    double x0[2], x1[2];
    free_model.project(j, a_held.data(), points.data(), x0);
    model.project(j, moved.data(), points.data(), x1);
    EXPECT_EQ(x0[0], x1[0]) << j;
    EXPECT_EQ(x0[1], x1[1]) << j;
    std::vector<double> A(2 * static_cast<std::size_t>(cnp)), Af(A.size());
    model.project_jacobian(j, a_held.data(), points.data(), nullptr, A.data(), nullptr);
    free_model.project_jacobian(j, a_held.data(), points.data(), nullptr, Af.data(), nullptr);
    for (int r = 0; r < 2; ++r)
      for (int c = 0; c < cnp; ++c) {
        const double want = held[static_cast<std::size_t>(j * cnp + c)] ? 0.0 : Af[static_cast<std::size_t>(r * cnp + c)];
        EXPECT_EQ(A[static_cast<std::size_t>(r * cnp + c)], want) << j << " " << c;
      }
    const cc::RigImage back = model.image(j, moved.data());
    EXPECT_EQ(back.params, images[static_cast<std::size_t>(j)].params);
    EXPECT_EQ(back.t_sensor, images[static_cast<std::size_t>(j)].t_sensor);
  }
  EXPECT_THROW(cc::RigCameraModel(images, points, std::vector<char>(3, 0)), std::invalid_argument);
  std::vector<cc::RigImage> bad = images;
  bad[0].q_sensor = {0, 0, 0, 0};
  EXPECT_THROW(cc::RigCameraModel(bad, points), std::invalid_argument);
}

namespace {

// Columns col..col+2 of the 2 x cnp A against H Jv, H the columns h..h+2 of A: equal to
// rounding.
void expect_chained(const std::vector<double> &A, int cnp, int col, int h, const double Jv[9], const char *what) {
  for (int r = 0; r < 2; ++r) {
    const double *H = A.data() + r * cnp + h;
    const double scale = std::fabs(H[0]) + std::fabs(H[1]) + std::fabs(H[2]);
    for (int c = 0; c < 3; ++c) {
      const double expected = H[0] * Jv[c] + H[1] * Jv[3 + c] + H[2] * Jv[6 + c];
      double size = 0;
      for (int k = 0; k < 3; ++k) size = std::max(size, std::fabs(Jv[k * 3 + c]));
      EXPECT_NEAR(A[static_cast<std::size_t>(r * cnp + col + c)], expected, 1e-14 * (1 + scale * size))
          << what << " row " << r << " column " << col + c;
    }
  }
}

// d(R(qs(v)) Y)/dv of the quaternion correction, differentiated as a quaternion.
void quaternion_derivative(const double v[3], const double *R0, const double X[3], double Jv[9]) {
  double Y[3];
  sbaeuc_mat3_vec(R0, X, Y);
  const sbaeuc_correction qs = sbaeuc_correction_of(v);
  sbaeuc_rotation_derivative(&qs, Y, Jv);
}

// Corrections inside the unit ball and outside it, where the rotation is the boundary one.
constexpr double kCorrections[][3] = {{0, 0, 0}, {0.01, -0.02, 0.015}, {-0.4, 0.3, 0.5}, {0.9, -0.6, 0.3}};

}  // namespace

// The rotation's columns of A are the translation's (dx/dt = dx/dX_c) times the quaternion's
// derivative d(R(qs(v)) R0 X)/dv, to rounding, however the model forms them.
TEST(ColmapCamera, RotationColumnsAreTheQuaternionDerivative) {
  const std::vector<double> points = {0.2, -0.1, 0.3, -0.5, 0.4, -0.2};
  const cc::CameraModel model(sample_cameras(), points);
  const int cnp = model.cnp();
  int checked = 0;
  for (int j = 0; j < model.ncameras(); ++j)
    for (const auto &v : kCorrections) {
      std::vector<double> a(model.initial_camera(j), model.initial_camera(j) + cnp);
      std::copy(v, v + 3, a.begin());
      for (std::size_t i = 0; i < points.size() / 3; ++i) {
        std::vector<double> A(2 * static_cast<std::size_t>(cnp));
        double x[2], B[6], Jv[9];
        if (!model.project_jacobian(j, a.data(), points.data() + 3 * i, x, A.data(), B)) continue;  // no pixel
        ++checked;
        quaternion_derivative(v, model.initial_rotation(j), points.data() + 3 * i, Jv);
        expect_chained(A, cnp, 0, 3, Jv, cc::model_name(j));
      }
    }
  EXPECT_EQ(checked, model.ncameras() * 8);  // every corrected camera sees both points
}

// The same for a rig image's frame rotation (beside the frame's translation, dx/dt_f = dx/dX_r)
// and its sensor rotation (beside the sensor's, dx/dt_s = dx/dX_c) at X_r = R_f X + t_f.
TEST(ColmapRigCamera, RotationColumnsAreTheQuaternionDerivative) {
  const std::vector<double> points = {0.2, -0.1, 0.3, -0.5, 0.4, -0.2};
  const cc::RigCameraModel model(sample_rig_images(), points);
  const int cnp = model.cnp();
  int checked = 0;
  for (int j = 0; j < model.ncameras(); ++j)
    for (const auto &v : kCorrections) {
      std::vector<double> a = moved_rig_params(model, j);
      std::copy(v, v + 3, a.begin());
      std::copy(v, v + 3, a.begin() + 6);
      for (std::size_t i = 0; i < points.size() / 3; ++i) {
        const double *X = points.data() + 3 * i;
        std::vector<double> A(2 * static_cast<std::size_t>(cnp));
        double x[2], B[6], Jv[9];
        if (!model.project_jacobian(j, a.data(), X, x, A.data(), B)) continue;  // no pixel
        ++checked;
        quaternion_derivative(v, model.initial_frame_rotation(j), X, Jv);
        expect_chained(A, cnp, 0, 3, Jv, cc::model_name(j));
        const sbaeuc_correction qf = sbaeuc_correction_of(v);
        double Rf[9], Mf[9], Xr[3];
        sbaeuc_rotation_matrix(qf.w, qf.u[0], qf.u[1], qf.u[2], Rf);
        for (int r = 0; r < 3; ++r)
          for (int c = 0; c < 3; ++c) {
            const double *R0 = model.initial_frame_rotation(j);
            Mf[r * 3 + c] = Rf[r * 3] * R0[c] + Rf[r * 3 + 1] * R0[3 + c] + Rf[r * 3 + 2] * R0[6 + c];
          }
        sbaeuc_mat3_vec(Mf, X, Xr);
        for (int r = 0; r < 3; ++r) Xr[r] += a[static_cast<std::size_t>(3 + r)];
        quaternion_derivative(v, model.initial_sensor_rotation(j), Xr, Jv);
        expect_chained(A, cnp, 6, 9, Jv, cc::model_name(j));
      }
    }
  EXPECT_EQ(checked, 112);  // of 144: the larger corrections turn some points out of view
}

// CachedProjection keeps each camera's frame while its parameters keep their bits: its
// projections, and whether the model shows the point, are project()'s, bit for bit, as the
// parameters of one camera and then another change between calls, and back.
template <class Model>
void expect_cached_projections(const Model &model, const std::vector<double> &points,
                               std::vector<double> (*params)(const Model &, int)) {
  cc::CachedProjection<Model> cache(model);
  int checked = 0;
  for (int round = 0; round < 2; ++round)
    for (int j = 0; j < model.ncameras(); ++j)
      for (const auto &v : kCorrections) {
        std::vector<double> a = params(model, j);
        std::copy(v, v + 3, a.begin());
        for (int twice = 0; twice < 2; ++twice)
          for (std::size_t i = 0; i < points.size() / 3; ++i) {
            double want[2] = {0, 0}, got[2] = {0, 0};
            const bool shown = model.project(j, a.data(), points.data() + 3 * i, want);
            EXPECT_EQ(cache.project(j, a.data(), points.data() + 3 * i, got), shown);
            EXPECT_EQ(std::memcmp(want, got, sizeof want), 0) << cc::model_name(j);
            ++checked;
          }
      }
  EXPECT_EQ(checked, 2 * model.ncameras() * 4 * 2 * int(points.size() / 3));
}

std::vector<double> camera_params(const cc::CameraModel &model, int j) {
  return std::vector<double>(model.initial_camera(j), model.initial_camera(j) + model.cnp());
}

TEST(ColmapCamera, CachedProjectionIsProject) {
  const std::vector<double> points = {0.2, -0.1, 0.3, -0.5, 0.4, -0.2};
  expect_cached_projections(cc::CameraModel(sample_cameras(), points), points, camera_params);
  expect_cached_projections(cc::RigCameraModel(sample_rig_images(), points), points, moved_rig_params);
}

using tangenttest::colmap_increment;

// rotation_tangent_jacobian is d(delta)/dv of the camera model's rotation, by central
// differences at corrections v_hat away from 0, of cameras whose initial rotations differ.
TEST(ColmapCamera, RotationTangentJacobian) {
  const double v_hats[][3] = {{0, 0, 0}, {0.1, -0.2, 0.05}, {-0.4, 0.3, 0.5}};
  const double q0s[][4] = {{1, 0, 0, 0}, {0.3, -0.5, 0.7, 0.2}};
  for (const auto &q0 : q0s) {
    cc::Camera cam;
    cam.params = {500, 320, 240};
    cam.q = {q0[0], q0[1], q0[2], q0[3]};
    const cc::CameraModel model({cam}, {0, 0, 5});
    const int cnp = model.cnp();
    for (const auto &v_hat : v_hats) {
      std::vector<double> a(model.initial_camera(0), model.initial_camera(0) + cnp);
      std::copy(v_hat, v_hat + 3, a.begin());
      const sbacameras::euclidean::Quaternion q_hat = model.camera(0, a.data()).q;
      double J[9];
      cc::rotation_tangent_jacobian(v_hat, J);
      const double h = 1e-6;
      for (int k = 0; k < 3; ++k) {
        std::vector<double> ap = a, am = a;
        ap[static_cast<std::size_t>(k)] += h;
        am[static_cast<std::size_t>(k)] -= h;
        const auto dp = colmap_increment(model.camera(0, ap.data()).q, q_hat);
        const auto dm = colmap_increment(model.camera(0, am.data()).q, q_hat);
        for (int r = 0; r < 3; ++r)
          EXPECT_NEAR((dp[static_cast<std::size_t>(r)] - dm[static_cast<std::size_t>(r)]) / (2 * h), J[r * 3 + k], 1e-8)
              << "v_hat " << v_hat[0] << " row " << r << " column " << k;
      }
    }
  }
}
