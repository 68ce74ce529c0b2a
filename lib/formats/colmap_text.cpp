// SPDX-License-Identifier: BSD-3-Clause
// COLMAP's text format: cameras.txt, images.txt, points3D.txt, rigs.txt and frames.txt.
#include <array>
#include <cmath>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "formats/colmap_check.h"
#include "formats/colmap_io_impl.h"
#include "formats/text_tokens.h"

namespace sbaformats::colmap {

namespace {

// The lines of a text file: "tokens" split on blanks, with the line number. The line and its
// tokens are views into the text, which outlives the reader: a model's millions of values are
// read without a string made for each.
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
    line_ = std::string_view(text_).substr(pos_, end - pos_);
    if (!line_.empty() && line_.back() == '\r') line_.remove_suffix(1);
    pos_ = end + 1;
    ++lineno_;
    split();
    return true;
  }
  bool is_blank_or_comment() const { return tokens_.empty() || tokens_[0][0] == '#'; }

  const std::vector<std::string_view> &tokens() const { return tokens_; }
  std::string_view line() const { return line_; }
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
      if (i > b) tokens_.push_back(line_.substr(b, i - b));
    }
  }

  const std::string &text_;
  const std::string &name_;
  std::size_t pos_ = 0;
  int lineno_ = 0;
  std::string_view line_;
  std::vector<std::string_view> tokens_;
};

// A finite decimal number, the whole token.
bool parse_real(std::string_view tok, double *out) {
  double v;
  if (!decimal_number(tok, &v) || !std::isfinite(v)) return false;
  *out = v;
  return true;
}

// An unsigned decimal integer <= max, the whole token.
bool parse_uint(std::string_view tok, std::uint64_t max, std::uint64_t *out) {
  if (tok.empty() || tok.size() > 20) return false;
  std::uint64_t v = 0;
  for (char c : tok) {
    if (c < '0' || c > '9') return false;
    const std::uint64_t d = static_cast<std::uint64_t>(c - '0');
    if (d > max || v > (max - d) / 10) return false;
    v = v * 10 + d;
  }
  *out = v;
  return true;
}

// A token quoted in a message.
std::string quoted(std::string_view tok) { return "'" + printable(std::string(tok)) + "'"; }

bool real_field(const TextReader &r, std::size_t k, const char *what, double *out, std::string *error) {
  if (parse_real(r.tokens()[k], out)) return true;
  return fail(error, r.where() + what + " must be a finite number, got " + quoted(r.tokens()[k]));
}

bool uint_field(const TextReader &r, std::size_t k, const char *what, std::uint64_t max, std::uint64_t *out,
                std::string *error) {
  if (parse_uint(r.tokens()[k], max, out)) return true;
  return fail(error, r.where() + what + " must be an integer from 0 to " + std::to_string(max) + ", got " +
                         quoted(r.tokens()[k]));
}

constexpr std::uint64_t kU32 = 0xffffffffu;

// An id of a camera, an image, a rig or a frame (what: CAMERA_ID, IMAGE_ID, RIG_ID, FRAME_ID):
// any 32-bit value, COLMAP's invalid one refused with the record (colmap_check.h).
bool id_field(const TextReader &r, std::size_t k, const char *what, std::uint32_t *out, std::string *error) {
  std::uint64_t v;
  if (!uint_field(r, k, what, kU32, &v, error)) return false;
  *out = static_cast<std::uint32_t>(v);
  return true;
}

// The record read from r's line keeps the rules of colmap_check.h: false with the line and why.
bool keeps_rules(const TextReader &r, const std::string &why, std::string *error) {
  return why.empty() || fail(error, r.where() + why);
}

int model_by_name(std::string_view name) {
  for (int i = 0; i < kNumModels; ++i)
    if (name == kModels[i].name) return i;
  return -1;
}

// QW QX QY QZ TX TY TZ from token k on.
bool pose_fields(const TextReader &r, std::size_t k, std::array<double, 4> *q, std::array<double, 3> *t,
                 std::string *error) {
  static const char *const kq[] = {"QW", "QX", "QY", "QZ"};
  static const char *const kt[] = {"TX", "TY", "TZ"};
  for (std::size_t i = 0; i < 4; ++i)
    if (!real_field(r, k + i, kq[i], &(*q)[i], error)) return false;
  for (std::size_t i = 0; i < 3; ++i)
    if (!real_field(r, k + 4 + i, kt[i], &(*t)[i], error)) return false;
  return true;
}

