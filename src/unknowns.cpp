// SPDX-License-Identifier: BSD-3-Clause
#include "unknowns.h"

namespace sba {

i64 count_unknowns(const Layout &lay) {
  return i64(lay.cams.unknowns()) + i64(lay.free_pts()) * lay.pnp;
}

namespace {

// fn(at, u, first) for every free camera parameter of an unknown, in ascending order: at its
// index in p, u its unknown, first whether it is u's first copy.
template <class Fn>
void for_each_copy(const Layout &lay, Fn fn) {
  const CameraMap &map = lay.cams;
  std::vector<char> seen(size_t(map.unknowns()), 0);
  for (int j = lay.mcon; j < lay.m; ++j)
    for (int c = 0; c < lay.cnp; ++c) {
      const int u = map.unknown(j, c);
      if (u < 0) continue;
      fn(lay.a_off(j) + c, u, !seen[size_t(u)]);
      seen[size_t(u)] = 1;
    }
}

}  // namespace

std::vector<double> tie_copies(const Layout &lay, double *p) {
  std::vector<double> given;
  if (!lay.cams.shared()) return given;
  std::vector<i64> first(size_t(lay.cams.unknowns()), -1);
  for_each_copy(lay, [&](i64 at, int u, bool is_first) {
    if (is_first) {
      first[size_t(u)] = at;
      return;
    }
    given.push_back(p[at]);
    p[at] = p[first[size_t(u)]];
  });
  return given;
}

void restore_copies(const Layout &lay, double *p, const std::vector<double> &given) {
  if (!lay.cams.shared()) return;
  size_t k = 0;
  for_each_copy(lay, [&](i64 at, int, bool is_first) {
    if (!is_first) p[at] = given[k++];
  });
}

}  // namespace sba
