// SPDX-License-Identifier: BSD-3-Clause
#include "formats/colmap_sba.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstddef>
#include <cstdint>
#include <unordered_map>
#include <utility>

namespace sbaformats::colmap {

namespace cc = sbacameras::colmap_camera;

namespace {

std::size_t at(int i) { return static_cast<std::size_t>(i); }

bool fail(std::string *error, const std::string &msg) {
  if (error) *error = msg;
  return false;
}

}  // namespace

std::string parse_refine_intrinsics(const std::string &text, RefineIntrinsics *out) {
  RefineIntrinsics r{false, false, false};
  if (text == "all") {
    r = {true, true, true};
  } else if (text != "none") {
    std::size_t pos = 0;
    while (pos <= text.size()) {
      std::size_t end = text.find(',', pos);
      if (end == std::string::npos) end = text.size();
      const std::string item = text.substr(pos, end - pos);
      if (item == "focal") r.focal = true;
      else if (item == "principal") r.principal = true;
      else if (item == "distortion") r.distortion = true;
      else return "expected none, all or a comma-separated list of focal, principal, distortion, got '" + item + "'";
      pos = end + 1;
    }
  }
  *out = r;
  return {};
}

std::string quoted(const std::string &item) {
  std::string out = "'";
  for (const char c : item) {
    const unsigned char u = static_cast<unsigned char>(c);
    if (u >= 0x20 && u != 0x7f) {
      out += c;
      continue;
    }
    char hex[5];
    std::snprintf(hex, sizeof hex, "\\x%02x", u);
    out += hex;
  }
  return out + "'";
}

namespace {

// Whether item is written as an IMAGE_ID is (plain decimal digits, no leading zero), with its
// value in *id when an IMAGE_ID (32 bits) can have it.
bool plain_decimal(const std::string &item, std::uint32_t *id, bool *fits) {
  if (item.empty() || (item.size() > 1 && item[0] == '0')) return false;
  std::uint64_t v = 0;
  for (const char c : item) {
    if (c < '0' || c > '9') return false;
    if (v <= 0xffffffffu) v = 10 * v + static_cast<std::uint64_t>(c - '0');  // past 32 bits, stays past
  }
  *fits = v <= 0xffffffffu;
  *id = static_cast<std::uint32_t>(v);
  return true;
}

}  // namespace

ImageIndex::ImageIndex(const std::vector<Image> &images) {
  for (std::size_t j = 0; j < images.size(); ++j) {
    by_id_.emplace(images[j].id, j);
    by_name_.emplace(images[j].name, j);
  }
}

bool ImageIndex::flag_id(std::uint64_t id, std::vector<char> *held) const {
  const auto it = id <= 0xffffffffu ? by_id_.find(static_cast<std::uint32_t>(id)) : by_id_.end();
  if (it == by_id_.end()) return false;
  (*held)[it->second] = 1;
  return true;
}

bool ImageIndex::flag_name(const std::string &name, std::vector<char> *held) const {
  const auto [first, last] = by_name_.equal_range(name);
  for (auto it = first; it != last; ++it) (*held)[it->second] = 1;
  return first != last;
}

std::string ImageIndex::hold_id(std::uint64_t id, std::vector<char> *held) const {
  return flag_id(id, held) ? std::string() : "no image has the IMAGE_ID " + std::to_string(id);
}

std::string ImageIndex::hold_name(const std::string &name, std::vector<char> *held) const {
  return flag_name(name, held) ? std::string() : "no image has the NAME " + quoted(name);
}

std::string ImageIndex::hold_text(const std::string &item, std::vector<char> *held) const {
  std::uint32_t id = 0;
  bool fits = false;
  const bool digits = plain_decimal(item, &id, &fits);
  if ((digits && fits && flag_id(id, held)) || flag_name(item, held)) return {};
  return std::string("no image has the ") + (digits ? "IMAGE_ID or NAME " : "NAME ") + quoted(item);
}

std::string split_image_list(const std::string &list, std::vector<std::string> *items) {
  std::vector<std::string> out;
  for (std::size_t pos = 0;;) {
    const std::size_t end = std::min(list.find(',', pos), list.size());
    if (end == pos)
      return "item " + std::to_string(out.size() + 1) +
             " is empty (two commas in a row, or a comma at an end)";
    out.push_back(list.substr(pos, end - pos));
    if (end == list.size()) break;
    pos = end + 1;
  }
  *items = std::move(out);
  return {};
}

std::string parse_image_list(const Model &model, const std::string &list, std::vector<char> *held) {
  std::vector<char> h = *held;
  h.resize(model.images.size(), 0);
  if (list == "all") {
    std::fill(h.begin(), h.end(), 1);
  } else {
    std::vector<std::string> items;
    if (std::string why = split_image_list(list, &items); !why.empty()) return why;
    const ImageIndex images(model.images);
    for (const std::string &item : items)
      if (std::string why = images.hold_text(item, &h); !why.empty()) return why;
  }
  *held = std::move(h);
  return {};
}

namespace {

// Each line of a file of names or ids (name stands for it in messages) through hold, blank lines
// skipped; the first reason hold gives, as "NAME:LINE: why", or empty.
template <class Hold>
std::string hold_lines(const std::string &text, const std::string &name, Hold hold) {
  std::size_t pos = 0;
  for (int line = 1; pos < text.size(); ++line) {
    const std::size_t eol = std::min(text.find('\n', pos), text.size());
    // A '\r' is taken off only as part of a "\r\n" line break.
    const std::size_t end = eol < text.size() && eol > pos && text[eol - 1] == '\r' ? eol - 1 : eol;
    const std::string item = text.substr(pos, end - pos);
    pos = eol + 1;
    if (item.empty()) continue;
    if (std::string why = hold(item); !why.empty()) return name + ":" + std::to_string(line) + ": " + why;
  }
  return {};
}

}  // namespace

std::string parse_image_names(const Model &model, const std::string &text, const std::string &name,
                              std::vector<char> *held) {
  std::vector<char> h = *held;
  h.resize(model.images.size(), 0);
  const ImageIndex images(model.images);
  if (std::string why = hold_lines(text, name, [&](const std::string &item) { return images.hold_name(item, &h); });
      !why.empty())
    return why;
  *held = std::move(h);
  return {};
}

namespace {

// item as an identifier of at most max, written as an IMAGE_ID of an image list is (plain
// decimal digits without a leading zero): false when it is not one.
bool decimal_id(const std::string &item, std::uint64_t max, std::uint64_t *id) {
  if (item.empty() || (item.size() > 1 && item[0] == '0')) return false;
  std::uint64_t v = 0;
  for (const char c : item) {
    if (c < '0' || c > '9') return false;
    const std::uint64_t d = static_cast<std::uint64_t>(c - '0');
    if (v > (max - d) / 10) return false;
    v = 10 * v + d;
  }
  *id = v;
  return true;
}

std::string not_an_id(const std::string &item, const char *kind) {
  return quoted(item) + " is not a " + kind + " (plain decimal digits without a leading zero)";
}

// The identifiers of the elements of a model's list (Model::cameras, Model::points) and what
// messages call them, for the lists of identifiers.
struct IdIndex {
  const char *kind, *noun;  // "CAMERA_ID", "camera"
  std::uint64_t max;
  std::unordered_map<std::uint64_t, std::size_t> index;

