/* SPDX-License-Identifier: BSD-3-Clause */
// What the tests of the model formats (test_colmap_io.cpp, test_bundler.cpp, test_output_file.cpp),
// of sbagen's files (test_sbagen.cpp) and of sbarefine (test_sbarefine.cpp, test_nvm.cpp, through
// sbarefine_runs.h) share: scratch directories and whole files, a generated scene as eucsbademo
// files and as a COLMAP model or a bundle, a model compared field by field, and the malformed
// inputs of the reader tests. Nothing here runs a program.
#ifndef SBA_TESTS_COLMAP_FIXTURES_H
#define SBA_TESTS_COLMAP_FIXTURES_H

#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cstddef>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include "formats/bundler_io.h"
#include "formats/colmap_io.h"
#include "formats/colmap_sba.h"
#include "formats/eucsba_io.h"
#include "generator/sbagen.h"
#include "scratch.h"

namespace refinetest {

// An empty directory of this process for the test `name`.
inline std::string temp_dir(const std::string &name) {
  const std::string d = sbatest::scratch_dir() + "test_refine_" + std::to_string(::getpid()) + "_" + name;
  std::filesystem::remove_all(d);
  std::filesystem::create_directories(d);
  return d;
}

inline std::string read_file(const std::string &path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

inline void write_file(const std::string &path, const std::string &text) {
  std::ofstream(path, std::ios::binary) << text;
}

// Every file and directory under dir, by its path there, with its bytes (a directory: "/"):
// what a failed run must leave as it found it.
using Tree = std::map<std::string, std::string>;
inline Tree tree(const std::string &dir) {
  Tree t;
  for (const auto &e : std::filesystem::recursive_directory_iterator(dir)) {
    const std::string path = std::filesystem::relative(e.path(), dir).string();
    t[path] = e.is_directory() ? "/" : read_file(e.path().string());
  }
  return t;
}

// What differs between two trees, path by path ("+ NEW", "- GONE", "~ CHANGED"); empty when
// nothing does.
inline std::string changes(const Tree &before, const Tree &after) {
  std::string out;
  for (const auto &[path, bytes] : after) {
    const auto was = before.find(path);
    if (was == before.end()) out += "+ " + path + "\n";
    else if (was->second != bytes) out += "~ " + path + "\n";
  }
  for (const auto &entry : before)
    if (after.count(entry.first) == 0) out += "- " + entry.first + "\n";
  return out;
}

// The names of a directory's entries (a model's files), sorted.
inline std::vector<std::string> entries(const std::string &dir) {
  std::vector<std::string> names;
  for (const auto &e : std::filesystem::directory_iterator(dir)) names.push_back(e.path().filename().string());
  std::sort(names.begin(), names.end());
  return names;
}

inline const std::vector<std::string> kBinaryFiles{"cameras.bin", "images.bin", "points3D.bin"};
inline const std::vector<std::string> kTextFiles{"cameras.txt", "images.txt", "points3D.txt"};

// The files of a directory, by name.
inline std::vector<std::string> contents(const std::string &dir, const std::vector<std::string> &names) {
  std::vector<std::string> out;
  for (const std::string &n : names) out.push_back(read_file(dir + "/" + n));
  return out;
}

// A generated scene (sbagen, seed 5) written as eucsbademo files dir/s-*, and read back, so
// that every format built from it starts from the same doubles as those files.
struct GeneratedScene {
  std::string prefix;
  sbaformats::eucsba::Problem problem;
};

inline GeneratedScene generate_scene(const std::string &dir, sbacameras::euclidean::CameraKind kind, int cameras, int points) {
  sbagen::Options o;
  o.kind = kind;
  o.cameras = cameras;
  o.points = points;
  o.seed = 5;
  sbagen::Scene s;
  std::string error;
  EXPECT_TRUE(sbagen::generate(o, &s, &error)) << error;
  GeneratedScene out;
  out.prefix = dir + "/s";
  EXPECT_TRUE(sbagen::write_problem(s, out.prefix, &error)) << error;
  const auto files = sbagen::problem_files(out.prefix, s);
  EXPECT_TRUE(sbaformats::eucsba::load_problem(files.cams, files.pts, files.calib, &out.problem, &error)) << error;
  return out;
}

// A generated scene and the COLMAP model of its values.
struct Scene {
  std::string prefix;
  sbaformats::eucsba::Problem problem;
  sbaformats::colmap::Model model;
};

inline Scene make_scene(const std::string &dir, sbacameras::euclidean::CameraKind kind, int cameras = 10,
                        int points = 200) {
  const GeneratedScene g = generate_scene(dir, kind, cameras, points);
  Scene out{g.prefix, g.problem, {}};
  std::string error;
  EXPECT_TRUE(sbaformats::colmap::from_problem(out.problem.kind, out.problem.cameras, out.problem.points, 640, 480,
                                               &out.model, &error))
      << error;
  return out;
}

// The bundle of a generated scene's values.
inline sbaformats::bundler::Bundle make_bundle(const Scene &s) {
  sbaformats::bundler::Bundle b;
  std::string error;
  EXPECT_TRUE(sbaformats::bundler::from_problem(s.problem.cameras, s.problem.points, &b, &error)) << error;
  return b;
}

// Two COLMAP models hold the same cameras, images and points, field by field and bit for bit.
inline void expect_same(const sbaformats::colmap::Model &a, const sbaformats::colmap::Model &b) {
  ASSERT_EQ(a.cameras.size(), b.cameras.size());
  ASSERT_EQ(a.images.size(), b.images.size());
  ASSERT_EQ(a.points.size(), b.points.size());
  for (std::size_t j = 0; j < a.cameras.size(); ++j) {
    EXPECT_EQ(a.cameras[j].id, b.cameras[j].id);
    EXPECT_EQ(a.cameras[j].model, b.cameras[j].model);
    EXPECT_EQ(a.cameras[j].width, b.cameras[j].width);
    EXPECT_EQ(a.cameras[j].height, b.cameras[j].height);
    EXPECT_EQ(a.cameras[j].params, b.cameras[j].params);
  }
  for (std::size_t j = 0; j < a.images.size(); ++j) {
    const sbaformats::colmap::Image &x = a.images[j], &y = b.images[j];
    EXPECT_EQ(x.id, y.id);
    EXPECT_EQ(x.q, y.q);
    EXPECT_EQ(x.t, y.t);
    EXPECT_EQ(x.camera_id, y.camera_id);
    EXPECT_EQ(x.name, y.name);
    ASSERT_EQ(x.points.size(), y.points.size());
    for (std::size_t k = 0; k < x.points.size(); ++k) {
      EXPECT_EQ(x.points[k].x, y.points[k].x);
      EXPECT_EQ(x.points[k].y, y.points[k].y);
      EXPECT_EQ(x.points[k].point3d_id, y.points[k].point3d_id);
    }
  }
  for (std::size_t i = 0; i < a.points.size(); ++i) {
    const sbaformats::colmap::Point3D &x = a.points[i], &y = b.points[i];
    EXPECT_EQ(x.id, y.id);
    EXPECT_EQ(x.xyz, y.xyz);
    EXPECT_EQ(x.rgb, y.rgb);
    EXPECT_EQ(x.error, y.error);
    ASSERT_EQ(x.track.size(), y.track.size());
    for (std::size_t k = 0; k < x.track.size(); ++k) {
      EXPECT_EQ(x.track[k].image_id, y.track[k].image_id);
      EXPECT_EQ(x.track[k].point2d_idx, y.track[k].point2d_idx);
    }
  }
}

// A malformed input of a reader and the one error it must give.
struct Bad {
  std::string text;
  const char *message;
};

}  // namespace refinetest

#endif  // SBA_TESTS_COLMAP_FIXTURES_H
