// SPDX-License-Identifier: BSD-3-Clause
#include "camera_unknowns.h"

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <unordered_map>

namespace sba {

namespace {

bool held(const CameraParamOptions &o, const Layout &lay, int j, int c) {
  if (!o.fixed) return false;
  return o.fixed[o.fixed_per_camera ? i64(j) * lay.cnp + c : c] != 0;
}

// Camera j's group number for parameter c, whichever way the caller gave them; -1: none.
int group_of(const CameraParamOptions &o, const Layout &lay, int j, int c) {
  if (o.param_group) return o.param_group[i64(j) * lay.cnp + c];
  if (o.group && o.shared[c]) return o.group[j];
  return -1;
}

// One shared unknown's key: its parameter and its group number.
std::uint64_t key(int c, int g) { return (std::uint64_t(std::uint32_t(c)) << 32) | std::uint32_t(g); }

std::string values_differ(double v0, double v) {
  char text[64];
  std::snprintf(text, sizeof text, "%.17g and %.17g", v0, v);
  return text;
}

}  // namespace

std::string check_camera_params(const CameraParamOptions &o, const Layout &lay, const double *p) {
  if (lay.cnp == 0) return {};
  if (o.param_group && (o.group || o.shared))
    return "cam_param_group and cam_group/cam_shared are given together: give one of the two";
  if (o.shared && !o.group) return "cam_shared is given but cam_group is NULL";
  if (o.group && !o.shared) return "cam_group is given but cam_shared is NULL";
  if (!o.param_group && !o.group) return {};
  const int cnp = lay.cnp;
  for (int j = 0; j < lay.m; ++j) {
    if (o.group) {
      const int g = o.group[j];
      if (g != -1 && (g < 0 || g >= lay.m))
        return "cam_group[" + std::to_string(j) + "] = " + std::to_string(g) +
               " is neither -1 nor a group number in [0, m-1]";
      if (g != -1 && j < lay.mcon)
        return "camera " + std::to_string(j) + " is below mcon = " + std::to_string(lay.mcon) +
               " (held whole) but in group " + std::to_string(g);
      continue;
    }
    for (int c = 0; c < cnp; ++c) {
      const int g = o.param_group[i64(j) * cnp + c];
      const std::string at = "cam_param_group[" + std::to_string(i64(j) * cnp + c) + "] = " + std::to_string(g);
      if (g < -1) return at + " is neither -1 nor a group number >= 0";
      if (g != -1 && j < lay.mcon)
        return at + ": camera " + std::to_string(j) + " is below mcon = " + std::to_string(lay.mcon) +
               " (held whole) and shares nothing";
    }
  }
  // Each shared parameter held in all of its cameras, with one value, or in none.
  std::unordered_map<std::uint64_t, int> first;  // (parameter, group) -> its first camera
  for (int j = lay.mcon; j < lay.m; ++j)
    for (int c = 0; c < cnp; ++c) {
      const int g = group_of(o, lay, j, c);
      if (g < 0) continue;
      const auto f = first.emplace(key(c, g), j);
      if (f.second) continue;
      const int j0 = f.first->second;
      const std::string pair = " by cameras " + std::to_string(j0) + " and " + std::to_string(j) +
                               (o.param_group ? " (cam_param_group " : " (group ") + std::to_string(g) + ")";
      if (held(o, lay, j, c) != held(o, lay, j0, c))
        return "parameter " + std::to_string(c) + " is shared" + pair + " but held (cam_fixed) in only one of them";
      // A held value is never rewritten, so one shared value held apart would come back apart.
      const double v = p[lay.a_off(j) + c], v0 = p[lay.a_off(j0) + c];
      if (held(o, lay, j, c) && std::memcmp(&v, &v0, sizeof v) != 0)
        return "parameter " + std::to_string(c) + " is shared" + pair + " and held, but its values differ: " +
               values_differ(v0, v);
    }
  return {};
}

CameraMap make_camera_map(const CameraParamOptions &o, const Layout &lay) {
  if (lay.cnp == 0 || !o.any()) return CameraMap(lay.m, lay.mcon, lay.cnp);
  const int cnp = lay.cnp;
  const size_t all = size_t(lay.m) * size_t(cnp);
  std::vector<char> flags;
  std::vector<i64> share;
  if (o.fixed) flags.resize(all);
  if (o.param_group || o.group) share.assign(all, -1);
  for (int j = lay.mcon; j < lay.m; ++j)
    for (int c = 0; c < cnp; ++c) {
      const size_t q = size_t(j) * cnp + c;
      if (o.fixed) flags[q] = held(o, lay, j, c);
      const int g = share.empty() ? -1 : group_of(o, lay, j, c);
      if (g >= 0) share[q] = i64(key(c, g));
    }
  CameraMap map(lay.m, lay.mcon, cnp, flags, share);
  map.index_points(lay.n, lay.pnp > 0 ? lay.ncon : lay.n, lay.rowptr.data(), lay.colidx.data());
  return map;
}

}  // namespace sba
