// SPDX-License-Identifier: BSD-3-Clause
// BAL support (lib/formats/bal_io.h, lib/cameras/bal_camera.h): the reader on the shared
// BAL files and on malformed inputs, the analytic Jacobian against finite differences, the writer's round
// trip, and a regression solve of the Ladybug problem-49-7776 with sba.
#include <gtest/gtest.h>

#include <bzlib.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <thread>
#include <vector>

#include "cameras/bal_camera.h"
#include "counting_new.h"
#include "formats/bal_io.h"
#include "ply_file.h"
#include "sba.h"
#include "sba_ext.h"
#include "scratch.h"

namespace bal = sbaformats::bal;
namespace bal_camera = sbacameras::bal;

namespace {

std::string bal_dir() { return std::string(SBA_SHARED_DATA_DIR) + "/bal"; }

bool exists(const std::string &path) {
  struct stat st;
  return ::stat(path.c_str(), &st) == 0;
}

// Skips the test when the shared data is absent.
#define REQUIRE_FILE(path)                                                                      \
  do {                                                                                          \
    if (!exists(path)) GTEST_SKIP() << "shared data not found: " << (path)                     \
                                    << " (set SBA_SHARED_DATA_DIR)";                            \
  } while (0)

// ctest runs each test in its own process, several at a time: the process id keeps their
// scratch files (balsba's captured output among them) apart.
std::string temp_path(const std::string &name) {
  return sbatest::scratch_dir() + "test_bal_" + std::to_string(::getpid()) + "_" + name;
}

std::string write_temp(const std::string &name, const std::string &text) {
  const std::string path = temp_path(name);
  std::ofstream(path, std::ios::binary) << text;
  return path;
}

// ---- reader ----

TEST(BalReader, DubrovnikSubset) {
  const std::string path = bal_dir() + "/dubrovnik-3-7-pre.txt.bz2";
  REQUIRE_FILE(path);
  bal::Problem p;
  std::string error;
  ASSERT_TRUE(bal::read_problem(path, &p, &error)) << error;
  EXPECT_EQ(p.ncameras, 3);
  EXPECT_EQ(p.npoints, 7);
  EXPECT_EQ(p.nobservations(), 19);
  EXPECT_EQ(p.cameras.size(), 27u);
  EXPECT_EQ(p.points.size(), 21u);

  // The README: its first observation is the first observation of problem-16-22106.
  const std::string big = bal_dir() + "/problem-16-22106-pre.txt.bz2";
  REQUIRE_FILE(big);
  bal::Problem q;
  ASSERT_TRUE(bal::read_problem(big, &q, &error)) << error;
  EXPECT_EQ(p.observations[0].camera, q.observations[0].camera);
  EXPECT_EQ(p.observations[0].point, q.observations[0].point);
  EXPECT_EQ(p.observations[0].x, q.observations[0].x);
  EXPECT_EQ(p.observations[0].y, q.observations[0].y);

  // sba's layout: point by point, cameras ascending, one (point, camera) pair per observation.
  bal::SbaLayout s;
  ASSERT_TRUE(bal::to_sba(p, path, &s, &error)) << error;
  EXPECT_EQ(s.n, 7);
  EXPECT_EQ(s.m, 3);
  ASSERT_EQ(s.nobservations(), 19);
  ASSERT_EQ(s.vis.size(), 19u);
  for (int k = 0; k < 19; ++k) {
    const bal::Observation &o = p.observations[s.order[k]];
    EXPECT_EQ(s.vis.point[k], o.point);
    EXPECT_EQ(s.vis.camera[k], o.camera);
    EXPECT_EQ(s.x[2 * k], o.x);
    EXPECT_EQ(s.x[2 * k + 1], o.y);
    if (k > 0) {
      const bal::Observation &prev = p.observations[s.order[k - 1]];
      EXPECT_TRUE(prev.point < o.point || (prev.point == o.point && prev.camera < o.camera));
    }
  }
  ASSERT_EQ(s.p.size(), 27u + 21u);
  EXPECT_EQ(s.p[0], p.cameras[0]);
  EXPECT_EQ(s.p[27], p.points[0]);
}

TEST(BalReader, SharedFilesMatchTheReadme) {
  struct Expect {
    const char *file;
    int cameras, points, observations;
  };
  const Expect table[] = {{"problem-49-7776-pre.txt.bz2", 49, 7776, 31843},
                          {"problem-21-11315-pre.txt.bz2", 21, 11315, 36455},
                          {"problem-16-22106-pre.txt.bz2", 16, 22106, 83718}};
  for (const Expect &e : table) {
    const std::string path = bal_dir() + "/" + e.file;
    REQUIRE_FILE(path);
    bal::Problem p;
    std::string error;
    ASSERT_TRUE(bal::read_problem(path, &p, &error)) << error;
    EXPECT_EQ(p.ncameras, e.cameras) << e.file;
    EXPECT_EQ(p.npoints, e.points) << e.file;
    EXPECT_EQ(p.nobservations(), e.observations) << e.file;
    // Every camera and point is observed (README), and the layout conversion succeeds.
    bal::SbaLayout s;
    ASSERT_TRUE(bal::to_sba(p, path, &s, &error)) << error;
    std::vector<int> per_camera(e.cameras), per_point(e.points);
    for (const bal::Observation &o : p.observations) {
      ++per_camera[o.camera];
      ++per_point[o.point];
    }
    for (int c : per_camera) EXPECT_GT(c, 0) << e.file;
    for (int c : per_point) EXPECT_GT(c, 0) << e.file;
  }
}

TEST(BalReader, PlainTextAndBlankLines) {
  // GTSAM-style blank lines between sections, tabs, CRLF line ends: any white space separates.
  const std::string text =
      "2 2 3\r\n\n0 0 1.5 -2\n1\t0 3 4\n1 1 -1e2 2.5e-1\n\n"
      "0 0 0 0 0 -5 500 0 0\n0.1 0 0 1 0 -5 400 -0.1 0.01\n\n1 2 3\n4 5 6\n";
  const std::string path = write_temp("plain.txt", text);
  bal::Problem p;
  std::string error;
  ASSERT_TRUE(bal::read_problem(path, &p, &error)) << error;
  EXPECT_EQ(p.ncameras, 2);
  EXPECT_EQ(p.npoints, 2);
  ASSERT_EQ(p.nobservations(), 3);
  EXPECT_EQ(p.observations[1].camera, 1);
  EXPECT_EQ(p.observations[1].point, 0);
  EXPECT_EQ(p.observations[2].x, -100.0);
  EXPECT_EQ(p.cameras[9], 0.1);
  EXPECT_EQ(p.cameras[17], 0.01);
  EXPECT_EQ(p.points[5], 6.0);
}

struct Malformed {
  const char *name;
  const char *text;
  const char *message;  // expected in the one-line error after "<path>: "
};

TEST(BalReader, MalformedInputs) {
  const Malformed cases[] = {
      {"empty", "", "empty file"},
      {"blank", " \n\t\n", "empty file"},
      {"short_header", "1 1", "header 'ncameras npoints nobservations' is incomplete"},
      {"real_count", "1 1.0 1\n", "line 1: header: the number of points must be an integer, got '1.0'"},
      {"zero_cameras", "0 1 1\n", "header: the number of cameras must be between 1 and"},
      {"negative_obs", "1 1 -3\n", "header: the number of observations must be between 1 and"},
      {"huge_count", "1 1 99999999999\n", "the number of observations must be between 1 and"},
      {"huge_header", "2000000000 2000000000 2000000000\n0 0 1 1\n", "truncated file: it ends inside observation 1"},
      {"too_many_obs", "1 1 2\n0 0 1 1\n0 0 1 1\n", "2 observations but only 1 camera-point pairs"},
      {"camera_range", "1 1 1\n1 0 1 1\n", "line 2: observation 0: the camera index 1 is out of range 0..0"},
      {"point_range", "1 1 1\n0 -1 1 1\n", "observation 0: the point index -1 is out of range 0..0"},
      {"index_real", "1 1 1\n0.0 0 1 1\n", "observation 0: the camera index must be an integer, got '0.0'"},
      {"x_nan", "1 1 1\n0 0 nan 1\n", "line 2: observation 0: x must be a finite number, got 'nan'"},
      {"y_inf", "1 1 1\n0 0 1 -inf\n", "observation 0: y must be a finite number, got '-inf'"},
      {"x_garbage", "1 1 1\n0 0 1.5x 1\n", "observation 0: x must be a finite number, got '1.5x'"},
      {"x_hex", "1 1 1\n0 0 0x1p3 1\n", "observation 0: x must be a finite number, got '0x1p3'"},
      {"camera_value", "1 1 1\n0 0 1 1\n0 0 0 0 0 -5 abc 0 0\n1 2 3\n",
       "line 3: camera 0: f must be a finite number, got 'abc'"},
      {"point_value", "1 1 1\n0 0 1 1\n0 0 0 0 0 -5 500 0 0\n1 1e999 3\n",
       "line 4: point 0: Y must be a finite number, got '1e999'"},
      {"truncated_obs", "1 2 2\n0 0 1 1\n0 1 1\n", "truncated file"},
      {"truncated_camera", "2 1 2\n0 0 1 1\n1 0 1 1\n0 0 0 0 0 -5 500 0 0\n0 0 0 0 0 -5 500\n1 2 3\n",
       "truncated file: it ends inside point 0"},
      {"truncated_point", "1 1 1\n0 0 1 1\n0 0 0 0 0 -5 500 0 0\n1 2\n", "truncated file: it ends inside point 0"},
      {"trailing", "1 1 1\n0 0 1 1\n0 0 0 0 0 -5 500 0 0\n1 2 3\n4\n",
       "line 5: more data than the header announces (1 observations, 1 cameras, 1 points): '4' after "
       "the last point"},
      {"duplicate", "2 2 3\n0 0 1 1\n1 1 2 2\n0 0 3 3\n0 0 0 0 0 -5 500 0 0\n0 0 0 0 0 -5 500 0 0\n1 2 3\n4 5 6\n",
       "line 4: observation 2 repeats point 0 in camera 0 (already observation 0)"},
  };
  for (const Malformed &c : cases) {
    const std::string path = write_temp(std::string(c.name) + ".txt", c.text);
    bal::Problem p;
    std::string error;
    EXPECT_FALSE(bal::read_problem(path, &p, &error)) << c.name;
    EXPECT_EQ(error.rfind(path + ": ", 0), 0u) << c.name << ": " << error;
    EXPECT_NE(error.find(c.message), std::string::npos) << c.name << ": got \"" << error << "\"";
    EXPECT_EQ(error.find('\n'), std::string::npos) << c.name;
  }
}

TEST(BalReader, MissingAndCorruptFiles) {
  std::string error;
  bal::Problem p;
  const std::string missing = temp_path("does-not-exist.txt");
  EXPECT_FALSE(bal::read_problem(missing, &p, &error));
  EXPECT_EQ(error, missing + ": cannot open: No such file or directory");

  // A bzip2 file cut short, and one with a damaged block.
  const std::string src = bal_dir() + "/problem-49-7776-pre.txt.bz2";
  REQUIRE_FILE(src);
  std::ifstream in(src, std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const std::string cut = write_temp("cut.txt.bz2", bytes.substr(0, bytes.size() / 2));
  EXPECT_FALSE(bal::read_problem(cut, &p, &error));
  EXPECT_EQ(error, cut + ": truncated bzip2 file (the compressed stream ends early)");

  std::string damaged = bytes;
  for (std::size_t k = 1000; k < 1100; ++k) damaged[k] = static_cast<char>(damaged[k] ^ 0x5a);
  const std::string bad = write_temp("damaged.txt.bz2", damaged);
  EXPECT_FALSE(bal::read_problem(bad, &p, &error));
  EXPECT_EQ(error, bad + ": corrupt bzip2 data");
}

// The reader holds a token at a time, never the whole text: a run without white space (a
// binary file) and a run of white space are refused once they pass their bounds.
TEST(BalReader, BoundsOnTokensAndWhiteSpace) {
  bal::Problem p;
  std::string error;
  const std::string values = "1 1 1\n0 0 1 1\n0 0 0 0 0 -5 500 0 0\n";
  EXPECT_FALSE(bal::parse_problem(values + "1 2 " + std::string(4097, '3') + "\n", "long", &p, &error));
  EXPECT_EQ(error, "long: line 4: more than 4096 bytes without white space (no number is that long)");
  // 4096 bytes are still a number.
  EXPECT_TRUE(bal::parse_problem(values + "1 2 " + std::string(4095, '0') + "3\n", "long", &p, &error)) << error;
  EXPECT_EQ(p.points[2], 3.0);
  EXPECT_FALSE(bal::parse_problem(values + "1 2 3" + std::string((1 << 20) + 1, ' ') + "\n", "blank", &p, &error));
  EXPECT_EQ(error, "blank: line 4: more than 1048576 bytes of white space in a row");
  EXPECT_TRUE(bal::parse_problem(values + "1 2 3" + std::string(1 << 20, '\n'), "blank", &p, &error)) << error;
}

// The reader stops at a parse error without reading the rest; when the data came from a
// damaged bzip2 block, the damage is the cause to name. Here the block's stored CRC (bytes
// 10 to 13, after "BZh9" and the block magic) is altered: its data decompress unchanged, with
// values too many, and only the check at the block's end, some 200 kB of output later (more
// than one read), tells the file is corrupt.
TEST(BalReader, ParseErrorInADamagedBlockNamesTheDamage) {
  std::string text = "1 1 1\n0 0 1 1\n0 0 0 0 0 -5 500 0 0\n1 2 3\n4\n";
  for (int k = 0; k < 100000; ++k) text += k % 2 ? "5\n" : "6\n";
  std::vector<char> out(text.size());
  unsigned int len = static_cast<unsigned int>(out.size());
  ASSERT_EQ(BZ2_bzBuffToBuffCompress(out.data(), &len, text.data(), static_cast<unsigned int>(text.size()), 9, 0, 0),
            BZ_OK);
  std::string bytes(out.data(), len);
  const std::string intact = write_temp("intact.txt.bz2", bytes);
  bal::Problem p;
  std::string error;
  EXPECT_FALSE(bal::read_problem(intact, &p, &error));
  EXPECT_EQ(error, intact + ": line 5: more data than the header announces (1 observations, 1 cameras, 1 points): "
                            "'4' after the last point");
  bytes[12] = static_cast<char>(bytes[12] ^ 0x01);
  const std::string damaged = write_temp("crc.txt.bz2", bytes);
  EXPECT_FALSE(bal::read_problem(damaged, &p, &error));
  EXPECT_EQ(error, damaged + ": corrupt bzip2 data");
}

TEST(BalReader, ToSbaRefusesDuplicatesBuiltInMemory) {
  bal::Problem p;
  p.ncameras = 1;
  p.npoints = 1;
  p.cameras.assign(9, 0.0);
  p.points.assign(3, 1.0);
  p.observations = {{0, 0, 1, 1}, {0, 0, 2, 2}};
  bal::SbaLayout s;
  std::string error;
  EXPECT_FALSE(bal::to_sba(p, "mem", &s, &error));
  EXPECT_EQ(error, "mem: observation 1 repeats point 0 in camera 0");
}

// ---- writer ----

TEST(BalWriter, RoundTripPlainAndBzip2) {
  const std::string path = bal_dir() + "/dubrovnik-3-7-pre.txt.bz2";
  REQUIRE_FILE(path);
  bal::Problem p;
  std::string error;
  ASSERT_TRUE(bal::read_problem(path, &p, &error)) << error;
  // Values that need all 17 digits survive too.
  p.cameras[0] = 0.1 + 0.2;
  p.points[1] = -1.0 / 3.0;
  for (const char *name : {"round.txt", "round.txt.bz2"}) {
    const std::string out = temp_path(name);
    ASSERT_TRUE(bal::write_problem(out, p, &error)) << error;
    bal::Problem q;
    ASSERT_TRUE(bal::read_problem(out, &q, &error)) << error;
    EXPECT_EQ(q.ncameras, p.ncameras);
    EXPECT_EQ(q.npoints, p.npoints);
    ASSERT_EQ(q.nobservations(), p.nobservations());
    for (int k = 0; k < p.nobservations(); ++k) {
      EXPECT_EQ(q.observations[k].camera, p.observations[k].camera);
      EXPECT_EQ(q.observations[k].point, p.observations[k].point);
      EXPECT_EQ(q.observations[k].x, p.observations[k].x);
      EXPECT_EQ(q.observations[k].y, p.observations[k].y);
    }
    EXPECT_EQ(q.cameras, p.cameras) << name;
    EXPECT_EQ(q.points, p.points) << name;
  }
  // The compressed one really is bzip2.
  std::ifstream in(temp_path("round.txt.bz2"), std::ios::binary);
  char magic[3] = {};
  in.read(magic, 3);
  EXPECT_EQ(std::string(magic, 3), "BZh");

  EXPECT_FALSE(bal::write_problem("/nonexistent-dir/x.txt", p, &error));
  EXPECT_EQ(error.rfind("/nonexistent-dir/x.txt: cannot open for writing: ", 0), 0u) << error;
}

// A problem on a pipe, plain or compressed: the bytes that tell bzip2 from text are read
// once, not read and then rewound (which a pipe cannot do).
TEST(BalReader, ReadsAPipe) {
  bal::Problem p;
  std::string error;
  const std::string camera = "0 0 0 0 0 -5 500 0 0\n";
  ASSERT_TRUE(bal::parse_problem("2 2 3\n0 0 1 1\n1 0 2 2\n1 1 3 3\n" + camera + camera + "1 2 3\n4 5 6\n", "p.txt", &p,
                                 &error))
      << error;
  p.cameras[4] = 0.1 + 0.2;
  for (const char *name : {"piped.txt", "piped.txt.bz2"}) {
    const std::string file = temp_path(name), fifo = temp_path("pipe");
    ASSERT_TRUE(bal::write_problem(file, p, &error)) << error;
    std::remove(fifo.c_str());
    ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
    std::thread writer([&] {
      std::ifstream in(file, std::ios::binary);
      std::ofstream(fifo, std::ios::binary) << in.rdbuf();
    });
    bal::Problem q;
    const bool read = bal::read_problem(fifo, &q, &error);
    writer.join();
    EXPECT_TRUE(read) << name << ": " << error;
    EXPECT_EQ(q.nobservations(), 3) << name;
    EXPECT_EQ(q.cameras, p.cameras) << name;
    EXPECT_EQ(q.points, p.points) << name;
    std::remove(fifo.c_str());
  }
}

TEST(BalWriter, FromSbaParams) {
  bal::Problem p;
  p.ncameras = 2;
  p.npoints = 1;
  p.cameras.assign(18, 0.0);
  p.points.assign(3, 0.0);
  std::vector<double> v(21);
  for (int k = 0; k < 21; ++k) v[k] = k;
  bal::from_sba_params(v.data(), &p);
  EXPECT_EQ(p.cameras[17], 17.0);
  EXPECT_EQ(p.points[0], 18.0);
  EXPECT_EQ(p.points[2], 20.0);
}

// ---- the camera model ----

// The rotation by angle |w| about w/|w|, written independently of the model's formula.
void axis_angle_matrix(const double w[3], double R[9]) {
  const double theta = std::sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2]);
  if (theta == 0) {
    for (int k = 0; k < 9; ++k) R[k] = k % 4 == 0 ? 1 : 0;
    return;
  }
  const double x = w[0] / theta, y = w[1] / theta, z = w[2] / theta;
  const double c = std::cos(theta), s = std::sin(theta), C = 1 - c;
  const double M[9] = {c + x * x * C,     x * y * C - z * s, x * z * C + y * s,
                       y * x * C + z * s, c + y * y * C,     y * z * C - x * s,
                       z * x * C - y * s, z * y * C + x * s, c + z * z * C};
  for (int k = 0; k < 9; ++k) R[k] = M[k];
}

