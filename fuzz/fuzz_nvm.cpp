// SPDX-License-Identifier: BSD-3-Clause
// libFuzzer target: the NVM reader (nvm::parse_nvm) and the mapping onto eucsbademo's camera
// model. What parses must format back to text that parses to the same text again, with the
// header line and the rest of the file as they were read, and must map onto a problem whose
// values are all finite, one measurement per visible projection.
#include <cstddef>
#include <cstdint>
#include <string>

#include "formats/nvm_io.h"
#include "fuzz_common.h"

namespace nvm = sbaformats::nvm;
namespace euclidean = sbacameras::euclidean;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t *data, std::size_t size) {
  using sbafuzz::require;
  const std::string name = "fuzz-input";
  const std::string text(reinterpret_cast<const char *>(data), size);
  nvm::Model m;
  std::string error;
  if (!nvm::parse_nvm(text, name, &m, &error)) {
    sbafuzz::check_error_line(error, name + ":");
    return 0;
  }
  const std::string once = sbafuzz::require_fixed_point(m, nvm::parse_nvm, nvm::format_nvm, name);
  // The header line starts the text and the rest of the file ends it, as they were read.
  require(once.compare(0, m.header.size() + 1, m.header + "\n") == 0, "the header is not written back as read");
  require(once.size() >= m.rest.size() && once.compare(once.size() - m.rest.size(), m.rest.size(), m.rest) == 0,
          "the rest of the file is not written back as read");
  nvm::SbaProblem p;
  if (!nvm::to_sba(m, true, name, &p, &error)) {
    sbafuzz::check_error_line(error, name + ": ");
    return 0;
  }
  require(p.cameras.size() == m.cameras.size(), "one sba camera per NVM camera");
  for (const euclidean::Camera &c : p.cameras) {
    const double q[4] = {c.q.w, c.q.x, c.q.y, c.q.z};
    sbafuzz::require_finite(q, q + 4, "a camera's rotation");
    sbafuzz::require_finite(c.t.begin(), c.t.end(), "a camera's translation");
  }
  sbafuzz::require_finite(p.points.x.begin(), p.points.x.end(), "the undistorted measurements");
  require(2 * p.points.pairs.size() == p.points.x.size(), "two values per visible projection");
  return 0;
}