// SENSOR_TYPE SENSOR_ID at tokens k and k + 1.
bool sensor_fields(const TextReader &r, std::size_t k, SensorId *out, std::string *error) {
  const std::string_view type = r.tokens()[k];
  if (type == "CAMERA") out->type = SensorType::Camera;
  else if (type == "IMU") out->type = SensorType::Imu;
  else return fail(error, r.where() + "SENSOR_TYPE must be CAMERA or IMU, got " + quoted(type));
  std::uint64_t v;
  if (!uint_field(r, k + 1, "SENSOR_ID", kU32, &v, error)) return false;
  out->id = static_cast<std::uint32_t>(v);
  return true;
}

}  // namespace

bool parse_cameras_text(const std::string &text, const std::string &name, std::vector<Camera> *out,
                        std::string *error) {
  TextReader r(text, name);
  std::vector<Camera> cams;
  IdIndex ids;
  while (r.next_data_line()) {
    const auto &t = r.tokens();
    if (t.size() < 4)
      return fail(error, r.where() + "expected CAMERA_ID MODEL WIDTH HEIGHT PARAMS[], found " +
                             std::to_string(t.size()) + " values");
    Camera c;
    if (!id_field(r, 0, "CAMERA_ID", &c.id, error)) return false;
    c.model = model_by_name(t[1]);
    if (c.model < 0) return fail(error, r.where() + "unknown camera model " + quoted(t[1]));
    if (!uint_field(r, 2, "WIDTH", UINT64_MAX, &c.width, error)) return false;
    if (!uint_field(r, 3, "HEIGHT", UINT64_MAX, &c.height, error)) return false;
    // Every value after HEIGHT is a parameter: their count is the model's (camera_problem).
    c.params.resize(t.size() - 4);
    for (std::size_t k = 0; k < c.params.size(); ++k)
      if (!real_field(r, 4 + k, "a camera parameter", &c.params[k], error)) return false;
    if (!keeps_rules(r, camera_problem(c), error)) return false;
    if (!ids.insert(c.id, cams.size())) return fail(error, r.where() + appears_twice("camera", c.id));
    cams.push_back(std::move(c));
  }
  *out = std::move(cams);
  return true;
}

bool parse_images_text(const std::string &text, const std::string &name, std::vector<Image> *out,
                       std::string *error) {
  TextReader r(text, name);
  std::vector<Image> images;
  IdIndex ids;
  while (r.next_data_line()) {
    const auto &t = r.tokens();
    if (t.size() < 10)
      return fail(error, r.where() + "expected IMAGE_ID QW QX QY QZ TX TY TZ CAMERA_ID NAME, found " +
                             std::to_string(t.size()) + " values");
    Image im;
    if (!id_field(r, 0, "IMAGE_ID", &im.id, error)) return false;
    if (!pose_fields(r, 1, &im.q, &im.t, error)) return false;
    if (!id_field(r, 8, "CAMERA_ID", &im.camera_id, error)) return false;
    // The name is the rest of the line, so that it may hold blanks: from the tenth token to
    // the end of the last.
    const std::string_view line = r.line();
    const std::size_t name_begin = static_cast<std::size_t>(t[9].data() - line.data());
    const std::size_t name_end = static_cast<std::size_t>(t.back().data() + t.back().size() - line.data());
    im.name.assign(line.substr(name_begin, name_end - name_begin));
    if (!keeps_rules(r, image_problem(im), error)) return false;
    if (!ids.insert(im.id, images.size())) return fail(error, r.where() + appears_twice("image", im.id));
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
      if (p[3 * k + 2] == std::string_view("-1")) {
        q.point3d_id = kNoPoint;
      } else if (!parse_uint(p[3 * k + 2], kNoPoint - 1, &q.point3d_id)) {
        return fail(error, r.where() + "POINT3D_ID must be -1 or an integer from 0 to " +
                               std::to_string(kNoPoint - 1) + ", got " + quoted(p[3 * k + 2]));
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
  IdIndex ids;
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
      if (!id_field(r, 8 + 2 * k, "IMAGE_ID", &p.track[k].image_id, error)) return false;
      if (!uint_field(r, 9 + 2 * k, "POINT2D_IDX", kU32, &v, error)) return false;
      p.track[k].point2d_idx = static_cast<std::uint32_t>(v);
    }
    if (!keeps_rules(r, point_problem(p), error)) return false;
    if (!ids.insert(p.id, points.size())) return fail(error, r.where() + appears_twice("point", p.id));
    points.push_back(std::move(p));
  }
  *out = std::move(points);
  return true;
}

