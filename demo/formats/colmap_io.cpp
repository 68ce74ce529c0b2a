// SPDX-License-Identifier: BSD-3-Clause
#include "formats/colmap_io.h"

#include <sys/stat.h>

#include <cerrno>
#include <cinttypes>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <map>
#include <set>
#include <unordered_map>
#include <unordered_set>

#include "formats/output_file.h"
#include "formats/text_tokens.h"

namespace colmap {

namespace {

using sbademo::g17;

struct ModelInfo {
  const char *name;
  int params;
  int focals;  // f, or fx and fy, leading the parameters
};
// Indexed by COLMAP's model id; ids 5 and up are COLMAP models without a counterpart here.
constexpr ModelInfo kModels[] = {
    {"SIMPLE_PINHOLE", 3, 1}, {"PINHOLE", 4, 2}, {"SIMPLE_RADIAL", 4, 1}, {"RADIAL", 5, 1}, {"OPENCV", 8, 2}};
constexpr int kNumModels = sizeof(kModels) / sizeof(kModels[0]);
// COLMAP's other models, named in the refusal so that the user knows what was found.
constexpr const char *kOtherModels[] = {"OPENCV_FISHEYE", "FULL_OPENCV", "FOV", "SIMPLE_RADIAL_FISHEYE",
                                        "RADIAL_FISHEYE", "THIN_PRISM_FISHEYE", "RAD_TAN_THIN_PRISM_FISHEYE"};
constexpr int kNumOtherModels = sizeof(kOtherModels) / sizeof(kOtherModels[0]);
constexpr const char *kAccepted = "SIMPLE_PINHOLE, PINHOLE, SIMPLE_RADIAL, RADIAL and OPENCV";

std::string unsupported_model(const std::string &model) {
  return "camera model " + model + " is not supported: sba's camera model expresses " + kAccepted;
}

// Why a camera's intrinsics are not a camera, empty when they are: a focal length must be
// positive, and fy / fx (the aspect ratio sba keeps) a number neither infinite nor zero;
// otherwise the solve would meet an infinite aspect ratio or a mirrored image, far from here.
std::string bad_intrinsics(const Camera &c) {
  const ModelInfo &m = kModels[c.model];
  const std::string camera = "camera " + std::to_string(c.id) + ": " + m.name + "'s ";
  static const char *const kFocal[2][2] = {{"f", ""}, {"fx", "fy"}};
  for (int k = 0; k < m.focals; ++k) {
    const double f = c.params[static_cast<std::size_t>(k)];
    if (!(f > 0)) return camera + kFocal[m.focals - 1][k] + " must be positive, got " + g17(f);
  }
  if (m.focals == 2) {
    const double ar = c.params[1] / c.params[0];
    if (!std::isfinite(ar) || ar == 0) return camera + "aspect ratio fy / fx overflows or underflows";
  }
  return {};
}

std::string printable(const std::string &s) {
  std::string out;
  for (char c : s) {
    if (out.size() >= 40) return out + "...";
    out += (c >= 32 && c < 127) ? c : '?';
  }
  return out;
}

// ---- text ----

// What separates values: a carriage return too, so that a CRLF file or a stray '\r' does
// not end up inside a value (or as an image name that a rewrite would lose).
bool is_blank(char c) { return c == ' ' || c == '\t' || c == '\r'; }

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

bool fail(std::string *error, const std::string &msg) {
  if (error) *error = msg;
  return false;
}

// A finite decimal number, the whole token.
bool parse_real(const std::string &tok, double *out) {
  double v;
  if (!sbademo::decimal_number(tok, &v) || !std::isfinite(v)) return false;
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

const char *camera_model_name(int model) {
  return model >= 0 && model < kNumModels ? kModels[model].name : nullptr;
}

int camera_model_params(int model) { return model >= 0 && model < kNumModels ? kModels[model].params : 0; }

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

// ---- binary (little-endian) ----

namespace {

class ByteReader {
 public:
  ByteReader(const std::string &bytes, const std::string &name) : b_(bytes), name_(name) {}

  std::size_t remaining() const { return b_.size() - pos_; }
  std::string where(std::size_t at) const { return name_ + ": byte " + std::to_string(at) + ": "; }
  std::size_t pos() const { return pos_; }

  bool u64(std::uint64_t *v, const char *what, std::string *error) { return uint(8, v, what, error); }
  bool u32(std::uint32_t *v, const char *what, std::string *error) {
    std::uint64_t w;
    if (!uint(4, &w, what, error)) return false;
    *v = static_cast<std::uint32_t>(w);
    return true;
  }
  bool u8(std::uint8_t *v, const char *what, std::string *error) {
    std::uint64_t w;
    if (!uint(1, &w, what, error)) return false;
    *v = static_cast<std::uint8_t>(w);
    return true;
  }
  bool real(double *v, const char *what, std::string *error) {
    const std::size_t at = pos_;
    std::uint64_t w;
    if (!uint(8, &w, what, error)) return false;
    std::memcpy(v, &w, sizeof w);
    if (!std::isfinite(*v)) return fail(error, where(at) + what + " is not a finite number");
    return true;
  }
  // A NUL-terminated string.
  bool cstring(std::string *s, const char *what, std::string *error) {
    const std::size_t end = b_.find('\0', pos_);
    if (end == std::string::npos) return fail(error, where(pos_) + "the file ends inside " + what);
    s->assign(b_, pos_, end - pos_);
    pos_ = end + 1;
    return true;
  }
  // A count of records of at least min_bytes each, checked against what is left.
  bool count(std::uint64_t *n, std::size_t min_bytes, const char *what, std::string *error) {
    const std::size_t at = pos_;
    if (!u64(n, what, error)) return false;
    if (*n > remaining() / min_bytes)
      return fail(error, where(at) + what + " is " + std::to_string(*n) + ", more than the " +
                             std::to_string(remaining()) + " bytes left can hold");
    return true;
  }
  bool at_end(std::string *error) const {
    if (pos_ == b_.size()) return true;
    return fail(error, where(pos_) + std::to_string(remaining()) + " bytes after the last record");
  }

 private:
  bool uint(int bytes, std::uint64_t *v, const char *what, std::string *error) {
    if (remaining() < static_cast<std::size_t>(bytes))
      return fail(error, where(pos_) + "the file ends inside " + what);
    std::uint64_t w = 0;
    for (int k = bytes - 1; k >= 0; --k) w = (w << 8) | static_cast<unsigned char>(b_[pos_ + static_cast<std::size_t>(k)]);
    pos_ += static_cast<std::size_t>(bytes);
    *v = w;
    return true;
  }

  const std::string &b_;
  const std::string &name_;
  std::size_t pos_ = 0;
};

void put_uint(std::string *out, std::uint64_t v, int bytes) {
  for (int k = 0; k < bytes; ++k) out->push_back(static_cast<char>((v >> (8 * k)) & 0xff));
}
void put_real(std::string *out, double v) {
  std::uint64_t w;
  std::memcpy(&w, &v, sizeof w);
  put_uint(out, w, 8);
}

}  // namespace

bool parse_cameras_binary(const std::string &bytes, const std::string &name, std::vector<Camera> *out,
                          std::string *error) {
  ByteReader r(bytes, name);
  std::uint64_t n;
  if (!r.count(&n, 24, "the number of cameras", error)) return false;
  std::vector<Camera> cams;
  cams.reserve(static_cast<std::size_t>(n));
  std::unordered_set<std::uint32_t> ids;
  for (std::uint64_t i = 0; i < n; ++i) {
    Camera c;
    const std::size_t at = r.pos();
    std::uint32_t model;
    if (!r.u32(&c.id, "CAMERA_ID", error) || !r.u32(&model, "MODEL_ID", error)) return false;
    const int m = static_cast<int>(static_cast<std::int32_t>(model));
    if (m < 0 || m >= kNumModels) {
      if (m >= kNumModels && m < kNumModels + kNumOtherModels)
        return fail(error, r.where(at) + "camera " + std::to_string(c.id) + ": " +
                               unsupported_model(kOtherModels[m - kNumModels]));
      return fail(error, r.where(at) + "camera " + std::to_string(c.id) + ": unknown camera model id " +
                             std::to_string(m));
    }
    c.model = m;
    if (!r.u64(&c.width, "WIDTH", error) || !r.u64(&c.height, "HEIGHT", error)) return false;
    c.params.resize(static_cast<std::size_t>(kModels[m].params));
    for (double &p : c.params)
      if (!r.real(&p, "a camera parameter", error)) return false;
    if (const std::string why = bad_intrinsics(c); !why.empty()) return fail(error, r.where(at) + why);
    if (!ids.insert(c.id).second)
      return fail(error, r.where(at) + "camera " + std::to_string(c.id) + " appears twice");
    cams.push_back(std::move(c));
  }
  if (!r.at_end(error)) return false;
  *out = std::move(cams);
  return true;
}

bool parse_images_binary(const std::string &bytes, const std::string &name, std::vector<Image> *out,
                         std::string *error) {
  ByteReader r(bytes, name);
  std::uint64_t n;
  // image id, 7 doubles, camera id, an empty name, no points: 4 + 56 + 4 + 1 + 8 bytes.
  if (!r.count(&n, 73, "the number of images", error)) return false;
  std::vector<Image> images;
  images.reserve(static_cast<std::size_t>(n));
  std::unordered_set<std::uint32_t> ids;
  for (std::uint64_t i = 0; i < n; ++i) {
    Image im;
    const std::size_t at = r.pos();
    if (!r.u32(&im.id, "IMAGE_ID", error)) return false;
    for (double &v : im.q)
      if (!r.real(&v, "a quaternion component", error)) return false;
    for (double &v : im.t)
      if (!r.real(&v, "a translation component", error)) return false;
    if (im.q[0] == 0 && im.q[1] == 0 && im.q[2] == 0 && im.q[3] == 0)
      return fail(error, r.where(at) + "image " + std::to_string(im.id) + ": the quaternion is zero");
    if (!r.u32(&im.camera_id, "CAMERA_ID", error) || !r.cstring(&im.name, "the image name", error)) return false;
    // The text format keeps a name on one line, between blanks that its reader trims: a name
    // it cannot hold is refused here, not lost or made unreadable by a rewrite as text.
    if (im.name.empty() || im.name.find_first_of("\r\n") != std::string::npos || is_blank(im.name.front()) ||
        is_blank(im.name.back()))
      return fail(error, r.where(at) + "image " + std::to_string(im.id) +
                             ": the name is empty, holds a line break or begins or ends with a blank, which the "
                             "text format cannot hold");
    std::uint64_t np;
    if (!r.count(&np, 24, "the number of POINTS2D", error)) return false;
    im.points.resize(static_cast<std::size_t>(np));
    for (Point2D &p : im.points)
      if (!r.real(&p.x, "X", error) || !r.real(&p.y, "Y", error) || !r.u64(&p.point3d_id, "POINT3D_ID", error))
        return false;
    if (!ids.insert(im.id).second) return fail(error, r.where(at) + "image " + std::to_string(im.id) + " appears twice");
    images.push_back(std::move(im));
  }
  if (!r.at_end(error)) return false;
  *out = std::move(images);
  return true;
}

bool parse_points_binary(const std::string &bytes, const std::string &name, std::vector<Point3D> *out,
                         std::string *error) {
  ByteReader r(bytes, name);
  std::uint64_t n;
  // id, xyz, rgb, error, track length: 8 + 24 + 3 + 8 + 8 bytes.
  if (!r.count(&n, 51, "the number of points", error)) return false;
  std::vector<Point3D> points;
  points.reserve(static_cast<std::size_t>(n));
  std::unordered_set<std::uint64_t> ids;
  for (std::uint64_t i = 0; i < n; ++i) {
    Point3D p;
    const std::size_t at = r.pos();
    if (!r.u64(&p.id, "POINT3D_ID", error)) return false;
    if (p.id == kNoPoint) return fail(error, r.where(at) + "POINT3D_ID -1 is not an identifier");
    for (double &v : p.xyz)
      if (!r.real(&v, "a coordinate", error)) return false;
    for (std::uint8_t &c : p.rgb)
      if (!r.u8(&c, "a color", error)) return false;
    if (!r.real(&p.error, "ERROR", error)) return false;
    std::uint64_t nt;
    if (!r.count(&nt, 8, "the track length", error)) return false;
    p.track.resize(static_cast<std::size_t>(nt));
    for (TrackElement &e : p.track)
      if (!r.u32(&e.image_id, "IMAGE_ID", error) || !r.u32(&e.point2d_idx, "POINT2D_IDX", error)) return false;
    if (!ids.insert(p.id).second) return fail(error, r.where(at) + "point " + std::to_string(p.id) + " appears twice");
    points.push_back(std::move(p));
  }
  if (!r.at_end(error)) return false;
  *out = std::move(points);
  return true;
}

bool check_model(const Model &model, const std::string &name, std::string *error) {
  const std::string where = name + ": ";
  std::unordered_set<std::uint32_t> cameras;
  for (const Camera &c : model.cameras) cameras.insert(c.id);
  std::unordered_map<std::uint32_t, const Image *> images;
  std::unordered_map<std::uint64_t, const Point3D *> points;
  for (const Point3D &p : model.points) points.emplace(p.id, &p);
  for (const Image &im : model.images) {
    images.emplace(im.id, &im);
    if (!cameras.count(im.camera_id))
      return fail(error, where + "image " + std::to_string(im.id) + " uses camera " + std::to_string(im.camera_id) +
                             ", which cameras does not hold");
  }
  // Each observation that names a point is claimed by exactly one track element.
  std::size_t observations = 0;
  for (const Image &im : model.images) {
    std::unordered_set<std::uint64_t> seen;
    for (std::size_t k = 0; k < im.points.size(); ++k) {
      const std::uint64_t pid = im.points[k].point3d_id;
      if (pid == kNoPoint) continue;
      ++observations;
      if (!points.count(pid))
        return fail(error, where + "image " + std::to_string(im.id) + " POINTS2D " + std::to_string(k) +
                               " names point " + std::to_string(pid) + ", which points3D does not hold");
      if (!seen.insert(pid).second)
        return fail(error, where + "image " + std::to_string(im.id) + " sees point " + std::to_string(pid) +
                               " twice: sba takes one observation per point and image");
    }
  }
  std::size_t elements = 0;
  for (const Point3D &p : model.points) {
    if (p.track.empty()) return fail(error, where + "point " + std::to_string(p.id) + " has an empty track");
    std::set<std::pair<std::uint32_t, std::uint32_t>> pairs;
    for (const TrackElement &e : p.track) {
      const auto it = images.find(e.image_id);
      if (it == images.end())
        return fail(error, where + "point " + std::to_string(p.id) + " is seen in image " +
                               std::to_string(e.image_id) + ", which images does not hold");
      const Image &im = *it->second;
      if (e.point2d_idx >= im.points.size())
        return fail(error, where + "point " + std::to_string(p.id) + ": POINT2D_IDX " +
                               std::to_string(e.point2d_idx) + " is out of range for image " +
                               std::to_string(im.id) + " (" + std::to_string(im.points.size()) + " POINTS2D)");
      if (im.points[e.point2d_idx].point3d_id != p.id)
        return fail(error, where + "point " + std::to_string(p.id) + " lists POINTS2D " +
                               std::to_string(e.point2d_idx) + " of image " + std::to_string(im.id) +
                               ", which does not name it");
      if (!pairs.insert({e.image_id, e.point2d_idx}).second)
        return fail(error, where + "point " + std::to_string(p.id) + " lists POINTS2D " +
                               std::to_string(e.point2d_idx) + " of image " + std::to_string(im.id) + " twice");
      ++elements;
    }
  }
  // Every element points back (checked above) and none repeats, so equal counts mean every
  // observation is listed.
  if (elements != observations)
    return fail(error, where + "the tracks of points3D list " + std::to_string(elements) +
                           " observations, the images name points in " + std::to_string(observations));
  return true;
}

// ---- files ----

bool read_rest(std::FILE *f, const std::string &path, bool text, std::string *out, std::string *error) {
  char buf[1 << 16];
  std::size_t got;
  while ((got = std::fread(buf, 1, sizeof buf, f)) > 0) {
    if (text && std::memchr(buf, '\0', got)) return fail(error, path + ": a NUL byte: not a text file");
    out->append(buf, got);
  }
  if (std::ferror(f)) return fail(error, path + ": read error");
  return true;
}

bool read_whole_file(const std::string &path, bool text, std::string *out, std::string *error) {
  std::FILE *f = std::fopen(path.c_str(), "rb");
  if (!f) return fail(error, path + ": cannot open: " + std::strerror(errno));
  // fopen opens a directory for reading, whose reading then fails without saying why.
  struct stat st {};
  if (::fstat(fileno(f), &st) == 0 && S_ISDIR(st.st_mode)) {
    std::fclose(f);
    return fail(error, path + ": is a directory");
  }
  std::string data;
  const bool read = read_rest(f, path, text, &data, error);
  std::fclose(f);
  if (!read) return false;
  *out = std::move(data);
  return true;
}

namespace {

// A model's files, the cameras first.
constexpr const char *kFileNames[] = {"cameras", "images", "points3D"};

const char *extension(Encoding encoding) { return encoding == Encoding::Text ? ".txt" : ".bin"; }

std::string slashed(const std::string &dir) { return dir.empty() || dir.back() == '/' ? dir : dir + "/"; }

// A model's file: a regular file, or its reading would never end (/dev/zero) or fail
// without saying why (a directory).
bool read_model_file(const std::string &path, bool text, std::string *out, std::string *error) {
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) return fail(error, path + ": cannot open: " + std::strerror(errno));
  if (S_ISDIR(st.st_mode)) return fail(error, path + ": is a directory");
  if (!S_ISREG(st.st_mode)) return fail(error, path + ": not a regular file");
  return read_whole_file(path, text, out, error);
}

}  // namespace

bool model_encoding(const std::string &dir, Encoding *out, std::string *error) {
  for (Encoding e : {Encoding::Text, Encoding::Binary}) {
    const std::string path = slashed(dir) + "cameras" + extension(e);
    struct stat st {};
    if (::stat(path.c_str(), &st) == 0) {
      *out = e;
      return true;
    }
    // A symbolic link loop or a directory that cannot be searched is said as it is.
    if (errno != ENOENT && errno != ENOTDIR) return fail(error, path + ": cannot open: " + std::strerror(errno));
  }
  return fail(error, dir + ": no COLMAP model (cameras.txt or cameras.bin)");
}

bool read_model(const std::string &dir, Model *out, Encoding *encoding, std::string *error) {
  Encoding enc;
  if (!model_encoding(dir, &enc, error)) return false;
  const bool text = enc == Encoding::Text;
  const std::string pc = slashed(dir) + "cameras" + extension(enc), pi = slashed(dir) + "images" + extension(enc),
                    pp = slashed(dir) + "points3D" + extension(enc);
  Model m;
  std::string content;
  if (!read_model_file(pc, text, &content, error)) return false;
  if (!(text ? parse_cameras_text : parse_cameras_binary)(content, pc, &m.cameras, error)) return false;
  if (!read_model_file(pi, text, &content, error)) return false;
  if (!(text ? parse_images_text : parse_images_binary)(content, pi, &m.images, error)) return false;
  if (!read_model_file(pp, text, &content, error)) return false;
  if (!(text ? parse_points_text : parse_points_binary)(content, pp, &m.points, error)) return false;
  if (!check_model(m, dir, error)) return false;
  *out = std::move(m);
  if (encoding) *encoding = enc;
  return true;
}

Files format_model(const Model &model, Encoding encoding) {
  Files f;
  if (encoding == Encoding::Binary) {
    put_uint(&f.cameras, model.cameras.size(), 8);
    for (const Camera &c : model.cameras) {
      put_uint(&f.cameras, c.id, 4);
      put_uint(&f.cameras, static_cast<std::uint32_t>(c.model), 4);
      put_uint(&f.cameras, c.width, 8);
      put_uint(&f.cameras, c.height, 8);
      for (double p : c.params) put_real(&f.cameras, p);
    }
    put_uint(&f.images, model.images.size(), 8);
    for (const Image &im : model.images) {
      put_uint(&f.images, im.id, 4);
      for (double v : im.q) put_real(&f.images, v);
      for (double v : im.t) put_real(&f.images, v);
      put_uint(&f.images, im.camera_id, 4);
      f.images += im.name;
      f.images.push_back('\0');
      put_uint(&f.images, im.points.size(), 8);
      for (const Point2D &p : im.points) {
        put_real(&f.images, p.x);
        put_real(&f.images, p.y);
        put_uint(&f.images, p.point3d_id, 8);
      }
    }
    put_uint(&f.points, model.points.size(), 8);
    for (const Point3D &p : model.points) {
      put_uint(&f.points, p.id, 8);
      for (double v : p.xyz) put_real(&f.points, v);
      for (std::uint8_t c : p.rgb) put_uint(&f.points, c, 1);
      put_real(&f.points, p.error);
      put_uint(&f.points, p.track.size(), 8);
      for (const TrackElement &e : p.track) {
        put_uint(&f.points, e.image_id, 4);
        put_uint(&f.points, e.point2d_idx, 4);
      }
    }
    return f;
  }
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

namespace {

// dir as a directory to write a model into: made when missing (*made then true).
bool make_directory(const std::string &dir, bool *made, std::string *error) {
  struct stat st {};
  *made = false;
  if (::stat(dir.c_str(), &st) == 0) return S_ISDIR(st.st_mode) || fail(error, dir + ": not a directory");
  if (::mkdir(dir.c_str(), 0777) != 0)
    return fail(error, dir + ": cannot create the directory: " + std::strerror(errno));
  *made = true;
  return true;
}

}  // namespace

bool model_writable(const std::string &dir, Encoding encoding, std::string *error) {
  bool made;
  if (!make_directory(dir, &made, error)) return false;
  // A directory made here is removed again: it is the write that creates it.
  if (made) {
    ::rmdir(dir.c_str());
    return true;
  }
  std::string why;
  for (const char *name : kFileNames) {
    const std::string path = slashed(dir) + name + extension(encoding);
    if (!sbademo::probe_writable(path, &why)) return fail(error, path + ": " + why);
  }
  return true;
}

bool write_model(const std::string &dir, const Model &model, Encoding encoding, std::string *error) {
  bool made;
  if (!make_directory(dir, &made, error)) return false;
  const Files files = format_model(model, encoding);
  const std::string *content[] = {&files.cameras, &files.images, &files.points};
  std::string paths[3];
  for (int k = 0; k < 3; ++k) paths[k] = slashed(dir) + kFileNames[k] + extension(encoding);
  // The model is replaced whole or not at all: its three files are renamed onto their names
  // only once all three are written and closed (a full disk at the second leaves the model
  // as it was, the temporaries removed with `out`).
  sbademo::OutputFile out[3];
  for (int k = 0; k < 3; ++k)
    if (!sbademo::write_closed(paths[k], *content[k], &out[k], error)) return false;
  for (int k = 0; k < 3; ++k) {
    std::string why;
    if (!out[k].publish(&why)) return fail(error, paths[k] + ": " + why);
  }
  // The other encoding's model goes, or a reader could take it for this one; its cameras file
  // first, without which no reader takes the other two for a model.
  const Encoding other = encoding == Encoding::Text ? Encoding::Binary : Encoding::Text;
  for (const char *name : kFileNames) {
    const std::string stale = slashed(dir) + name + extension(other);
    if (std::remove(stale.c_str()) != 0 && errno != ENOENT)
      return fail(error, stale + ": cannot remove the model of the other format: " + std::strerror(errno));
  }
  return true;
}

}  // namespace colmap