  // Flags the element of item; why not, empty when it is flagged.
  std::string hold(const std::string &item, std::vector<char> *held) const {
    std::uint64_t id = 0;
    if (!decimal_id(item, max, &id)) return not_an_id(item, kind);
    const auto it = index.find(id);
    if (it == index.end()) return std::string("no ") + noun + " has the " + kind + " " + quoted(item);
    (*held)[it->second] = 1;
    return {};
  }
};

IdIndex camera_ids(const Model &model) {
  IdIndex ids{"CAMERA_ID", "camera", 0xffffffffu, {}};
  for (std::size_t c = 0; c < model.cameras.size(); ++c) ids.index.emplace(model.cameras[c].id, c);
  return ids;
}

IdIndex point_ids(const Model &model) {
  IdIndex ids{"POINT3D_ID", "point", UINT64_MAX, {}};
  for (std::size_t i = 0; i < model.points.size(); ++i) ids.index.emplace(model.points[i].id, i);
  return ids;
}

// parse_camera_list and parse_point_list over ids, of `size` elements.
std::string parse_id_list(const IdIndex &ids, std::size_t size, const std::string &list, std::vector<char> *held) {
  std::vector<char> h = *held;
  h.resize(size, 0);
  if (list == "all") {
    std::fill(h.begin(), h.end(), 1);
  } else {
    std::vector<std::string> items;
    if (std::string why = split_image_list(list, &items); !why.empty()) return why;
    for (const std::string &item : items)
      if (std::string why = ids.hold(item, &h); !why.empty()) return why;
  }
  *held = std::move(h);
  return {};
}

}  // namespace

std::string check_id_list(const std::string &list, const char *kind, std::uint64_t max) {
  if (list == "all") return {};
  std::vector<std::string> items;
  if (std::string why = split_image_list(list, &items); !why.empty()) return why;
  for (std::size_t k = 0; k < items.size(); ++k) {
    std::uint64_t id = 0;
    if (!decimal_id(items[k], max, &id)) return "item " + std::to_string(k + 1) + ": " + not_an_id(items[k], kind);
  }
  return {};
}

std::string parse_camera_list(const Model &model, const std::string &list, std::vector<char> *held) {
  return parse_id_list(camera_ids(model), model.cameras.size(), list, held);
}

std::string parse_point_list(const Model &model, const std::string &list, std::vector<char> *held) {
  return parse_id_list(point_ids(model), model.points.size(), list, held);
}

std::string parse_point_ids(const Model &model, const std::string &text, const std::string &name,
                            std::vector<char> *held) {
  std::vector<char> h = *held;
  h.resize(model.points.size(), 0);
  const IdIndex ids = point_ids(model);
  if (std::string why = hold_lines(text, name, [&](const std::string &item) { return ids.hold(item, &h); });
      !why.empty())
    return why;
  *held = std::move(h);
  return {};
}

std::size_t frames_of_several_images(const Model &model) {
  return static_cast<std::size_t>(std::count_if(model.frames.begin(), model.frames.end(), [](const Frame &f) {
    return std::count_if(f.data.begin(), f.data.end(),
                         [](const DataId &d) { return d.sensor.type == SensorType::Camera; }) > 1;
  }));
}

bool to_euclidean(const cc::Camera &c, sbacameras::euclidean::Camera *out) {
  sbacameras::euclidean::Camera e;
  const std::vector<double> &p = c.params;
  int nd = 0;  // Bouguet's kc = (k1 k2 p1 p2 k3) is OpenCV's
  switch (c.model) {
    case kSimplePinhole: case kSimpleRadial: case kRadial:
      e.k.fu = p[0];
      e.k.u0 = p[1];
      e.k.v0 = p[2];
      nd = c.model == kSimplePinhole ? 0 : c.model == kSimpleRadial ? 1 : 2;
      for (int k = 0; k < nd; ++k) e.kc[at(k)] = p[at(3 + k)];
      break;
    case kPinhole: case kOpenCV:
      e.k.fu = p[0];
      e.k.ar = p[1] / p[0];
      e.k.u0 = p[2];
      e.k.v0 = p[3];
      nd = c.model == kPinhole ? 0 : 4;
      for (int k = 0; k < nd; ++k) e.kc[at(k)] = p[at(4 + k)];
      break;
    default: return false;
  }
  e.q = c.q;
  e.t = c.t;
  *out = e;
  return true;
}

}  // namespace sbaformats::colmap

