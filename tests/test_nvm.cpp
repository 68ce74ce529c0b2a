// SPDX-License-Identifier: BSD-3-Clause
// VisualSFM NVM files (lib/formats/nvm_io.h) and sbarefine on them: the reader on malformed input,
// round trips that keep the rest of the file, the mapping (centres, undistorted
// measurements), and refinement of a generated scene against the same scene through
// eucsbademo's files.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <string>
#include <vector>

#include "formats/eucsba_io.h"
#include "formats/nvm_io.h"
#include "sbarefine_runs.h"

namespace colmap = sbaformats::colmap;
namespace nvm = sbaformats::nvm;
namespace eucsba = sbaformats::eucsba;
namespace euclidean = sbacameras::euclidean;

namespace {

using namespace refinetest;  // NOLINT: the helpers of sbarefine's tests

// What VisualSFM puts after the first model: a model of one camera without points, the 0
// that ends the models, the PLY section.
const char kRest[] =
    "\n1\nlost.jpg 700 1 0 0 0 0 0 0 0 0\n\n0\n\n0\n\n"
    "#the last part of NVM file points to the PLY files\n#the first number is the number of associated PLY files\n0\n";

// A generated scene as an NVM model with a calibration token in the header and a rest.
nvm::Model make_model(const eucsba::Problem &p) {
  nvm::Model m;
  std::string error;
  EXPECT_TRUE(nvm::from_problem(p.cameras, p.points, &m, &error)) << error;
  m.header = "NVM_V3 FixedK 800 320 800 240";
  m.rest = kRest;
  return m;
}

void expect_same(const nvm::Model &a, const nvm::Model &b) {
  EXPECT_EQ(a.header, b.header);
  EXPECT_EQ(a.rest, b.rest);
  ASSERT_EQ(a.cameras.size(), b.cameras.size());
  for (std::size_t j = 0; j < a.cameras.size(); ++j) {
    EXPECT_EQ(a.cameras[j].name, b.cameras[j].name);
    EXPECT_EQ(a.cameras[j].f, b.cameras[j].f);
    EXPECT_EQ(a.cameras[j].q, b.cameras[j].q);
    EXPECT_EQ(a.cameras[j].c, b.cameras[j].c);
    EXPECT_EQ(a.cameras[j].k, b.cameras[j].k);
  }
  ASSERT_EQ(a.points.size(), b.points.size());
  for (std::size_t i = 0; i < a.points.size(); ++i) {
    EXPECT_EQ(a.points[i].xyz, b.points[i].xyz);
    EXPECT_EQ(a.points[i].rgb, b.points[i].rgb);
    ASSERT_EQ(a.points[i].measurements.size(), b.points[i].measurements.size());
    for (std::size_t k = 0; k < a.points[i].measurements.size(); ++k) {
      const nvm::Measurement &x = a.points[i].measurements[k], &y = b.points[i].measurements[k];
      EXPECT_EQ(x.camera, y.camera);
      EXPECT_EQ(x.feature, y.feature);
      EXPECT_EQ(x.x, y.x);
      EXPECT_EQ(x.y, y.y);
    }
  }
}

// ---- round trips ----

TEST(NvmRoundTrip, BitForBitWithTheRestOfTheFile) {
  const std::string dir = temp_dir("nvm_rt");
  const refinetest::GeneratedScene s =
      refinetest::generate_scene(dir, euclidean::CameraKind::VaryingIntrinsics, 6, 50);
  nvm::Model m = make_model(s.problem);
  m.cameras[2].k = -3.25e-8;
  const std::string text = nvm::format_nvm(m);
  EXPECT_EQ(text.rfind("NVM_V3 FixedK 800 320 800 240\n\n6\nimg_0000.jpg ", 0), 0u) << text.substr(0, 80);
  nvm::Model back;
  std::string error;
  ASSERT_TRUE(nvm::parse_nvm(text, "n.nvm", &back, &error)) << error;
  expect_same(m, back);
  EXPECT_EQ(nvm::format_nvm(back), text);
  // Through a file: the same bytes.
  ASSERT_TRUE(nvm::write_nvm(dir + "/m.nvm", back, &error)) << error;
  EXPECT_EQ(read_file(dir + "/m.nvm"), text);
  nvm::Model again;
  ASSERT_TRUE(nvm::read_nvm(dir + "/m.nvm", &again, &error)) << error;
  expect_same(m, again);
}

TEST(NvmRoundTrip, CrlfAndOddSpacingReadAsWritten) {
  const std::string text =
      "NVM_V3 FixedK 500 0 500 0\r\n\r\n 2\r\n"
      "a.jpg 500 1 0 0 0 0 0 -5 0 0\r\n"
      "b.jpg\t600 0 1 0 0 1 0 5 1e-7 0\r\n"
      "1\r\n"
      "0 0 0 10 20 30 2  0 7 1.5 -2  1 9 -98.5 -2 \r\n\r\n0\r\n";
  nvm::Model m;
  std::string error;
  ASSERT_TRUE(nvm::parse_nvm(text, "n.nvm", &m, &error)) << error;
  EXPECT_EQ(m.header, "NVM_V3 FixedK 500 0 500 0\r");
  EXPECT_EQ(m.rest, "\r\n0\r\n");
  ASSERT_EQ(m.cameras.size(), 2u);
  EXPECT_EQ(m.cameras[1].name, "b.jpg");
  EXPECT_EQ(m.cameras[1].f, 600);
  EXPECT_EQ(m.cameras[1].k, 1e-7);
  EXPECT_EQ(m.cameras[1].c, (std::array<double, 3>{1, 0, 5}));
  ASSERT_EQ(m.points.size(), 1u);
  EXPECT_EQ(m.points[0].rgb, (std::array<int, 3>{10, 20, 30}));
  ASSERT_EQ(m.points[0].measurements.size(), 2u);
  EXPECT_EQ(m.points[0].measurements[1].camera, 1);
  EXPECT_EQ(m.points[0].measurements[1].feature, 9);
  EXPECT_EQ(m.points[0].measurements[1].x, -98.5);
  const std::string once = nvm::format_nvm(m);
  EXPECT_EQ(once,
            "NVM_V3 FixedK 500 0 500 0\r\n\n2\n"
            "a.jpg 500 1 0 0 0 0 0 -5 0 0\n"
            "b.jpg 600 0 1 0 0 1 0 5 9.9999999999999995e-08 0\n"
            "\n1\n"
            "0 0 0 10 20 30 2 0 7 1.5 -2 1 9 -98.5 -2\n\r\n0\r\n");
  nvm::Model back;
  ASSERT_TRUE(nvm::parse_nvm(once, "n.nvm", &back, &error)) << error;
  expect_same(m, back);
  // A model that ends the file, and one whose rest starts on its last line.
  ASSERT_TRUE(nvm::parse_nvm(text.substr(0, text.size() - 7), "n.nvm", &m, &error)) << error;
  EXPECT_EQ(m.rest, "");
  ASSERT_TRUE(nvm::parse_nvm(text.substr(0, text.size() - 8) + " 0\n", "n.nvm", &m, &error)) << error;
  EXPECT_EQ(m.rest, "0\n");
}

// ---- strictness ----

TEST(NvmReader, Errors) {
  const std::string head = "NVM_V3\n\n2\na.jpg 500 1 0 0 0 0 0 -5 0 0\nb.jpg 500 1 0 0 0 1 0 -5 0 0\n1\n";
  const Bad cases[] = {
      {"NVM_V2\n\n1\n", "n.nvm:1: expected the header 'NVM_V3', got 'NVM_V2'"},
      {"NVM_V3_R9T\n\n1\n", "n.nvm:1: expected the header 'NVM_V3', got 'NVM_V3_R9T'"},
      {"NVM_V3\n", "n.nvm:1: the file ends before the number of cameras"},
      {"NVM_V3\n\n0\n", "n.nvm:3: the first model has no camera (a count of 0 ends the models)"},
      {"NVM_V3\n\n1000\n", "n.nvm: 1000 cameras need more values than the file holds"},
      {"NVM_V3\n\n-1\n", "n.nvm:3: the number of cameras is -1, expected 0..16777216"},
      {"NVM_V3\n\n1\na.jpg -500 1 0 0 0 0 0 -5 0 0\n0\n",
       "n.nvm:4: camera 0 focal length must be positive, got -500"},
      {"NVM_V3\n\n1\na.jpg 500 0 0 0 0 0 0 -5 0 0\n0\n", "n.nvm:4: camera 0 quaternion is zero"},
      {"NVM_V3\n\n1\na.jpg 0x1p9 1 0 0 0 0 0 -5 0 0\n0\n",
       "n.nvm:4: camera 0 focal length must be a finite number, got '0x1p9'"},
      {"NVM_V3\n\n1\na.jpg 500 1 0 0 0 0 0 nan 0 0\n0\n", "n.nvm:4: camera 0 cz must be a finite number, got 'nan'"},
      {"NVM_V3\n\n1\na.jpg 500 1 0 0 0 0 0 -5 0 1\n0\n", "n.nvm:4: camera 0 must end with 0, got '1'"},
      {"NVM_V3\n\n1\na.jpg 500 1 0 0 0 0 0 -5 0\n\n\n",
       "n.nvm:4: the file ends before camera 0 closing 0"},
      {head + "0 0 0 10 20 256 1 0 7 1.5 -2\n", "n.nvm:7: point 0 blue is 256, expected 0..255"},
      {head + "0 0 0 10 20 30 0\n", "n.nvm:7: point 0 measurement count is 0, expected 1..2"},
      {head + "0 0 0 10 20 30 1 2 7 1.5 -2\n", "n.nvm:7: point 0 image index is 2, expected 0..1"},
      {head + "0 0 0 10 20 30 1 0 -7 1.5 -2\n", "n.nvm:7: point 0 feature index is -7, expected 0..2147483647"},
      {head + "0 0 0 10 20 30 2 0 7 1.5 -2 0 8 1 2\n", "n.nvm:7: point 0 is seen twice by camera 0"},
      {head + "0 0 0 10 20 30 2 0 7 1.5 -2 1 8 1 inf\n", "n.nvm:7: point 0 y must be a finite number, got 'inf'"},
      {head + "0 0 0 10 20 30 2 0 7 1.5 -2 1 8 1\n", "n.nvm:7: the file ends before point 0 y"},
      {head.substr(0, head.size() - 2) + "5\n0 0 0 10 20 30 1 0 7 1.5 -2\n",
       "n.nvm: 5 points need more values than the file holds"},
  };
  for (const Bad &b : cases) {
    nvm::Model out;
    std::string error;
    EXPECT_FALSE(nvm::parse_nvm(b.text, "n.nvm", &out, &error)) << b.text;
    EXPECT_EQ(error, b.message);
  }
  nvm::Model out;
  std::string error;
  EXPECT_TRUE(nvm::parse_nvm(head + "0 0 0 10 20 30 2 0 7 1.5 -2 1 8 1 2\n", "n.nvm", &out, &error)) << error;
}

// ---- mapping ----

TEST(NvmMapping, CentresAndUndistortedMeasurements) {
  const std::string text =
      "NVM_V3\n\n2\na.jpg 500 1 0 0 0 0 0 -5 1e-6 0\nb.jpg 600 2 0 0 0 1 0 -5 0 0\n"
      "2\n0 0 0 10 20 30 2 1 7 1.5 -2 0 3 100 -50\n1 1 1 1 2 3 1 0 4 0 0\n";
  nvm::Model m;
  std::string error;
  ASSERT_TRUE(nvm::parse_nvm(text, "n.nvm", &m, &error)) << error;
  nvm::SbaProblem p;
  ASSERT_TRUE(nvm::to_sba(m, true, "n.nvm", &p, &error)) << error;
  EXPECT_EQ(p.nccalib, 4);
  EXPECT_EQ(p.ncdist, 5);
  ASSERT_EQ(p.cameras.size(), 2u);
  EXPECT_EQ(p.cameras[1].k.fu, 600);
  EXPECT_EQ(p.cameras[1].k.u0, 0);
  // t = -R C: a quaternion of norm 2 is the identity rotation.
  EXPECT_EQ(p.cameras[1].t, (std::array<double, 3>{-1, 0, 5}));
  // Point 0's measurements, cameras ascending; camera 0's undistorted: m (1 + 1e-6 |m|^2).
  EXPECT_TRUE(p.points.vmask.empty());  // the visibility as pairs: point 0 in cameras 0 and 1, point 1 in 0
  EXPECT_EQ(p.points.pairs.point, (std::vector<int>{0, 0, 1}));
  EXPECT_EQ(p.points.pairs.camera, (std::vector<int>{0, 1, 0}));
  ASSERT_EQ(p.points.x.size(), 6u);
  EXPECT_DOUBLE_EQ(p.points.x[0], 101.25);
  EXPECT_DOUBLE_EQ(p.points.x[1], -50.625);
  EXPECT_EQ(p.points.x[2], 1.5);
  EXPECT_EQ(p.points.x[3], -2);
  ASSERT_TRUE(nvm::to_sba(m, false, "n.nvm", &p, &error)) << error;
  EXPECT_EQ(p.nccalib, 5);
  // Values whose products overflow.
  nvm::Model big = m;
  big.cameras[0].k = 1e305;
  EXPECT_FALSE(nvm::to_sba(big, true, "n.nvm", &p, &error));
  EXPECT_EQ(error, "n.nvm: point 0: its measurement in camera 0 undistorts to a value that overflows");
  big = m;
  big.cameras[1].q = {2, 1, 0, 0};
  big.cameras[1].c = {0, 1.5e308, -1.5e308};
  EXPECT_FALSE(nvm::to_sba(big, true, "n.nvm", &p, &error));
  EXPECT_EQ(error, "n.nvm: camera 1: its translation -R C overflows");
    // Camera 1 left without a point.
  m.points[0].measurements.erase(m.points[0].measurements.begin());
  EXPECT_FALSE(nvm::to_sba(m, true, "n.nvm", &p, &error));
  EXPECT_EQ(error, "n.nvm: camera 1 (b.jpg) sees no point: sba cannot place it");
  m.points.clear();
  EXPECT_FALSE(nvm::to_sba(m, true, "n.nvm", &p, &error));
  EXPECT_EQ(error, "n.nvm: the first model has no cameras or no points");
}

// ---- sbarefine ----

struct Refinement {
  std::string dir, cams, pts;  // eucsbademo's files of the scene, VaryingIntrinsicsDistortion
  eucsba::Problem problem;
  double expected = 0;         // their final error with the focal length refined
};

// A generated varK scene as eucsbademo's varKD files (no distortion): with --nccalib 4
// --ncdist 5 eucsbademo refines what sbarefine refines in an NVM file by default.
Refinement make_refinement(const std::string &name) {
  Refinement r;
  r.dir = temp_dir(name);
  const refinetest::GeneratedScene s =
      refinetest::generate_scene(r.dir, euclidean::CameraKind::VaryingIntrinsics, 10, 200);
  r.cams = r.dir + "/kd-cams.txt";
  r.pts = s.prefix + "-pts.txt";
  std::string error;
  EXPECT_TRUE(
      eucsba::write_cameras(r.cams, euclidean::CameraKind::VaryingIntrinsicsDistortion, s.problem.cameras, &error))
      << error;
  EXPECT_TRUE(eucsba::load_problem(r.cams, r.pts, "", &r.problem, &error)) << error;
  r.expected = eucsbademo_error("--nccalib 4 --ncdist 5 " + r.cams + " " + r.pts);
  return r;
}

TEST(SbarefineNvm, SameErrorAsEucsbademoAndEverythingElseKept) {
  const Refinement e = make_refinement("nvm_refine");
  ASSERT_GT(e.expected, 0.1);
  ASSERT_LT(e.expected, 1.0);
  const nvm::Model m = make_model(e.problem);
  std::string error;
  ASSERT_TRUE(nvm::write_nvm(e.dir + "/in.nvm", m, &error)) << error;
  const Outcome r = run(e.dir + "/in.nvm --write " + e.dir + "/out.nvm --initial-ply " + e.dir + "/i.ply");
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_NE(r.out.find("NVM file " + e.dir + "/in.nvm: 10 cameras, 200 points, "), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("Intrinsics refined: focal (nccalib 4); radial distortion held: VisualSFM applies it to the "
                       "measurements, which sba takes as data\n"),
            std::string::npos)
      << r.out;
  EXPECT_NEAR(final_error(r.out), e.expected, 1e-6 * e.expected) << r.out;
  nvm::Model back;
  ASSERT_TRUE(nvm::read_nvm(e.dir + "/out.nvm", &back, &error)) << error;
  // Focal lengths, poses and structure refined; with them put back, the model is the input:
  // header, names, k, colors, feature indices, measurements and the rest of the file.
  nvm::Model unrefined = back;
  ASSERT_EQ(back.cameras.size(), m.cameras.size());
  for (std::size_t j = 0; j < m.cameras.size(); ++j) {
    EXPECT_NE(back.cameras[j].f, m.cameras[j].f);
    EXPECT_NE(back.cameras[j].c, m.cameras[j].c);
    unrefined.cameras[j].f = m.cameras[j].f;
    unrefined.cameras[j].q = m.cameras[j].q;
    unrefined.cameras[j].c = m.cameras[j].c;
  }
  ASSERT_EQ(back.points.size(), m.points.size());
  for (std::size_t i = 0; i < m.points.size(); ++i) {
    EXPECT_NE(back.points[i].xyz, m.points[i].xyz);
    unrefined.points[i].xyz = m.points[i].xyz;
  }
  expect_same(unrefined, m);
  // The PLY file: 200 points, then 10 camera centres in red, the first the file's.
  const std::string ply = read_file(e.dir + "/i.ply");
  EXPECT_NE(ply.find("element vertex 210\n"), std::string::npos);
  char centre[128];
  std::snprintf(centre, sizeof centre, "\n%.17g %.17g %.17g 255 0 0\n", m.cameras[0].c[0], m.cameras[0].c[1],
                m.cameras[0].c[2]);
  EXPECT_NE(ply.find(centre), std::string::npos) << centre;
}

// Measurements from the image corner (as COLMAP writes NVM) rather than its centre: one
// warning naming the file; the solve runs and its status is kept. Centred ones: no warning.
TEST(SbarefineNvm, WarnsWhenMeasurementsLookUncentred) {
  const Refinement e = make_refinement("nvm_uncentred");
  const nvm::Model centred = make_model(e.problem);
  nvm::Model corner = centred;
  for (nvm::Point &pt : corner.points)
    for (nvm::Measurement &v : pt.measurements) {
      v.x += 320;
      v.y += 240;
    }
  EXPECT_FALSE(nvm::looks_uncentred(centred));
  EXPECT_TRUE(nvm::looks_uncentred(corner));
  std::string error;
  ASSERT_TRUE(nvm::write_nvm(e.dir + "/centred.nvm", centred, &error)) << error;
  ASSERT_TRUE(nvm::write_nvm(e.dir + "/corner.nvm", corner, &error)) << error;
  Outcome r = run(e.dir + "/centred.nvm --itmax 5");
  EXPECT_EQ(r.status, 0) << r.err;
  EXPECT_EQ(r.err, "");
  r = run(e.dir + "/corner.nvm --itmax 5");
  EXPECT_EQ(r.status, 0) << r.err;
  EXPECT_EQ(r.err, "sbarefine: warning: " + e.dir +
                       "/corner.nvm: the measurements look measured from the image corner, not from its centre as "
                       "NVM's are (99% of them have x >= 0 and y >= 0); COLMAP writes NVM files so, and they do not "
                       "refine to a small error\n");
  // Below 100 measurements nothing is judged: a file too small to tell.
  nvm::Model small = corner;
  small.points.resize(9);
  std::size_t count = 0;
  for (const nvm::Point &pt : small.points) count += pt.measurements.size();
  ASSERT_LT(count, 100u);
  EXPECT_FALSE(nvm::looks_uncentred(small));
}

TEST(SbarefineNvm, HeldFocalAndHeldCamerasAsFixedK) {
  const std::string dir = temp_dir("nvm_fixed");
  const refinetest::GeneratedScene s = refinetest::generate_scene(dir, euclidean::CameraKind::FixedIntrinsics, 10, 200);
  const double expected =
      eucsbademo_error("--mcon 1 " + s.prefix + "-cams.txt " + s.prefix + "-pts.txt " + s.prefix + "-calib.txt");
  const nvm::Model m = make_model(s.problem);
  std::string error;
  ASSERT_TRUE(nvm::write_nvm(dir + "/in.nvm", m, &error)) << error;
  const Outcome r =
      run(dir + "/in.nvm --intrinsics none --mcon 1 --write " + dir + "/out.nvm --json " + dir + "/r.json");
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_NE(r.out.find("Intrinsics refined: none (nccalib 5); "), std::string::npos) << r.out;
  // The unknowns: the 9 cameras' poses from --mcon 1 on and the points; the intrinsics, which
  // eucsbademo's camera model holds, are parameters only (16 a camera).
  const std::string unknowns = std::to_string(9 * 6 + 3 * m.points.size()),
                    parameters = std::to_string(10 * 16 + 3 * m.points.size());
  EXPECT_NE(r.out.find(" observations, " + unknowns + " unknowns (" + parameters + " parameters, "), std::string::npos)
      << r.out;
  EXPECT_NE(read_file(dir + "/r.json").find("\"variables\": " + parameters + ", \"unknowns\": " + unknowns + "}"),
            std::string::npos);
  EXPECT_NEAR(final_error(r.out), expected, 1e-6 * expected) << r.out;
  nvm::Model back;
  ASSERT_TRUE(nvm::read_nvm(dir + "/out.nvm", &back, &error)) << error;
  for (std::size_t j = 0; j < m.cameras.size(); ++j) EXPECT_EQ(back.cameras[j].f, m.cameras[j].f);
  // The held camera is written back bit for bit.
  EXPECT_EQ(back.cameras[0].q, m.cameras[0].q);
  EXPECT_EQ(back.cameras[0].c, m.cameras[0].c);
  EXPECT_NE(back.cameras[1].c, m.cameras[1].c);
  // --json names each camera by its image.
  EXPECT_NE(read_file(dir + "/r.json").find("{\"camera\": 9, \"name\": \"img_0009.jpg\", \"observations\": "),
            std::string::npos);
}

// Measurements distorted the way VisualSFM undistorts them (solving m (1 + k |m|^2) = u for
// m) refine as the undistorted ones do, and k and the measurements are written back as read.
TEST(SbarefineNvm, RadialDistortionHeldOnTheMeasurements) {
  const Refinement e = make_refinement("nvm_distortion");
  nvm::Model m = make_model(e.problem);
  for (std::size_t j = 0; j < m.cameras.size(); ++j) m.cameras[j].k = 2e-7 * (1 + static_cast<double>(j % 3));
  for (nvm::Point &p : m.points)
    for (nvm::Measurement &v : p.measurements) {
      const double k = m.cameras[static_cast<std::size_t>(v.camera)].k, ux = v.x, uy = v.y;
      for (int it = 0; it < 60; ++it) {
        const double s = 1 + k * (v.x * v.x + v.y * v.y);
        v.x = ux / s;
        v.y = uy / s;
      }
    }
  // The distortion moved the measurements: undistorted the other way, the error would grow.
  const nvm::Model plain = make_model(e.problem);
  EXPECT_GT(std::fabs(m.points[3].measurements[1].x - plain.points[3].measurements[1].x), 1e-3);
  std::string error;
  ASSERT_TRUE(nvm::write_nvm(e.dir + "/in.nvm", m, &error)) << error;
  const Outcome r = run(e.dir + "/in.nvm --write " + e.dir + "/out.nvm");
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_NEAR(final_error(r.out), e.expected, 1e-6 * e.expected) << r.out;
  nvm::Model back;
  ASSERT_TRUE(nvm::read_nvm(e.dir + "/out.nvm", &back, &error)) << error;
  for (std::size_t j = 0; j < m.cameras.size(); ++j) EXPECT_EQ(back.cameras[j].k, m.cameras[j].k);
  EXPECT_EQ(back.points[3].measurements[1].x, m.points[3].measurements[1].x);
}

TEST(SbarefineNvm, ConvertsToEucsbademo) {
  const Refinement e = make_refinement("nvm_convert");
  std::string error;
  ASSERT_TRUE(nvm::write_nvm(e.dir + "/in.nvm", make_model(e.problem), &error)) << error;
  const Outcome r = run(e.dir + "/in.nvm --itmax 0 --write-eucsba " + e.dir + "/e");
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_NEAR(eucsbademo_error("--nccalib 4 --ncdist 5 " + e.dir + "/e-cams.txt " + e.dir + "/e-pts.txt"), e.expected,
              1e-6 * e.expected);
}

// A file on a pipe is read once: the format is told from the bytes read, not from a second
// opening of the file.
TEST(SbarefineNvm, ReadsAPipe) {
  const Refinement e = make_refinement("nvm_pipe");
  std::string error;
  ASSERT_TRUE(nvm::write_nvm(e.dir + "/in.nvm", make_model(e.problem), &error)) << error;
  const Outcome file = run(e.dir + "/in.nvm --write " + e.dir + "/file.nvm");
  ASSERT_EQ(file.status, 0) << file.err;
  const Outcome pipe = run("/dev/stdin --write " + e.dir + "/pipe.nvm", "cat " + e.dir + "/in.nvm | ");
  ASSERT_EQ(pipe.status, 0) << pipe.err;
  EXPECT_NEAR(final_error(pipe.out), e.expected, 1e-6 * e.expected) << pipe.out;
  EXPECT_EQ(read_file(e.dir + "/pipe.nvm"), read_file(e.dir + "/file.nvm"));
}

// A run that fails at a report (on a full disk: /dev/full here) leaves the NVM file it writes
// over as it was, and no eucsbademo file of --write-eucsba.
TEST(SbarefineNvm, FailedRunLeavesTheFileAsItWas) {
  const refinetest::GeneratedScene g =
      refinetest::generate_scene(temp_dir("nvm_failed_scene"), euclidean::CameraKind::VaryingIntrinsics, 6, 60);
  for (const char *report : {"--json", "--final-ply"}) {
    SCOPED_TRACE(report);
    const std::string dir = temp_dir(std::string("nvm_failed") + report);
    std::string error;
    ASSERT_TRUE(nvm::write_nvm(dir + "/in.nvm", make_model(g.problem), &error)) << error;
    const Tree before = tree(dir);
    const Outcome r = run(dir + "/in.nvm --write " + dir + "/in.nvm --write-eucsba " + dir + "/e " + report + " /dev/full");
    EXPECT_EQ(r.status, 1);
    EXPECT_EQ(r.err, "/dev/full: write failed: No space left on device\n");
    EXPECT_EQ(changes(before, tree(dir)), "");
  }
}

TEST(SbarefineNvm, CommandLineErrors) {
  const std::string dir = temp_dir("nvm_cli");
  const std::string nvm_file = dir + "/m.nvm";
  write_file(nvm_file, "NVM_V3\n\n2\na.jpg 500 1 0 0 0 0 0 -5 0 0\nb.jpg 500 1 0 0 0 1 0 -5 0 0\n"
                       "1\n0 0 0 10 20 30 1 0 7 1.5 -2\n");
  const struct {
    std::string args;
    int status;
    std::string err;
  } cases[] = {
      {"--intrinsics focal,principal " + nvm_file, 2,
       "sbarefine: --intrinsics focal,principal: an NVM file has no principal point (its measurements are relative "
       "to the image centre)\n"},
      {"--write-format text " + nvm_file, 2, "sbarefine: --write-format is for COLMAP models\n"},
      {"--write-bal " + dir + "/x.bal " + nvm_file, 2, "sbarefine: --write-bal is for Bundler files\n"},
      {nvm_file, 1, nvm_file + ": camera 1 (b.jpg) sees no point: sba cannot place it\n"},
  };
  for (const auto &c : cases) {
    const Outcome r = run(c.args);
    EXPECT_EQ(r.status, c.status) << c.args;
    EXPECT_EQ(r.err, c.err) << c.args;
    EXPECT_EQ(r.out, "") << c.args;
  }
  write_file(nvm_file, "NVM_V3_R9T\n\n1\n");
  const Outcome r = run(nvm_file);
  EXPECT_EQ(r.status, 1);
  EXPECT_EQ(r.err, nvm_file + ":1: expected the header 'NVM_V3', got 'NVM_V3_R9T'\n");
}

// sbagen writes a scene as NVM, and refuses what NVM cannot hold.
TEST(SbagenNvm, WritesAnNvmFile) {
  const std::string dir = temp_dir("nvm_sbagen");
  const std::string gen = std::string(SBAGEN_EXE) + " --cameras 6 --points 60 --quiet --out " + dir + "/g";
  ASSERT_EQ(std::system((gen + " --kind varK --nvm " + dir + "/g.nvm").c_str()), 0);
  nvm::Model m;
  std::string error;
  ASSERT_TRUE(nvm::read_nvm(dir + "/g.nvm", &m, &error)) << error;
  ASSERT_EQ(m.cameras.size(), 6u);
  EXPECT_EQ(m.cameras[5].name, "img_0005.jpg");
  EXPECT_EQ(m.points.size(), 60u);
  EXPECT_EQ(m.points[1].rgb, (std::array<int, 3>{37, 75, 254}));
  EXPECT_EQ(m.header, "NVM_V3");
  EXPECT_EQ(m.rest, "");
  const int st = std::system((gen + " --kind varKD --nvm " + dir + "/x.nvm 2>" + dir + "/err").c_str());
  EXPECT_EQ(WEXITSTATUS(st), 1);
  EXPECT_EQ(read_file(dir + "/err"),
            "sbagen: camera 0 has an aspect ratio, a skew or distortion terms, which NVM cannot hold\n");
}

}  // namespace
