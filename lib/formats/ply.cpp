// SPDX-License-Identifier: BSD-3-Clause
#include "formats/ply.h"

#include <cstdio>

#include "formats/output_file.h"

namespace sbaformats {

bool write_ply(const std::string &path, const Cloud &cloud, std::string *error, OutputSet *outputs) {
  // Grey stands out from the red centres on a dark or a light background alike.
  constexpr std::array<int, 3> kNoColor{160, 160, 160};
  SetFile file(outputs);
  if (!file.open(path, error)) return false;
  std::FILE *f = file.get();
  std::fprintf(f,
               "ply\nformat ascii 1.0\ncomment points, then camera centres (red)\nelement vertex %zu\n"
               "property double x\nproperty double y\nproperty double z\n"
               "property uchar red\nproperty uchar green\nproperty uchar blue\nend_header\n",
               cloud.points.size() + cloud.centres.size());
  const bool colored = cloud.colors.size() == cloud.points.size();
  for (std::size_t i = 0; i < cloud.points.size(); ++i) {
    const std::array<double, 3> &x = cloud.points[i];
    const std::array<int, 3> &c = colored ? cloud.colors[i] : kNoColor;
    std::fprintf(f, "%.17g %.17g %.17g %d %d %d\n", x[0], x[1], x[2], c[0], c[1], c[2]);
  }
  for (const auto &x : cloud.centres) std::fprintf(f, "%.17g %.17g %.17g 255 0 0\n", x[0], x[1], x[2]);
  return file.close(error);
}

}  // namespace sbaformats