namespace sbaformats::colmap {

bool from_problem(sbacameras::euclidean::CameraKind kind, const std::vector<sbacameras::euclidean::Camera> &cameras, const eucsba::PointSet &points,
                  int width, int height, Model *out, std::string *error) {
  const int m = static_cast<int>(cameras.size()), n = points.npoints();
  if (points.ncameras != m || points.vmask.size() != static_cast<std::size_t>(n) * static_cast<std::size_t>(m))
    return fail(error, "a COLMAP model needs the points' dense visibility mask");
  Model model;
  const bool shared = kind == sbacameras::euclidean::CameraKind::FixedIntrinsics;
  const bool distortion = kind == sbacameras::euclidean::CameraKind::VaryingIntrinsicsDistortion;
  for (int j = 0; j < m; ++j) {
    const sbacameras::euclidean::Camera &c = cameras[static_cast<std::size_t>(j)];
    if (c.k.s != 0) return fail(error, "camera " + std::to_string(j) + " has a skew, which COLMAP cannot hold");
    if (c.kc[4] != 0) return fail(error, "camera " + std::to_string(j) + " has kc4 (k3), which OPENCV cannot hold");
    if (!shared || j == 0) {
      Camera cam;
      cam.id = shared ? 1 : 100 + static_cast<std::uint32_t>(j);
      cam.model = distortion ? kOpenCV : kPinhole;
      cam.width = static_cast<std::uint64_t>(width);
      cam.height = static_cast<std::uint64_t>(height);
      cam.params = {c.k.fu, c.k.fu * c.k.ar, c.k.u0, c.k.v0};
      if (distortion) cam.params.insert(cam.params.end(), c.kc.begin(), c.kc.begin() + 4);
      model.cameras.push_back(cam);
    }
    Image im;
    im.id = 10 + 3 * static_cast<std::uint32_t>(j);
    im.q = {c.q.w, c.q.x, c.q.y, c.q.z};
    for (int k = 0; k < 3; ++k) im.t[k] = c.t[k];
    im.camera_id = model.cameras.back().id;
    char name[32];
    std::snprintf(name, sizeof name, "img_%04d.png", j);
    im.name = name;
    im.points.push_back({0.5, 0.5, kNoPoint});
    model.images.push_back(std::move(im));
  }
  model.points.resize(static_cast<std::size_t>(n));
  for (int i = 0; i < n; ++i) {
    Point3D &pt = model.points[static_cast<std::size_t>(i)];
    pt.id = 1000 + 7 * static_cast<std::uint64_t>(i);
    for (int c = 0; c < 3; ++c) pt.xyz[c] = points.xyz[3 * static_cast<std::size_t>(i) + c];
    const std::array<int, 3> rgb = eucsba::generated_color(i);
    for (int c = 0; c < 3; ++c) pt.rgb[c] = static_cast<std::uint8_t>(rgb[c]);
    pt.error = 1;
  }
  eucsba::for_each_projection(points, [&](int i, int j, const double *x) {
    Point3D &pt = model.points[static_cast<std::size_t>(i)];
    Image &im = model.images[static_cast<std::size_t>(j)];
    pt.track.push_back({im.id, static_cast<std::uint32_t>(im.points.size())});
    im.points.push_back({x[0], x[1], pt.id});
  });
  *out = std::move(model);
  return true;
}

}  // namespace sbaformats::colmap
