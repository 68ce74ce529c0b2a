// SPDX-License-Identifier: BSD-3-Clause
// libFuzzer target: the Bundler reader (bundler::parse_bundle) and the mapping onto the BAL
// problem, and the image list's reader (bundler::parse_list) on the same input. A bundle that
// parses must format back to text that parses to the same text again, and must map onto a
// BAL problem whose observations are all in range; a list that parses names every line.
#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "formats/bal_io.h"
#include "formats/bundler_io.h"
#include "fuzz_common.h"

namespace bundler = sbaformats::bundler;
namespace bal = sbaformats::bal;
namespace bal_camera = sbacameras::bal;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t *data, std::size_t size) {
  using sbafuzz::require;
  const std::string name = "fuzz-input";
  const std::string text(reinterpret_cast<const char *>(data), size);
  bundler::ImageList list;
  std::string error;
  if (bundler::parse_list(text, name, &list, &error)) {
    std::size_t lines = static_cast<std::size_t>(std::count(text.begin(), text.end(), '\n'));
    if (!text.empty() && text.back() != '\n') ++lines;
    require(list.names.size() == lines && list.text == text, "a list that does not name every line");
    for (const std::string &n : list.names) require(!n.empty(), "an empty name in a list");
  } else {
    sbafuzz::check_error_line(error, name + ":");
  }
  bundler::Bundle b;
  if (!bundler::parse_bundle(text, name, &b, &error)) {
    sbafuzz::check_error_line(error, name + ":");
    return 0;
  }
  sbafuzz::require_fixed_point(b, bundler::parse_bundle, bundler::format_bundle, name);
  bal::Problem p;
  std::vector<int> cameras;
  if (!bundler::to_bal(b, name, &p, &cameras, &error)) {
    sbafuzz::check_error_line(error, name + ": ");
    return 0;
  }
  require(p.cameras.size() == cameras.size() * bal_camera::kCameraParams, "camera parameters per registered camera");
  sbafuzz::require_finite(p.cameras.begin(), p.cameras.end(), "the BAL cameras");
  for (const bal::Observation &o : p.observations)
    require(o.camera >= 0 && o.camera < p.ncameras && o.point >= 0 && o.point < p.npoints,
            "an observation index out of range");
  bal::SbaLayout s;
  if (!bal::to_sba(p, name, &s, &error)) sbafuzz::broken("to_sba refused a mapped bundle: " + error);
  return 0;
}
