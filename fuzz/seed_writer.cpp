// SPDX-License-Identifier: BSD-3-Clause
// Writes the seed corpora of fuzz_colmap, fuzz_bundler and fuzz_nvm: the files of small
// generated scenes (sbagen) as COLMAP text and binary, rigs and frames too, each behind the
// selector byte fuzz_colmap reads, and whole text models (with and without rigs and frames),
// into COLMAP_DIR, the same scenes as Bundler files with their image lists
// into BUNDLER_DIR, and as NVM files (one with a calibration token, a second model and a PLY
// section after the first) into NVM_DIR. Some seeds hold what the readers must take although
// it is rare: quaternions whose squares overflow or underflow, names that are not UTF-8.
#include <cstdio>
#include <string>
#include <vector>

#include "formats/bundler_io.h"
#include "formats/colmap_io.h"
#include "formats/colmap_sba.h"
#include "formats/nvm_io.h"
#include "formats/output_file.h"
#include "generator/sbagen.h"

namespace colmap = sbaformats::colmap;
namespace bundler = sbaformats::bundler;
namespace nvm = sbaformats::nvm;
namespace euclidean = sbacameras::euclidean;

namespace {

// Quaternions near 1e300 and 1e-200 (their squares overflow and underflow) and a name with
// bytes that are not UTF-8, for image or camera j.
double odd_scale(std::size_t j) { return j % 2 ? 1e300 : 1e-200; }
std::string odd_name(std::size_t j) { return "img\xff\xfe" + std::to_string(j) + ".jpg"; }

// The model with rigs and frames: one rig of an IMU without a pose (its reference) and every
// camera, each at a pose of its own in the rig; a frame for each image (its id not the
// image's), with a measurement of the IMU, at the pose that composes to the image's; and a
// frame of the rig with no measurement.
colmap::Model rigged(colmap::Model m) {
  using colmap::SensorType;
  m.has_rigs = true;
  m.rigs.push_back({5, {{{SensorType::Imu, 2}, false, {}}}});
  for (std::size_t c = 0; c < m.cameras.size(); ++c)
    m.rigs[0].sensors.push_back({{SensorType::Camera, m.cameras[c].id},
                                 true,
                                 {{0.96, 0, 0.28, 0}, {0.5 * static_cast<double>(c), 0, -0.25}}});
  for (const colmap::Image &im : m.images)
    m.frames.push_back(
        {100 + im.id, 5, {}, {{{SensorType::Camera, im.camera_id}, im.id}, {{SensorType::Imu, 2}, im.id}}});
  const std::vector<colmap::ImagePlace> places = colmap::image_places(m);
  for (std::size_t i = 0; i < m.images.size(); ++i)
    m.frames[places[i].frame].rig_from_world = colmap::frame_pose(
        {m.images[i].q, m.images[i].t}, &m.rigs[places[i].rig].sensors[places[i].sensor].sensor_from_rig);
  m.frames.push_back({7, 5, {}, {}});
  return m;
}

bool write_seed(const std::string &path, int selector, const std::string &content) {
  std::FILE *out = std::fopen(path.c_str(), "wb");
  if (!out) {
    std::fprintf(stderr, "seed_writer: cannot write %s\n", path.c_str());
    return false;
  }
  if (selector >= 0) std::fputc(selector, out);
  std::fwrite(content.data(), 1, content.size(), out);
  return std::fclose(out) == 0;
}

}  // namespace

