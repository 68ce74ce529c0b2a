// SPDX-License-Identifier: BSD-3-Clause
// Writes the seed corpora of fuzz_colmap and fuzz_bundler: the six files of small generated
// scenes (sbagen) as COLMAP text and binary, each behind the selector byte fuzz_colmap
// reads, into COLMAP_DIR, and the same scenes as Bundler files into BUNDLER_DIR.
#include <cstdio>
#include <string>

#include "bundler_io.h"
#include "colmap_io.h"
#include "colmap_sba.h"
#include "sbagen.h"

int main(int argc, char **argv) {
  if (argc != 3) {
    std::fprintf(stderr, "usage: seed_writer COLMAP_DIR BUNDLER_DIR\n");
    return 2;
  }
  const std::string dir = argv[1], bundler_dir = argv[2];
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
    if (kind != eucsba::CameraKind::VaryingIntrinsicsDistortion) {  // Bundler has no tangential terms
      if (!bundler::from_problem(scene.initial_cameras, scene.measurements, &bundle, &error) ||
          !bundler::write_bundle(bundler_dir + "/seed-" + sbagen::camera_kind_name(kind) + ".out", bundle, &error)) {
        std::fprintf(stderr, "seed_writer: %s\n", error.c_str());
        return 1;
      }
      ++written;
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
