// SPDX-License-Identifier: BSD-3-Clause
// The priors of a COLMAP model (formats/colmap_priors.h, and ProblemPriors of
// formats/colmap_problem.h): WGS84 to east-north-up, the robust similarity and the model moved
// by it, the readers of COLMAP's database (both layouts) and of the text files with their
// errors, and a solve in which the priors place a model the projections leave free.
#include <gtest/gtest.h>
#include <sqlite3.h>
#include <unistd.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <string>
#include <vector>

#include "formats/colmap_io.h"
#include "formats/colmap_priors.h"
#include "formats/colmap_problem.h"
#include "sba.h"
#include "sba_ext.h"

namespace {

namespace colmap = sbaformats::colmap;
using Vec3 = std::array<double, 3>;

std::string temp_path(const std::string &name) {
  return ::testing::TempDir() + "colmap_priors_" + std::to_string(::getpid()) + "_" + name;
}

void write_file(const std::string &path, const std::string &text) {
  std::ofstream(path, std::ios::binary) << text;
}

colmap::PosePrior wgs84(double lat, double lon, double alt) {
  colmap::PosePrior p;
  p.system = colmap::PriorSystem::Wgs84;
  p.position = {lat, lon, alt};
  return p;
}

// The east-north-up coordinates are those of the WGS84 ellipsoid (a = 6378137 m, f =
// 1/298.257223563), around the first prior: 0.001 degrees of latitude at 47.38 N is 111.186 m
// north, 0.002 degrees of longitude 151.045 m east, 100 m up is 100 m up; the curvature drops a
// point 3.85 km away by 1.16 m.
TEST(Wgs84ToEnu, AroundTheFirstPrior) {
  std::vector<colmap::PosePrior> p = {wgs84(47.3785, 8.5490, 448.0), wgs84(47.3795, 8.5490, 448.0),
                                      wgs84(47.3785, 8.5510, 448.0), wgs84(47.3785, 8.5490, 548.0),
                                      wgs84(47.40, 8.60, 500.0)};
  colmap::PosePrior cartesian;
  cartesian.system = colmap::PriorSystem::Cartesian;
  cartesian.position = {1, 2, 3};
  p.insert(p.begin() + 2, cartesian);
  colmap::wgs84_to_enu(&p);
  const Vec3 expected[] = {{0, 0, 0},
                           {0, 111.1860501248, -9.702815358e-4},
                           {1, 2, 3},
                           {151.0450333041, 1.939854052e-3, -1.785131134e-3},
                           {0, 0, 99.99999999963},
                           {3850.113151821, 2391.784716439, 50.39116392488}};
  for (std::size_t k = 0; k < p.size(); ++k) {
    EXPECT_EQ(p[k].system, colmap::PriorSystem::Cartesian);
    for (int a = 0; a < 3; ++a) EXPECT_NEAR(p[k].position[a], expected[k][a], 1e-6) << k << " " << a;
  }
}

TEST(Wgs84ToEnu, SouthernAndEasternHemispheres) {
  std::vector<colmap::PosePrior> p = {wgs84(-33.87, 151.21, 0.0), wgs84(-33.8688, 151.2093, 10.0)};
  colmap::wgs84_to_enu(&p);
  EXPECT_NEAR(p[1].position[0], -64.768705542913, 1e-6);
  EXPECT_NEAR(p[1].position[1], 133.104024050772, 1e-6);
  EXPECT_NEAR(p[1].position[2], 9.998277626094, 1e-6);
}

colmap::Similarity some_similarity() {
  colmap::Similarity x;
  const double c = std::cos(0.7), s = std::sin(0.7);  // about z, then a tilt about x
  const double cx = std::cos(0.3), sx = std::sin(0.3);
  const double Rz[9] = {c, -s, 0, s, c, 0, 0, 0, 1}, Rx[9] = {1, 0, 0, 0, cx, -sx, 0, sx, cx};
  for (int a = 0; a < 3; ++a)
    for (int b = 0; b < 3; ++b) {
      double v = 0;
      for (int k = 0; k < 3; ++k) v += Rx[a * 3 + k] * Rz[k * 3 + b];
      x.R[static_cast<std::size_t>(a * 3 + b)] = v;
    }
  x.s = 2.5;
  x.t = {100, -40, 7};
  return x;
}

Vec3 moved(const colmap::Similarity &x, const Vec3 &p) {
  Vec3 q;
  for (int a = 0; a < 3; ++a)
    q[static_cast<std::size_t>(a)] =
        x.s * (x.R[static_cast<std::size_t>(a * 3)] * p[0] + x.R[static_cast<std::size_t>(a * 3 + 1)] * p[1] +
               x.R[static_cast<std::size_t>(a * 3 + 2)] * p[2]) +
        x.t[static_cast<std::size_t>(a)];
  return q;
}

// Twelve points in general position, and their images under truth each moved by noise times
// (k mod 4 - 1.4) along axis k mod 3.
void twelve_pairs(const colmap::Similarity &truth, double noise, std::vector<Vec3> *src, std::vector<Vec3> *dst) {
  for (int k = 0; k < 12; ++k) {
    const Vec3 p{std::cos(k * 0.9) * 3, std::sin(k * 1.3) * 2, 0.5 * k - 2};
    src->push_back(p);
    dst->push_back(moved(truth, p));
    dst->back()[static_cast<std::size_t>(k % 3)] += noise * (k % 4 - 1.4);
  }
}

TEST(RobustSimilarity, RecoversTheSimilarityDespiteOutliers) {
  const colmap::Similarity truth = some_similarity();
  std::vector<Vec3> src, dst;
  twelve_pairs(truth, 0, &src, &dst);
  dst[3][0] += 50;  // two wrong priors
  dst[8][2] -= 80;
  colmap::Similarity x;
  int inliers = 0;
  ASSERT_TRUE(colmap::robust_similarity(src, dst, 1.0, &x, &inliers));
  EXPECT_EQ(inliers, 10);
  EXPECT_NEAR(x.s, 2.5, 1e-12);
  for (std::size_t k = 0; k < 9; ++k) EXPECT_NEAR(x.R[k], truth.R[k], 1e-12);
  for (std::size_t k = 0; k < 3; ++k) EXPECT_NEAR(x.t[k], truth.t[k], 1e-10);
}

// Eight camera centres of a reconstruction and their GPS priors, 1.5 m off each (COLMAP's
// synthetic noise), all within the threshold of the least-squares fit of all eight: that fit is
// the one kept (scale 1.976477977112128, Umeyama's), not the fixed point of seven that a triple's
// refits can settle in (scale 2.136, one prior 4.73 m off), from which the bundle adjustment
// starts in a worse place.
TEST(RobustSimilarity, KeepsTheFitOfEveryPairWhenAllAgree) {
  const std::array<Vec3, 2> pairs[] = {
      {{{7.608881053192466, -4.491787683023387, 4.726106710675373}, {-4.405961383650423, 2.5223314636161125, 4.265900566190422}}},
      {{{10.933579211458731, -1.3637081949481666, 1.916793470777634}, {5.255408253305203, 4.792530469179105, -3.0636530380742966}}},
      {{{8.38405667142245, -2.587698705078429, 5.091442001026748}, {-1.9199433001436201, 4.757784394617979, 4.506689141782016}}},
      {{{12.62547207213031, -5.274619882094733, 3.6153354479900894}, {2.149256030253051, -1.8620632533084, -1.8309578892796234}}},
      {{{12.639884124655579, -5.371541073242563, 3.3828480569843435}, {3.4077118319310404, -4.5871438876652295, 1.3010001261744768}}},
      {{{7.614728146606867, -2.261000994576504, 3.5063411850026407}, {0.16024103908604426, 6.526849518754992, 0.22407854770542968}}},
      {{{10.872898350238883, -3.7272433280393926, 5.851785360348341}, {5.953653122100679, 0.8450690076609516, 4.3251026625909565}}},
      {{{11.038740008922822, -1.2133266805532974, 2.5247019307794303}, {6.281412228232879, 3.0162840549440135, -2.72618873254037}}}};
  std::vector<Vec3> src, dst;
  for (const auto &p : pairs) {
    src.push_back(p[0]);
    dst.push_back(p[1]);
  }
  colmap::Similarity x;
  int inliers = 0;
  ASSERT_TRUE(colmap::robust_similarity(src, dst, 4.5, &x, &inliers));
  EXPECT_EQ(inliers, 8);
  EXPECT_NEAR(x.s, 1.976477977112128, 1e-12);
}

TEST(RobustSimilarity, RefusesCollinearPoints) {
  std::vector<Vec3> src = {{0, 0, 0}, {1, 1, 1}, {2, 2, 2}, {3, 3, 3}};
  colmap::Similarity x;
  int inliers = 0;
  // Collinear points fix no rotation about their line: no triple spans a plane, and the
  // least-squares fit of all is Horn's, which picks one; coincident points have none.
  std::vector<Vec3> same = {{1, 1, 1}, {1, 1, 1}, {1, 1, 1}};
  EXPECT_FALSE(colmap::robust_similarity(same, same, 1.0, &x, &inliers));
  EXPECT_TRUE(colmap::robust_similarity(src, src, 1.0, &x, &inliers));
  EXPECT_NEAR(x.s, 1.0, 1e-12);
}

// The priors' cost sum rho(e^T C^-1 e) of the points y against dst, covariances C (each
// diagonal here), rho Cauchy's of scale c, or least squares for c 0.
double priors_cost(const std::vector<Vec3> &y, const std::vector<Vec3> &dst, const std::vector<std::array<double, 9>> &C,
                   double c) {
  double cost = 0;
  for (std::size_t k = 0; k < y.size(); ++k) {
    double s = 0;
    for (std::size_t a = 0; a < 3; ++a) s += (y[k][a] - dst[k][a]) * (y[k][a] - dst[k][a]) / C[k][a * 4];
    cost += c > 0 ? c * c * std::log1p(s / (c * c)) : s;
  }
  return cost;
}

// Twelve priors, two of them far off. The robust fit leaves those two out; the solve's
// position priors do not, and a similarity moves the cost the priors add without moving the
// projections': least_cost_similarity takes the robust fit to that cost's minimum, which with
// equal round covariances and least squares is the fit of all twelve.
TEST(LeastCostSimilarity, TakesTheRobustFitToThePriorsLeastCost) {
  std::vector<Vec3> src, dst;
  twelve_pairs(some_similarity(), 0.05, &src, &dst);
  dst[3][0] += 5;
  dst[8][2] -= 8;
  colmap::Similarity robust, all;
  int inliers = 0;
  ASSERT_TRUE(colmap::robust_similarity(src, dst, 1.0, &robust, &inliers));
  ASSERT_EQ(inliers, 10);
  ASSERT_TRUE(colmap::robust_similarity(src, dst, 1e9, &all, &inliers));
  ASSERT_EQ(inliers, 12);
  ASSERT_GT(std::fabs(robust.s - all.s), 1e-3);

  const std::array<double, 9> round = {2.25, 0, 0, 0, 2.25, 0, 0, 0, 2.25};
  std::vector<const std::array<double, 9> *> covariances(12, &round);
  colmap::Similarity x = robust;
  ASSERT_TRUE(colmap::least_cost_similarity(src, dst, covariances, "", 0, &x));
  EXPECT_NEAR(x.s, all.s, 1e-12);
  for (std::size_t k = 0; k < 9; ++k) EXPECT_NEAR(x.R[k], all.R[k], 1e-12);
  for (std::size_t k = 0; k < 3; ++k) EXPECT_NEAR(x.t[k], all.t[k], 1e-10);
  // At its minimum already: nothing to do.
  EXPECT_FALSE(colmap::least_cost_similarity(src, dst, covariances, "", 0, &x));

  // Covariances of their own, long in one axis, and Cauchy's loss: the cost the solve adds is
  // at a minimum over similarities, which each of the seven one-parameter moves shows (the
  // cost rises both ways), and below the robust fit's.
  std::vector<std::array<double, 9>> own(12);
  for (std::size_t k = 0; k < 12; ++k) {
    own[k] = {0.5 + 0.1 * static_cast<double>(k), 0, 0, 0, 1, 0, 0, 0, 4.0 - 0.2 * static_cast<double>(k)};
    covariances[k] = &own[k];
  }
  const double scale = 2.7954834829151074;
  x = robust;
  ASSERT_TRUE(colmap::least_cost_similarity(src, dst, covariances, "cauchy", scale, &x));
  const auto cost_of = [&](const colmap::Similarity &z) {
    std::vector<Vec3> y;
    for (const Vec3 &p : src) y.push_back(moved(z, p));
    return priors_cost(y, dst, own, scale);
  };
  const double at = cost_of(x);
  EXPECT_LT(at, cost_of(robust) - 0.1);
  for (int d = 0; d < 7; ++d)
    for (double h : {-1e-4, 1e-4}) {
      colmap::Similarity z = x;
      if (d == 0) z.s *= 1 + h;
      if (d >= 4) z.t[static_cast<std::size_t>(d - 4)] += h;
      if (d >= 1 && d <= 3) {  // z.R turned by h about axis d - 1 (on the left)
        const std::size_t a = static_cast<std::size_t>(d % 3), b = static_cast<std::size_t>((d + 1) % 3);
        for (std::size_t col = 0; col < 3; ++col) {
          const double u = z.R[a * 3 + col], v = z.R[b * 3 + col];
          z.R[a * 3 + col] = std::cos(h) * u - std::sin(h) * v;
          z.R[b * 3 + col] = std::sin(h) * u + std::cos(h) * v;
        }
      }
      EXPECT_GT(cost_of(z), at) << "parameter " << d << ", step " << h;
    }
}

// A small model: two cameras, three images and four points, all seen by every image.
colmap::Model small_model(std::uint32_t images = 3) {
  colmap::Model m;
  m.cameras = {{1, colmap::kSimplePinhole, 640, 480, {500, 320, 240}}};
  for (std::uint32_t k = 0; k < images; ++k) {
    colmap::Image im;
    im.id = 10 + k;
    im.camera_id = 1;
    im.name = "im" + std::to_string(k) + ".jpg";
    const double a = 0.1 * k;
    im.q = {std::cos(a / 2), 0, std::sin(a / 2), 0};
    im.t = {-0.5 * k, 0.1, 0.2 * k};
    m.images.push_back(im);
  }
  for (std::uint64_t i = 0; i < 4; ++i) {
    colmap::Point3D pt;
    pt.id = 100 + i;
    pt.xyz = {0.3 * static_cast<double>(i) - 0.4, 0.2 * static_cast<double>(i % 2), 5.0 + 0.1 * static_cast<double>(i)};
    for (colmap::Image &im : m.images) {
      pt.track.push_back({im.id, static_cast<std::uint32_t>(im.points.size())});
      im.points.push_back({0, 0, pt.id});
    }
    m.points.push_back(pt);
  }
  return m;
}

TEST(TransformModel, MovesCentresAndPointsByTheSimilarity) {
  colmap::Model m = small_model();
  const std::vector<Vec3> before = colmap::image_centres(m);
  const colmap::Model original = m;
  const colmap::Similarity x = some_similarity();
  colmap::transform_model(x, &m);
  const std::vector<Vec3> after = colmap::image_centres(m);
  for (std::size_t k = 0; k < before.size(); ++k) {
    const Vec3 want = moved(x, before[k]);
    for (std::size_t a = 0; a < 3; ++a) EXPECT_NEAR(after[k][a], want[a], 1e-11);
  }
  for (std::size_t i = 0; i < m.points.size(); ++i) {
    const Vec3 want = moved(x, original.points[i].xyz);
    for (std::size_t a = 0; a < 3; ++a) EXPECT_NEAR(m.points[i].xyz[a], want[a], 1e-12);
  }
  // What a camera sees does not change: a point's depth scales by s, its direction stays.
  for (std::size_t k = 0; k < m.images.size(); ++k) {
    const auto in_camera = [](const colmap::Image &im, const Vec3 &X) {
      double R[9];
      const double w = im.q[0], a = im.q[1], b = im.q[2], c = im.q[3];
      const double r[9] = {1 - 2 * (b * b + c * c), 2 * (a * b - w * c),     2 * (a * c + w * b),
                           2 * (a * b + w * c),     1 - 2 * (a * a + c * c), 2 * (b * c - w * a),
                           2 * (a * c - w * b),     2 * (b * c + w * a),     1 - 2 * (a * a + b * b)};
      std::copy(r, r + 9, R);
      return Vec3{R[0] * X[0] + R[1] * X[1] + R[2] * X[2] + im.t[0], R[3] * X[0] + R[4] * X[1] + R[5] * X[2] + im.t[1],
                  R[6] * X[0] + R[7] * X[1] + R[8] * X[2] + im.t[2]};
    };
    const Vec3 c0 = in_camera(original.images[k], original.points[0].xyz), c1 = in_camera(m.images[k], m.points[0].xyz);
    for (std::size_t a = 0; a < 3; ++a) EXPECT_NEAR(c1[a], x.s * c0[a], 1e-10);
  }
}

TEST(PosePriorsText, ReadsNamesCovariancesAndSystems) {
  const colmap::Model m = small_model();
  const std::string path = temp_path("poses.txt");
  write_file(path,
             "# NAME X Y Z [covariance] [system]\n"
             "im0.jpg 1 2 3\n"
             "\n"
             "im1.jpg 47.1 8.2 400 WGS84\n"
             "elsewhere.jpg 1 1 1\n"
             "im2.jpg 4 5 6 2 0 0 0 3 0 0 0 4 CARTESIAN\n");
  std::vector<colmap::PosePrior> p;
  int unknown = -1;
  std::string error;
  ASSERT_TRUE(colmap::read_pose_priors_text(path, m, &p, &unknown, &error)) << error;
  EXPECT_EQ(unknown, 1);
  ASSERT_EQ(p.size(), 3u);
  EXPECT_EQ(p[0].image_id, 10u);
  EXPECT_EQ(p[0].system, colmap::PriorSystem::Cartesian);
  EXPECT_FALSE(p[0].has_covariance);
  EXPECT_EQ(p[1].system, colmap::PriorSystem::Wgs84);
  EXPECT_EQ(p[1].where, path + ":4");
  EXPECT_TRUE(p[2].has_covariance);
  EXPECT_EQ(p[2].covariance[8], 4.0);

  const struct {
    const char *text, *message;
  } bad[] = {
      {"im0.jpg 1 2\n", ":1: expected NAME X Y Z, then optionally the 9 values of a covariance and CARTESIAN or "
                        "WGS84 (got 3 values)"},
      {"im0.jpg 1 2 3 ECEF\n", ":1: the coordinate system must be CARTESIAN or WGS84, got 'ECEF'"},
      {"\nim0.jpg 1 nan 3\n", ":2: Y must be a finite number, got 'nan'"},
      {"im0.jpg 1 2 3 1 0 0 0 1 0 0 0 x\n", ":1: covariance value 9 must be a finite number, got 'x'"},
  };
  for (const auto &b : bad) {
    write_file(path, b.text);
    EXPECT_FALSE(colmap::read_pose_priors_text(path, m, &p, &unknown, &error)) << b.text;
    EXPECT_EQ(error, path + b.message);
  }
}

TEST(PosePriors, UsableOnesGetTheirCovarianceOrTheFallback) {
  const colmap::Model m = small_model();
  colmap::PosePrior a, b, none, twice;
  a.image_id = 10;
  a.where = "a";
  a.position = {1, 2, 3};
  b.image_id = 11;
  b.where = "b";
  b.has_covariance = true;
  b.covariance = {4, 1, 0, 1, 4, 0, 0, 0, 4};
  none.image_id = 12;
  none.position = {NAN, NAN, NAN};  // COLMAP's prior without a position
  colmap::PosePriorOptions options;
  options.fallback_stddev = 2;
  std::vector<colmap::PosePrior> out;
  std::string error;
  ASSERT_TRUE(colmap::usable_pose_priors(m, {a, b, none}, options, &out, &error)) << error;
  ASSERT_EQ(out.size(), 2u);
  EXPECT_EQ(out[0].covariance, (std::array<double, 9>{4, 0, 0, 0, 4, 0, 0, 0, 4}));
  EXPECT_EQ(out[1].covariance, b.covariance);

  twice = a;
  twice.where = "c";
  EXPECT_FALSE(colmap::usable_pose_priors(m, {a, twice}, options, &out, &error));
  EXPECT_EQ(error, "c: image 10 has a position prior already");
  colmap::PosePrior singular = b;
  singular.covariance = {1, 2, 0, 2, 1, 0, 0, 0, 1};
  EXPECT_FALSE(colmap::usable_pose_priors(m, {singular}, options, &out, &error));
  EXPECT_EQ(error, "b: its covariance is not symmetric positive definite");
  colmap::PosePrior infinite = a;
  infinite.position[1] = INFINITY;
  EXPECT_FALSE(colmap::usable_pose_priors(m, {infinite}, options, &out, &error));
  EXPECT_EQ(error, "a: its position is not finite");
  options.fallback_stddev = 0;
  EXPECT_FALSE(colmap::usable_pose_priors(m, {a}, options, &out, &error));
}

// Eight images with priors, one far off: place_on_priors leaves the model where the
// solve's priors cost least, the least-squares fit of all eight centres (the fallback
// covariance is round), not the robust fit of the seven from which the solve would have to
// turn and scale the whole model back, a little every iteration.
TEST(PlaceOnPriors, LeavesTheModelWhereThePriorsCostLeast) {
  colmap::Model m = small_model(8);
  const std::vector<Vec3> centres = colmap::image_centres(m);
  const colmap::Similarity truth = some_similarity();
  std::vector<colmap::PosePrior> priors(8);
  std::vector<Vec3> dst;
  for (std::size_t k = 0; k < 8; ++k) {
    priors[k].image_id = static_cast<std::uint32_t>(10 + k);
    priors[k].position = moved(truth, centres[k]);
    priors[k].position[k % 3] += 0.1 * static_cast<double>(k % 3) - 0.1;
    priors[k].where = "p";
    dst.push_back(priors[k].position);
  }
  priors[5].position[1] += 20;
  dst[5][1] += 20;
  colmap::Similarity all;
  int inliers = 0;
  ASSERT_TRUE(colmap::robust_similarity(centres, dst, 1e9, &all, &inliers));
  std::vector<colmap::PosePrior> usable;
  std::string said, error;
  ASSERT_TRUE(colmap::place_on_priors(priors, 0, "priors.txt", {}, {}, {}, true, &m, &usable, &said, &error))
      << error;
  EXPECT_NE(said.find(" (7 of 8 within 3), then refined with them"), std::string::npos) << said;
  const std::vector<Vec3> placed = colmap::image_centres(m);
  for (std::size_t k = 0; k < 8; ++k) {
    const Vec3 want = moved(all, centres[k]);
    for (std::size_t a = 0; a < 3; ++a) EXPECT_NEAR(placed[k][a], want[a], 1e-9) << "image " << k;
  }
}

// Priors at the edge of double's range give a similarity that would send the model to
// infinity: refused, the model left as it was, not moved to values that are not finite.
TEST(PlaceOnPriors, RefusesASimilarityBeyondDoublesRange) {
  colmap::Model m = small_model();
  const colmap::Model original = m;
  std::vector<colmap::PosePrior> priors(3);
  const Vec3 positions[] = {{1e308, 2, 3}, {0, 5, 5}, {47.1, 8.2, 400}};
  for (std::size_t k = 0; k < 3; ++k) {
    priors[k].image_id = static_cast<std::uint32_t>(10 + k);
    priors[k].position = positions[k];
    priors[k].where = "p";
  }
  std::vector<colmap::PosePrior> usable;
  std::string said, error;
  EXPECT_FALSE(colmap::place_on_priors(priors, 0, "priors.txt", {}, {}, {}, true, &m, &usable, &said, &error));
  EXPECT_EQ(error.rfind("priors.txt: the model cannot be moved onto these priors: their similarity (scale ", 0), 0u)
      << error;
  for (std::size_t i = 0; i < m.points.size(); ++i) EXPECT_EQ(m.points[i].xyz, original.points[i].xyz);

  std::vector<colmap::PointPrior> points(3);
  for (std::size_t k = 0; k < 3; ++k) {
    points[k].point_id = 100 + k;
    points[k].position = positions[k];
    points[k].covariance = {1, 0, 0, 0, 1, 0, 0, 0, 1};
  }
  EXPECT_FALSE(colmap::place_on_priors({}, 0, {}, points, "gcp.txt", {}, true, &m, &usable, &said, &error));
  EXPECT_EQ(error.rfind("gcp.txt: the model cannot be moved onto these priors", 0), 0u) << error;
  // Far but in range: moved, and finite.
  for (std::size_t k = 0; k < 3; ++k) priors[k].position[0] += k == 0 ? -1e308 + 1e6 : 0;
  ASSERT_TRUE(colmap::place_on_priors(priors, 0, "priors.txt", {}, {}, {}, true, &m, &usable, &said, &error))
      << error;
  for (const colmap::Point3D &p : m.points)
    for (double v : p.xyz) EXPECT_TRUE(std::isfinite(v));
}

// A database with COLMAP 4's pose_priors table, or 3.x's, holding `rows`.
void make_database(const std::string &path, bool v4, const std::vector<std::string> &rows) {
  std::remove(path.c_str());
  sqlite3 *db = nullptr;
  ASSERT_EQ(sqlite3_open(path.c_str(), &db), SQLITE_OK);
  const char *table =
      v4 ? "CREATE TABLE pose_priors (pose_prior_id INTEGER PRIMARY KEY NOT NULL, corr_data_id INTEGER NOT NULL, "
           "corr_sensor_id INTEGER NOT NULL, corr_sensor_type INTEGER NOT NULL, position BLOB, position_covariance "
           "BLOB, gravity BLOB, coordinate_system INTEGER NOT NULL)"
         : "CREATE TABLE pose_priors (image_id INTEGER PRIMARY KEY NOT NULL, position BLOB, coordinate_system INTEGER "
           "NOT NULL, position_covariance BLOB)";
  ASSERT_EQ(sqlite3_exec(db, table, nullptr, nullptr, nullptr), SQLITE_OK);
  for (const std::string &row : rows) {
    char *message = nullptr;
    ASSERT_EQ(sqlite3_exec(db, row.c_str(), nullptr, nullptr, &message), SQLITE_OK) << (message ? message : "");
  }
  sqlite3_close(db);
}

// X'...' of the doubles' bytes, as SQLite writes a blob.
std::string blob(const std::vector<double> &v) {
  std::string hex = "X'";
  const unsigned char *b = reinterpret_cast<const unsigned char *>(v.data());
  char two[3];
  for (std::size_t k = 0; k < v.size() * sizeof(double); ++k) {
    std::snprintf(two, sizeof two, "%02X", b[k]);
    hex += two;
  }
  return hex + "'";
}

TEST(PosePriorsDatabase, ReadsColmap4sLayout) {
  const std::string path = temp_path("v4.db");
  const std::string nan3 = blob({NAN, NAN, NAN});
  make_database(path, true,
                {"INSERT INTO pose_priors VALUES (2, 11, 1, 0, " + blob({4, 5, 6}) + ", " +
                     blob({1, 0, 0, 0, 2, 0, 0, 0, 3}) + ", " + nan3 + ", 1)",
                 "INSERT INTO pose_priors VALUES (1, 10, 1, 0, " + blob({47.1, 8.2, 400}) + ", NULL, " + nan3 + ", 0)",
                 "INSERT INTO pose_priors VALUES (3, 7, 1, 1, " + blob({0, 0, 0}) + ", NULL, " + nan3 + ", 1)"});
  std::vector<colmap::PosePrior> p;
  std::string error;
  ASSERT_TRUE(colmap::read_pose_priors_database(path, &p, &error)) << error;
  ASSERT_EQ(p.size(), 2u);  // the IMU's prior (sensor type 1) places no image
  EXPECT_EQ(p[0].image_id, 10u);
  EXPECT_EQ(p[0].system, colmap::PriorSystem::Wgs84);
  EXPECT_FALSE(p[0].has_covariance);
  EXPECT_EQ(p[1].image_id, 11u);
  EXPECT_EQ(p[1].position, (Vec3{4, 5, 6}));
  EXPECT_TRUE(p[1].has_covariance);
  EXPECT_EQ(p[1].covariance[4], 2.0);
  EXPECT_EQ(p[1].where, path + ": pose prior 2 (data 11)");
}

TEST(PosePriorsDatabase, ReadsColmap3sLayout) {
  const std::string path = temp_path("v3.db");
  make_database(path, false, {"INSERT INTO pose_priors VALUES (12, " + blob({1, 2, 3}) + ", 1, NULL)"});
  std::vector<colmap::PosePrior> p;
  std::string error;
  ASSERT_TRUE(colmap::read_pose_priors_database(path, &p, &error)) << error;
  ASSERT_EQ(p.size(), 1u);
  EXPECT_EQ(p[0].image_id, 12u);
  EXPECT_EQ(p[0].position, (Vec3{1, 2, 3}));
}

TEST(PosePriorsDatabase, RefusesWhatItCannotRead) {
  std::vector<colmap::PosePrior> p;
  std::string error;
  const std::string path = temp_path("bad.db");
  make_database(path, true, {"INSERT INTO pose_priors VALUES (5, 11, 1, 0, " + blob({4, 5}) + ", NULL, NULL, 1)"});
  EXPECT_FALSE(colmap::read_pose_priors_database(path, &p, &error));
  EXPECT_EQ(error, path + ": pose prior 5 (data 11): its position has 16 bytes, expected 24 (3 doubles)");
  make_database(path, true,
                {"INSERT INTO pose_priors VALUES (5, 11, 1, 0, " + blob({4, 5, 6}) + ", " + blob({1, 0, 0}) +
                 ", NULL, 1)"});
  EXPECT_FALSE(colmap::read_pose_priors_database(path, &p, &error));
  EXPECT_EQ(error, path + ": pose prior 5 (data 11): its position_covariance has 24 bytes, expected 72 (9 doubles)");
  make_database(path, true, {"INSERT INTO pose_priors VALUES (5, 11, 1, 0, " + blob({4, 5, 6}) + ", NULL, NULL, 7)"});
  EXPECT_FALSE(colmap::read_pose_priors_database(path, &p, &error));
  EXPECT_EQ(error, path + ": pose prior 5 (data 11): its coordinate_system is 7, expected -1 (UNDEFINED), 0 (WGS84) "
                          "or 1 (CARTESIAN)");

  std::remove(path.c_str());
  sqlite3 *db = nullptr;
  ASSERT_EQ(sqlite3_open(path.c_str(), &db), SQLITE_OK);
  ASSERT_EQ(sqlite3_exec(db, "CREATE TABLE images (image_id INTEGER)", nullptr, nullptr, nullptr), SQLITE_OK);
  sqlite3_close(db);
  EXPECT_FALSE(colmap::read_pose_priors_database(path, &p, &error));
  EXPECT_EQ(error, path + ": the database has no pose_priors table (COLMAP's database, from 3.9 on, keeps the pose "
                          "priors there)");

  write_file(path, "not a database at all, but long enough to have a header's worth of bytes in it.......");
  EXPECT_FALSE(colmap::read_pose_priors_database(path, &p, &error));
  EXPECT_EQ(error.rfind(path + ": ", 0), 0u) << error;
  const std::string missing = temp_path("missing.db");
  EXPECT_FALSE(colmap::read_pose_priors_database(missing, &p, &error));
  EXPECT_EQ(error.rfind(missing + ": cannot open as an SQLite database", 0), 0u) << error;
  EXPECT_NE(::access(missing.c_str(), F_OK), 0) << "the reader made a database";
}

TEST(PointPriors, ReadsSigmasAndCovariancesAndRefusesBadLines) {
  const colmap::Model m = small_model();
  const std::string path = temp_path("points.txt");
  write_file(path, "100 1 2 3 0.5\n103 4 5 6 1 0 0 0 2 0 0 0 3\n");
  std::vector<colmap::PointPrior> p;
  std::string error;
  ASSERT_TRUE(colmap::read_point_priors(path, m, &p, &error)) << error;
  ASSERT_EQ(p.size(), 2u);
  EXPECT_EQ(p[0].covariance, (std::array<double, 9>{0.25, 0, 0, 0, 0.25, 0, 0, 0, 0.25}));
  EXPECT_EQ(p[1].point_id, 103u);
  const struct {
    const char *text, *message;
  } bad[] = {{"100 1 2 3 0\n", ":1: SIGMA must be > 0 (and its square finite and not 0), got 0"},
             {"100 1 2 3 -1\n", ":1: SIGMA must be > 0 (and its square finite and not 0), got -1"},
             {"100 1 2 3 1e-300\n", ":1: SIGMA must be > 0 (and its square finite and not 0), got 1e-300"},
             {"7 1 2 3 1\n", ":1: no point has POINT3D_ID 7 in the model"},
             {"100 1 2 3 1\n100 1 2 3 1\n", ":2: point 100 has a prior already"},
             {"100 1 inf 3 1\n", ":1: Y must be a finite number, got 'inf'"},
             {"100 1 2 3 1 0 0 0 -1 0 0 0 1\n", ":1: its covariance is not symmetric positive definite"},
             {"100 1 2 3\n", ":1: expected POINT3D_ID X Y Z SIGMA, or POINT3D_ID X Y Z and the 9 values of a "
                             "covariance (got 4 values)"}};
  for (const auto &b : bad) {
    write_file(path, b.text);
    EXPECT_FALSE(colmap::read_point_priors(path, m, &p, &error)) << b.text;
    EXPECT_EQ(error, path + b.message);
  }
}

TEST(IntrinsicPriors, ReadsNamesAndIndices) {
  colmap::Model m = small_model();
  m.cameras.push_back({2, colmap::kOpenCV, 640, 480, {500, 505, 320, 240, 0.1, 0.01, 0, 0}});
  const std::string path = temp_path("intrinsics.txt");
  write_file(path, "1 f 510 5\n2 fy 500 2\n2 4 0 0.05\n1 cy 240 1\n");
  std::vector<colmap::IntrinsicPrior> p;
  std::string error;
  ASSERT_TRUE(colmap::read_intrinsic_priors(path, m, &p, &error)) << error;
  ASSERT_EQ(p.size(), 4u);
  EXPECT_EQ(p[0].param, 0);
  EXPECT_EQ(p[1].param, 1);
  EXPECT_EQ(p[2].param, 4);
  EXPECT_EQ(p[3].param, 2);
  const struct {
    const char *text, *message;
  } bad[] = {{"1 fx 500 1\n", ":1: camera 1 (SIMPLE_PINHOLE) has no parameter 'fx' (its parameters are 0..2, or f, "
                              "cx, cy)"},
             {"2 8 0 1\n", ":1: camera 2 (OPENCV) has no parameter '8' (its parameters are 0..7, or fx, fy, cx, cy)"},
             {"3 f 500 1\n", ":1: no camera has CAMERA_ID 3 in the model"},
             {"1 f 500 0\n", ":1: STDDEV must be > 0, got 0"},
             {"1 f 500 1\n1 0 500 1\n", ":2: parameter 0 of camera 1 has a prior already"}};
  for (const auto &b : bad) {
    write_file(path, b.text);
    EXPECT_FALSE(colmap::read_intrinsic_priors(path, m, &p, &error)) << b.text;
    EXPECT_EQ(error, path + b.message);
  }
}

// The problem's centre and its Jacobian: c = -R^T t of the camera the parameters give, and
// dc/da against central differences taken far from the ones the problem takes.
TEST(ProblemPriors, CentreAndItsJacobian) {
  const colmap::Model m = small_model();
  colmap::Problem problem;
  std::string error;
  ASSERT_TRUE(colmap::Problem::build(m, {}, "m", &problem, &error)) << error;
  const std::vector<Vec3> centres = colmap::image_centres(m);
  const int cnp = problem.cnp();
  std::vector<double> a(problem.initial_params().begin() + cnp, problem.initial_params().begin() + 2 * cnp);
  double c[3];
  std::vector<double> J(static_cast<std::size_t>(3 * cnp));
  problem.centre(1, a.data(), c, J.data());
  for (int r = 0; r < 3; ++r) EXPECT_NEAR(c[r], centres[1][static_cast<std::size_t>(r)], 1e-14);
  a[0] += 0.01;
  a[4] -= 0.2;  // a rotation and a translation away from the start
  problem.centre(1, a.data(), c, J.data());
  for (int k = 0; k < cnp; ++k) {
    std::vector<double> x = a;
    const double h = 1e-4;
    double plus[3], minus[3];
    x[static_cast<std::size_t>(k)] = a[static_cast<std::size_t>(k)] + h;
    problem.centre(1, x.data(), plus, nullptr);
    x[static_cast<std::size_t>(k)] = a[static_cast<std::size_t>(k)] - h;
    problem.centre(1, x.data(), minus, nullptr);
    for (int r = 0; r < 3; ++r)
      EXPECT_NEAR(J[static_cast<std::size_t>(r * cnp + k)], (plus[r] - minus[r]) / (2 * h), 1e-7) << r << " " << k;
  }
}

TEST(ProblemPriors, RefusesPriorsTheProblemHolds) {
  const colmap::Model m = small_model();
  colmap::Options options;
  options.constants.points = {0, 1, 0, 0};  // point 101
  colmap::Problem problem;
  std::string error;
  ASSERT_TRUE(colmap::Problem::build(m, options, "m", &problem, &error)) << error;
  colmap::ProblemPriors priors;
  colmap::PointPrior held;
  held.point_id = 101;
  held.where = "gcp:3";
  EXPECT_FALSE(priors.build(problem, {}, {}, {held}, {}, &error));
  EXPECT_EQ(error, "gcp:3: point 101 is held (a constant point): a prior on it cannot move it");
  colmap::IntrinsicPrior cx;
  cx.camera_id = 1;
  cx.param = 1;  // the principal point, held at COLMAP's defaults
  cx.where = "k:1";
  EXPECT_FALSE(priors.build(problem, {}, {}, {}, {cx}, &error));
  EXPECT_EQ(error, "k:1: parameter 1 of camera 1 is held (--intrinsics, --refine-*, --hold-intrinsics): a prior on "
                   "it cannot move it");
  cx.param = 0;
  ASSERT_TRUE(priors.build(problem, {}, {}, {}, {cx}, &error)) << error;
  sba_ext_options ext{};
  priors.attach(&ext);
  EXPECT_EQ(ext.ncamera_linear_priors, 1);
  EXPECT_EQ(ext.camera_linear_priors[0].camera, 0);
  EXPECT_EQ(ext.camera_linear_priors[0].params[0], 6);  // after the pose's 6
}

}  // namespace