int main(int argc, char **argv) {
  if (argc != 4) {
    std::fprintf(stderr, "usage: seed_writer COLMAP_DIR BUNDLER_DIR NVM_DIR\n");
    return 2;
  }
  const std::string dir = argv[1], bundler_dir = argv[2], nvm_dir = argv[3];
  int written = 0;
  for (euclidean::CameraKind kind : {euclidean::CameraKind::FixedIntrinsics, euclidean::CameraKind::VaryingIntrinsics,
                                  euclidean::CameraKind::VaryingIntrinsicsDistortion}) {
    sbagen::Options o;
    o.kind = kind;
    o.cameras = 4;
    o.points = 12;
    o.track_max = 4;
    sbagen::Scene scene;
    std::string error;
    colmap::Model model;
    if (!sbagen::generate(o, &scene, &error) ||
        !colmap::from_problem(scene.kind, scene.initial_cameras, scene.measurements, o.image_width, o.image_height,
                              &model, &error)) {
      std::fprintf(stderr, "seed_writer: %s\n", error.c_str());
      return 1;
    }
    bundler::Bundle bundle;
    nvm::Model nvm_model;
    // Neither Bundler nor NVM holds eucsbademo's tangential terms.
    if (kind != euclidean::CameraKind::VaryingIntrinsicsDistortion) {
      const std::string seed = std::string("/seed-") + sbagen::camera_kind_name(kind);
      if (!bundler::from_problem(scene.initial_cameras, scene.measurements, &bundle, &error) ||
          !bundler::write_bundle(bundler_dir + seed + ".out", bundle, &error) ||
          !nvm::from_problem(scene.initial_cameras, scene.measurements, &nvm_model, &error)) {
        std::fprintf(stderr, "seed_writer: %s\n", error.c_str());
        return 1;
      }
      if (kind == euclidean::CameraKind::FixedIntrinsics) {
        nvm_model.header = "NVM_V3 FixedK 800 320 800 240";
        nvm_model.cameras[1].k = -2.5e-8;
        nvm_model.rest = "\n1\nlost.jpg 700 1 0 0 0 0 0 0 0 0\n\n0\n\n0\n\n#PLY files\n0\n";
      }
      nvm::Model odd = nvm_model;
      for (std::size_t j = 0; j < odd.cameras.size(); ++j) {
        for (double &v : odd.cameras[j].q) v *= odd_scale(j);
        odd.cameras[j].name = odd_name(j);
      }
      if (!nvm::write_nvm(nvm_dir + seed + ".nvm", nvm_model, &error) ||
          !write_seed(nvm_dir + seed + "-odd.nvm", -1, nvm::format_nvm(odd))) {
        std::fprintf(stderr, "seed_writer: %s\n", error.c_str());
        return 1;
      }
      // An image list: the line of every camera, some with the EXIF focal length, one with a
      // name that is not UTF-8.
      std::string list;
      for (std::size_t j = 0; j < bundle.cameras.size(); ++j)
        list += "images/" + (j == 1 ? odd_name(j) : nvm_model.cameras[j].name) + (j % 2 ? "\n" : " 0 812.5\n");
      if (!sbaformats::write_whole_file(bundler_dir + seed + "-list.txt", list, &error)) {
        std::fprintf(stderr, "seed_writer: %s\n", error.c_str());
        return 1;
      }
      written += 4;
    }
    colmap::Model odd = model;
    for (std::size_t j = 0; j < odd.images.size(); ++j) {
      for (double &v : odd.images[j].q) v *= odd_scale(j);
      odd.images[j].name = odd_name(j);
    }
    for (colmap::Encoding e : {colmap::Encoding::Text, colmap::Encoding::Binary}) {
      const colmap::Files f = colmap::format_model(model, e);
      const std::string *files[] = {&f.cameras, &f.images, &f.points};
      const int binary = e == colmap::Encoding::Binary ? 3 : 0;
      const std::string seed = dir + "/seed-" + sbagen::camera_kind_name(kind) + "-";
      for (int k = 0; k < 3; ++k)
        if (!write_seed(seed + std::to_string(k + binary), k + binary, *files[k])) return 1;
      if (!write_seed(seed + "odd-" + std::to_string(1 + binary), 1 + binary, colmap::format_model(odd, e).images))
        return 1;
      const colmap::Files r = colmap::format_model(rigged(model), e);
      if (!write_seed(seed + std::to_string(6 + binary / 3 * 2), 6 + binary / 3 * 2, r.rigs) ||
          !write_seed(seed + std::to_string(7 + binary / 3 * 2), 7 + binary / 3 * 2, r.frames))
        return 1;
      written += 6;
    }
    // Whole models for fuzz_colmap's model checks: the text files, each ended by a line "%%".
    const std::string seed = dir + "/seed-" + sbagen::camera_kind_name(kind) + "-model";
    for (const bool with_rigs : {false, true}) {
      const colmap::Files f = colmap::format_model(with_rigs ? rigged(model) : model, colmap::Encoding::Text);
      std::string all = f.cameras + "%%\n" + f.images + "%%\n" + f.points;
      if (with_rigs) all += "%%\n" + f.rigs + "%%\n" + f.frames;
      if (!write_seed(seed + (with_rigs ? "-rigs-10" : "-10"), 10, all) ||
          !write_seed(seed + (with_rigs ? "-rigs-11" : "-11"), 11, all))
        return 1;
      written += 2;
    }
  }
  std::printf("seed_writer: %d seeds\n", written);
  return 0;
}