TEST(BalModel, RotationMatchesAxisAngleOnBothSidesOfTheSeries) {
  const double dirs[3][3] = {{1, 0, 0}, {0.3, -0.5, 0.8}, {-0.6, 0.64, 0.48}};
  const double angles[] = {0, 1e-12, 1e-7, 1e-3, 0.05, 0.2499999, 0.25, 0.2500001, 0.7, 2.0, 3.1, 4.5};
  for (const auto &d : dirs) {
    const double nd = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    for (double a : angles) {
      const double w[3] = {d[0] / nd * a, d[1] / nd * a, d[2] / nd * a};
      double R[9], E[9];
      bal_camera::rotation_matrix(w, R);
      axis_angle_matrix(w, E);
      for (int k = 0; k < 9; ++k) EXPECT_NEAR(R[k], E[k], 4e-16 * 4) << "angle " << a << " entry " << k;
    }
  }
}

TEST(BalModel, ProjectionByHand) {
  // w = 0, t = 0: Q = X = (1, 2, -4), p = (0.25, 0.5), r2 = 0.3125.
  const double a[9] = {0, 0, 0, 0, 0, 0, 2.0, 0.1, 0.01};
  const double b[3] = {1, 2, -4};
  double x[2];
  bal_camera::project(a, b, x);
  const double d = 1 + 0.1 * 0.3125 + 0.01 * 0.3125 * 0.3125;
  EXPECT_DOUBLE_EQ(x[0], 2.0 * d * 0.25);
  EXPECT_DOUBLE_EQ(x[1], 2.0 * d * 0.5);

  // A quarter turn about z maps (1, 0, 0) to (0, 1, 0); t moves it in front of the camera.
  const double pi = std::acos(-1.0);
  const double a2[9] = {0, 0, pi / 2, 0, 0, -2, 1.0, 0, 0};
  const double b2[3] = {1, 0, 0};
  bal_camera::project(a2, b2, x);
  EXPECT_NEAR(x[0], 0.0, 1e-16);
  EXPECT_NEAR(x[1], 0.5, 1e-15);  // -(1 / -2)
}

