// SPDX-License-Identifier: BSD-3-Clause
// sbarefine's projection of COLMAP's camera models (lib/cameras/colmap_camera.h), for
// pycolmap_models.py to compare with COLMAP's own: each line of standard input
//   MODEL_ID PARAMS... X Y Z
// (the model's parameter count of PARAMS, then a point of the camera frame) gives a line
//   x y
// of the pixels, with 17 significant digits ("nan" where the model's formula has no value).
// A line it cannot read ends the run with exit status 2 and a message naming the line.
#include <cstddef>
#include <cstdio>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

#include "cameras/colmap_camera.h"

namespace cc = sbacameras::colmap_camera;

int main() {
  std::string line;
  for (int n = 1; std::getline(std::cin, line); ++n) {
    std::istringstream in(line);
    int model = -1;
    in >> model;
    const int np = cc::param_count(model);
    std::vector<double> params(static_cast<std::size_t>(np));
    double X[3];
    for (double &p : params) in >> p;
    for (double &c : X) in >> c;
    std::string rest;
    if (np == 0 || !in || in >> rest) {
      std::fprintf(stderr, "colmap_project: line %d: expected MODEL_ID PARAMS... X Y Z\n", n);
      return 2;
    }
    double x[2];
    cc::project(model, params.data(), X, x, nullptr, nullptr);
    std::printf("%.17g %.17g\n", x[0], x[1]);
  }
  return 0;
}