bool parse_rigs_text(const std::string &text, const std::string &name, std::vector<Rig> *out,
                     std::string *error) {
  TextReader r(text, name);
  std::vector<Rig> rigs;
  IdIndex ids;
  while (r.next_data_line()) {
    const auto &t = r.tokens();
    if (t.size() < 2)
      return fail(error, r.where() +
                             "expected RIG_ID NUM_SENSORS [REF_SENSOR_TYPE REF_SENSOR_ID] SENSORS[], found " +
                             std::to_string(t.size()) + " values");
    Rig rig;
    std::uint64_t v, n;
    if (!id_field(r, 0, "RIG_ID", &rig.id, error) || !uint_field(r, 1, "NUM_SENSORS", kU32, &n, error))
      return false;
    const std::string of_rig = "rig " + std::to_string(rig.id) + ": ";
    // The reference sensor takes two values, each other one three or ten: the values of the
    // line bound the sensors read before they are counted.
    std::size_t k = 2;
    for (std::uint64_t i = 0; i < n; ++i) {
      RigSensor sensor;
      const std::size_t need = i == 0 ? 2 : 3;
      if (t.size() - k < need)
        return fail(error, r.where() + of_rig + "the line ends inside sensor " + std::to_string(i + 1) +
                               " of " + std::to_string(n));
      if (!sensor_fields(r, k, &sensor.sensor, error)) return false;
      k += 2;
      if (i > 0) {
        if (!uint_field(r, k++, "HAS_POSE", 1, &v, error)) return false;
        sensor.has_pose = v == 1;
        if (sensor.has_pose) {
          if (t.size() - k < 7)
            return fail(error, r.where() + of_rig + "the line ends inside the pose of sensor " +
                                   std::to_string(i + 1) + " of " + std::to_string(n));
          Pose &p = sensor.sensor_from_rig;
          if (!pose_fields(r, k, &p.q, &p.t, error)) return false;
          k += 7;
        }
      }
      rig.sensors.push_back(sensor);
    }
    if (k != t.size())
      return fail(error, r.where() + of_rig + std::to_string(t.size() - k) + " values after its " +
                             std::to_string(n) + " sensors");
    if (!keeps_rules(r, rig_problem(rig), error)) return false;
    if (!ids.insert(rig.id, rigs.size())) return fail(error, r.where() + appears_twice("rig", rig.id));
    rigs.push_back(std::move(rig));
  }
  *out = std::move(rigs);
  return true;
}

bool parse_frames_text(const std::string &text, const std::string &name, std::vector<Frame> *out,
                       std::string *error) {
  TextReader r(text, name);
  std::vector<Frame> frames;
  IdIndex ids;
  while (r.next_data_line()) {
    const auto &t = r.tokens();
    if (t.size() < 10)
      return fail(error, r.where() +
                             "expected FRAME_ID RIG_ID QW QX QY QZ TX TY TZ NUM_DATA_IDS DATA_IDS[], found " +
                             std::to_string(t.size()) + " values");
    Frame f;
    std::uint64_t n;
    if (!id_field(r, 0, "FRAME_ID", &f.id, error) || !id_field(r, 1, "RIG_ID", &f.rig_id, error)) return false;
    if (!pose_fields(r, 2, &f.rig_from_world.q, &f.rig_from_world.t, error)) return false;
    if (!uint_field(r, 9, "NUM_DATA_IDS", kU32, &n, error)) return false;
    // Three values a measurement: n is bounded by the line before it is multiplied.
    if ((t.size() - 10) % 3 != 0 || (t.size() - 10) / 3 != n)
      return fail(error, r.where() + "frame " + std::to_string(f.id) + " has NUM_DATA_IDS " +
                             std::to_string(n) + ", followed by " + std::to_string(t.size() - 10) +
                             " values (SENSOR_TYPE SENSOR_ID DATA_ID each)");
    f.data.resize(static_cast<std::size_t>(n));
    for (std::size_t i = 0; i < f.data.size(); ++i) {
      if (!sensor_fields(r, 10 + 3 * i, &f.data[i].sensor, error) ||
          !uint_field(r, 12 + 3 * i, "DATA_ID", UINT64_MAX, &f.data[i].id, error))
        return false;
    }
    if (!keeps_rules(r, frame_problem(f), error)) return false;
    if (!ids.insert(f.id, frames.size())) return fail(error, r.where() + appears_twice("frame", f.id));
    frames.push_back(std::move(f));
  }
  *out = std::move(frames);
  return true;
}

