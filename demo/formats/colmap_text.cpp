// SPDX-License-Identifier: BSD-3-Clause
// COLMAP's text format: cameras.txt, images.txt and points3D.txt.
#include <cmath>
#include <cstdint>
#include <string>
#include <unordered_set>
#include <vector>

#include "formats/colmap_io_impl.h"
#include "formats/text_tokens.h"

namespace sbaformats::colmap {

namespace {

// The lines of a text file: "tokens" split on blanks, with the line number.
class TextReader {
 public:
  TextReader(const std::string &text, const std::string &name) : text_(text), name_(name) {}

  // The next line that is neither blank nor a comment; false at the end.
  bool next_data_line() {
    while (next_line())
      if (!is_blank_or_comment()) return true;
    return false;
  }
  // The very next line, whatever it holds; false at the end.
  bool next_line() {
    if (pos_ >= text_.size()) return false;
    std::size_t end = text_.find('\n', pos_);
    if (end == std::string::npos) end = text_.size();
    line_.assign(text_, pos_, end - pos_);
    if (!line_.empty() && line_.back() == '\r') line_.pop_back();
    pos_ = end + 1;
    ++lineno_;
    split();
    return true;
  }
  bool is_blank_or_comment() const { return tokens_.empty() || tokens_[0][0] == '#'; }

  const std::vector<std::string> &tokens() const { return tokens_; }
  const std::string &line() const { return line_; }
  int lineno() const { return lineno_; }
  std::string where() const { return name_ + ":" + std::to_string(lineno_) + ": "; }

 private:
  void split() {
    tokens_.clear();
    std::size_t i = 0;
    while (i < line_.size()) {
      while (i < line_.size() && is_blank(line_[i])) ++i;
      const std::size_t b = i;
      while (i < line_.size() && !is_blank(line_[i])) ++i;
      if (i > b) tokens_.emplace_back(line_, b, i - b);
    }
  }

