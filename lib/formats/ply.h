/* SPDX-License-Identifier: BSD-3-Clause */
// A model's points and camera centres as an ASCII PLY file, which any point-cloud viewer opens:
// what --initial-ply and --final-ply write (cli/ply_options.h).
#ifndef SBA_LIB_FORMATS_PLY_H
#define SBA_LIB_FORMATS_PLY_H

#include <array>
#include <string>
#include <vector>

namespace sbaformats {

class OutputSet;  // output_file.h

// What a PLY file shows: points, with their colors when the model has them, and camera centres.
struct Cloud {
  std::vector<std::array<double, 3>> points;
  std::vector<std::array<int, 3>> colors;  // one per point, or empty: a model without colors
  std::vector<std::array<double, 3>> centres;
};

// The points (in their colors, or grey) then the camera centres (red), all as one vertex
// element so that a viewer draws them alike. The file appears whole or not at all
// (output_file.h); with `outputs`, when that set of a run's outputs is committed. On failure
// returns false with the reason in *error.
bool write_ply(const std::string &path, const Cloud &cloud, std::string *error, OutputSet *outputs = nullptr);

}  // namespace sbaformats

#endif  // SBA_LIB_FORMATS_PLY_H