// The most characters that a value takes in the text (g17's longest, -1.2345678901234567e-308,
// and the longest integers) plus its separator: each file's string is reserved at once to an
// upper bound of its size, never copied as it grows. What is reserved and never written costs
// address space only.
constexpr std::size_t kRealChars = 25, kU64Chars = 21, kU32Chars = 11, kU8Chars = 4,
                      kSensorChars = 7 + kU32Chars;

namespace {

// " QW QX QY QZ TX TY TZ".
void append_pose(std::string *out, const std::array<double, 4> &q, const std::array<double, 3> &t) {
  for (double v : q) {
    *out += ' ';
    append_g17(out, v);
  }
  for (double v : t) {
    *out += ' ';
    append_g17(out, v);
  }
}

// " SENSOR_TYPE SENSOR_ID".
void append_sensor(std::string *out, const SensorId &s) {
  *out += ' ';
  *out += sensor_type_name(s.type);
  *out += ' ';
  append_uint(out, s.id);
}

// rigs.txt and frames.txt, their comments as COLMAP writes them.
void format_rigs_and_frames(const Model &model, Files *f) {
  std::size_t size = 400;
  for (const Rig &rig : model.rigs)
    size += 2 * kU32Chars + (kSensorChars + 2 + 7 * kRealChars) * rig.sensors.size() + 1;
  std::string &rigs = f->rigs;
  rigs.reserve(size);
  rigs +=
      "# Rig calib list with one line of data per calib:\n"
      "#   RIG_ID, NUM_SENSORS, REF_SENSOR_TYPE, REF_SENSOR_ID, SENSORS[] as (SENSOR_TYPE, SENSOR_ID, "
      "HAS_POSE, [QW, QX, QY, QZ, TX, TY, TZ])\n"
      "# Number of rigs: ";
  append_uint(&rigs, model.rigs.size());
  rigs += '\n';
  for (const Rig &rig : model.rigs) {
    append_uint(&rigs, rig.id);
    rigs += ' ';
    append_uint(&rigs, rig.sensors.size());
    for (std::size_t k = 0; k < rig.sensors.size(); ++k) {
      const RigSensor &s = rig.sensors[k];
      append_sensor(&rigs, s.sensor);
      if (k == 0) continue;  // the reference sensor: no pose
      rigs += s.has_pose ? " 1" : " 0";
      if (s.has_pose) append_pose(&rigs, s.sensor_from_rig.q, s.sensor_from_rig.t);
    }
    rigs += '\n';
  }

  size = 400;
  for (const Frame &fr : model.frames)
    size += 3 * kU32Chars + 7 * kRealChars + (kSensorChars + kU64Chars) * fr.data.size() + 1;
  std::string &frames = f->frames;
  frames.reserve(size);
  frames +=
      "# Frame list with one line of data per frame:\n"
      "#   FRAME_ID, RIG_ID, RIG_FROM_WORLD[QW, QX, QY, QZ, TX, TY, TZ], NUM_DATA_IDS, DATA_IDS[] as "
      "(SENSOR_TYPE, SENSOR_ID, DATA_ID)\n"
      "# Number of frames: ";
  append_uint(&frames, model.frames.size());
  frames += '\n';
  for (const Frame &fr : model.frames) {
    append_uint(&frames, fr.id);
    frames += ' ';
    append_uint(&frames, fr.rig_id);
    append_pose(&frames, fr.rig_from_world.q, fr.rig_from_world.t);
    frames += ' ';
    append_uint(&frames, fr.data.size());
    for (const DataId &d : fr.data) {
      append_sensor(&frames, d.sensor);
      frames += ' ';
      append_uint(&frames, d.id);
    }
    frames += '\n';
  }
}

// cameras.txt.
std::string format_cameras(const Model &model) {
  std::size_t size = 200;
  for (const Camera &c : model.cameras) size += kU32Chars + 32 + 2 * kU64Chars + kRealChars * c.params.size() + 1;
  std::string cams;
  cams.reserve(size);
  cams += "# Camera list with one line of data per camera:\n"
          "#   CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[]\n"
          "# Number of cameras: ";
  append_uint(&cams, model.cameras.size());
  cams += '\n';
  for (const Camera &c : model.cameras) {
    append_uint(&cams, c.id);
    cams += ' ';
    cams += kModels[c.model].name;
    cams += ' ';
    append_uint(&cams, c.width);
    cams += ' ';
    append_uint(&cams, c.height);
    for (double p : c.params) {
      cams += ' ';
      append_g17(&cams, p);
    }
    cams += '\n';
  }
  return cams;
}

// images.txt.
std::string format_images(const Model &model, const std::vector<Pose> &poses) {
  std::size_t size = 200;
  for (const Image &im : model.images)
    size += kU32Chars + 7 * kRealChars + kU32Chars + im.name.size() + 2 +
            (kRealChars + kRealChars + kU64Chars) * im.points.size();
  std::string ims;
  ims.reserve(size);
  ims += "# Image list with two lines of data per image:\n"
         "#   IMAGE_ID, QW, QX, QY, QZ, TX, TY, TZ, CAMERA_ID, NAME\n"
         "#   POINTS2D[] as (X, Y, POINT3D_ID)\n"
         "# Number of images: ";
  append_uint(&ims, model.images.size());
  ims += '\n';
  for (std::size_t i = 0; i < model.images.size(); ++i) {
    const Image &im = model.images[i];
    append_uint(&ims, im.id);
    append_pose(&ims, poses[i].q, poses[i].t);
    ims += ' ';
    append_uint(&ims, im.camera_id);
    ims += ' ';
    ims += im.name;
    ims += '\n';
    for (std::size_t k = 0; k < im.points.size(); ++k) {
      const Point2D &p = im.points[k];
      if (k) ims += ' ';
      append_g17(&ims, p.x);
      ims += ' ';
      append_g17(&ims, p.y);
      ims += ' ';
      if (p.point3d_id == kNoPoint) ims += "-1";
      else append_uint(&ims, p.point3d_id);
    }
    ims += '\n';
  }
  return ims;
}

// points3D.txt.
std::string format_points(const Model &model) {
  std::size_t size = 200;
  for (const Point3D &p : model.points)
    size += kU64Chars + 4 * kRealChars + 3 * kU8Chars + (kU32Chars + kU32Chars) * p.track.size() + 1;
  std::string pts;
  pts.reserve(size);
  pts += "# 3D point list with one line of data per point:\n"
         "#   POINT3D_ID, X, Y, Z, R, G, B, ERROR, TRACK[] as (IMAGE_ID, POINT2D_IDX)\n"
         "# Number of points: ";
  append_uint(&pts, model.points.size());
  pts += '\n';
  for (const Point3D &p : model.points) {
    append_uint(&pts, p.id);
    for (double v : p.xyz) {
      pts += ' ';
      append_g17(&pts, v);
    }
    for (std::uint8_t c : p.rgb) {
      pts += ' ';
      append_uint(&pts, c);
    }
    pts += ' ';
    append_g17(&pts, p.error);
    for (const TrackElement &e : p.track) {
      pts += ' ';
      append_uint(&pts, e.image_id);
      pts += ' ';
      append_uint(&pts, e.point2d_idx);
    }
    pts += '\n';
  }
  return pts;
}

}  // namespace

Files format_text(const Model &model, const std::vector<Pose> &poses) {
  Files f;
  f.cameras = format_cameras(model);
  f.images = format_images(model, poses);
  f.points = format_points(model);
  format_rigs_and_frames(model, &f);
  return f;
}

}  // namespace sbaformats::colmap
