// SPDX-License-Identifier: BSD-3-Clause
#include "model_files.h"

#include <sys/resource.h>

#include <array>
#include <cmath>
#include <csignal>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <vector>

#include "cameras/colmap_camera.h"
#include "cameras/euclidean.h"
#include "formats/colmap_io.h"
#include "formats/colmap_sba.h"
#include "sba_ext.h"
#include "sbagen.h"

namespace colmap = sbaformats::colmap;
namespace euclidean = sbacameras::euclidean;
namespace colmap_camera = sbacameras::colmap_camera;

namespace soakfiles {
namespace {

namespace fs = std::filesystem;

// Every file of dir by name, with its bytes.
std::map<std::string, std::string> snapshot(const fs::path &dir) {
  std::map<std::string, std::string> files;
  for (const auto &e : fs::directory_iterator(dir)) {
    std::ifstream in(e.path(), std::ios::binary);
    std::stringstream ss;
    ss << in.rdbuf();
    files[e.path().filename().string()] = ss.str();
  }
  return files;
}

// A model as bytes that hold every value exactly (names included): its binary files.
std::string bytes_of(const colmap::Model &m) {
  const colmap::Files f = colmap::format_model(m, colmap::Encoding::Binary);
  return f.cameras + f.images + f.points;
}

colmap::Encoding encoding(bool binary) { return binary ? colmap::Encoding::Binary : colmap::Encoding::Text; }

bool unit(const euclidean::Quaternion &q) {
  return std::fabs(std::sqrt(q.w * q.w + q.x * q.x + q.y * q.y + q.z * q.z) - 1) < 1e-12;
}

// The model's solve as sbarefine runs it (intrinsics held), a few iterations: true when it
// ends finite and no worse than it began; *rotations whether every camera's is one.
bool solve(const colmap::Model &model, bool *rotations) {
  colmap::ColmapProblem pr;
  std::string error;
  if (!colmap::to_sba(model, {false, false, false}, {}, 0, "soak", &pr, &error)) return false;
  const colmap_camera::CameraModel sm(pr.cameras, pr.points.xyz, pr.cam_fixed);
  *rotations = true;
  for (int j = 0; j < sm.ncameras(); ++j) *rotations = *rotations && unit(sm.input_camera(j).q);
  std::vector<double> p = sm.initial_camera_params();
  p.insert(p.end(), sm.initial_points().begin(), sm.initial_points().end());
  const sbaformats::Visibility &v = pr.points.pairs;
  const sba_visibility vis{static_cast<long long>(v.size()), v.point.data(), v.camera.data()};
  sba_ext_options ext;
  sba_ext_options_init(&ext);
  ext.linsolver = "chol";
  ext.cam_fixed = pr.cam_fixed.data();
  ext.cam_fixed_per_camera = 1;
  ext.cam_group = pr.cam_group.data();
  ext.cam_shared = pr.cam_shared.data();
  ext.quiet = 1;
  double info[SBA_INFOSZ] = {};
  const int ret = sba_motstr_levmar_x_vis(sm.npoints(), 0, sm.ncameras(), 0, &vis, p.data(), sm.cnp(), 3,
                                          pr.points.x.data(), nullptr, 2, colmap_camera::motstr_func,
                                          colmap_camera::motstr_fjac, colmap_camera::as_adata(sm), 20,
                                          0, nullptr, info, &ext);
  return ret >= 0 && std::isfinite(info[1]) && info[1] <= info[0] * (1 + 1e-12);
}

}  // namespace

void run(const Case &c, Outcome *out) {
  sbagen::Options o;
  o.kind = euclidean::CameraKind::VaryingIntrinsicsDistortion;
  o.cameras = c.cameras;
  o.points = c.points;
  o.seed = c.seed;
  sbagen::Scene scene;
  colmap::Model model;
  std::string error;
  if (!sbagen::generate(o, &scene, &error) ||
      !colmap::from_problem(scene.kind, scene.initial_cameras, scene.measurements, o.image_width, o.image_height,
                            &model, &error))
    return;
  for (std::size_t j = 0; j < model.images.size(); ++j) {
    for (double &v : model.images[j].q) v *= c.q_scale;
    if (c.odd_names) model.images[j].name = "im\xff\xfe" + std::to_string(j) + "\xc3\xa9.png";
  }
  // What a refinement writes over it: poses and points moved.
  colmap::Model moved = model;
  for (colmap::Image &im : moved.images) im.t[2] += 0.25;
  for (colmap::Point3D &p : moved.points) p.xyz[0] += 0.5;

  const char *tmp = std::getenv("TMPDIR");
  std::string templ = std::string(tmp && *tmp ? tmp : "/tmp") + "/sba-soak-model-XXXXXX";
  if (!::mkdtemp(templ.data())) return;
  const fs::path dir = templ;
  if (colmap::write_model(dir.string(), model, encoding(c.binary), &error)) {
    const std::map<std::string, std::string> before = snapshot(dir);
    rlimit old{};
    ::getrlimit(RLIMIT_FSIZE, &old);
    const auto handler = std::signal(SIGXFSZ, SIG_IGN);
    if (c.file_limit > 0) {
      const rlimit low{static_cast<rlim_t>(c.file_limit), old.rlim_max};
      ::setrlimit(RLIMIT_FSIZE, &low);
    }
    out->write_failed = !colmap::write_model(dir.string(), moved, encoding(c.rewrite_binary), &error);
    ::setrlimit(RLIMIT_FSIZE, &old);
    std::signal(SIGXFSZ, handler);
    const colmap::Model &expected = out->write_failed ? model : moved;
    const std::map<std::string, std::string> after = snapshot(dir);
    // One model: three files, of the encoding last written.
    const bool binary = out->write_failed ? c.binary : c.rewrite_binary;
    out->intact = out->write_failed ? after == before
                                    : after.size() == 3 && after.count(binary ? "images.bin" : "images.txt") == 1;
    colmap::Model back;
    out->read_back = colmap::read_model(dir.string(), &back, nullptr, &error) && bytes_of(back) == bytes_of(expected);
    bool rotations = false;
    out->solved = solve(back, &rotations);
    out->rotations = rotations;
  }
  fs::remove_all(dir);
  out->done = 1;
}

std::string judge(const Outcome &o) {
  if (!o.done) return "the model files case did not run to its end";
  if (!o.intact)
    return o.write_failed ? "a write that failed changed the model's directory"
                          : "the directory does not hold one model, the one written";
  if (!o.read_back) return "the model read back is not the one written last";
  if (!o.rotations) return "a quaternion did not normalize to a rotation";
  if (!o.solved) return "the solve of the model read back failed or made it worse";
  return {};
}

}  // namespace soakfiles
