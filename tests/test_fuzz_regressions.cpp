// SPDX-License-Identifier: BSD-3-Clause
// Inputs found by the fuzz targets of fuzz/, kept in tests/fuzz_regressions/ as
// TARGET-NAME with TARGET one of cameras, points, calibration, bal, colmap, bundler, nvm (see the README
// there).
// Each must give a clean error: one line naming the file from the reader itself, and one
// line on stderr with exit status 1 from the program that reads such files (eucsbademo,
// balsba, sbarefine). Under `make check-sanitize` the same runs are checked by ASan and UBSan.
#include <gtest/gtest.h>

#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "formats/bal_io.h"
#include "formats/bundler_io.h"
#include "formats/colmap_io.h"
#include "formats/eucsba_io.h"
#include "formats/nvm_io.h"

namespace colmap = sbaformats::colmap;
namespace bundler = sbaformats::bundler;
namespace nvm = sbaformats::nvm;
namespace eucsba = sbaformats::eucsba;
namespace bal = sbaformats::bal;
namespace euclidean = sbacameras::euclidean;

namespace {

namespace fs = std::filesystem;

const fs::path kDir = fs::path(SBA_PROJECT_DIR) / "tests" / "fuzz_regressions";
const fs::path kData = fs::path(SBA_PROJECT_DIR) / "data";

// The inputs for one target, sorted by name.
std::vector<fs::path> inputs(const std::string &target) {
  std::vector<fs::path> out;
  if (!fs::is_directory(kDir)) return out;
  for (const auto &e : fs::directory_iterator(kDir)) {
    const std::string name = e.path().filename().string();
    if (e.is_regular_file() && name.rfind(target + "-", 0) == 0) out.push_back(e.path());
  }
  std::sort(out.begin(), out.end());
  return out;
}

void expect_one_line(const std::string &msg, const std::string &prefix, const fs::path &input) {
  EXPECT_FALSE(msg.empty()) << input;
  EXPECT_EQ(msg.find('\n'), std::string::npos) << input << ": " << msg;
  EXPECT_EQ(msg.rfind(prefix, 0), 0u) << input << ": '" << msg << "' does not start with " << prefix;
}

std::string shell_quote(const std::string &s) {
  std::string q = "'";
  for (char c : s) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return q + "'";
}

struct Run {
  int status = -1;
  std::string err;
};

// Runs a command with its stderr captured (stdout discarded).
Run run(const std::string &cmd) {
  const fs::path err = fs::temp_directory_path() / ("sba-fuzzreg-" + std::to_string(::getpid()) + ".err");
  Run r;
  const int st = std::system((cmd + " >/dev/null 2>" + shell_quote(err.string())).c_str());
  r.status = WIFEXITED(st) ? WEXITSTATUS(st) : -1;
  std::ifstream in(err);
  std::stringstream ss;
  ss << in.rdbuf();
  r.err = ss.str();
  fs::remove(err);
  return r;
}

// The program's verdict: exit status 1 and exactly one line on stderr, about the input.
void expect_program_refuses(const std::string &cmd, const fs::path &input) {
  const Run r = run(cmd);
  EXPECT_EQ(r.status, 1) << cmd << "\n" << r.err;
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << cmd << "\n" << r.err;
  EXPECT_NE(r.err.find(input.string()), std::string::npos) << cmd << "\n" << r.err;
}

TEST(FuzzRegressions, TheDirectoryHoldsInputs) {
  ASSERT_TRUE(fs::is_directory(kDir)) << kDir;
  EXPECT_FALSE(inputs("cameras").empty() && inputs("points").empty() && inputs("calibration").empty() &&
               inputs("bal").empty() && inputs("colmap").empty() && inputs("bundler").empty() &&
               inputs("nvm").empty());
}

TEST(FuzzRegressions, CameraFiles) {
  for (const fs::path &in : inputs("cameras")) {
    eucsba::CameraFile cams;
    std::string error;
    EXPECT_FALSE(eucsba::read_cameras(in.string(), &cams, &error)) << in;
    expect_one_line(error, in.string() + ":", in);
    expect_program_refuses(shell_quote(EUCSBADEMO_EXE) + " " + shell_quote(in.string()) + " " +
                               shell_quote((kData / "orbit-fixedK-pts.txt").string()) + " " +
                               shell_quote((kData / "orbit-fixedK-calib.txt").string()),
                           in);
  }
}

TEST(FuzzRegressions, PointsFiles) {
  for (const fs::path &in : inputs("points")) {
    eucsba::PointSet pts;
    std::string error;
    EXPECT_FALSE(eucsba::read_points(in.string(), 64, &pts, &error)) << in;
    expect_one_line(error, in.string() + ":", in);
    expect_program_refuses(shell_quote(EUCSBADEMO_EXE) + " " +
                               shell_quote((kData / "orbit-fixedK-cams.txt").string()) + " " +
                               shell_quote(in.string()) + " " +
                               shell_quote((kData / "orbit-fixedK-calib.txt").string()),
                           in);
  }
}

TEST(FuzzRegressions, CalibrationFiles) {
  for (const fs::path &in : inputs("calibration")) {
    euclidean::Intrinsics k;
    std::string error;
    EXPECT_FALSE(eucsba::read_calibration(in.string(), &k, &error)) << in;
    expect_one_line(error, in.string() + ":", in);
    expect_program_refuses(shell_quote(EUCSBADEMO_EXE) + " " +
                               shell_quote((kData / "orbit-fixedK-cams.txt").string()) + " " +
                               shell_quote((kData / "orbit-fixedK-pts.txt").string()) + " " +
                               shell_quote(in.string()),
                           in);
  }
}

TEST(FuzzRegressions, BalFiles) {
  for (const fs::path &in : inputs("bal")) {
    bal::Problem p;
    std::string error;
    EXPECT_FALSE(bal::read_problem(in.string(), &p, &error)) << in;
    expect_one_line(error, in.string() + ": ", in);
    expect_program_refuses(shell_quote(BALSBA_EXE) + " " + shell_quote(in.string()), in);
  }
}

// Whether a parser of one COLMAP file takes content.
template <class T>
bool parses(bool (*parse)(const std::string &, const std::string &, std::vector<T> *, std::string *),
            const std::string &content, const std::string &name, std::string *error) {
  std::vector<T> records;
  return parse(content, name, &records, error);
}

// A whole model of fuzz_colmap (selectors 10 and 11): its text files, each ended by a line
// "%%", written into dir as a model (rigs and frames when there are five).
void write_model_parts(const std::string &content, const fs::path &dir) {
  std::vector<std::string> parts(1);
  std::istringstream in(content);
  for (std::string line; std::getline(in, line);) {
    if (line == "%%") parts.emplace_back();
    else parts.back() += line + "\n";
  }
  const char *const names[] = {"cameras.txt", "images.txt", "points3D.txt", "rigs.txt", "frames.txt"};
  const std::size_t files = parts.size() >= 5 ? 5 : 3;
  parts.resize(5);
  for (std::size_t k = 0; k < files; ++k) std::ofstream(dir / names[k], std::ios::binary) << parts[k];
}

// fuzz_colmap's inputs: a selector byte (mod 12: cameras, images, points3D as text, then as
// binary; rigs and frames as text, then as binary; a whole model) and the content. Cameras
// files also go through sbarefine, alone in a model directory (the cameras are read first);
// a whole model goes through read_model and sbarefine as a model directory.
TEST(FuzzRegressions, ColmapFiles) {
  for (const fs::path &in : inputs("colmap")) {
    std::ifstream f(in, std::ios::binary);
    std::stringstream ss;
    ss << f.rdbuf();
    const std::string all = ss.str();
    ASSERT_FALSE(all.empty()) << in;
    const std::string content = all.substr(1), name = in.string();
    const int selector = static_cast<unsigned char>(all[0]) % 12;
    const fs::path dir = fs::temp_directory_path() / ("sba-fuzzreg-colmap-" + std::to_string(::getpid()));
    std::string error;
    bool ok = true;
    std::string prefix = name + ":";
    switch (selector) {
      case 0: ok = parses(colmap::parse_cameras_text, content, name, &error); break;
      case 1: ok = parses(colmap::parse_images_text, content, name, &error); break;
      case 2: ok = parses(colmap::parse_points_text, content, name, &error); break;
      case 3: ok = parses(colmap::parse_cameras_binary, content, name, &error); break;
      case 4: ok = parses(colmap::parse_images_binary, content, name, &error); break;
      case 5: ok = parses(colmap::parse_points_binary, content, name, &error); break;
      case 6: ok = parses(colmap::parse_rigs_text, content, name, &error); break;
      case 7: ok = parses(colmap::parse_frames_text, content, name, &error); break;
      case 8: ok = parses(colmap::parse_rigs_binary, content, name, &error); break;
      case 9: ok = parses(colmap::parse_frames_binary, content, name, &error); break;
      default: {
        fs::create_directories(dir);
        write_model_parts(content, dir);
        colmap::Model m;
        ok = colmap::read_model(dir.string(), &m, nullptr, &error);
        prefix = dir.string();
        break;
      }
    }
    EXPECT_FALSE(ok) << in;
    expect_one_line(error, prefix, in);
    if (selector == 0 || selector == 3) {
      fs::create_directories(dir);
      const fs::path cams = dir / (selector == 0 ? "cameras.txt" : "cameras.bin");
      std::ofstream(cams, std::ios::binary) << content;
      expect_program_refuses(shell_quote(SBAREFINE_EXE) + " " + shell_quote(dir.string()), cams);
    } else if (selector >= 10) {
      expect_program_refuses(shell_quote(SBAREFINE_EXE) + " " + shell_quote(dir.string()), dir);
    }
    fs::remove_all(dir);
  }
}

// Inputs of a file format sbarefine tells by its first bytes, `magic`: read(path, &error)
// refuses each, and so does sbarefine when the file starts as one of its kind.
template <class Read>
void expect_refused(const std::string &target, const std::string &magic, Read read) {
  for (const fs::path &in : inputs(target)) {
    std::string error;
    EXPECT_FALSE(read(in.string(), &error)) << in;
    expect_one_line(error, in.string() + ":", in);
    std::ifstream f(in, std::ios::binary);
    std::string head(magic.size(), '\0');
    f.read(&head[0], static_cast<std::streamsize>(magic.size()));
    if (head == magic) expect_program_refuses(shell_quote(SBAREFINE_EXE) + " " + shell_quote(in.string()), in);
  }
}

TEST(FuzzRegressions, BundlerFiles) {
  expect_refused("bundler", "# Bundle file", [](const std::string &path, std::string *error) {
    bundler::Bundle b;
    return bundler::read_bundle(path, &b, error);
  });
  // fuzz_bundler also reads its inputs as image lists: refused with one line, if at all.
  for (const fs::path &in : inputs("bundler")) {
    bundler::ImageList list;
    std::string error;
    if (!bundler::read_list(in.string(), &list, &error)) expect_one_line(error, in.string() + ":", in);
  }
}

TEST(FuzzRegressions, NvmFiles) {
  expect_refused("nvm", "NVM_V3", [](const std::string &path, std::string *error) {
    nvm::Model m;
    return nvm::read_nvm(path, &m, error);
  });
}

// Found in the fuzzers' corpora (not as a crash): a token with a NUL byte inside
// ("500<NUL>zzz") must not be read as the number before the NUL, and no message may echo
// a NUL, control bytes or escape sequences to the terminal.
TEST(FuzzRegressions, NulAndControlBytesInATokenAreRefusedAndNotEchoed) {
  const fs::path dir = fs::temp_directory_path();
  auto write = [&](const std::string &name, const std::string &text) {
    const fs::path p = dir / ("sba-fuzzreg-" + std::to_string(::getpid()) + "-" + name);
    std::ofstream(p, std::ios::binary) << text;
    return p;
  };
  auto printable = [](const std::string &msg) {
    return std::all_of(msg.begin(), msg.end(), [](char c) { return c >= 32 && c <= 126; });
  };
  const fs::path calib = write("calib.txt", std::string("500\0zzz 0 320\n0 500 240\n0 0 1\n", 30));
  euclidean::Intrinsics k;
  std::string error;
  EXPECT_FALSE(eucsba::read_calibration(calib.string(), &k, &error)) << "'500<NUL>zzz' was read as " << k.fu;
  EXPECT_TRUE(printable(error)) << error;
  const fs::path pts = write("pts.txt", "1 2 3 1 0 4\x1b[2J 5\n");
  eucsba::PointSet ps;
  EXPECT_FALSE(eucsba::read_points(pts.string(), 64, &ps, &error));
  EXPECT_TRUE(printable(error)) << error;
  fs::remove(calib);
  fs::remove(pts);
}

}  // namespace
