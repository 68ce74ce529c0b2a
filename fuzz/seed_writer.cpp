// SPDX-License-Identifier: BSD-3-Clause
// Writes the seed corpora of fuzz_colmap, fuzz_bundler and fuzz_nvm: the six files of small
// generated scenes (sbagen) as COLMAP text and binary, each behind the selector byte
// fuzz_colmap reads, into COLMAP_DIR, the same scenes as Bundler files with their image lists
// into BUNDLER_DIR, and as NVM files (one with a calibration token, a second model and a PLY
// section after the first) into NVM_DIR.
#include <cstdio>
#include <string>

#include "bundler_io.h"
#include "colmap_io.h"
#include "colmap_sba.h"
#include "nvm_io.h"
#include "output_file.h"
#include "sbagen.h"

int main(int argc, char **argv) {
  if (argc != 4) {
    std::fprintf(stderr, "usage: seed_writer COLMAP_DIR BUNDLER_DIR NVM_DIR\n");
    return 2;
  }
  const std::string dir = argv[1], bundler_dir = argv[2], nvm_dir = argv[3];
  int written = 0;
  for (eucsba::CameraKind kind : {eucsba::CameraKind::FixedIntrinsics, eucsba::CameraKind::VaryingIntrinsics,
                                  eucsba::CameraKind::VaryingIntrinsicsDistortion}) {
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
    if (kind != eucsba::CameraKind::VaryingIntrinsicsDistortion) {
      const std::string seed = std::string("/seed-") + sbagen::camera_kind_name(kind);
      if (!bundler::from_problem(scene.initial_cameras, scene.measurements, &bundle, &error) ||
          !bundler::write_bundle(bundler_dir + seed + ".out", bundle, &error) ||
          !nvm::from_problem(scene.initial_cameras, scene.measurements, &nvm_model, &error)) {
        std::fprintf(stderr, "seed_writer: %s\n", error.c_str());
        return 1;
      }
      if (kind == eucsba::CameraKind::FixedIntrinsics) {
        nvm_model.header = "NVM_V3 FixedK 800 320 800 240";
        nvm_model.cameras[1].k = -2.5e-8;
        nvm_model.rest = "\n1\nlost.jpg 700 1 0 0 0 0 0 0 0 0\n\n0\n\n0\n\n#PLY files\n0\n";
      }
      if (!nvm::write_nvm(nvm_dir + seed + ".nvm", nvm_model, &error)) {
        std::fprintf(stderr, "seed_writer: %s\n", error.c_str());
        return 1;
      }
      // An image list: the line of every camera, some with the EXIF focal length.
      std::string list;
      for (std::size_t j = 0; j < bundle.cameras.size(); ++j)
        list += "images/" + nvm_model.cameras[j].name + (j % 2 ? "\n" : " 0 812.5\n");
      if (!sbademo::write_whole_file(bundler_dir + seed + "-list.txt", list, &error)) {
        std::fprintf(stderr, "seed_writer: %s\n", error.c_str());
        return 1;
      }
      written += 3;
    }
    for (colmap::Encoding e : {colmap::Encoding::Text, colmap::Encoding::Binary}) {
      const colmap::Files f = colmap::format_model(model, e);
      const std::string *files[] = {&f.cameras, &f.images, &f.points};
      for (int k = 0; k < 3; ++k) {
        const int selector = k + (e == colmap::Encoding::Binary ? 3 : 0);
        const std::string path = dir + "/seed-" + sbagen::camera_kind_name(kind) + "-" + std::to_string(selector);
        std::FILE *out = std::fopen(path.c_str(), "wb");
        if (!out) {
          std::fprintf(stderr, "seed_writer: cannot write %s\n", path.c_str());
          return 1;
        }
        std::fputc(selector, out);
        std::fwrite(files[k]->data(), 1, files[k]->size(), out);
        if (std::fclose(out) != 0) return 1;
        ++written;
      }
    }
  }
  std::printf("seed_writer: %d seeds\n", written);
  return 0;
}