// Central differences of project() in every parameter, against the analytic blocks.
void check_jacobian(const double a[9], const double b[3], const char *what) {
  double x[2], A[18], B[6];
  bal_camera::project_jacobian(a, b, x, A, B);
  double x0[2];
  bal_camera::project(a, b, x0);
  EXPECT_EQ(x[0], x0[0]);
  EXPECT_EQ(x[1], x0[1]);
  for (int c = 0; c < 12; ++c) {
    double ap[9], am[9], bp[3], bm[3];
    std::copy(a, a + 9, ap);
    std::copy(a, a + 9, am);
    std::copy(b, b + 3, bp);
    std::copy(b, b + 3, bm);
    double &vp = c < 9 ? ap[c] : bp[c - 9];
    double &vm = c < 9 ? am[c] : bm[c - 9];
    const double h = 1e-6 * std::max(1.0, std::fabs(vp));
    vp += h;
    vm -= h;
    double xp[2], xm[2];
    bal_camera::project(ap, bp, xp);
    bal_camera::project(am, bm, xm);
    for (int r = 0; r < 2; ++r) {
      const double fd = (xp[r] - xm[r]) / (2 * h);
      const double an = c < 9 ? A[r * 9 + c] : B[r * 3 + c - 9];
      const double scale = std::max({1.0, std::fabs(fd), std::fabs(x[r])});
      EXPECT_NEAR(an, fd, 2e-7 * scale) << what << ": row " << r << " column " << c;
    }
  }
}

