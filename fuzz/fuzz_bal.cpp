// SPDX-License-Identifier: BSD-3-Clause
// libFuzzer target: the BAL reader. Plain text goes to bal::parse_problem directly; inputs
// that start with the bzip2 signature "BZh" go through a file and bal::read_problem, which
// decompresses them. Problems that parse are converted with bal::to_sba.
#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <set>
#include <string>
#include <utility>

#include "formats/bal_io.h"
#include "fuzz_common.h"

namespace bal = sbaformats::bal;
namespace bal_camera = sbacameras::bal;

namespace {

void check_problem(const bal::Problem &p, const std::string &name) {
  using sbafuzz::require;
  require(p.ncameras > 0 && p.npoints > 0 && p.nobservations() > 0, "accepted a count <= 0");
  require(p.cameras.size() == std::size_t(p.ncameras) * bal_camera::kCameraParams, "camera values do not match the header");
  require(p.points.size() == std::size_t(p.npoints) * bal_camera::kPointParams, "point values do not match the header");
  sbafuzz::require_finite(p.cameras.begin(), p.cameras.end(), "the cameras");
  sbafuzz::require_finite(p.points.begin(), p.points.end(), "the points");
  std::set<std::pair<int, int>> pairs;
  for (const bal::Observation &o : p.observations) {
    require(o.camera >= 0 && o.camera < p.ncameras && o.point >= 0 && o.point < p.npoints,
            "an observation index out of range");
    require(std::isfinite(o.x) && std::isfinite(o.y), "a non-finite observation");
    require(pairs.insert({o.point, o.camera}).second, "a repeated (point, camera) pair");
  }

  bal::SbaLayout s;
  std::string error;
  if (!bal::to_sba(p, name, &s, &error)) sbafuzz::broken("to_sba refused a problem the reader accepted: " + error);
  require(s.n == p.npoints && s.m == p.ncameras, "to_sba sizes");
  require(s.nobservations() == p.nobservations() && s.x.size() == 2 * std::size_t(s.nobservations()),
          "to_sba observation count");
  require(s.vis.size() == std::size_t(s.nobservations()), "to_sba has not one visibility pair per observation");
  require(s.p.size() == p.cameras.size() + p.points.size(), "to_sba parameter vector size");
  for (int k = 1; k < s.nobservations(); ++k) {
    const bal::Observation &a = p.observations[std::size_t(s.order[std::size_t(k) - 1])];
    const bal::Observation &b = p.observations[std::size_t(s.order[std::size_t(k)])];
    require(a.point < b.point || (a.point == b.point && a.camera < b.camera),
            "to_sba order is not by point, then camera");
    require(s.vis.point[std::size_t(k)] == b.point && s.vis.camera[std::size_t(k)] == b.camera,
            "to_sba visibility is not the observations'");
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t *data, std::size_t size) {
  static const sbafuzz::InputFile file("problem.bal");
  bal::Problem problem;
  std::string error;
  bool ok;
  std::string name;
  if (size >= 3 && data[0] == 'B' && data[1] == 'Z' && data[2] == 'h') {
    if (!file.write(data, size)) return 0;
    name = file.path();
    ok = bal::read_problem(name, &problem, &error);
  } else {
    name = "fuzz-input";
    ok = bal::parse_problem(std::string(reinterpret_cast<const char *>(data), size), name, &problem, &error);
  }
  if (!ok) {
    sbafuzz::check_error_line(error, name + ": ");
    return 0;
  }
  check_problem(problem, name);
  return 0;
}
