// SPDX-License-Identifier: BSD-3-Clause
// libFuzzer target: the NVM reader (nvm::parse_nvm) and the mapping onto eucsbademo's camera
// model. What parses must format back to text that parses to the same text again (the rest
// of the file included), and must map onto a problem whose values are all finite, one
// measurement per visible projection.
#include <cstddef>
#include <cstdint>
#include <string>

#include "fuzz_common.h"
#include "nvm_io.h"

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
  const std::string once = nvm::format_nvm(m);
  nvm::Model again;
  if (!nvm::parse_nvm(once, name, &again, &error)) sbafuzz::broken("the formatted model does not parse: " + error);
  require(nvm::format_nvm(again) == once, "formatting the model read back gives other text");
  require(again.rest == m.rest && again.header == m.header, "the header or the rest of the file changed");
  colmap::SbaProblem p;
  if (!nvm::to_sba(m, true, name, &p, &error)) {
    sbafuzz::check_error_line(error, name + ": ");
    return 0;
  }
  require(p.cameras.size() == m.cameras.size(), "one sba camera per NVM camera");
  for (const eucsba::Camera &c : p.cameras) {
    const double q[4] = {c.q.w, c.q.x, c.q.y, c.q.z};
    sbafuzz::require_finite(q, q + 4, "a camera's rotation");
    sbafuzz::require_finite(c.t.begin(), c.t.end(), "a camera's translation");
  }
  sbafuzz::require_finite(p.points.x.begin(), p.points.x.end(), "the undistorted measurements");
  std::size_t visible = 0;
  for (char v : p.points.vmask) visible += v != 0;
  require(2 * visible == p.points.x.size(), "two values per visible projection");
  return 0;
}