TEST(BalModel, JacobianMatchesFiniteDifferences) {
  // Rotations from zero through the series branch (|w| < 1/4), its edge and large angles;
  // realistic BAL magnitudes (f ~ 500, distortion, points a few units in front).
  const double rotations[][3] = {{0, 0, 0},        {1e-9, -2e-9, 5e-10}, {0.01, -0.02, 0.015},
                                 {0.1, 0.15, -0.1}, {0.2, 0.15, 0},      {0.2499, 0, 0},  {0.25, 0, 0},
                                 {-0.3, 0.4, 0.5},  {1.2, -0.7, 0.3},    {2.5, 1.5, -1.0}};
  const double b[3] = {0.7, -1.3, 2.1};
  for (const auto &w : rotations) {
    const double a[9] = {w[0], w[1], w[2], 0.3, -0.2, -6.0, 520.0, -0.08, 0.02};
    check_jacobian(a, b, "camera with distortion");
    const double a0[9] = {w[0], w[1], w[2], -0.1, 0.4, -4.0, 1.0, 0, 0};
    check_jacobian(a0, b, "unit focal, no distortion");
  }
}

// The rotation's columns against central differences extrapolated (Richardson: (4 D(h/2) -
// D(h)) / 3, error of order h^4), which resolve them to about 1e-11: on both sides of the
// series' limit (|w| = 1/4) in directions where every term of the rotation shows.
TEST(BalModel, RotationColumnsMatchExtrapolatedDifferences) {
  const double dirs[][3] = {{0.3, -0.5, 0.8}, {-0.6, 0.64, 0.48}};
  const double norms[] = {1e-6, 0.1, 0.2499999, 0.2500001, 0.9, 2.5};
  const double b[3] = {0.7, -1.3, 2.1};
  for (const auto &d : dirs)
    for (double n : norms) {
      const double nd = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
      double a[9] = {d[0] / nd * n, d[1] / nd * n, d[2] / nd * n, 0.3, -0.2, -6.0, 520.0, -0.08, 0.02};
      double x[2], A[18], B[6];
      bal_camera::project_jacobian(a, b, x, A, B);
      for (int c = 0; c < 3; ++c) {
        const auto central = [&](double h, int r) {
          double ap[9], am[9], xp[2], xm[2];
          std::copy(a, a + 9, ap);
          std::copy(a, a + 9, am);
          ap[c] += h;
          am[c] -= h;
          bal_camera::project(ap, b, xp);
          bal_camera::project(am, b, xm);
          return (xp[r] - xm[r]) / (2 * h);
        };
        for (int r = 0; r < 2; ++r) {
          const double h = 1e-3, fd = (4 * central(h / 2, r) - central(h, r)) / 3;
          EXPECT_NEAR(A[r * 9 + c], fd, 1e-9 * std::max(1.0, std::fabs(fd))) << "|w| " << n << " row " << r << " column " << c;
        }
      }
    }
}

TEST(BalModel, JacobianOnARealProblem) {
  const std::string path = bal_dir() + "/problem-49-7776-pre.txt.bz2";
  REQUIRE_FILE(path);
  bal::Problem p;
  std::string error;
  ASSERT_TRUE(bal::read_problem(path, &p, &error)) << error;
  for (int k = 0; k < p.nobservations(); k += 997) {
    const bal::Observation &o = p.observations[k];
    check_jacobian(p.camera(o.camera), p.point(o.point), "problem-49-7776");
  }
}

// A hand-built index of visible projections: 2 points, 2 cameras; point 0 seen by both,
// point 1 by camera 1 only. Camera 0's rotation is in the series range of the Rodrigues
// coefficients, camera 1's in the closed form. Not copyable (idx points into the arrays).
struct TwoCameraScene {
  std::vector<double> p = {0.01, 0.02, -0.03, 0.1, 0.2, -5, 500, -0.05, 0.01,
                           -0.4, 0.3, 0.5, -0.3, 0.1, -6, 480, 0.02, -0.01,
                           0.5, -0.4, 1.0, -0.2, 0.3, 0.4};
  int val[3] = {0, 1, 2}, colidx[3] = {0, 1, 1}, rowptr[3] = {0, 2, 3};
  sba_crsm idx{2, 2, 3, val, colidx, rowptr};
  bal_camera::CallbackData data{2};
  TwoCameraScene() = default;
  TwoCameraScene(const TwoCameraScene &) = delete;
  void func(double *hx) { bal_camera::motstr_func(p.data(), &idx, nullptr, nullptr, hx, &data); }
  void fjac(double *jac) { bal_camera::motstr_fjac(p.data(), &idx, nullptr, nullptr, jac, &data); }
};

// The callbacks address outputs by idxij.val. The simple driver's callbacks (balsba
// --single-precision-jacobian) give each projection the same bits.
TEST(BalModel, ExpertCallbacksFollowTheMeasurementOrdinals) {
  TwoCameraScene sc;
  double hx[6], jac[3 * 24];
  sc.func(hx);
  sc.fjac(jac);
  const int cams[3] = {0, 1, 1}, pts[3] = {0, 0, 1};
  for (int k = 0; k < 3; ++k) {
    double x[2], A[18], B[6], xs[2], J[24];
    double *a = &sc.p[9 * cams[k]], *b = &sc.p[18 + 3 * pts[k]];
    bal_camera::project_jacobian(a, b, x, A, B);
    EXPECT_EQ(hx[2 * k], x[0]);
    EXPECT_EQ(hx[2 * k + 1], x[1]);
    for (int c = 0; c < 18; ++c) EXPECT_EQ(jac[24 * k + c], A[c]);
    for (int c = 0; c < 6; ++c) EXPECT_EQ(jac[24 * k + 18 + c], B[c]);
    bal_camera::motstr_proj(cams[k], pts[k], a, b, xs, nullptr);
    bal_camera::motstr_projac(cams[k], pts[k], a, b, J, J + 18, nullptr);
    EXPECT_EQ(xs[0], x[0]);
    EXPECT_EQ(xs[1], x[1]);
    for (int c = 0; c < 24; ++c) EXPECT_EQ(J[c], jac[24 * k + c]) << k << " " << c;
  }
}

