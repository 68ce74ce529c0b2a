// SPDX-License-Identifier: BSD-3-Clause
#include "camera_unknowns.h"

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <numeric>
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

namespace {

// The held flags of the free cameras' parameters (m * cnp); empty when none is held.
std::vector<char> held_flags(const CameraParamOptions &o, const Layout &lay) {
  const int cnp = lay.cnp;
  std::vector<char> flags(size_t(lay.m) * size_t(cnp), 0);
  for (int j = lay.mcon; j < lay.m; ++j)
    for (int c = 0; c < cnp; ++c) flags[size_t(j) * cnp + c] = held(o, lay, j, c);
  if (std::find(flags.begin(), flags.end(), 1) == flags.end()) flags.clear();
  return flags;
}

// How many free cameras have each (parameter, group) key. A key of one camera only is that
// camera's own parameter after all.
std::unordered_map<std::uint64_t, int> key_counts(const CameraParamOptions &o, const Layout &lay) {
  std::unordered_map<std::uint64_t, int> count;
  for (int j = lay.mcon; j < lay.m; ++j)
    for (int c = 0; c < lay.cnp; ++c) {
      const int g = group_of(o, lay, j, c);
      if (g >= 0) ++count[key(c, g)];
    }
  return count;
}

// An unknown before the unknowns are ordered: its parameter and its cameras (ascending).
struct Provisional {
  int column;
  std::vector<int> cams;
};

// The unknowns in the order the cameras' parameters meet them, and per camera parameter its
// unknown (prov_of, m * cnp, -1 for a held or fixed one). A held parameter is no unknown at
// all: nothing of it reaches the solvers, its step is -0.0.
std::vector<Provisional> provisional_unknowns(const CameraParamOptions &o, const Layout &lay,
                                              const std::vector<char> &held_flags,
                                              const std::unordered_map<std::uint64_t, int> &count,
                                              std::vector<int> *prov_of) {
  const int cnp = lay.cnp;
  std::vector<Provisional> prov;
  std::unordered_map<std::uint64_t, int> by_key;
  prov_of->assign(size_t(lay.m) * size_t(cnp), -1);
  for (int j = lay.mcon; j < lay.m; ++j)
    for (int c = 0; c < cnp; ++c) {
      if (!held_flags.empty() && held_flags[size_t(j) * cnp + c]) continue;
      const int g = group_of(o, lay, j, c);
      int u;
      if (g >= 0 && count.at(key(c, g)) > 1) {
        const auto f = by_key.emplace(key(c, g), int(prov.size()));
        if (f.second) prov.push_back({c, {}});
        u = f.first->second;
      } else {
        u = int(prov.size());
        prov.push_back({c, {}});
      }
      prov[size_t(u)].cams.push_back(j);
      (*prov_of)[size_t(j) * cnp + c] = u;
    }
  return prov;
}

// The unknowns numbered in blocks, the unknowns of one set of cameras, ordered by their first
// camera, then by set, each block's unknowns by parameter: map's nunknowns, copies, column,
// block_start and unknown. Returns each block's cameras.
std::vector<const std::vector<int> *> number_in_blocks(const std::vector<Provisional> &prov,
                                                       const std::vector<int> &prov_of, CameraMap &map) {
  std::vector<int> order(prov.size());
  std::iota(order.begin(), order.end(), 0);
  std::sort(order.begin(), order.end(), [&](int a, int b) {
    const Provisional &pa = prov[size_t(a)], &pb = prov[size_t(b)];
    if (pa.cams != pb.cams) return pa.cams < pb.cams;
    return pa.column < pb.column;
  });
  const int K = int(prov.size());
  std::vector<int> final_of(static_cast<size_t>(K));
  map.nunknowns = K;
  map.copies.resize(size_t(K));
  map.column.resize(size_t(K));
  std::vector<const std::vector<int> *> block_cams;
  for (int q = 0; q < K; ++q) {
    const Provisional &pu = prov[size_t(order[size_t(q)])];
    if (q == 0 || pu.cams != prov[size_t(order[size_t(q) - 1])].cams) {
      map.block_start.push_back(q);
      block_cams.push_back(&pu.cams);
    }
    final_of[size_t(order[size_t(q)])] = q;
    map.copies[size_t(q)] = int(pu.cams.size());
    map.column[size_t(q)] = pu.column;
  }
  map.block_start.push_back(K);
  map.unknown.assign(prov_of.size(), -1);
  for (size_t q = 0; q < prov_of.size(); ++q)
    if (prov_of[q] >= 0) map.unknown[q] = final_of[size_t(prov_of[q])];
  return block_cams;
}

// The index both ways between the m cameras and the blocks: map's block_cam_start,
// block_cams, cam_start and cam_blocks.
void index_cameras(const std::vector<const std::vector<int> *> &block_cams, int m, CameraMap &map) {
  const int nb = map.nblocks();
  map.block_cam_start.assign(size_t(nb) + 1, 0);
  std::vector<std::vector<int>> cam_blocks(static_cast<size_t>(m));
  for (int b = 0; b < nb; ++b) {
    map.block_cam_start[size_t(b) + 1] = map.block_cam_start[size_t(b)] + int(block_cams[size_t(b)]->size());
    for (int j : *block_cams[size_t(b)]) {
      map.block_cams.push_back(j);
      cam_blocks[size_t(j)].push_back(b);  // b ascends: each camera's list is sorted
    }
  }
  map.cam_start.assign(size_t(m) + 1, 0);
  for (int j = 0; j < m; ++j) {
    map.cam_start[size_t(j) + 1] = map.cam_start[size_t(j)] + int(cam_blocks[size_t(j)].size());
    map.cam_blocks.insert(map.cam_blocks.end(), cam_blocks[size_t(j)].begin(), cam_blocks[size_t(j)].end());
  }
}

}  // namespace

CameraMap make_camera_map(const CameraParamOptions &o, const Layout &lay) {
  CameraMap map;
  if (lay.cnp == 0 || !o.any()) return map;
  if (o.fixed) map.held = held_flags(o, lay);
  if (!o.param_group && !o.group) return map;
  const std::unordered_map<std::uint64_t, int> count = key_counts(o, lay);
  bool any_shared = false;
  for (const auto &kc : count) any_shared = any_shared || kc.second > 1;
  if (!any_shared) return map;
  std::vector<int> prov_of;
  const std::vector<Provisional> prov = provisional_unknowns(o, lay, map.held, count, &prov_of);
  index_cameras(number_in_blocks(prov, prov_of, map), lay.m, map);
  return map;
}

}  // namespace sba
