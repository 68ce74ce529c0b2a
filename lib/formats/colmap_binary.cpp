// SPDX-License-Identifier: BSD-3-Clause
// COLMAP's binary format (little-endian): cameras.bin, images.bin, points3D.bin, rigs.bin and
// frames.bin.
#include <array>
#include <cassert>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

#include "formats/colmap_check.h"
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
  // The record read from byte `at` keeps the rules of colmap_check.h: false with its byte and
  // why.
  bool keeps_rules(std::size_t at, const std::string &why, std::string *error) const {
    return why.empty() || fail(error, where(at) + why);
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
    // Worded as the text reader words it, with the value in place of the token.
    if (!std::isfinite(*v))
      return fail(error, where(at) + what + " must be a finite number, got " +
                             (std::isnan(*v) ? "nan" : *v > 0 ? "inf" : "-inf"));
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
  // A count of records of at least min_bytes each, checked against what is left: a uint64, or
  // (count32) a uint32.
  bool count(std::uint64_t *n, std::size_t min_bytes, const char *what, std::string *error) {
    const std::size_t at = pos_;
    return u64(n, what, error) && room(at, *n, min_bytes, what, error);
  }
  bool count32(std::uint64_t *n, std::size_t min_bytes, const char *what, std::string *error) {
    const std::size_t at = pos_;
    std::uint32_t v;
    if (!u32(&v, what, error)) return false;
    *n = v;
    return room(at, *n, min_bytes, what, error);
  }
  // A sensor type (an int32), one of COLMAP's: of names its record in the message.
  bool sensor_type(SensorType *type, const std::string &of, std::string *error) {
    const std::size_t at = pos_;
    std::uint32_t v;
    if (!u32(&v, "SENSOR_TYPE", error)) return false;
    const std::int32_t t = static_cast<std::int32_t>(v);
    if (t != static_cast<std::int32_t>(SensorType::Camera) && t != static_cast<std::int32_t>(SensorType::Imu))
      return fail(error, where(at) + of + "unknown sensor type " + std::to_string(t));
    *type = static_cast<SensorType>(t);
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

  bool room(std::size_t at, std::uint64_t n, std::size_t min_bytes, const char *what,
            std::string *error) const {
    if (n <= remaining() / min_bytes) return true;
    return fail(error, where(at) + what + " is " + std::to_string(n) + ", more than the " +
                           std::to_string(remaining()) + " bytes left can hold");
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

// QW QX QY QZ TX TY TZ.
bool read_pose(ByteReader *r, std::array<double, 4> *q, std::array<double, 3> *t, std::string *error) {
  for (double &v : *q)
    if (!r->real(&v, "a quaternion component", error)) return false;
  for (double &v : *t)
    if (!r->real(&v, "a translation component", error)) return false;
  return true;
}

void write_pose(ByteWriter *w, const std::array<double, 4> &q, const std::array<double, 3> &t) {
  for (double v : q) w->real(v);
  for (double v : t) w->real(v);
}

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
std::size_t rigs_bytes(const Model &model) {
  std::size_t n = 8;
  for (const Rig &rig : model.rigs) {
    n += 8;
    for (std::size_t k = 0; k < rig.sensors.size(); ++k)
      n += k == 0 ? 8 : 9 + (rig.sensors[k].has_pose ? 56 : 0);
  }
  return n;
}
std::size_t frames_bytes(const Model &model) {
  std::size_t n = 8;
  for (const Frame &f : model.frames) n += 8 + 56 + 4 + 16 * f.data.size();
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
    // COLMAP's int32: the model's parameter count tells how many values follow.
    c.model = static_cast<int>(static_cast<std::int32_t>(model));
    if (!r.keeps_rules(at, camera_head_problem(c), error)) return false;
    if (!r.u64(&c.width, "WIDTH", error) || !r.u64(&c.height, "HEIGHT", error)) return false;
    c.params.resize(static_cast<std::size_t>(camera_model_params(c.model)));
    for (double &p : c.params)
      if (!r.real(&p, "a camera parameter", error)) return false;
    if (!r.keeps_rules(at, camera_problem(c), error)) return false;
    if (!ids.insert(c.id, i)) return fail(error, r.where(at) + appears_twice("camera", c.id));
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
    if (!read_pose(&r, &im.q, &im.t, error)) return false;
    if (!r.u32(&im.camera_id, "CAMERA_ID", error) || !r.cstring(&im.name, "the image name", error)) return false;
    // A name the text format cannot hold is refused too (image_problem), not lost or made
    // unreadable by a rewrite as text.
    if (!r.keeps_rules(at, image_problem(im), error)) return false;
    std::uint64_t np;
    if (!r.count(&np, 24, "the number of POINTS2D", error)) return false;
    im.points.resize(static_cast<std::size_t>(np));
    for (Point2D &p : im.points)
      if (!r.real(&p.x, "X", error) || !r.real(&p.y, "Y", error) || !r.u64(&p.point3d_id, "POINT3D_ID", error))
        return false;
    if (!ids.insert(im.id, i)) return fail(error, r.where(at) + appears_twice("image", im.id));
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
    if (!r.keeps_rules(at, point_problem(p), error)) return false;
    if (!ids.insert(p.id, i)) return fail(error, r.where(at) + appears_twice("point", p.id));
    points.push_back(std::move(p));
  }
  if (!r.at_end(error)) return false;
  *out = std::move(points);
  return true;
}

bool parse_rigs_binary(const std::string &bytes, const std::string &name, std::vector<Rig> *out,
                       std::string *error) {
  ByteReader r(bytes, name);
  std::uint64_t n;
  // rig id and sensor count: 8 bytes.
  if (!r.count(&n, 8, "the number of rigs", error)) return false;
  std::vector<Rig> rigs;
  rigs.reserve(static_cast<std::size_t>(n));
  IdIndex ids(static_cast<std::size_t>(n));
  for (std::uint64_t i = 0; i < n; ++i) {
    Rig rig;
    const std::size_t at = r.pos();
    std::uint64_t ns;
    if (!r.u32(&rig.id, "RIG_ID", error)) return false;
    const std::string of_rig = "rig " + std::to_string(rig.id) + ": ";
    // The reference sensor takes 8 bytes, each other one 9 or 65.
    if (!r.count32(&ns, 8, "the number of sensors", error)) return false;
    rig.sensors.resize(static_cast<std::size_t>(ns));
    for (std::size_t k = 0; k < rig.sensors.size(); ++k) {
      RigSensor &s = rig.sensors[k];
      const std::size_t sensor_at = r.pos();
      if (!r.sensor_type(&s.sensor.type, of_rig, error) || !r.u32(&s.sensor.id, "SENSOR_ID", error))
        return false;
      if (k == 0) continue;  // the reference sensor: no pose
      std::uint8_t has_pose;
      if (!r.u8(&has_pose, "HAS_POSE", error)) return false;
      if (has_pose > 1)
        return fail(error, r.where(sensor_at) + of_rig + "HAS_POSE of " + sensor_name(s.sensor) +
                               " must be 0 or 1, got " + std::to_string(has_pose));
      s.has_pose = has_pose == 1;
      if (s.has_pose && !read_pose(&r, &s.sensor_from_rig.q, &s.sensor_from_rig.t, error)) return false;
    }
    if (!r.keeps_rules(at, rig_problem(rig), error)) return false;
    if (!ids.insert(rig.id, i)) return fail(error, r.where(at) + appears_twice("rig", rig.id));
    rigs.push_back(std::move(rig));
  }
  if (!r.at_end(error)) return false;
  *out = std::move(rigs);
  return true;
}

bool parse_frames_binary(const std::string &bytes, const std::string &name, std::vector<Frame> *out,
                         std::string *error) {
  ByteReader r(bytes, name);
  std::uint64_t n;
  // frame id, rig id, 7 doubles, no data: 4 + 4 + 56 + 4 bytes.
  if (!r.count(&n, 68, "the number of frames", error)) return false;
  std::vector<Frame> frames;
  frames.reserve(static_cast<std::size_t>(n));
  IdIndex ids(static_cast<std::size_t>(n));
  for (std::uint64_t i = 0; i < n; ++i) {
    Frame f;
    const std::size_t at = r.pos();
    if (!r.u32(&f.id, "FRAME_ID", error) || !r.u32(&f.rig_id, "RIG_ID", error) ||
        !read_pose(&r, &f.rig_from_world.q, &f.rig_from_world.t, error))
      return false;
    std::uint64_t nd;
    const std::string of_frame = "frame " + std::to_string(f.id) + ": ";
    if (!r.count32(&nd, 16, "the number of data ids", error)) return false;
    f.data.resize(static_cast<std::size_t>(nd));
    for (DataId &d : f.data)
      if (!r.sensor_type(&d.sensor.type, of_frame, error) || !r.u32(&d.sensor.id, "SENSOR_ID", error) ||
          !r.u64(&d.id, "DATA_ID", error))
        return false;
    if (!r.keeps_rules(at, frame_problem(f), error)) return false;
    if (!ids.insert(f.id, i)) return fail(error, r.where(at) + appears_twice("frame", f.id));
    frames.push_back(std::move(f));
  }
  if (!r.at_end(error)) return false;
  *out = std::move(frames);
  return true;
}

Files format_binary(const Model &model, const std::vector<Pose> &poses) {
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
    for (std::size_t i = 0; i < model.images.size(); ++i) {
      const Image &im = model.images[i];
      w.uint<4>(im.id);
      write_pose(&w, poses[i].q, poses[i].t);
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
  {
    ByteWriter w(&f.rigs, rigs_bytes(model));
    w.uint<8>(model.rigs.size());
    for (const Rig &rig : model.rigs) {
      w.uint<4>(rig.id);
      w.uint<4>(rig.sensors.size());
      for (std::size_t k = 0; k < rig.sensors.size(); ++k) {
        const RigSensor &s = rig.sensors[k];
        w.uint<4>(static_cast<std::uint32_t>(s.sensor.type));
        w.uint<4>(s.sensor.id);
        if (k == 0) continue;  // the reference sensor: no pose
        w.uint<1>(s.has_pose ? 1 : 0);
        if (s.has_pose) write_pose(&w, s.sensor_from_rig.q, s.sensor_from_rig.t);
      }
    }
  }
  {
    ByteWriter w(&f.frames, frames_bytes(model));
    w.uint<8>(model.frames.size());
    for (const Frame &fr : model.frames) {
      w.uint<4>(fr.id);
      w.uint<4>(fr.rig_id);
      write_pose(&w, fr.rig_from_world.q, fr.rig_from_world.t);
      w.uint<4>(fr.data.size());
      for (const DataId &d : fr.data) {
        w.uint<4>(static_cast<std::uint32_t>(d.sensor.type));
        w.uint<4>(d.sensor.id);
        w.uint<8>(d.id);
      }
    }
  }
  return f;
}

}  // namespace sbaformats::colmap
