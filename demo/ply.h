/* SPDX-License-Identifier: BSD-3-Clause */
// --initial-ply and --final-ply of sbarefine, balsba and eucsbademo: a model's points and
// camera centres as an ASCII PLY file, which any point-cloud viewer opens.
#ifndef SBA_DEMO_PLY_H
#define SBA_DEMO_PLY_H

#include <array>
#include <string>
#include <vector>

#include "cli.h"

namespace sbademo {

// What a PLY file shows: points, with their colors when the model has them, and camera centres.
struct Cloud {
  std::vector<std::array<double, 3>> points;
  std::vector<std::array<int, 3>> colors;  // one per point, or empty: a model without colors
  std::vector<std::array<double, 3>> centres;
};

// The points (in their colors, or grey) then the camera centres (red), all as one vertex
// element so that a viewer draws them alike. The file appears whole or not at all
// (output_file.h). On failure returns false with the reason in *error.
bool write_ply(const std::string &path, const Cloud &cloud, std::string *error);

// --initial-ply FILE and --final-ply FILE, into *initial and *final_ply; colored: the model's
// points have colors, which the help then mentions.
void add_ply_options(std::vector<sbacli::Option> *table, std::string *initial, std::string *final_ply, bool colored);

// write_ply for an option: nothing when path is empty; "PATH: why" on stderr when it fails.
bool write_ply_option(const std::string &path, const Cloud &cloud);

}  // namespace sbademo

#endif  // SBA_DEMO_PLY_H
