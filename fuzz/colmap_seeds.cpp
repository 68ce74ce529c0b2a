// SPDX-License-Identifier: BSD-3-Clause
// Writes the seed corpus of fuzz_colmap into DIR: the six files of a small generated scene
// (sbagen, as COLMAP text and binary), each behind the selector byte fuzz_colmap reads.
#include <cstdio>
#include <string>

#include "colmap_io.h"
#include "colmap_sba.h"
#include "sbagen.h"

int main(int argc, char **argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: colmap_seeds DIR\n");
    return 2;
  }
  const std::string dir = argv[1];
  int written = 0;
  for (eucsba::CameraKind kind : {eucsba::CameraKind::FixedIntrinsics, eucsba::CameraKind::VaryingIntrinsicsDistortion}) {
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
      std::fprintf(stderr, "colmap_seeds: %s\n", error.c_str());
      return 1;
    }
    for (colmap::Encoding e : {colmap::Encoding::Text, colmap::Encoding::Binary}) {
      const colmap::Files f = colmap::format_model(model, e);
      const std::string *files[] = {&f.cameras, &f.images, &f.points};
      for (int k = 0; k < 3; ++k) {
        const int selector = k + (e == colmap::Encoding::Binary ? 3 : 0);
        const std::string path = dir + "/seed-" + sbagen::camera_kind_name(kind) + "-" + std::to_string(selector);
        std::FILE *out = std::fopen(path.c_str(), "wb");
        if (!out) {
          std::fprintf(stderr, "colmap_seeds: cannot write %s\n", path.c_str());
          return 1;
        }
        std::fputc(selector, out);
        std::fwrite(files[k]->data(), 1, files[k]->size(), out);
        if (std::fclose(out) != 0) return 1;
        ++written;
      }
    }
  }
  std::printf("colmap_seeds: %d seeds in %s\n", written, dir.c_str());
  return 0;
}
