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
#include "formats/colmap_problem.h"
#include "formats/colmap_sba.h"
#include "formats/output_file.h"
#include "formats/ply.h"
#include "generator/sbagen.h"
#include "sba_ext.h"

namespace colmap = sbaformats::colmap;
namespace euclidean = sbacameras::euclidean;
namespace colmap_camera = sbacameras::colmap_camera;

namespace soakfiles {
namespace {

namespace fs = std::filesystem;

// What the run's report holds (a stand-in for --json).
const char kReport[] = "{\"program\": \"soak\"}\n";

// Every file and directory under dir by its path there, with its bytes (a directory: "/").
std::map<std::string, std::string> snapshot(const fs::path &dir) {
  std::map<std::string, std::string> files;
  for (const auto &e : fs::recursive_directory_iterator(dir)) {
    std::string &bytes = files[fs::relative(e.path(), dir).string()];
    if (e.is_directory()) {
      bytes = "/";
      continue;
    }
    std::ifstream in(e.path(), std::ios::binary);
    std::stringstream ss;
    ss << in.rdbuf();
    bytes = ss.str();
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
  colmap::Options options;
  options.intrinsics = {false, false, false};
  colmap::Problem pr;
  std::string error;
  if (!colmap::Problem::build(model, options, "soak", &pr, &error)) return false;
  std::vector<double> p = pr.initial_params();
  *rotations = true;
  for (const colmap_camera::Camera &c : pr.cameras(p.data())) *rotations = *rotations && unit(c.q);
  const sbaformats::Visibility &v = pr.points().pairs;
  const sba_visibility vis{static_cast<long long>(v.size()), v.point.data(), v.camera.data()};
  sba_ext_options ext;
  sba_ext_options_init(&ext);
  ext.linsolver = "chol";
  ext.cam_fixed = pr.cam_fixed().data();
  ext.cam_fixed_per_camera = 1;
  ext.cam_param_group = pr.cam_param_group().data();
  ext.quiet = 1;
  double info[SBA_INFOSZ] = {};
  std::vector<double> x = pr.points().x;
  const int ret = sba_motstr_levmar_x_vis(pr.npoints(), 0, pr.ncameras(), 0, &vis, p.data(), pr.cnp(), 3, x.data(),
                                          nullptr, 2, pr.func(), pr.fjac(), pr.adata(), 20, 0, nullptr, info, &ext);
  return ret >= 0 && std::isfinite(info[1]) && info[1] <= info[0] * (1 + 1e-12);
}

// What the program's PLY file shows of a model: its points.
sbaformats::Cloud cloud(const colmap::Model &m) {
  sbaformats::Cloud c;
  for (const colmap::Point3D &p : m.points) c.points.push_back(p.xyz);
  return c;
}

// The outputs of a run over the input model, as the programs write them: the model marked to
// be renamed last, the report (created first, so renamed before the PLY file), the PLY file.
// False when one cannot be written or the set cannot be published; `block`, called before the
// commit, may take a name.
template <class Block>
bool write_outputs(const Case &c, const fs::path &dir, const colmap::Model &moved, Block block) {
  const fs::path target = dir / (c.new_directory ? "new" : "model");
  sbaformats::OutputSet set;
  std::string error;
  const std::string ply = c.failing == 1 ? "/dev/full" : (dir / "final.ply").string();
  const bool written =
      set.publish_last([&] {
        return colmap::write_model(target.string(), moved, encoding(c.rewrite_binary), &error, &set);
      }) &&
      sbaformats::write_whole_file((dir / "report.json").string(), kReport, &error, &set) &&
      sbaformats::write_ply(ply, cloud(moved), &error, &set);
  if (!written) return false;
  block();
  return set.commit(&error);
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
  const fs::path dir = templ, input = dir / "model";
  if (c.old_report) std::ofstream(dir / "report.json") << "an earlier run's\n";
  if (colmap::write_model(input.string(), model, encoding(c.binary), &error)) {
    const std::map<std::string, std::string> before = snapshot(dir);
    rlimit old{};
    ::getrlimit(RLIMIT_FSIZE, &old);
    const auto handler = std::signal(SIGXFSZ, SIG_IGN);
    if (c.file_limit > 0) {
      const rlimit low{static_cast<rlim_t>(c.file_limit), old.rlim_max};
      ::setrlimit(RLIMIT_FSIZE, &low);
    }
    // A directory where the PLY file goes fails its rename, after the report's.
    const fs::path blocked = dir / "final.ply" / "in";
    out->write_failed = !write_outputs(c, dir, moved, [&] {
      if (c.failing == 2) fs::create_directories(blocked);
    });
    ::setrlimit(RLIMIT_FSIZE, &old);
    std::signal(SIGXFSZ, handler);
    if (c.failing == 2) fs::remove_all(dir / "final.ply");
    const std::map<std::string, std::string> after = snapshot(dir);
    const fs::path written = out->write_failed || !c.new_directory ? input : dir / "new";
    if (out->write_failed) {
      // The report may have replaced the old one before the PLY file's rename failed.
      std::map<std::string, std::string> replaced = before;
      if (c.failing == 2 && c.old_report) replaced["report.json"] = kReport;
      out->intact = after == before || after == replaced;
    } else {
      // The model's files, of the encoding last written, where it went (the input as it was
      // when that is elsewhere), the reports, and nothing else; the model's bytes are judged
      // by reading it back below.
      const std::string to = c.new_directory ? "new" : "model", ext = c.rewrite_binary ? ".bin" : ".txt";
      std::map<std::string, std::string> expected = before;
      if (!c.new_directory)
        for (auto e = expected.begin(); e != expected.end();)
          e = e->first.rfind("model/", 0) == 0 ? expected.erase(e) : ++e;
      expected[to] = "/";
      for (const std::string &name :
           {to + "/cameras" + ext, to + "/images" + ext, to + "/points3D" + ext, std::string("final.ply")})
        expected[name] = after.count(name) ? after.at(name) : "(missing)";
      expected["report.json"] = kReport;
      out->intact = after == expected;
    }
    const colmap::Model &expected = out->write_failed ? model : moved;
    colmap::Model back;
    out->read_back =
        colmap::read_model(written.string(), &back, nullptr, &error) && bytes_of(back) == bytes_of(expected);
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
    return o.write_failed ? "a run that failed changed the directory (a file, a new file or directory left)"
                          : "the directory does not hold the model written, the input and the reports, "
                            "and only them";
  if (!o.read_back) return "the model read back is not the one written last";
  if (!o.rotations) return "a quaternion did not normalize to a rotation";
  if (!o.solved) return "the solve of the model read back failed or made it worse";
  return {};
}

}  // namespace soakfiles
