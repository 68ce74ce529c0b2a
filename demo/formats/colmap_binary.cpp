// SPDX-License-Identifier: BSD-3-Clause
// COLMAP's binary format (little-endian): cameras.bin, images.bin and points3D.bin.
#include <cassert>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

#include "formats/colmap_io_impl.h"

namespace sbaformats::colmap {

namespace {

class ByteReader {
 public:
  ByteReader(const std::string &bytes, const std::string &name) : b_(bytes), name_(name) {}

  std::size_t remaining() const { return b_.size() - pos_; }
  std::string where(std::size_t at) const { return name_ + ": byte " + std::to_string(at) + ": "; }
  std::size_t pos() const { return pos_; }

  bool u64(std::uint64_t *v, const char *what, std::string *error) { return uint<8>(v, what, error); }
  bool u32(std::uint32_t *v, const char *what, std::string *error) {
    std::uint64_t w;
    if (!uint<4>(&w, what, error)) return false;
    *v = static_cast<std::uint32_t>(w);
    return true;
  }
  bool u8(std::uint8_t *v, const char *what, std::string *error) {
    std::uint64_t w;
    if (!uint<1>(&w, what, error)) return false;
    *v = static_cast<std::uint8_t>(w);
    return true;
  }
  bool real(double *v, const char *what, std::string *error) {
    const std::size_t at = pos_;
    std::uint64_t w;
    if (!uint<8>(&w, what, error)) return false;
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
  // The byte count is a template argument so that the compiler sees a fixed little-endian
  // load, which it turns into one load instruction on a little-endian machine.
  template <int Bytes>
  bool uint(std::uint64_t *v, const char *what, std::string *error) {
    if (remaining() < static_cast<std::size_t>(Bytes))
      return fail(error, where(pos_) + "the file ends inside " + what);
    const unsigned char *p = reinterpret_cast<const unsigned char *>(b_.data()) + pos_;
    std::uint64_t w = 0;
    for (int k = 0; k < Bytes; ++k) w |= std::uint64_t{p[k]} << (8 * k);
    pos_ += static_cast<std::size_t>(Bytes);
    *v = w;
    return true;
  }

  const std::string &b_;
  const std::string &name_;
  std::size_t pos_ = 0;
};

// Little-endian values into a buffer sized beforehand to what they fill exactly: no check of
// the room left on each byte, as appending to a string would make.
class ByteWriter {
 public:
  ByteWriter(std::string *out, std::size_t size) : out_(out) {
    out->resize(size);
    p_ = &(*out)[0];
  }
  ByteWriter(const ByteWriter &) = delete;
  ByteWriter &operator=(const ByteWriter &) = delete;
  // Every byte of the size given was written (the sizes below agree with the records).
  ~ByteWriter() { assert(p_ == out_->data() + out_->size()); }

  template <int Bytes>
  void uint(std::uint64_t v) {
    for (int k = 0; k < Bytes; ++k) p_[k] = static_cast<char>((v >> (8 * k)) & 0xff);
    p_ += Bytes;
  }
  void real(double v) {
    std::uint64_t w;
    std::memcpy(&w, &v, sizeof w);
    uint<8>(w);
  }
  // s and its terminating NUL.
  void cstring(const std::string &s) {
    std::memcpy(p_, s.data(), s.size());
    p_[s.size()] = '\0';
    p_ += s.size() + 1;
  }

 private:
  std::string *out_;
  char *p_;
};

// The bytes of each file, for ByteWriter.
std::size_t cameras_bytes(const Model &model) {
  std::size_t n = 8;
  for (const Camera &c : model.cameras) n += 24 + 8 * c.params.size();
  return n;
}
std::size_t images_bytes(const Model &model) {
  std::size_t n = 8;
  for (const Image &im : model.images) n += 4 + 56 + 4 + im.name.size() + 1 + 8 + 24 * im.points.size();
  return n;
}
std::size_t points_bytes(const Model &model) {
  std::size_t n = 8;
  for (const Point3D &p : model.points) n += 8 + 24 + 3 + 8 + 8 + 8 * p.track.size();
  return n;
}

}  // namespace

bool parse_cameras_binary(const std::string &bytes, const std::string &name, std::vector<Camera> *out,
                          std::string *error) {
  ByteReader r(bytes, name);
  std::uint64_t n;
  if (!r.count(&n, 24, "the number of cameras", error)) return false;
  std::vector<Camera> cams;
  cams.reserve(static_cast<std::size_t>(n));
  IdIndex ids(static_cast<std::size_t>(n));
  for (std::uint64_t i = 0; i < n; ++i) {
    Camera c;
    const std::size_t at = r.pos();
    std::uint32_t model;
    if (!r.u32(&c.id, "CAMERA_ID", error) || !r.u32(&model, "MODEL_ID", error)) return false;
    const int m = static_cast<int>(static_cast<std::int32_t>(model));
    if (m < 0 || m >= kNumModels)
      return fail(error, r.where(at) + "camera " + std::to_string(c.id) + ": unknown camera model id " +
                             std::to_string(m));
    c.model = m;
    if (!r.u64(&c.width, "WIDTH", error) || !r.u64(&c.height, "HEIGHT", error)) return false;
    c.params.resize(static_cast<std::size_t>(kModels[m].params));
    for (double &p : c.params)
      if (!r.real(&p, "a camera parameter", error)) return false;
    if (const std::string why = bad_intrinsics(c); !why.empty()) return fail(error, r.where(at) + why);
    if (!ids.insert(c.id, i))
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
  IdIndex ids(static_cast<std::size_t>(n));
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
    if (!ids.insert(im.id, i)) return fail(error, r.where(at) + "image " + std::to_string(im.id) + " appears twice");
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
  IdIndex ids(static_cast<std::size_t>(n));
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
    if (!ids.insert(p.id, i)) return fail(error, r.where(at) + "point " + std::to_string(p.id) + " appears twice");
    points.push_back(std::move(p));
  }
  if (!r.at_end(error)) return false;
  *out = std::move(points);
  return true;
}

Files format_binary(const Model &model) {
  Files f;
  {
    ByteWriter w(&f.cameras, cameras_bytes(model));
    w.uint<8>(model.cameras.size());
    for (const Camera &c : model.cameras) {
      w.uint<4>(c.id);
      w.uint<4>(static_cast<std::uint32_t>(c.model));
      w.uint<8>(c.width);
      w.uint<8>(c.height);
      for (double p : c.params) w.real(p);
    }
  }
  {
    ByteWriter w(&f.images, images_bytes(model));
    w.uint<8>(model.images.size());
    for (const Image &im : model.images) {
      w.uint<4>(im.id);
      for (double v : im.q) w.real(v);
      for (double v : im.t) w.real(v);
      w.uint<4>(im.camera_id);
      w.cstring(im.name);
      w.uint<8>(im.points.size());
      for (const Point2D &p : im.points) {
        w.real(p.x);
        w.real(p.y);
        w.uint<8>(p.point3d_id);
      }
    }
  }
  {
    ByteWriter w(&f.points, points_bytes(model));
    w.uint<8>(model.points.size());
    for (const Point3D &p : model.points) {
      w.uint<8>(p.id);
      for (double v : p.xyz) w.real(v);
      for (std::uint8_t c : p.rgb) w.uint<1>(c);
      w.real(p.error);
      w.uint<8>(p.track.size());
      for (const TrackElement &e : p.track) {
        w.uint<4>(e.image_id);
        w.uint<4>(e.point2d_idx);
      }
    }
  }
  return f;
}

}  // namespace sbaformats::colmap
