// SPDX-License-Identifier: BSD-3-Clause
// libFuzzer target: the COLMAP model parsers. The first byte chooses the file (its value
// mod 6: cameras, images, points3D as text, then the same as binary), the rest is its
// content. What parses must format back to content that parses to the same records, and
// a text file's formatted form must be a fixed point; what parses keeps the readers' promises
// (positive focal lengths, quaternions that normalize, names the text format can hold).
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "cameras/euclidean.h"
#include "cameras/colmap_camera.h"
#include "formats/colmap_io.h"
#include "fuzz_common.h"

namespace colmap = sbaformats::colmap;
namespace euclidean = sbacameras::euclidean;

namespace {

using sbafuzz::require;

template <class T>
using Parser = bool (*)(const std::string &, const std::string &, std::vector<T> *, std::string *);

// Formats records of one file as the writer would, with the others empty.
std::string format_cameras(const std::vector<colmap::Camera> &c, colmap::Encoding e) {
  return colmap::format_model({c, {}, {}}, e).cameras;
}
std::string format_images(const std::vector<colmap::Image> &i, colmap::Encoding e) {
  return colmap::format_model({{}, i, {}}, e).images;
}
std::string format_points(const std::vector<colmap::Point3D> &p, colmap::Encoding e) {
  return colmap::format_model({{}, {}, p}, e).points;
}

// What the readers promise of what they accept, beyond its syntax.
void require_valid(const colmap::Camera &c) {
  // The focal lengths (f, or fx and fy) lead the parameters and are positive.
  const int focals = sbacameras::colmap_camera::focal_count(c.model);
  for (int k = 0; k < focals; ++k)
    require(c.params[std::size_t(k)] > 0, "accepted a focal length that is not positive");
}
void require_valid(const colmap::Image &im) {
  sbafuzz::require_rotation(euclidean::normalized_rotation({im.q[0], im.q[1], im.q[2], im.q[3]}), "an image's quaternion");
  require(!im.name.empty() && im.name.front() != ' ' && im.name.back() != ' ', "accepted a name text cannot hold");
}
void require_valid(const colmap::Point3D &) {}

template <class T>
void check(const std::string &content, Parser<T> parse, std::string (*format)(const std::vector<T> &, colmap::Encoding),
           colmap::Encoding e) {
  const std::string name = "fuzz-input";
  std::vector<T> records;
  std::string error;
  if (!parse(content, name, &records, &error)) {
    sbafuzz::check_error_line(error, name + ":");
    return;
  }
  for (const T &record : records) require_valid(record);
  const std::string once = format(records, e);
  std::vector<T> again;
  if (!parse(once, name, &again, &error)) sbafuzz::broken("the formatted records do not parse: " + error);
  require(format(again, e) == once, "formatting the records read back gives other content");
  // Both encodings carry the same values (names aside, which text trims).
  require(again.size() == records.size(), "a different number of records after the round trip");
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t *data, std::size_t size) {
  if (size == 0) return 0;
  const std::string content(reinterpret_cast<const char *>(data) + 1, size - 1);
  const colmap::Encoding text = colmap::Encoding::Text, binary = colmap::Encoding::Binary;
  switch (data[0] % 6) {
    case 0: check<colmap::Camera>(content, colmap::parse_cameras_text, format_cameras, text); break;
    case 1: check<colmap::Image>(content, colmap::parse_images_text, format_images, text); break;
    case 2: check<colmap::Point3D>(content, colmap::parse_points_text, format_points, text); break;
    case 3: check<colmap::Camera>(content, colmap::parse_cameras_binary, format_cameras, binary); break;
    case 4: check<colmap::Image>(content, colmap::parse_images_binary, format_images, binary); break;
    default: check<colmap::Point3D>(content, colmap::parse_points_binary, format_points, binary); break;
  }
  return 0;
}
