// SPDX-License-Identifier: BSD-3-Clause
// libFuzzer target: eucsbademo's points file reader (eucsba::read_points) for 64 cameras
// (more than any seed file has).
#include <algorithm>
#include <cstddef>
#include <cstdint>

#include "formats/eucsba_io.h"
#include "fuzz_common.h"

namespace eucsba = sbaformats::eucsba;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t *data, std::size_t size) {
  constexpr int kCameras = 64;
  static const sbafuzz::InputFile file("pts.txt");
  if (!file.write(data, size)) return 0;
  eucsba::PointSet pts;
  std::string error;
  if (!eucsba::read_points(file.path(), kCameras, &pts, &error)) {
    sbafuzz::check_format_error(error, file.path());
    return 0;
  }
  using sbafuzz::require;
  const std::size_t n = pts.xyz.size() / 3, nproj = pts.x.size() / 2;
  require(n > 0 && pts.xyz.size() == 3 * n, "xyz is empty or not 3 per point");
  require(pts.x.size() == 2 * nproj && nproj >= n, "x is not 2 per projection, or a point has none");
  require(pts.ncameras == kCameras, "ncameras changed");
  require(pts.vmask.size() == n * kCameras, "vmask is not npoints x ncameras");
  require(std::size_t(std::count_if(pts.vmask.begin(), pts.vmask.end(), [](char c) { return c != 0; })) == nproj,
          "vmask does not have one entry per projection");
  for (std::size_t i = 0; i < n; ++i)
    require(std::any_of(pts.vmask.begin() + i * kCameras, pts.vmask.begin() + (i + 1) * kCameras,
                        [](char c) { return c != 0; }),
            "a point without projections");
  sbafuzz::require_finite(pts.xyz.begin(), pts.xyz.end(), "xyz");
  sbafuzz::require_finite(pts.x.begin(), pts.x.end(), "x");
  if (pts.form == eucsba::CovarianceForm::None) {
    require(pts.covx.empty(), "covariances without a covariance form");
  } else {
    require(pts.covx.size() == 4 * nproj, "covx is not 4 per projection");
    sbafuzz::require_finite(pts.covx.begin(), pts.covx.end(), "covx");
    for (std::size_t k = 0; k < nproj; ++k) {
      const double *c = pts.covx.data() + 4 * k;
      require(c[1] == c[2], "an asymmetric covariance");
      require(c[0] > 0 && c[0] * c[3] - c[1] * c[2] > 0, "a covariance that is not positive definite");
    }
  }
  return 0;
}