  const std::string &text_;
  const std::string &name_;
  std::size_t pos_ = 0;
  int lineno_ = 0;
  std::string line_;
  std::vector<std::string> tokens_;
};

// A finite decimal number, the whole token.
bool parse_real(const std::string &tok, double *out) {
  double v;
  if (!decimal_number(tok, &v) || !std::isfinite(v)) return false;
  *out = v;
  return true;
}

// An unsigned decimal integer <= max, the whole token.
bool parse_uint(const std::string &tok, std::uint64_t max, std::uint64_t *out) {
  if (tok.empty() || tok.size() > 20) return false;
  std::uint64_t v = 0;
  for (char c : tok) {
    if (c < '0' || c > '9') return false;
    const std::uint64_t d = static_cast<std::uint64_t>(c - '0');
    if (v > (max - d) / 10) return false;
    v = v * 10 + d;
  }
  *out = v;
  return true;
}

bool real_field(const TextReader &r, std::size_t k, const char *what, double *out, std::string *error) {
  if (parse_real(r.tokens()[k], out)) return true;
  return fail(error, r.where() + what + " must be a finite number, got '" + printable(r.tokens()[k]) + "'");
}

bool uint_field(const TextReader &r, std::size_t k, const char *what, std::uint64_t max, std::uint64_t *out,
                std::string *error) {
  if (parse_uint(r.tokens()[k], max, out)) return true;
  return fail(error, r.where() + what + " must be an integer from 0 to " + std::to_string(max) + ", got '" +
                         printable(r.tokens()[k]) + "'");
}

int model_by_name(const std::string &name) {
  for (int i = 0; i < kNumModels; ++i)
    if (name == kModels[i].name) return i;
  return -1;
}

bool is_other_model(const std::string &name) {
  for (int i = 0; i < kNumOtherModels; ++i)
    if (name == kOtherModels[i]) return true;
  return false;
}

constexpr std::uint64_t kU32 = 0xffffffffu;

}  // namespace

bool parse_cameras_text(const std::string &text, const std::string &name, std::vector<Camera> *out,
                        std::string *error) {
  TextReader r(text, name);
  std::vector<Camera> cams;
  std::unordered_set<std::uint32_t> ids;
  while (r.next_data_line()) {
    const auto &t = r.tokens();
    if (t.size() < 4)
      return fail(error, r.where() + "expected CAMERA_ID MODEL WIDTH HEIGHT PARAMS[], found " +
                             std::to_string(t.size()) + " values");
    Camera c;
    std::uint64_t v;
    if (!uint_field(r, 0, "CAMERA_ID", kU32, &v, error)) return false;
    c.id = static_cast<std::uint32_t>(v);
    c.model = model_by_name(t[1]);
    if (c.model < 0)
      return fail(error, r.where() + (is_other_model(t[1]) ? unsupported_model(t[1])
                                                          : "unknown camera model '" + printable(t[1]) + "'"));
    if (!uint_field(r, 2, "WIDTH", UINT64_MAX, &c.width, error)) return false;
    if (!uint_field(r, 3, "HEIGHT", UINT64_MAX, &c.height, error)) return false;
    const int np = kModels[c.model].params;
    if (t.size() != 4 + static_cast<std::size_t>(np))
      return fail(error, r.where() + t[1] + " has " + std::to_string(np) + " parameters, found " +
                             std::to_string(t.size() - 4));
    c.params.resize(static_cast<std::size_t>(np));
    for (int k = 0; k < np; ++k)
      if (!real_field(r, 4 + static_cast<std::size_t>(k), "a camera parameter", &c.params[k], error)) return false;
    if (const std::string why = bad_intrinsics(c); !why.empty()) return fail(error, r.where() + why);
    if (!ids.insert(c.id).second) return fail(error, r.where() + "camera " + std::to_string(c.id) + " appears twice");
    cams.push_back(std::move(c));
  }
  *out = std::move(cams);
  return true;
}

bool parse_images_text(const std::string &text, const std::string &name, std::vector<Image> *out,
                       std::string *error) {
  TextReader r(text, name);
  std::vector<Image> images;
  std::unordered_set<std::uint32_t> ids;
  while (r.next_data_line()) {
    const auto &t = r.tokens();
    if (t.size() < 10)
      return fail(error, r.where() + "expected IMAGE_ID QW QX QY QZ TX TY TZ CAMERA_ID NAME, found " +
                             std::to_string(t.size()) + " values");
    Image im;
    std::uint64_t v;
    if (!uint_field(r, 0, "IMAGE_ID", kU32, &v, error)) return false;
    im.id = static_cast<std::uint32_t>(v);
    static const char *const kq[] = {"QW", "QX", "QY", "QZ"};
    static const char *const kt[] = {"TX", "TY", "TZ"};
    for (int k = 0; k < 4; ++k)
      if (!real_field(r, 1 + static_cast<std::size_t>(k), kq[k], &im.q[k], error)) return false;
    for (int k = 0; k < 3; ++k)
      if (!real_field(r, 5 + static_cast<std::size_t>(k), kt[k], &im.t[k], error)) return false;
    if (im.q[0] == 0 && im.q[1] == 0 && im.q[2] == 0 && im.q[3] == 0)
      return fail(error, r.where() + "the quaternion is zero");
    if (!uint_field(r, 8, "CAMERA_ID", kU32, &v, error)) return false;
    im.camera_id = static_cast<std::uint32_t>(v);
    // The name is the rest of the line, so that it may hold blanks.
    std::size_t pos = 0;
    for (int k = 0; k < 9; ++k) {
      pos = r.line().find_first_not_of(" \t\r", pos);
      pos = r.line().find_first_of(" \t\r", pos);
    }
    pos = r.line().find_first_not_of(" \t\r", pos);
    im.name = r.line().substr(pos);
    while (!im.name.empty() && is_blank(im.name.back())) im.name.pop_back();
    if (!ids.insert(im.id).second) return fail(error, r.where() + "image " + std::to_string(im.id) + " appears twice");
    const int image_line = r.lineno();
    if (!r.next_line())
      return fail(error, name + ":" + std::to_string(image_line) +
                             ": the image's line of POINTS2D (X Y POINT3D_ID ...) is missing");
    const auto &p = r.tokens();
    if (!p.empty() && p[0][0] == '#')
      return fail(error, r.where() + "expected the POINTS2D of image " + std::to_string(im.id) + ", found a comment");
    if (p.size() % 3 != 0)
      return fail(error, r.where() + "POINTS2D come in triples X Y POINT3D_ID, found " + std::to_string(p.size()) +
                             " values");
    if (p.size() / 3 > kU32) return fail(error, r.where() + "too many POINTS2D");
    im.points.resize(p.size() / 3);
    for (std::size_t k = 0; k < im.points.size(); ++k) {
      Point2D &q = im.points[k];
      if (!real_field(r, 3 * k, "X", &q.x, error) || !real_field(r, 3 * k + 1, "Y", &q.y, error)) return false;
      if (p[3 * k + 2] == "-1") {
        q.point3d_id = kNoPoint;
      } else if (!parse_uint(p[3 * k + 2], kNoPoint - 1, &q.point3d_id)) {
        return fail(error, r.where() + "POINT3D_ID must be -1 or an integer from 0 to " +
                               std::to_string(kNoPoint - 1) + ", got '" + printable(p[3 * k + 2]) + "'");
      }
    }
    images.push_back(std::move(im));
  }
  *out = std::move(images);
  return true;
}

bool parse_points_text(const std::string &text, const std::string &name, std::vector<Point3D> *out,
                       std::string *error) {
  TextReader r(text, name);
  std::vector<Point3D> points;
  std::unordered_set<std::uint64_t> ids;
  while (r.next_data_line()) {
    const auto &t = r.tokens();
    if (t.size() < 8 || (t.size() - 8) % 2 != 0)
      return fail(error, r.where() + "expected POINT3D_ID X Y Z R G B ERROR and pairs IMAGE_ID POINT2D_IDX, found " +
                             std::to_string(t.size()) + " values");
    Point3D p;
    if (!uint_field(r, 0, "POINT3D_ID", kNoPoint - 1, &p.id, error)) return false;
    static const char *const kx[] = {"X", "Y", "Z"};
    static const char *const kc[] = {"R", "G", "B"};
    for (int k = 0; k < 3; ++k)
      if (!real_field(r, 1 + static_cast<std::size_t>(k), kx[k], &p.xyz[k], error)) return false;
    for (int k = 0; k < 3; ++k) {
      std::uint64_t v;
      if (!uint_field(r, 4 + static_cast<std::size_t>(k), kc[k], 255, &v, error)) return false;
      p.rgb[k] = static_cast<std::uint8_t>(v);
    }
    if (!real_field(r, 7, "ERROR", &p.error, error)) return false;
    p.track.resize((t.size() - 8) / 2);
    for (std::size_t k = 0; k < p.track.size(); ++k) {
      std::uint64_t v;
      if (!uint_field(r, 8 + 2 * k, "IMAGE_ID", kU32, &v, error)) return false;
      p.track[k].image_id = static_cast<std::uint32_t>(v);
      if (!uint_field(r, 9 + 2 * k, "POINT2D_IDX", kU32, &v, error)) return false;
      p.track[k].point2d_idx = static_cast<std::uint32_t>(v);
    }
    if (!ids.insert(p.id).second) return fail(error, r.where() + "point " + std::to_string(p.id) + " appears twice");
    points.push_back(std::move(p));
  }
  *out = std::move(points);
  return true;
}

Files format_text(const Model &model) {
  Files f;
  f.cameras = "# Camera list with one line of data per camera:\n"
              "#   CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[]\n"
              "# Number of cameras: " + std::to_string(model.cameras.size()) + "\n";
  for (const Camera &c : model.cameras) {
    f.cameras += std::to_string(c.id) + " " + kModels[c.model].name + " " + std::to_string(c.width) + " " +
                 std::to_string(c.height);
    for (double p : c.params) f.cameras += " " + g17(p);
    f.cameras += "\n";
  }
  f.images = "# Image list with two lines of data per image:\n"
             "#   IMAGE_ID, QW, QX, QY, QZ, TX, TY, TZ, CAMERA_ID, NAME\n"
             "#   POINTS2D[] as (X, Y, POINT3D_ID)\n"
             "# Number of images: " + std::to_string(model.images.size()) + "\n";
  for (const Image &im : model.images) {
    f.images += std::to_string(im.id);
    for (double v : im.q) f.images += " " + g17(v);
    for (double v : im.t) f.images += " " + g17(v);
    f.images += " " + std::to_string(im.camera_id) + " " + im.name + "\n";
    for (std::size_t k = 0; k < im.points.size(); ++k) {
      const Point2D &p = im.points[k];
      if (k) f.images += " ";
      f.images += g17(p.x) + " " + g17(p.y) + " " +
                  (p.point3d_id == kNoPoint ? std::string("-1") : std::to_string(p.point3d_id));
    }
    f.images += "\n";
  }
  f.points = "# 3D point list with one line of data per point:\n"
             "#   POINT3D_ID, X, Y, Z, R, G, B, ERROR, TRACK[] as (IMAGE_ID, POINT2D_IDX)\n"
             "# Number of points: " + std::to_string(model.points.size()) + "\n";
  for (const Point3D &p : model.points) {
    f.points += std::to_string(p.id);
    for (double v : p.xyz) f.points += " " + g17(v);
    for (std::uint8_t c : p.rgb) f.points += " " + std::to_string(c);
    f.points += " " + g17(p.error);
    for (const TrackElement &e : p.track)
      f.points += " " + std::to_string(e.image_id) + " " + std::to_string(e.point2d_idx);
    f.points += "\n";
  }
  return f;
}

}  // namespace sbaformats::colmap
