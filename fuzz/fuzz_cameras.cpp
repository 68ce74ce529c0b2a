// SPDX-License-Identifier: BSD-3-Clause
// libFuzzer target: eucsbademo's camera file reader (eucsba::read_cameras).
#include <cstddef>
#include <cstdint>

#include "cameras/euclidean.h"
#include "formats/eucsba_io.h"
#include "fuzz_common.h"

namespace eucsba = sbaformats::eucsba;
namespace euclidean = sbacameras::euclidean;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t *data, std::size_t size) {
  static const sbafuzz::InputFile file("cams.txt");
  if (!file.write(data, size)) return 0;
  eucsba::CameraFile cams;
  std::string error;
  if (!eucsba::read_cameras(file.path(), &cams, &error)) {
    sbafuzz::check_format_error(error, file.path());
    return 0;
  }
  sbafuzz::require(!cams.cameras.empty(), "accepted a file without cameras");
  sbafuzz::require(cams.first_line > 0, "first_line not set");
  for (const euclidean::Camera &c : cams.cameras) {
    const double v[] = {c.k.fu, c.k.u0, c.k.v0, c.k.ar, c.k.s, c.q.w, c.q.x, c.q.y, c.q.z, c.t[0], c.t[1], c.t[2]};
    sbafuzz::require_finite(std::begin(v), std::end(v), "a camera");
    sbafuzz::require_finite(c.kc.begin(), c.kc.end(), "a camera's distortion");
    sbafuzz::require(c.q.w != 0 || c.q.x != 0 || c.q.y != 0 || c.q.z != 0, "accepted a zero quaternion");
    sbafuzz::require_rotation(euclidean::normalized_rotation(c.q), "a camera's quaternion");
  }
  return 0;
}