// The callbacks project two observations at a time, side by side, and an odd one alone: each
// projection must get project_jacobian's bits wherever it falls, over all of problem-49's rows
// and over parts of them of odd and even lengths (concurrent callbacks get parts).
TEST(BalModel, CallbacksGiveEveryProjectionItsOwnBits) {
  const std::string path = bal_dir() + "/problem-49-7776-pre.txt.bz2";
  REQUIRE_FILE(path);
  bal::Problem prob;
  std::string error;
  ASSERT_TRUE(bal::read_problem(path, &prob, &error)) << error;
  bal::SbaLayout s;
  ASSERT_TRUE(bal::to_sba(prob, path, &s, &error)) << error;
  const int nobs = s.nobservations();
  std::vector<int> rowptr(size_t(s.n) + 1, 0);
  std::vector<int> colidx(static_cast<size_t>(nobs)), val(static_cast<size_t>(nobs));
  for (int k = 0; k < nobs; ++k) {
    rowptr[size_t(s.vis.point[size_t(k)]) + 1]++;
    colidx[size_t(k)] = s.vis.camera[size_t(k)];
    val[size_t(k)] = k;
  }
  for (int i = 0; i < s.n; ++i) rowptr[size_t(i) + 1] += rowptr[size_t(i)];
  bal_camera::CallbackData data{s.m};
  // Rows [r0, r1) as the index of a part: its own row pointers, the ordinals global.
  const auto part = [&](int r0, int r1, double *hx, double *jac) {
    std::vector<int> rp(rowptr.begin() + r0, rowptr.begin() + r1 + 1);
    const int e0 = rp[0];
    for (int &r : rp) r -= e0;
    sba_crsm idx{r1 - r0, s.m, rp.back(), val.data() + e0, colidx.data() + e0, rp.data()};
    double *pb = s.p.data() + 9 * s.m + 3 * r0;
    std::vector<double> pp(s.p.begin(), s.p.begin() + 9 * s.m);
    pp.insert(pp.end(), pb, pb + 3 * (r1 - r0));
    bal_camera::motstr_func(pp.data(), &idx, nullptr, nullptr, hx, &data);
    bal_camera::motstr_fjac(pp.data(), &idx, nullptr, nullptr, jac, &data);
  };
  std::vector<double> hx(size_t(nobs) * 2, NAN), jac(size_t(nobs) * 24, NAN);
  const int cuts[] = {0, 1, 2, 5, 6, 101, 1000, 1001, s.n};
  for (int c = 0; c + 1 < int(std::size(cuts)); ++c) part(cuts[c], cuts[c + 1], hx.data(), jac.data());
  std::vector<double> whole_hx(hx.size(), NAN), whole_jac(jac.size(), NAN);
  part(0, s.n, whole_hx.data(), whole_jac.data());
  int differing = 0;
  for (int k = 0; k < nobs; ++k) {
    double x[2], J[24];
    const double *a = s.p.data() + 9 * colidx[size_t(k)], *b = s.p.data() + 9 * s.m + 3 * s.vis.point[size_t(k)];
    bal_camera::project_jacobian(a, b, x, J, J + 18);
    const double *got[4] = {hx.data() + 2 * k, whole_hx.data() + 2 * k, jac.data() + 24 * k, whole_jac.data() + 24 * k};
    if (std::memcmp(got[0], x, sizeof x) || std::memcmp(got[1], x, sizeof x) || std::memcmp(got[2], J, sizeof J) ||
        std::memcmp(got[3], J, sizeof J))
      ++differing;
  }
  EXPECT_EQ(differing, 0) << "of " << nobs << " projections";
}

// The callbacks make each camera's rotation terms once, in a buffer of the call; without
// memory for it they make them per projection, which must give the same bits.
TEST(BalModel, CallbacksWithoutMemoryForTheirCameraTermsGiveTheSameBits) {
#ifdef SBA_TEST_SANITIZED
  GTEST_SKIP() << "needs the counting operator new, which the sanitizers replace";
#else
  TwoCameraScene sc;
  double hx[6], jac[3 * 24], hx_bare[6], jac_bare[3 * 24];
  sc.func(hx);
  sc.fjac(jac);
  faults::g_fail_countdown.store(1);  // the call's one allocation fails
  sc.func(hx_bare);
  EXPECT_EQ(faults::g_fail_countdown.load(), 0) << "motstr_func allocated nothing";
  faults::g_fail_countdown.store(1);
  sc.fjac(jac_bare);
  EXPECT_EQ(faults::g_fail_countdown.load(), 0) << "motstr_fjac allocated nothing";
  faults::g_fail_countdown.store(0);
  for (int k = 0; k < 6; ++k) EXPECT_EQ(hx_bare[k], hx[k]) << k;
  for (int k = 0; k < 3 * 24; ++k) EXPECT_EQ(jac_bare[k], jac[k]) << k;
#endif
}

// ---- a regression solve ----

// problem-49-7776-pre with the analytic Jacobian, as the default options run it or as the
// strategy or solver named (null: the default); its mean squared error in *msq.
std::array<double, SBA_INFOSZ> solve_problem49(const char *strategy, const char *solver, int *ret, double *msq) {
  std::array<double, SBA_INFOSZ> info{};
  const std::string path = bal_dir() + "/problem-49-7776-pre.txt.bz2";
  bal::Problem problem;
  bal::SbaLayout s;
  std::string error;
  EXPECT_TRUE(bal::read_problem(path, &problem, &error)) << error;
  EXPECT_TRUE(bal::to_sba(problem, path, &s, &error)) << error;
  sba_ext_options ext;
  sba_ext_options_init(&ext);
  ext.quiet = 1;
  ext.strategy = strategy;
  ext.linsolver = solver;
  bal_camera::CallbackData data;
  data.ncameras = s.m;
  // The 1.6 entry point, whose default solver (chol, SBA_LINSOLVER) sba 1.6's figures are for.
  std::vector<char> vmask = s.vis.vmask(s.n, s.m);
  *ret = sba_motstr_levmar_x_ext(s.n, 0, s.m, 0, vmask.data(), s.p.data(), 9, 3, s.x.data(), nullptr, 2,
                                 bal_camera::motstr_func, bal_camera::motstr_fjac, &data, 150, 0, nullptr, info.data(), &ext);
  *msq = info[1] / s.nobservations();
  EXPECT_NEAR(info[0] / s.nobservations(), 53.4442, 5e-4);  // initial mean squared error (pixels^2)
  std::printf("problem-49-7776 (%s, %s): %d iterations, reason %g, mean squared error %.12g\n",
              strategy ? strategy : "default", solver ? solver : "default", *ret, info[6], *msq);
  return info;
}

// The default options: sba's LM (no Jacobi scaling) runs into itmax on this problem. sba 1.6
// itself, on the same callbacks (OpenBLAS at 1 and 2 threads): 150 iterations, reason 3,
// 155/150 function/Jacobian evaluations, 187 linear systems, mean squared error 0.842328 to
// 0.842334. Its rejected steps are retried on the blocks as they were left, which restarts the
// damping high: the clean retries below get further in fewer iterations.
TEST(BalSolve, Problem49AsSba16) {
  REQUIRE_FILE(bal_dir() + "/problem-49-7776-pre.txt.bz2");
  int ret = 0;
  double msq = 0;
  const std::array<double, SBA_INFOSZ> info = solve_problem49(nullptr, nullptr, &ret, &msq);
  ASSERT_NE(ret, SBA_ERROR);
  EXPECT_GE(msq, 0.842328 * (1 - 3e-5));
  EXPECT_LE(msq, 0.842334 * (1 + 3e-5));
  EXPECT_EQ(info[6], 3.0);
  EXPECT_EQ(ret, 150);
  EXPECT_LE(std::fabs(info[7] - 155), 0.35 * 155);
  EXPECT_LE(std::fabs(info[9] - 187), 0.35 * 187);
}

// sba-clean-retry: sba 1.6's relative-reduction test, as 1.6 writes it, ends the run in the
// flat part of the descent, about half-way to the 150 iterations of reason 3. Every solver and
// thread count must reproduce these figures, recorded with chol.
TEST(BalSolve, Problem49CleanRetryRegression) {
  REQUIRE_FILE(bal_dir() + "/problem-49-7776-pre.txt.bz2");
  int ret = 0;
  double msq = 0;
  const std::array<double, SBA_INFOSZ> info = solve_problem49("sba-clean-retry", nullptr, &ret, &msq);
  ASSERT_NE(ret, SBA_ERROR);
  EXPECT_NEAR(msq, 0.838894, 5e-6);
  EXPECT_EQ(info[6], 4.0);
  EXPECT_GE(ret, 60);
  EXPECT_LE(ret, 95);
}

// The same problem with the trust-region strategy reaches the minimum Ceres reaches at its
// defaults (mean squared error 0.838132 with DENSE_SCHUR), which 1.6's
// strategy stops short of.
TEST(BalSolve, Problem49TrustRegionReachesTheMinimum) {
  REQUIRE_FILE(bal_dir() + "/problem-49-7776-pre.txt.bz2");
  int ret = 0;
  double msq = 0;
  const std::array<double, SBA_INFOSZ> info = solve_problem49("trust-region", nullptr, &ret, &msq);
  ASSERT_NE(ret, SBA_ERROR);
  EXPECT_LE(msq, 0.838132 * (1 + 1e-6));
  EXPECT_GE(msq, 0.838120);
  EXPECT_EQ(info[6], 4.0);
  EXPECT_GE(ret, 20);
  EXPECT_LE(ret, 40);
}

