// SPDX-License-Identifier: BSD-3-Clause
// libFuzzer target: eucsbademo's calibration file reader (eucsba::read_calibration).
#include <cstddef>
#include <cstdint>

#include "formats/eucsba_io.h"
#include "fuzz_common.h"

namespace eucsba = sbaformats::eucsba;
namespace euclidean = sbacameras::euclidean;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t *data, std::size_t size) {
  static const sbafuzz::InputFile file("calib.txt");
  if (!file.write(data, size)) return 0;
  euclidean::Intrinsics k;
  std::string error;
  if (!eucsba::read_calibration(file.path(), &k, &error)) {
    sbafuzz::check_format_error(error, file.path());
    return 0;
  }
  const double v[] = {k.fu, k.u0, k.v0, k.ar, k.s};
  sbafuzz::require_finite(std::begin(v), std::end(v), "the calibration");
  sbafuzz::require(k.fu != 0, "accepted fu == 0");
  sbafuzz::require(k.ar != 0, "accepted fv == 0");
  return 0;
}
