// SPDX-License-Identifier: BSD-3-Clause
#include "unknowns.h"

#include <algorithm>

namespace sba {

i64 count_unknowns(const Layout &lay) {
  const CameraMap &map = lay.cams;
  const i64 points = i64(lay.free_pts()) * lay.pnp;
  if (map.shared()) return map.nunknowns + points;
  const i64 held = map.any_held() ? i64(std::count(map.held.begin(), map.held.end(), 1)) : 0;
  return i64(lay.free_cams()) * lay.cnp - held + points;
}

std::vector<double> tie_copies(const Layout &lay, double *p) {
  std::vector<double> given;
  const CameraMap &map = lay.cams;
  if (!map.shared()) return given;
  std::vector<i64> first(size_t(map.nunknowns), -1);
  const int cnp = lay.cnp;
  for (int j = lay.mcon; j < lay.m; ++j)
    for (int c = 0; c < cnp; ++c) {
      const int u = map.unknown[size_t(j) * cnp + c];
      if (u < 0) continue;
      const i64 at = lay.a_off(j) + c;
      if (first[size_t(u)] < 0) {
        first[size_t(u)] = at;
        continue;
      }
      given.push_back(p[at]);
      p[at] = p[first[size_t(u)]];
    }
  return given;
}

void restore_copies(const Layout &lay, double *p, const std::vector<double> &given) {
  const CameraMap &map = lay.cams;
  if (!map.shared()) return;
  std::vector<char> seen(size_t(map.nunknowns), 0);
  size_t k = 0;
  const int cnp = lay.cnp;
  for (int j = lay.mcon; j < lay.m; ++j)
    for (int c = 0; c < cnp; ++c) {
      const int u = map.unknown[size_t(j) * cnp + c];
      if (u < 0) continue;
      if (!seen[size_t(u)]) {
        seen[size_t(u)] = 1;
        continue;
      }
      p[lay.a_off(j) + c] = given[k++];
    }
}

void to_unknowns(const Layout &lay, const double *x_cams, double *x_unknowns) {
  const CameraMap &map = lay.cams;
  const int cnp = lay.cnp;
  std::fill(x_unknowns, x_unknowns + map.nunknowns, 0.0);
  for (int j = lay.mcon; j < lay.m; ++j)
    for (int c = 0; c < cnp; ++c) {
      const int u = map.unknown[size_t(j) * cnp + c];
      if (u >= 0) x_unknowns[u] += x_cams[lay.a_off(j) + c];
    }
}

void to_cameras(const Layout &lay, const double *x_unknowns, double held_value, double *x_cams) {
  const CameraMap &map = lay.cams;
  const int cnp = lay.cnp;
  for (int j = lay.mcon; j < lay.m; ++j)
    for (int c = 0; c < cnp; ++c) {
      const int u = map.unknown[size_t(j) * cnp + c];
      x_cams[lay.a_off(j) + c] = u >= 0 ? x_unknowns[u] : held_value;
    }
}

}  // namespace sba