// The same problem with the implicit-Schur CG solver and clean retries. LM stops by its
// relative-reduction test (reason 4) in the flat part of the valley, where inexact steps stop a
// little way from where chol's exact ones do: the error is chol's (0.838894474, above) to
// within 2e-6 relative. Hundreds of CG iterations per solve on this badly conditioned problem:
// with the slow cases only.
TEST(BalSolve, Problem49IterativeSchurReachesCholsMinimum) {
  if (!std::getenv("SBA_LONG_TESTS") || std::string(std::getenv("SBA_LONG_TESTS")) != "1")
    GTEST_SKIP() << "slow: set SBA_LONG_TESTS=1";
  REQUIRE_FILE(bal_dir() + "/problem-49-7776-pre.txt.bz2");
  int ret = 0;
  double msq = 0;
  const std::array<double, SBA_INFOSZ> info = solve_problem49("sba-clean-retry", "iterative-schur", &ret, &msq);
  ASSERT_NE(ret, SBA_ERROR);
  EXPECT_NEAR(msq, 0.838894474, 2e-6 * 0.838894474);
  EXPECT_EQ(info[6], 4.0);
}

}  // namespace

// ---- the balsba program ----

#ifdef BALSBA_EXE
namespace {

struct Output {
  int status = -1;
  std::string out, err;
};

std::string slurp(const std::string &path) {
  std::ifstream in(path, std::ios::binary);
  return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

// 512 MiB of address space for balsba, where an address-space limit can work (not under a
// sanitizer: see sanitized.h).
#ifdef SBA_TEST_SANITIZED
const char *const kAddressSpaceLimit = "";
#else
const char *const kAddressSpaceLimit = "ulimit -v 524288";
#endif

// Runs balsba through /bin/sh. setup: shell commands run first (e.g. ulimit); stdout_to: where
// stdout goes instead of a captured file (o.out is then empty).
Output run_balsba(const std::string &args, const std::string &setup = "", const std::string &stdout_to = "") {
  const std::string out = temp_path("balsba.out"), err = temp_path("balsba.err");
  std::remove(out.c_str());
  const std::string cmd = (setup.empty() ? "" : setup + "; ") + "exec " + std::string(BALSBA_EXE) + " " + args +
                          " > " + (stdout_to.empty() ? out : stdout_to) + " 2> " + err;
  Output o;
  const int raw = std::system(cmd.c_str());
  o.status = WIFEXITED(raw) ? WEXITSTATUS(raw) : -1;
  o.out = slurp(out);
  o.err = slurp(err);
  return o;
}

int count_lines(const std::string &s) { return static_cast<int>(std::count(s.begin(), s.end(), '\n')); }

TEST(BalSba, BadCommandLines) {
  Output o = run_balsba("");
  EXPECT_EQ(o.status, 2);
  EXPECT_EQ(count_lines(o.err), 1) << o.err;
  o = run_balsba("--solver no-such-solver x.txt");
  EXPECT_EQ(o.status, 2);
  EXPECT_EQ(o.err, std::string("balsba: bad value 'no-such-solver' for --solver: expected one of: ") +
                       sba_linsolver_names() + "\n");
  o = run_balsba("x.txt --itmax -1");
  EXPECT_EQ(o.status, 2);
  o = run_balsba("--help");
  EXPECT_EQ(o.status, 0);
  EXPECT_EQ(o.out.rfind("Usage: balsba [OPTION]... FILE\n", 0), 0u) << o.out;
  const std::string missing = temp_path("missing.txt");
  o = run_balsba(missing);
  EXPECT_EQ(o.status, 1);
  EXPECT_EQ(o.err, missing + ": cannot open: No such file or directory\n");
}

TEST(BalSba, UnderdeterminedProblemIsOneClearError) {
  const std::string path = bal_dir() + "/dubrovnik-3-7-pre.txt.bz2";
  REQUIRE_FILE(path);
  const Output o = run_balsba(path);
  EXPECT_EQ(o.status, 1);
  EXPECT_EQ(count_lines(o.err), 1) << o.err;
  EXPECT_NE(o.err.find("fewer measurements"), std::string::npos) << o.err;
  EXPECT_EQ(o.out, "");
}

// Holding the first cameras fixed (--mcon) fixes the gauge of a problem that has fewer
// observations than parameters; the fixed cameras come back unchanged.
TEST(BalSba, FixedCamerasMakeAnUnderdeterminedProblemSolvable) {
  const std::string path = bal_dir() + "/dubrovnik-3-7-pre.txt.bz2";
  REQUIRE_FILE(path);
  const std::string written = temp_path("refined-dubrovnik.txt");
  std::remove(written.c_str());
  const Output o = run_balsba(path + " --mcon=2 --solver chol --threads=1 --no-progress --write " + written);
  ASSERT_EQ(o.status, 0) << o.err;
  EXPECT_NE(o.out.find("3 cameras, 7 points, 19 observations, 48 variables\n"), std::string::npos) << o.out;
  EXPECT_NE(o.out.find("\nSolver chol on 1 thread, "), std::string::npos) << o.out;
  bal::Problem before, after;
  std::string error;
  ASSERT_TRUE(bal::read_problem(path, &before, &error)) << error;
  ASSERT_TRUE(bal::read_problem(written, &after, &error)) << error;
  ASSERT_EQ(after.cameras.size(), before.cameras.size());
  for (std::size_t k = 0; k < 2 * 9; ++k) EXPECT_EQ(after.cameras[k], before.cameras[k]) << k;
  EXPECT_NE(std::vector<double>(after.cameras.begin() + 18, after.cameras.end()),
            std::vector<double>(before.cameras.begin() + 18, before.cameras.end()));
  EXPECT_EQ(run_balsba(path + " --mcon=4").err, "balsba: --mcon 4 is more than the 3 cameras\n");
}

TEST(BalSba, SolvesAndWrites) {
  const std::string path = bal_dir() + "/problem-49-7776-pre.txt.bz2";
  REQUIRE_FILE(path);
  const std::string written = temp_path("refined-49.txt");
  std::remove(written.c_str());
  const Output o = run_balsba(path + " --itmax 3 --solver sparse-chol --threads 1 --write " + written);
  ASSERT_EQ(o.status, 0) << o.err;
  EXPECT_NE(o.out.find("49 cameras, 7776 points, 31843 observations, 23769 variables"), std::string::npos) << o.out;
  EXPECT_NE(o.out.find("SBA returned 3 in 3 iter, reason 3, error "), std::string::npos) << o.out;
  EXPECT_NE(o.out.find("[initial 53.4442]"), std::string::npos) << o.out;
  bal::Problem before, after;
  std::string error;
  ASSERT_TRUE(bal::read_problem(path, &before, &error)) << error;
  ASSERT_TRUE(bal::read_problem(written, &after, &error)) << error;
  ASSERT_EQ(after.nobservations(), before.nobservations());
  for (int k = 0; k < before.nobservations(); k += 101) {
    EXPECT_EQ(after.observations[k].camera, before.observations[k].camera);
    EXPECT_EQ(after.observations[k].x, before.observations[k].x);
  }
  EXPECT_NE(after.cameras, before.cameras);  // refined
  EXPECT_NE(after.points, before.points);
}

// balsba moves its solve's workers off a core another of its threads uses unless
// SBA_AVOID_SHARED_CORES says otherwise, says so in its report, and solves the same either way.
TEST(BalSba, ThreadPlacementIsTheProgramsChoice) {
  const std::string path = bal_dir() + "/problem-49-7776-pre.txt.bz2";
  REQUIRE_FILE(path);
  const std::string report = temp_path("placement-49.json");
  std::string first;
  for (const auto &[setup, on] : std::vector<std::pair<std::string, bool>>{
           {"unset SBA_AVOID_SHARED_CORES", true}, {"export SBA_AVOID_SHARED_CORES=0", false}}) {
    SCOPED_TRACE(setup);
    const Output o = run_balsba(path + " --itmax 3 --threads 2 --json " + report, setup);
    ASSERT_EQ(o.status, 0) << o.err;
    EXPECT_NE(slurp(report).find(std::string("\"threads\": 2, \"avoid_shared_cores\": ") + (on ? "true" : "false")),
              std::string::npos)
        << slurp(report);
    const std::string tail = o.out.substr(o.out.find("SBA returned"));
    const std::string result = tail.substr(0, tail.find("Elapsed"));
    if (first.empty()) first = result;
    EXPECT_EQ(result, first);
  }
  EXPECT_NE(first.find("SBA returned 3 in 3 iter"), std::string::npos) << first;
}

// --single-precision-jacobian runs the simple driver with the Jacobian in single precision:
// the same minimum as the expert driver in double (problem-16 with the trust region, where both
// stop at it), with the evaluations counted per projection as 1.6's simple drivers count them;
// a solver that cannot take it is refused with the reason, and nothing is written.
TEST(BalSba, SinglePrecisionJacobianReachesTheSameMinimum) {
  const std::string path = bal_dir() + "/problem-16-22106-pre.txt.bz2";
  REQUIRE_FILE(path);
  const std::string report = temp_path("single-16.json");
  const Output dbl = run_balsba(path + " --strategy=trust-region");
  const Output single = run_balsba(path + " --strategy=trust-region --single-precision-jacobian --json " + report);
  ASSERT_EQ(dbl.status, 0) << dbl.err;
  ASSERT_EQ(single.status, 0) << single.err;
  EXPECT_NE(slurp(report).find("\"max_time\": null, \"jacobian\": \"single\"}"), std::string::npos) << slurp(report);
  for (const Output *o : {&dbl, &single}) {
    EXPECT_NE(o->out.find("reason 4, error 0.430825 [initial 99.9943]"), std::string::npos) << o->out;
    EXPECT_NE(o->out.find("final 0.656373 px"), std::string::npos) << o->out;
  }
  // 83718 projections: the evaluations of the LM loop, one call of proj per projection each.
  EXPECT_NE(single.out.find("in 7 iter, reason 4"), std::string::npos) << single.out;
  EXPECT_NE(single.out.find("669744/586026 func/fjac evals"), std::string::npos) << single.out;
  const std::string written = temp_path("refused-16.txt");
  std::remove(written.c_str());
  const Output refused = run_balsba(path + " --single-precision-jacobian --solver=ldl-amd --write " + written);
  EXPECT_EQ(refused.status, 1);
  EXPECT_NE(refused.err.find("ldl-amd"), std::string::npos) << refused.err;
  EXPECT_FALSE(std::ifstream(written).good());
}

// A report that cannot be written is a failure, with the reason on stderr, not exit status 0.
TEST(BalSba, StdoutWriteErrorIsAFailure) {
  Output o = run_balsba("--help", "", "/dev/full");
  EXPECT_EQ(o.status, 1);
  EXPECT_EQ(o.err, "balsba: error writing standard output: No space left on device\n");
  const std::string path = bal_dir() + "/problem-49-7776-pre.txt.bz2";
  REQUIRE_FILE(path);
  o = run_balsba(path + " --itmax 1 --threads 1", "", "/dev/full");
  EXPECT_EQ(o.status, 1);
  EXPECT_EQ(o.err, "balsba: error writing standard output: No space left on device\n");
}

bool has_temporary(const std::string &dir) {
  for (const auto &e : std::filesystem::directory_iterator(dir))
    if (e.path().filename().string().find(".tmp.") != std::string::npos) return true;
  return false;
}

// --write cut short by the file size limit (a full disk, as root can meet it): the run fails,
// an existing file keeps its content, and no temporary is left beside it.
TEST(BalSba, FailedWriteLeavesTheOldFileAndNoTemporary) {
  const std::string path = bal_dir() + "/problem-49-7776-pre.txt.bz2";
  REQUIRE_FILE(path);
  const std::string dir = temp_path("write-fails");
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  for (const char *name : {"old.txt", "old.txt.bz2"}) {
    SCOPED_TRACE(name);
    const std::string target = dir + "/" + name;
    std::ofstream(target) << "OLD\n";
    // At most 64 blocks of 512 bytes per file; SIGXFSZ ignored, so writes fail with EFBIG.
    const Output o = run_balsba(path + " --itmax 1 --threads 1 --write " + target, "trap '' XFSZ; ulimit -f 64");
    EXPECT_EQ(o.status, 1);
    EXPECT_EQ(o.err, target + ": write error: File too large\n");
    EXPECT_EQ(o.out, "");
    const std::string after = slurp(target);
    EXPECT_TRUE(after == "OLD\n") << "the old file now starts with: " << after.substr(0, 60);
    EXPECT_FALSE(has_temporary(dir));
  }
  std::filesystem::remove_all(dir);
}

// A run that fails after the solve, at a report (--json or --final-ply on a full disk,
// /dev/full here) or at its summary on stdout, leaves the file --write names as it was, and
// makes none where there was none.
TEST(BalSba, FailedRunLeavesTheOldFileAndMakesNoNewOne) {
  const std::string path = bal_dir() + "/problem-49-7776-pre.txt.bz2";
  REQUIRE_FILE(path);
  const std::string dir = temp_path("report-fails");
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  const std::string old = dir + "/old.txt", fresh = dir + "/new.txt";
  const struct {
    std::string args, stdout_to, err;
  } cases[] = {
      {"--json /dev/full", "", "/dev/full: write failed: No space left on device\n"},
      {"--final-ply /dev/full", "", "/dev/full: write failed: No space left on device\n"},
      {"", "/dev/full", "balsba: error writing standard output: No space left on device\n"},
  };
  for (const auto &c : cases)
    for (const std::string &target : {old, fresh}) {
      SCOPED_TRACE(c.args + " " + c.stdout_to + " " + target);
      std::ofstream(old) << "OLD\n";
      std::filesystem::remove(fresh);
      const Output o = run_balsba(path + " --itmax 1 --threads 1 --write " + target + " " + c.args, "", c.stdout_to);
      EXPECT_EQ(o.status, 1);
      EXPECT_EQ(o.err, c.err);
      const std::string after = slurp(old);
      EXPECT_TRUE(after == "OLD\n") << "the old file now starts with: " << after.substr(0, 60);
      EXPECT_FALSE(std::filesystem::exists(fresh));
      EXPECT_FALSE(has_temporary(dir));
    }
  std::filesystem::remove_all(dir);
}

// A successful --write replaces the old file whole, keeps its permissions, leaves no temporary;
// /dev/null is written to, not replaced.
TEST(BalSba, WriteReplacesTheOldFileAndLeavesNoTemporary) {
  const std::string path = bal_dir() + "/problem-49-7776-pre.txt.bz2";
  REQUIRE_FILE(path);
  const std::string dir = temp_path("write-ok");
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  const std::string target = dir + "/refined.txt";
  std::ofstream(target) << "OLD\n";
  ASSERT_EQ(::chmod(target.c_str(), 0640), 0);
  Output o = run_balsba(path + " --itmax 1 --threads 1 --write " + target);
  ASSERT_EQ(o.status, 0) << o.err;
  bal::Problem refined;
  std::string error;
  ASSERT_TRUE(bal::read_problem(target, &refined, &error)) << error;
  EXPECT_EQ(refined.nobservations(), 31843);
  struct stat st {};
  ASSERT_EQ(::stat(target.c_str(), &st), 0);
  EXPECT_EQ(st.st_mode & 0777, 0640u);
  std::vector<std::string> names;
  for (const auto &e : std::filesystem::directory_iterator(dir)) names.push_back(e.path().filename().string());
  EXPECT_EQ(names, std::vector<std::string>{"refined.txt"});

  o = run_balsba(path + " --itmax 1 --threads 1 --write /dev/null");
  EXPECT_EQ(o.status, 0) << o.err;
  ASSERT_EQ(::stat("/dev/null", &st), 0);
  EXPECT_TRUE(S_ISCHR(st.st_mode));
  std::filesystem::remove_all(dir);
}

// A FIFO as --write target: its reader gets the whole problem. Checking it beforehand must
// neither block (opening it to read waits for a writer) nor end the reader's stream.
TEST(BalSba, WritesToAFifo) {
  const std::string path = bal_dir() + "/problem-49-7776-pre.txt.bz2";
  REQUIRE_FILE(path);
  const std::string fifo = temp_path("fifo"), received = temp_path("fifo-received.txt");
  std::remove(fifo.c_str());
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  const std::string err = temp_path("fifo.err");
  const std::string cmd = "cat " + fifo + " > " + received + " & timeout 10 " + std::string(BALSBA_EXE) + " " + path +
                          " --itmax 1 --threads 1 --write " + fifo + " > /dev/null 2> " + err +
                          "; st=$?; [ $st -eq 0 ] || timeout 5 sh -c ': > " + fifo + "'; wait; exit $st";
  const int raw = std::system(cmd.c_str());
  EXPECT_EQ(WIFEXITED(raw) ? WEXITSTATUS(raw) : -1, 0) << slurp(err);
  bal::Problem p;
  std::string error;
  EXPECT_TRUE(bal::read_problem(received, &p, &error)) << error;
  EXPECT_EQ(p.nobservations(), 31843);
  std::remove(fifo.c_str());
}

// A small bzip2 file that expands to more than the header announces: balsba stops reading at
// the first value too many, within a memory limit (512 MiB of address space) that reading
// the whole text first would exceed. The file: one stream with a problem of 1 observation,
// 1 camera and 1 point, then the same stream of 1 MiB of "0\n" 640 times.
TEST(BalSba, DecompressionBombStopsAtTheAnnouncedSize) {
  auto compress = [](const std::string &text) {
    std::vector<char> out(text.size() / 50 + 1024);
    unsigned int len = static_cast<unsigned int>(out.size());
    const int rc = BZ2_bzBuffToBuffCompress(out.data(), &len, const_cast<char *>(text.data()),
                                            static_cast<unsigned int>(text.size()), 9, 0, 0);
    EXPECT_EQ(rc, BZ_OK);
    return std::string(out.data(), len);
  };
  std::string zeros;
  for (int k = 0; k < (1 << 19); ++k) zeros += "0\n";
  const std::string problem = "1 1 1\n0 0 1 1\n" + std::string("0\n0\n0\n0\n0\n0\n0\n0\n0\n") + "1\n2\n3\n";
  std::string bytes = compress(problem);
  const std::string zero_stream = compress(zeros);
  for (int k = 0; k < 640; ++k) bytes += zero_stream;
  ASSERT_LT(bytes.size(), 100000u);
  const std::string path = write_temp("bomb.txt.bz2", bytes);
  const Output o = run_balsba(path, kAddressSpaceLimit);
  EXPECT_EQ(o.status, 1);
  EXPECT_EQ(o.err, path + ": line 15: more data than the header announces (1 observations, 1 cameras, 1 points): "
                          "'0' after the last point\n");
  EXPECT_EQ(o.out, "");
}

// /dev/zero has no white space: refused at once, not read until memory runs out.
TEST(BalSba, DevZeroIsRefusedAtOnce) {
  const Output o = run_balsba("/dev/zero", kAddressSpaceLimit);
  EXPECT_EQ(o.status, 1);
  EXPECT_EQ(o.err, "/dev/zero: line 1: more than 4096 bytes without white space (no number is that long)\n");
  EXPECT_EQ(o.out, "");
}

// The centre -R^T t of BAL camera a, with the test's own rotation.
std::array<double, 3> centre_of(const double a[9]) {
  double R[9];
  axis_angle_matrix(a, R);
  std::array<double, 3> c{};
  for (int k = 0; k < 3; ++k) c[k] = -(R[k] * a[3] + R[3 + k] * a[4] + R[6 + k] * a[5]);
  return c;
}

// The PLY of a problem: its points in grey, then its camera centres in red.
void expect_ply_of(const plytest::PlyFile &ply, const bal::Problem &problem) {
  EXPECT_TRUE(ply.header_ok);
  ASSERT_EQ(ply.announced, problem.npoints + problem.ncameras);
  ASSERT_EQ(ply.vertices.size(), static_cast<std::size_t>(ply.announced));
  for (int i = 0; i < problem.npoints; ++i) {
    const plytest::Vertex &v = ply.vertices[static_cast<std::size_t>(i)];
    for (int k = 0; k < 3; ++k) EXPECT_EQ(v.x[k], problem.point(i)[k]) << "point " << i;  // %.17g both
    EXPECT_EQ(v.rgb, (std::array<int, 3>{160, 160, 160})) << "point " << i;
  }
  for (int j = 0; j < problem.ncameras; ++j) {
    const plytest::Vertex &v = ply.vertices[static_cast<std::size_t>(problem.npoints + j)];
    const std::array<double, 3> c = centre_of(problem.camera(j));
    for (int k = 0; k < 3; ++k) EXPECT_NEAR(v.x[k], c[k], 1e-13 * (1 + std::fabs(c[k]))) << "camera " << j;
    EXPECT_EQ(v.rgb, (std::array<int, 3>{255, 0, 0})) << "camera " << j;
  }
}

// --initial-ply and --final-ply: the problem read and the problem --write writes, as points and
// camera centres; the cameras --mcon holds stay where they were.
TEST(BalSba, PlyFilesHoldThePointsAndCameraCentres) {
  const std::string path = bal_dir() + "/dubrovnik-3-7-pre.txt.bz2";
  REQUIRE_FILE(path);
  const std::string written = temp_path("ply-refined.txt");
  const std::string initial = temp_path("i.ply"), final_ply = temp_path("f.ply");
  const Output o = run_balsba(path + " --mcon=2 --threads=1 --no-progress --write " + written + " --initial-ply " +
                              initial + " --final-ply " + final_ply);
  ASSERT_EQ(o.status, 0) << o.err;
  bal::Problem before, after;
  std::string error;
  ASSERT_TRUE(bal::read_problem(path, &before, &error)) << error;
  ASSERT_TRUE(bal::read_problem(written, &after, &error)) << error;
  const plytest::PlyFile i = plytest::read_ply(initial), f = plytest::read_ply(final_ply);
  EXPECT_EQ(i.announced, 7 + 3);
  expect_ply_of(i, before);
  expect_ply_of(f, after);
  // Camera 2 of the file, worked out by hand from its w and t.
  const std::array<double, 3> kCentre2{-10.22479120657731, -4.9935831578422185, -1.2752215160037905};
  for (int k = 0; k < 3; ++k) EXPECT_NEAR(i.vertices[9].x[k], kCentre2[k], 1e-12) << k;
  // Cameras 0 and 1 held, camera 2 and the points refined.
  for (int v = 7; v < 9; ++v) EXPECT_EQ(f.vertices[v].text, i.vertices[v].text) << v;
  EXPECT_NE(f.vertices[9].text, i.vertices[9].text);
  for (int v = 0; v < 7; ++v) EXPECT_NE(f.vertices[v].text, i.vertices[v].text) << v;
  for (const std::string &p : {written, initial, final_ply}) std::remove(p.c_str());
}

}  // namespace
#endif  // BALSBA_EXE
