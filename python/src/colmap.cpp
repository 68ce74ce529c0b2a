// SPDX-License-Identifier: BSD-3-Clause
#include "colmap.h"

#include <pybind11/numpy.h>
#include <pybind11/stl.h>

#include <algorithm>
#include <array>
#include <cfloat>
#include <cstdint>
#include <numeric>
#include <stdexcept>
#include <string>
#include <unordered_map>
#include <unordered_set>
#include <utility>
#include <vector>

#include "arrays.h"
#include "formats/colmap_check.h"
#include "formats/colmap_io.h"
#include "formats/colmap_problem.h"
#include "formats/colmap_sba.h"
#include "gil.h"
#include "option_values.h"
#include "run.h"
#include "session.h"

namespace colmap = sbaformats::colmap;

namespace pysba {
namespace {

constexpr std::uint64_t kU32 = 0xffffffffu;
constexpr std::uint64_t kU64 = ~std::uint64_t{0};
// How the library's messages name a model that came from Python, where a file's path would be.
const char *const kModelName = "model";

// ---- a model from Python: its attributes, each checked and named as the caller wrote it ----

py::object get(py::handle obj, const char *name) { return obj.attr(name); }

std::string type_name(py::handle v) { return Py_TYPE(v.ptr())->tp_name; }

// v, an int (or what operator.index takes, but not a bool), in [0, max].
std::uint64_t whole_number(py::handle v, std::uint64_t max, const std::string &where) {
  if (PyBool_Check(v.ptr()) || !PyIndex_Check(v.ptr()))
    throw py::type_error(where + " must be an int, got " + type_name(v));
  const PyRef i(PyNumber_Index(v.ptr()));
  if (!i) throw py::error_already_set();
  const unsigned long long x = PyLong_AsUnsignedLongLong(i.get());
  const bool overflow = x == ~0ULL && PyErr_Occurred();
  if (overflow) PyErr_Clear();
  if (overflow || x > max)
    throw py::value_error(where + " must be in [0, " + std::to_string(max) + "], got " +
                          std::string(py::str(i.handle())));
  return x;
}

// obj as integers in [0, max], of the given shape (-1: any size), in C order: a TypeError for
// an array of another kind (floats, bools, strs), except an empty one, which has no entries to
// be of the wrong kind ([] is an array of floats to numpy). minus_one: -1 stands for max, as
// POINT3D_ID -1 is the unsigned 2^64 - 1 of the binary files.
template <class T>
std::vector<T> whole_numbers(py::handle obj, std::uint64_t max, const std::string &what,
                             std::vector<py::ssize_t> shape, bool minus_one = false) {
  const py::array a = py::array::ensure(obj);
  const char kind = a ? a.dtype().kind() : '?';
  if (kind != 'i' && kind != 'u' && !(a && a.size() == 0 && kind == 'f'))
    throw py::type_error(what + " must be an array of integers, got " + what_it_is(obj));
  const std::vector<py::ssize_t> got = check_shape(a, what.c_str(), std::move(shape));
  const std::vector<long long> dims(got.begin(), got.end());
  std::vector<T> out(static_cast<size_t>(a.size()));
  const auto bad = [&](py::ssize_t k, const std::string &value) {
    return py::value_error(entry_name(what, dims, k) + " = " + value + " is not in [0, " +
                           std::to_string(max) + "]" + (minus_one ? " (nor -1)" : ""));
  };
  if (kind == 'u') {
    const auto u = py::array_t<std::uint64_t, py::array::c_style | py::array::forcecast>::ensure(a);
    for (py::ssize_t k = 0; k < a.size(); ++k) {
      if (u.data()[k] > max) throw bad(k, std::to_string(u.data()[k]));
      out[size_t(k)] = static_cast<T>(u.data()[k]);
    }
  } else if (kind == 'i') {
    const Indices s = Indices::ensure(a);
    for (py::ssize_t k = 0; k < a.size(); ++k) {
      const long long v = s.data()[k];
      if (minus_one && v == -1) {
        out[size_t(k)] = static_cast<T>(max);
        continue;
      }
      if (v < 0 || static_cast<std::uint64_t>(v) > max) throw bad(k, std::to_string(v));
      out[size_t(k)] = static_cast<T>(v);
    }
  }
  return out;
}

// obj as finite numbers of the given shape (-1: any size).
Doubles finite_numbers(py::handle obj, const std::string &what, std::vector<py::ssize_t> shape) {
  Doubles a = float_array(obj, what.c_str());
  check_shape(a, what.c_str(), std::move(shape));
  check_finite(a, what.c_str());
  return a;
}

template <size_t N>
std::array<double, N> finite_vector(py::handle obj, const std::string &what) {
  const Doubles a = finite_numbers(obj, what, {py::ssize_t(N)});
  std::array<double, N> out;
  std::copy_n(a.data(), N, out.begin());
  return out;
}

// A str as the bytes the files hold: UTF-8, and a name read from bytes that are not UTF-8
// back as those bytes (surrogateescape, as name_of gives it).
std::string text(py::handle v, const std::string &where) {
  if (!PyUnicode_Check(v.ptr())) throw py::type_error(where + " must be a str, got " + type_name(v));
  const PyRef b(PyUnicode_AsEncodedString(v.ptr(), "utf-8", "surrogateescape"));
  if (!b) throw py::error_already_set();
  return std::string(PyBytes_AS_STRING(b.get()), size_t(PyBytes_GET_SIZE(b.get())));
}

// The items of a list (or of anything iterable but a str).
py::list items(py::handle v, const std::string &where) {
  PyObject *list = PyUnicode_Check(v.ptr()) || PyBytes_Check(v.ptr()) ? nullptr : PySequence_List(v.ptr());
  if (!list) {
    PyErr_Clear();
    throw py::type_error(where + " must be a list, got " + type_name(v));
  }
  return py::reinterpret_steal<py::list>(list);
}

std::string at(const std::string &what, size_t k) { return what + "[" + std::to_string(k) + "]"; }

int model_id(const std::string &name, const std::string &where) {
  for (int k = 0; colmap::camera_model_name(k); ++k)
    if (name == colmap::camera_model_name(k)) return k;
  std::string known;
  for (int k = 0; colmap::camera_model_name(k); ++k)
    known += std::string(k ? ", " : "") + colmap::camera_model_name(k);
  throw py::value_error(where + ": unknown camera model '" + name + "' (COLMAP's are " + known + ")");
}

const char *sensor_type_text(colmap::SensorType type) {
  return type == colmap::SensorType::Camera ? "CAMERA" : "IMU";
}

colmap::SensorType sensor_type(py::handle v, const std::string &where) {
  const std::string t = text(v, where);
  if (t == "CAMERA") return colmap::SensorType::Camera;
  if (t == "IMU") return colmap::SensorType::Imu;
  throw py::value_error(where + " must be 'CAMERA' or 'IMU', got '" + t + "'");
}

// A pose's q and t (qw qx qy qz, t), into *out.
void pose_of(py::handle obj, const std::string &where, colmap::Pose *out) {
  out->q = finite_vector<4>(get(obj, "q"), where + ".q");
  out->t = finite_vector<3>(get(obj, "t"), where + ".t");
}

// Whether obj (a rig's sensor, a frame, an image) has a pose: its q and t both given, not
// both None.
bool has_pose(py::handle obj, const std::string &where, const char *none_means) {
  const bool no_q = get(obj, "q").is_none(), no_t = get(obj, "t").is_none();
  if (no_q != no_t)
    throw py::value_error(where + ": q and t go together: both None (" + none_means + ") or both given");
  return !no_q;
}

colmap::Camera camera_of(py::handle c, const std::string &where) {
  colmap::Camera out;
  out.id = static_cast<std::uint32_t>(whole_number(get(c, "id"), kU32, where + ".id"));
  out.model = model_id(text(get(c, "model"), where + ".model"), where + ".model");
  out.width = whole_number(get(c, "width"), kU64, where + ".width");
  out.height = whole_number(get(c, "height"), kU64, where + ".height");
  const Doubles params = finite_numbers(get(c, "params"), where + ".params", {-1});
  out.params.assign(params.data(), params.data() + params.size());
  return out;
}

// An image, and in *posed whether it has a pose (an image without one keeps the default).
colmap::Image image_of(py::handle im, const std::string &where, bool *posed) {
  colmap::Image out;
  out.id = static_cast<std::uint32_t>(whole_number(get(im, "id"), kU32, where + ".id"));
  out.name = text(get(im, "name"), where + ".name");
  out.camera_id = static_cast<std::uint32_t>(whole_number(get(im, "camera_id"), kU32, where + ".camera_id"));
  *posed = has_pose(im, where, "no pose: not registered");
  if (*posed) {
    colmap::Pose pose;
    pose_of(im, where, &pose);
    out.q = pose.q;
    out.t = pose.t;
  }
  const Doubles xy = finite_numbers(get(im, "points2D"), where + ".points2D", {-1, 2});
  const std::vector<std::uint64_t> ids = whole_numbers<std::uint64_t>(
      get(im, "point3D_ids"), colmap::kNoPoint, where + ".point3D_ids", {xy.shape(0)}, true);
  out.points.resize(ids.size());
  for (size_t k = 0; k < ids.size(); ++k) out.points[k] = {xy.data()[2 * k], xy.data()[2 * k + 1], ids[k]};
  return out;
}

std::vector<colmap::Point3D> points_of(py::handle pts) {
  const std::string w = "points3D.";
  const std::vector<std::uint64_t> ids = whole_numbers<std::uint64_t>(get(pts, "ids"), kU64, w + "ids", {-1});
  const py::ssize_t n = py::ssize_t(ids.size());
  const Doubles xyz = finite_numbers(get(pts, "xyz"), w + "xyz", {n, 3});
  const std::vector<std::uint8_t> rgb = whole_numbers<std::uint8_t>(get(pts, "rgb"), 255, w + "rgb", {n, 3});
  const Doubles error = finite_numbers(get(pts, "error"), w + "error", {n});
  const std::vector<std::uint64_t> offsets =
      whole_numbers<std::uint64_t>(get(pts, "track_offsets"), kU64, w + "track_offsets", {n + 1});
  const std::vector<std::uint32_t> images =
      whole_numbers<std::uint32_t>(get(pts, "track_image_ids"), kU32, w + "track_image_ids", {-1});
  const std::vector<std::uint32_t> idxs = whole_numbers<std::uint32_t>(
      get(pts, "track_point2D_idxs"), kU32, w + "track_point2D_idxs", {py::ssize_t(images.size())});
  // Point k's track is elements track_offsets[k] to track_offsets[k + 1] - 1.
  for (size_t k = 0; k <= ids.size(); ++k) {
    const bool ends = k == 0 ? offsets[k] == 0 : k < ids.size() || offsets[k] == images.size();
    if (!ends || (k > 0 && offsets[k] < offsets[k - 1]))
      throw py::value_error(
          w + "track_offsets must rise from 0 to len(track_image_ids) = " + std::to_string(images.size()) +
          ", got track_offsets[" + std::to_string(k) + "] = " + std::to_string(offsets[k]));
  }
  std::vector<colmap::Point3D> out(ids.size());
  for (size_t k = 0; k < ids.size(); ++k) {
    colmap::Point3D &p = out[k];
    p.id = ids[k];
    std::copy_n(xyz.data() + 3 * k, 3, p.xyz.begin());
    std::copy_n(rgb.data() + 3 * k, 3, p.rgb.begin());
    p.error = error.data()[k];
    for (std::uint64_t e = offsets[k]; e < offsets[k + 1]; ++e) p.track.push_back({images[e], idxs[e]});
  }
  return out;
}

colmap::Rig rig_of(py::handle r, const std::string &where) {
  colmap::Rig out;
  out.id = static_cast<std::uint32_t>(whole_number(get(r, "id"), kU32, where + ".id"));
  const py::list sensors = items(get(r, "sensors"), where + ".sensors");
  for (size_t k = 0; k < sensors.size(); ++k) {
    const py::handle s = sensors[k];
    const std::string sw = at(where + ".sensors", k);
    colmap::RigSensor rs;
    rs.sensor.type = sensor_type(get(s, "type"), sw + ".type");
    rs.sensor.id = static_cast<std::uint32_t>(whole_number(get(s, "id"), kU32, sw + ".id"));
    rs.has_pose = has_pose(s, sw, "no pose in the rig");
    if (rs.has_pose) pose_of(s, sw, &rs.sensor_from_rig);
    out.sensors.push_back(rs);
  }
  return out;
}

// A frame, and in *posed whether it has a pose.
colmap::Frame frame_of(py::handle f, const std::string &where, bool *posed) {
  colmap::Frame out;
  out.id = static_cast<std::uint32_t>(whole_number(get(f, "id"), kU32, where + ".id"));
  out.rig_id = static_cast<std::uint32_t>(whole_number(get(f, "rig_id"), kU32, where + ".rig_id"));
  *posed = has_pose(f, where, "no pose: not registered");
  if (*posed) pose_of(f, where, &out.rig_from_world);
  const py::list data = items(get(f, "data"), where + ".data");
  for (size_t k = 0; k < data.size(); ++k) {
    const std::string dw = at(where + ".data", k);
    const py::list d = items(data[k], dw);
    if (d.size() != 3)
      throw py::value_error(dw + " must be (type, sensor_id, data_id), got " + std::to_string(d.size()) +
                            " values");
    colmap::DataId id;
    id.sensor.type = sensor_type(d[0], dw + "[0]");
    id.sensor.id = static_cast<std::uint32_t>(whole_number(d[1], kU32, dw + "[1]"));
    id.id = whole_number(d[2], kU64, dw + "[2]");
    out.data.push_back(id);
  }
  return out;
}

template <class Record, class Convert>
std::vector<Record> records(py::handle list, const char *what, Convert convert) {
  const py::list l = items(list, what);
  std::vector<Record> out;
  out.reserve(l.size());
  for (size_t k = 0; k < l.size(); ++k) out.push_back(convert(l[k], at(what, k)));
  return out;
}

// The records of a list that have a pose, and the place among them of each item of the list
// (-1: none, for one without a pose) in *rows.
template <class Record, class Convert>
std::vector<Record> posed_records(py::handle list, const char *what, Convert convert, std::vector<long long> *rows,
                                  std::vector<Record> *unposed) {
  const py::list l = items(list, what);
  std::vector<Record> out;
  for (size_t k = 0; k < l.size(); ++k) {
    bool posed = false;
    Record r = convert(l[k], at(what, k), &posed);
    rows->push_back(posed ? static_cast<long long>(out.size()) : -1);
    (posed ? out : *unposed).push_back(std::move(r));
  }
  return out;
}

// The frame of each image that a list of frames names (a camera's data), by IMAGE_ID.
std::unordered_map<std::uint64_t, std::uint32_t> frames_by_image(const std::vector<colmap::Frame> &frames) {
  std::unordered_map<std::uint64_t, std::uint32_t> out;
  for (const colmap::Frame &f : frames)
    for (const colmap::DataId &d : f.data)
      if (d.sensor.type == colmap::SensorType::Camera) out.emplace(d.id, f.id);
  return out;
}

// The frames without a pose and their images are what pycolmap holds of a frame it has not
// registered (or has deregistered): neither COLMAP's files nor a solve have a place for them,
// so they stay out of the model, but what to_pycolmap gives pycolmap of them must hold
// together: an image without a pose is in a frame without one and observes no point, and such
// a frame holds only images without a pose.
void check_unposed(const colmap::Model &m, const std::vector<long long> &image_rows,
                   const std::vector<colmap::Image> &images, const std::vector<long long> &frame_rows,
                   const std::vector<colmap::Frame> &frames) {
  const auto posed_frame = frames_by_image(m.frames), unposed_frame = frames_by_image(frames);
  const std::string rule = ": COLMAP 4 registers the images of a frame with it";
  std::unordered_set<std::uint64_t> unposed;
  size_t next = 0;
  for (size_t k = 0; k < image_rows.size(); ++k) {
    const std::string where = at("images", k);
    if (image_rows[k] >= 0) {
      const auto f = unposed_frame.find(m.images[size_t(image_rows[k])].id);
      if (f != unposed_frame.end())
        throw py::value_error(where + " has a pose, but its frame " + std::to_string(f->second) + " has none" + rule);
      continue;
    }
    const colmap::Image &im = images[next++];
    unposed.insert(im.id);
    if (!m.has_rigs)
      throw py::value_error(where + " has no pose (q and t None), which only an image of a frame without one may "
                            "have, and the model has no frames");
    if (const auto f = posed_frame.find(im.id); f != posed_frame.end())
      throw py::value_error(where + " has no pose (q and t None), but its frame " + std::to_string(f->second) +
                            " has one" + rule);
    if (!unposed_frame.count(im.id)) throw py::value_error(where + " has no pose (q and t None) and is in no frame");
    for (size_t i = 0; i < im.points.size(); ++i)
      if (im.points[i].point3d_id != colmap::kNoPoint)
        throw py::value_error(where + " has no pose (not registered) but observes point " +
                              std::to_string(im.points[i].point3d_id) + " (point3D_ids[" + std::to_string(i) +
                              "]): an image without a pose observes no point");
  }
  next = 0;
  for (size_t k = 0; k < frame_rows.size(); ++k) {
    if (frame_rows[k] >= 0) continue;
    for (const colmap::DataId &d : frames[next++].data)
      if (d.sensor.type == colmap::SensorType::Camera && !unposed.count(d.id))
        throw py::value_error(at("frames", k) + " has no pose (q and t None), but its image " + std::to_string(d.id) +
                              " is none of the images without one");
  }
}

// A ColmapModel (its attributes: see pysba/_colmap.py), checked as the readers check a model
// (ValueError or TypeError otherwise), so that what write_model makes of it reads back. Its
// frames without a pose and their images are left out (check_unposed); image_rows, when given,
// receives the place in the result of each of the ColmapModel's images (-1: left out).
colmap::Model model_of(py::handle obj, std::vector<long long> *image_rows = nullptr) {
  colmap::Model m;
  std::vector<long long> rows, frame_rows;
  std::vector<colmap::Image> unposed_images;
  std::vector<colmap::Frame> unposed_frames;
  m.cameras = records<colmap::Camera>(get(obj, "cameras"), "cameras", camera_of);
  m.images = posed_records<colmap::Image>(get(obj, "images"), "images", image_of, &rows, &unposed_images);
  m.points = points_of(get(obj, "points3D"));
  const py::object rigs = get(obj, "rigs"), frames = get(obj, "frames");
  if (rigs.is_none() != frames.is_none())
    throw py::value_error(
        "rigs and frames go together, as COLMAP 4 refuses a model with one of the two: both "
        "lists, or both None");
  m.has_rigs = !rigs.is_none();
  if (m.has_rigs) {
    m.rigs = records<colmap::Rig>(rigs, "rigs", rig_of);
    m.frames = posed_records<colmap::Frame>(frames, "frames", frame_of, &frame_rows, &unposed_frames);
  }
  check_unposed(m, rows, unposed_images, frame_rows, unposed_frames);
  std::string error;
  if (!colmap::check_records(m, kModelName, &error) || !colmap::check_model(m, kModelName, &error))
    throw py::value_error(error);
  if (image_rows) *image_rows = std::move(rows);
  return m;
}

// ---- a model to Python: plain values that pysba/__init__.py makes its classes of ----

template <size_t N>
py::array_t<double> vector_of(const std::array<double, N> &v) {
  return copy_of(v.data(), {py::ssize_t(N)});
}

py::str name_of(const std::string &name) {
  PyObject *s = PyUnicode_DecodeUTF8(name.data(), Py_ssize_t(name.size()), "surrogateescape");
  if (!s) throw py::error_already_set();
  return py::reinterpret_steal<py::str>(s);
}

// An image with its pose (colmap::image_poses: derived from its frame in a model with rigs).
py::tuple python_image(const colmap::Image &im, const colmap::Pose &pose) {
  const size_t k = im.points.size();
  std::vector<double> xy(2 * k);
  std::vector<std::uint64_t> ids(k);
  for (size_t i = 0; i < k; ++i) {
    xy[2 * i] = im.points[i].x;
    xy[2 * i + 1] = im.points[i].y;
    ids[i] = im.points[i].point3d_id;
  }
  return py::make_tuple(im.id, name_of(im.name), im.camera_id, vector_of(pose.q), vector_of(pose.t),
                        adopt(std::move(xy), {py::ssize_t(k), 2}), adopt(std::move(ids), {py::ssize_t(k)}));
}

py::tuple python_points(const std::vector<colmap::Point3D> &points) {
  const size_t n = points.size();
  std::vector<std::uint64_t> ids(n), offsets(n + 1, 0);
  std::vector<double> xyz(3 * n), error(n);
  std::vector<std::uint8_t> rgb(3 * n);
  std::vector<std::uint32_t> images, idxs;
  for (size_t k = 0; k < n; ++k) {
    const colmap::Point3D &p = points[k];
    ids[k] = p.id;
    std::copy(p.xyz.begin(), p.xyz.end(), xyz.begin() + 3 * k);
    std::copy(p.rgb.begin(), p.rgb.end(), rgb.begin() + 3 * k);
    error[k] = p.error;
    for (const colmap::TrackElement &e : p.track) {
      images.push_back(e.image_id);
      idxs.push_back(e.point2d_idx);
    }
    offsets[k + 1] = images.size();
  }
  const py::ssize_t len = py::ssize_t(n), elements = py::ssize_t(images.size());
  return py::make_tuple(adopt(std::move(ids), {len}), adopt(std::move(xyz), {len, 3}),
                        adopt(std::move(rgb), {len, 3}), adopt(std::move(error), {len}),
                        adopt(std::move(offsets), {len + 1}), adopt(std::move(images), {elements}),
                        adopt(std::move(idxs), {elements}));
}

py::object python_pose(const colmap::Pose &p) { return py::make_tuple(vector_of(p.q), vector_of(p.t)); }

py::dict python_model(const colmap::Model &m) {
  py::list cameras, images, rigs, frames;
  for (const colmap::Camera &c : m.cameras)
    cameras.append(py::make_tuple(c.id, colmap::camera_model_name(c.model), c.width, c.height,
                                  copy_of(c.params.data(), {py::ssize_t(c.params.size())})));
  const std::vector<colmap::Pose> poses = colmap::image_poses(m);
  for (size_t i = 0; i < m.images.size(); ++i) images.append(python_image(m.images[i], poses[i]));
  for (const colmap::Rig &r : m.rigs) {
    py::list sensors;
    for (const colmap::RigSensor &s : r.sensors)
      sensors.append(py::make_tuple(sensor_type_text(s.sensor.type), s.sensor.id,
                                    s.has_pose ? python_pose(s.sensor_from_rig) : py::none()));
    rigs.append(py::make_tuple(r.id, sensors));
  }
  for (const colmap::Frame &f : m.frames) {
    py::list data;
    for (const colmap::DataId &d : f.data)
      data.append(py::make_tuple(sensor_type_text(d.sensor.type), d.sensor.id, d.id));
    frames.append(py::make_tuple(f.id, f.rig_id, python_pose(f.rig_from_world), data));
  }
  py::dict d;
  d["cameras"] = cameras;
  d["images"] = images;
  d["points3D"] = python_points(m.points);
  d["rigs"] = m.has_rigs ? py::object(rigs) : py::object(py::none());
  d["frames"] = m.has_rigs ? py::object(frames) : py::object(py::none());
  return d;
}

// ---- reading, writing, refining ----

// Whether a message of read_model is about reaching the files (OSError) rather than what
// they hold (ValueError): "DIR: no COLMAP model ...", or "DIR/FILE: " and a reason below.
bool unreadable(const std::string &error, const std::string &dir) {
  if (error.rfind(dir + ": no COLMAP model", 0) == 0) return true;
  const std::string folder = dir.empty() || dir.back() == '/' ? dir : dir + "/";
  if (error.rfind(folder, 0) != 0) return false;
  const size_t colon = error.find(": ", folder.size());
  if (colon == std::string::npos || error.find_first_of("/:", folder.size()) < colon) return false;
  for (const char *reason : {"cannot open: ", "is a directory", "not a regular file", "read error"})
    if (error.compare(colon + 2, std::string::traits_type::length(reason), reason) == 0) return true;
  return false;
}

py::dict read_colmap(const std::string &dir) {
  colmap::Model m;
  std::string error;
  if (!without_gil([&] { return colmap::read_model(dir, &m, nullptr, &error); }))
    raise_file_error(unreadable(error, dir) ? PyExc_OSError : PyExc_ValueError, error);
  return python_model(m);
}

void write_colmap(py::handle model, const std::string &dir, const std::string &encoding) {
  if (encoding != "text" && encoding != "binary")
    throw py::value_error("encoding must be 'text' or 'binary', got '" + encoding + "'");
  const colmap::Model m = model_of(model);
  const colmap::Encoding e = encoding == "text" ? colmap::Encoding::Text : colmap::Encoding::Binary;
  std::string error;
  if (!without_gil([&] { return colmap::write_model(dir, m, e, &error); }))
    raise_file_error(PyExc_OSError, error);
}

// Blocks of one kind as {id: (k, k) array}, and their coordinates as {id: tuple} into coords
// (pose and point coordinates by name, a camera's parameters by index, as sbarefine writes them).
py::dict covariance_blocks(const std::vector<colmap::CovarianceBlock> &blocks, const char *const *names,
                           py::dict &coords) {
  py::dict out;
  for (const colmap::CovarianceBlock &b : blocks) {
    const auto k = static_cast<py::ssize_t>(b.coords.size());
    py::tuple c(b.coords.size());
    for (size_t q = 0; q < b.coords.size(); ++q)
      c[q] = names ? py::object(py::str(names[b.coords[q]])) : py::object(py::int_(b.coords[q]));
    const py::int_ id(b.id);
    out[id] = copy_of(b.cov.data(), {k, k});
    coords[id] = c;
  }
  return out;
}

// refine_colmap's covariance=True: the covariances at p in COLMAP's convention
// (colmap::Problem::covariance) into d["colmap_covariance"], or why the library refused them into
// d["covariance_error"]; nothing once a callback or Ctrl-C failed the session.
void colmap_covariance(const colmap::Problem &pr, const colmap::ProblemPriors &priors, const colmap::Model &model,
                       const std::vector<double> &p, Session &session, const colmap::CovarianceOptions &options,
                       py::dict &d) {
  static const char *const pose[] = {"rx", "ry", "rz", "tx", "ty", "tz"};
  static const char *const point[] = {"x", "y", "z"};
  colmap::Covariances c;
  const size_t nerrors = session.errors().size();
  sba_ext_options ext = *session.ext(true);
  priors.attach(&ext);  // the priors' information is part of J^T J
  const bool ok = without_gil(session.released_thread(), [&] { return pr.covariance(model, p.data(), ext, options, &c); });
  if (session.failed()) {
    d["error"] = session.error();
    return;
  }
  if (!ok) {
    const std::vector<std::string> &errors = session.errors();
    d["covariance_error"] = errors.size() > nerrors ? errors[nerrors] : "the covariance could not be computed";
    return;
  }
  py::dict cov, coords;
  const struct {
    const char *kind;
    const std::vector<colmap::CovarianceBlock> &blocks;
    const char *const *names;
  } kinds[] = {{"images", c.images, pose}, {"frames", c.frames, pose}, {"sensors", c.sensors, pose},
               {"cameras", c.cameras, nullptr}, {"points", c.points, point}};
  for (const auto &k : kinds) {
    py::dict kc;
    cov[k.kind] = covariance_blocks(k.blocks, k.names, kc);
    coords[k.kind] = kc;
  }
  cov["coords"] = coords;
  cov["sigma2"] = c.sigma2;
  cov["rank"] = c.rank;
  cov["nfree"] = c.nfree;
  d["colmap_covariance"] = cov;
}

// refine_colmap's position priors (COLMAP's pose priors): from a database, or as given.
struct PriorInput {
  std::string database_path;             // empty: priors
  std::vector<colmap::PosePrior> priors;
  colmap::PosePriorOptions options;
};

// The solve sbarefine runs on a COLMAP model: the problem colmap::Problem builds, solved
// through its callbacks with its held and shared parameters, and written back into the model
// by Problem::apply unless nothing was solved (itmax 0), the points' errors with
// point_errors; d["behind"] lists the observations removed before (behind). With position
// priors, the model is
// first placed on them as sbarefine places it (colmap::place_on_priors), and d["priors_said"]
// tells how.
py::dict refine_model(colmap::Model model, const colmap::Options &options, SolveOptions o,
                      const colmap::CovarianceOptions &covariance_options, const PriorInput &prior_input,
                      bool point_errors, const colmap::DepthFilter &behind) {
  colmap::Problem pr;
  std::string error;
  std::vector<colmap::PosePrior> read = prior_input.priors, poses;
  if (!prior_input.database_path.empty() &&
      !colmap::read_pose_priors_database(prior_input.database_path, &read, &error))
    throw py::value_error(error);
  std::string said;
  const std::string source = !prior_input.database_path.empty() ? prior_input.database_path
                             : read.empty()                      ? std::string()
                                                                 : std::string("pose_priors");
  if (!colmap::place_on_priors(std::move(read), 0, source, {}, {}, prior_input.options, o.itmax > 0, &model, &poses,
                               &said, &error))
    throw py::value_error(error);
  if (!colmap::Problem::build(model, options, kModelName, &pr, &error)) throw py::value_error(error);
  colmap::ProblemPriors priors;
  if (!priors.build(pr, poses, prior_input.options, {}, {}, &error)) throw py::value_error(error);
  // The library can only say that the initial error is not finite (with itmax 0 too, which it
  // still evaluates); the model can say where.
  if (std::string why = pr.nonfinite_error(model, kModelName); !why.empty()) throw py::value_error(why);
  Run run;
  Observations &obs = run.obs;
  const sbaformats::eucsba::PointSet &points = pr.points();
  const int m = pr.ncameras(), n = pr.npoints(), cnp = pr.cnp();
  obs.n = n;
  obs.m = m;
  obs.mnp = 2;
  obs.point = points.pairs.point;
  obs.camera = points.pairs.camera;
  obs.x = points.x;
  obs.order.resize(obs.point.size());
  std::iota(obs.order.begin(), obs.order.end(), 0LL);
  run.p = pr.initial_params();
  run.cnp = cnp;
  run.pnp = 3;
  run.func = pr.func();
  run.fjac = pr.fjac();
  run.adata = pr.adata();
  run.parallel = true;  // the callbacks are re-entrant, as sbarefine runs them
  if (priors.size() > 0) run.colmap_priors = &priors;
  o.has_fixed = true;
  o.fixed = pr.cam_fixed();
  o.fixed_shape = {m, cnp};
  o.has_param_groups = true;
  o.param_groups = pr.cam_param_group();
  o.param_groups_shape = {m, cnp};
  o.ncon = pr.held_points();
  // The covariance is the problem's, in COLMAP's convention, not run_driver's over sba's parameters.
  const bool covariance = o.covariance;
  o.covariance = false;
  Session session(o);
  py::dict d = run_driver(run, session, o);
  const bool solved = d["ret"].cast<int>() != SBA_ERROR && !session.failed();
  if (covariance && solved) colmap_covariance(pr, priors, model, run.p, session, covariance_options, d);
  if (o.itmax > 0 && d["ret"].cast<int>() != SBA_ERROR) pr.apply(run.p.data(), &model, point_errors);
  d["model"] = python_model(model);
  d["cameras"] = copy_of(run.p.data(), {m, cnp});
  d["points"] = copy_of(run.p.data() + size_t(m) * size_t(cnp), {n, 3});
  d["nobs"] = obs.nobs();
  d["priors_said"] = said;
  d["npriors"] = priors.size();
  py::list removed;
  for (const colmap::TrackElement &e : behind.observations) removed.append(py::make_tuple(e.image_id, e.point2d_idx));
  d["behind"] = removed;
  return d;
}

// The images of a ColmapModel (every one, with a pose or not: its id and name) that hold_poses
// names, by the one matching rule of the lists of images (colmap::ImageIndex): all of them, or
// each item's, an int an IMAGE_ID and a str a NAME (pysba checked the types). Flags by the images
// of the model solved: rows gives each ColmapModel image's place there (-1: without a pose, not
// solved); empty when nothing is held.
std::vector<char> held_poses(py::handle model, bool all, const py::list &named, const std::vector<long long> &rows,
                             size_t solved) {
  if (!all && named.empty()) return {};
  const py::list images = items(get(model, "images"), "images");
  std::vector<colmap::Image> listed(images.size());
  for (size_t k = 0; k < images.size(); ++k) {
    listed[k].id = static_cast<std::uint32_t>(whole_number(get(images[k], "id"), kU32, at("images", k) + ".id"));
    listed[k].name = text(get(images[k], "name"), at("images", k) + ".name");
  }
  const colmap::ImageIndex index(listed);
  std::vector<char> flags(listed.size(), all ? 1 : 0);
  for (size_t k = 0; k < named.size(); ++k) {
    const py::handle item = named[k];
    std::string why;
    if (PyUnicode_Check(item.ptr())) {
      why = index.hold_name(text(item, at("hold_poses", k)), &flags);
    } else {
      const unsigned long long id = PyLong_AsUnsignedLongLong(item.ptr());
      if (id == ~0ULL && PyErr_Occurred()) {  // negative, or past 64 bits: no IMAGE_ID
        PyErr_Clear();
        why = "no image has the IMAGE_ID " + std::string(py::str(item));
      } else {
        why = index.hold_id(id, &flags);
      }
    }
    if (!why.empty()) throw py::value_error(at("hold_poses", k) + ": " + why);
  }
  std::vector<char> held(solved, 0);
  for (size_t k = 0; k < flags.size(); ++k)
    if (flags[k] && rows[k] >= 0) held[size_t(rows[k])] = 1;
  return held;
}

// A list of identifiers of refine_colmap (hold_intrinsics, hold_sensor_from_rig: CAMERA_IDs;
// hold_points: POINT3D_IDs): what it names, and what messages call it.
struct IdList {
  const char *option, *noun, *kind;  // "hold_points", "point", "POINT3D_ID"
  std::uint64_t max;
  std::string (*parse)(const colmap::Model &, const std::string &, std::vector<char> *);
};

// The flags (one per Model::cameras or Model::points) of what a list of identifiers names: all
// of them, or each item's (ints: pysba checked the types). The items go to the library's
// parse_camera_list or parse_point_list as sbarefine's --hold-intrinsics, --hold-sensor-from-rig
// and --hold-points give them, as one list of their decimal texts, so that an id names what it
// names there. An int no id can be (negative, or past the kind's range) names nothing, as an
// id the model does not have. Empty when nothing is held.
std::vector<char> held_ids(const colmap::Model &m, const IdList &l, bool all, const py::list &named) {
  std::vector<char> held;
  if (!all && named.empty()) return held;
  std::string list = "all";
  std::vector<size_t> ends;  // where the text of items 0..k ends in list
  std::string beyond;        // why the first int that is no id names nothing (the items before it are parsed)
  if (!all) {
    list.clear();
    for (size_t k = 0; k < named.size() && beyond.empty(); ++k) {
      const unsigned long long id = PyLong_AsUnsignedLongLong(named[k].ptr());
      if ((id == ~0ULL && PyErr_Occurred()) || id > l.max) {
        PyErr_Clear();
        beyond = at(l.option, k) + ": no " + l.noun + " has the " + l.kind + " '" +
                 std::string(py::str(named[k])) + "'";
      } else {
        list += (k ? "," : "") + std::to_string(id);
        ends.push_back(list.size());
      }
    }
  }
  const std::string why = ends.empty() && !all ? std::string() : l.parse(m, list, &held);
  if (why.empty() && !beyond.empty()) throw py::value_error(beyond);
  if (why.empty()) return held;
  // The library names the first item that names nothing, not its place: the shortest prefix of
  // the list that it refuses ends with that item (a few more parses, on the way to an error).
  size_t good = 0, bad = ends.size();
  while (bad - good > 1) {
    const size_t mid = (good + bad) / 2;
    std::vector<char> scratch;
    (l.parse(m, list.substr(0, ends[mid - 1]), &scratch).empty() ? good : bad) = mid;
  }
  throw py::value_error(at(l.option, bad - 1) + ": " + why);
}

// Flags by records (a model's frames, images or points: what has each id) of the ids a
// configuration names (option and kind name them in messages: "hold_frames", "frame with a pose",
// "FRAME_ID"); an id no record has is a ValueError, as COLMAP refuses one. Empty when none is
// named.
template <typename Record>
std::vector<char> flags_of(const std::vector<Record> &records, const py::list &ids, const char *option,
                           const char *noun, const char *kind) {
  std::vector<char> flags;
  if (ids.empty()) return flags;
  std::unordered_map<std::uint64_t, std::size_t> index;
  for (std::size_t k = 0; k < records.size(); ++k) index.emplace(records[k].id, k);
  flags.assign(records.size(), 0);
  for (std::size_t k = 0; k < ids.size(); ++k) {
    const unsigned long long id = PyLong_AsUnsignedLongLong(ids[k].ptr());
    if (id == ~0ULL && PyErr_Occurred()) PyErr_Clear();
    const auto it = index.find(id);
    if (it == index.end())
      throw py::value_error(at(option, k) + ": no " + noun + " has the " + kind + " '" + std::string(py::str(ids[k])) +
                            "'");
    flags[it->second] = 1;
  }
  return flags;
}

py::dict refine_colmap(py::handle model, bool hold_all, const py::list &hold_poses, bool focal, bool principal,
                       bool extra, bool rig_from_world, bool sensor_from_rig, bool constant_rotation,
                       const py::tuple &hold_intrinsics, const py::tuple &hold_sensor_from_rig,
                       const py::tuple &hold_points, bool covariance_points, double covariance_damping,
                       const std::string &database_path, const py::list &pose_priors, double fallback_stddev,
                       const std::string &prior_loss, double prior_loss_scale, double alignment_max_error,
                       const py::list &hold_frames, const py::object &config_images, const py::list &variable_points,
                       int min_track_length, bool refine_points, const std::string &gauge, bool point_errors,
                       bool remove_behind, const py::kwargs &kw) {
  const SolveOptions o = solve_options(kw);
  std::vector<long long> rows;
  colmap::Model m = model_of(model, &rows);
  colmap::DepthFilter behind;  // sbarefine's filter, before the points are indexed: it deletes some
  if (remove_behind) behind = colmap::filter_negative_depth(&m);
  std::vector<char> held = held_poses(model, hold_all, hold_poses, rows, m.images.size());
  colmap::Options options;
  options.intrinsics = {focal, principal, extra};
  options.poses = {rig_from_world, sensor_from_rig, constant_rotation};
  options.constants.poses = std::move(held);
  // Each (all, ids) as pysba/_colmap.py's _held_ids gives it.
  const struct {
    const py::tuple &given;
    IdList list;
    std::vector<char> *held;
  } lists[] = {
      {hold_intrinsics, {"hold_intrinsics", "camera", "CAMERA_ID", UINT32_MAX, colmap::parse_camera_list},
       &options.constants.intrinsics},
      {hold_sensor_from_rig, {"hold_sensor_from_rig", "camera", "CAMERA_ID", UINT32_MAX, colmap::parse_camera_list},
       &options.constants.sensor_from_rig},
      {hold_points, {"hold_points", "point", "POINT3D_ID", UINT64_MAX, colmap::parse_point_list},
       &options.constants.points}};
  for (const auto &l : lists)
    *l.held = held_ids(m, l.list, l.given[0].cast<bool>(), l.given[1].cast<py::list>());
  options.mcon = o.mcon;
  options.ncon = o.ncon;
  // COLMAP's BundleAdjustmentConfig (pysba.colmap.bundle_adjustment's): ids pysba took from it.
  options.constants.frames = flags_of(m.frames, hold_frames, "hold_frames", "frame with a pose", "FRAME_ID");
  if (!config_images.is_none()) {
    const py::list images = config_images.cast<py::list>();
    if (images.empty()) throw py::value_error("images names no image: give None for every one");
    options.selection.images = flags_of(m.images, images, "images", "image with a pose", "IMAGE_ID");
  }
  options.selection.variable_points = flags_of(m.points, variable_points, "variable_points", "point", "POINT3D_ID");
  options.selection.min_track_length = min_track_length;
  options.refine_points = refine_points;
  if (gauge == "two-cams")
    options.gauge = colmap::Gauge::TwoCamsFromWorld;
  else if (gauge == "three-points")
    options.gauge = colmap::Gauge::ThreePoints;
  else if (!gauge.empty())
    throw py::value_error("gauge must be '', 'two-cams' or 'three-points', got '" + gauge + "'");
  if (!(covariance_damping >= 0.0 && covariance_damping <= DBL_MAX))
    throw py::value_error("covariance_damping must be finite and >= 0, got " + std::string(py::repr(py::float_(covariance_damping))));
  PriorInput priors;
  priors.database_path = database_path;
  priors.options.fallback_stddev = fallback_stddev;
  priors.options.loss = prior_loss;
  priors.options.loss_scale = prior_loss_scale;
  priors.options.alignment_max_error = alignment_max_error;
  // Each (image_id, position, covariance or None, coordinate system) as pysba/_colmap.py's
  // _pose_priors gives it, checked there.
  for (size_t k = 0; k < pose_priors.size(); ++k) {
    const py::tuple t = pose_priors[k].cast<py::tuple>();
    colmap::PosePrior p;
    p.where = at("pose_priors", k);
    p.image_id = t[0].cast<std::uint32_t>();
    const std::vector<double> position = t[1].cast<std::vector<double>>();
    std::copy(position.begin(), position.end(), p.position.begin());
    if (!t[2].is_none()) {
      const std::vector<double> cov = t[2].cast<std::vector<double>>();
      std::copy(cov.begin(), cov.end(), p.covariance.begin());
      p.has_covariance = true;
    }
    p.system = static_cast<colmap::PriorSystem>(t[3].cast<int>());
    priors.priors.push_back(p);
  }
  return refine_model(std::move(m), options, o, {covariance_points, covariance_damping}, priors, point_errors,
                      behind);
}

// COLMAP's stopping rule (colmap::colmap_stop_rule): (strategy, eps1, eps4), the strategy to
// run unless one is given, or None when the rule leaves sba's tests (eps4 then unchanged).
py::tuple colmap_stop_rule(double function_tolerance, double gradient_tolerance, bool strategy_given, double eps1,
                           double eps4) {
  const bool applies = colmap::colmap_stop_rule(function_tolerance, gradient_tolerance, strategy_given, &eps1, &eps4);
  return py::make_tuple(applies ? py::object(py::str(colmap::kColmapStrategy)) : py::object(py::none()), eps1, eps4);
}

}  // namespace

void add_colmap(py::module_ &mod) {
  mod.def("read_colmap", &read_colmap, py::arg("path"));
  mod.def("write_colmap", &write_colmap, py::arg("model"), py::arg("path"), py::arg("encoding"));
  mod.def("colmap_stop_rule", &colmap_stop_rule, py::arg("function_tolerance"), py::arg("gradient_tolerance"),
          py::arg("strategy_given"), py::arg("eps1"), py::arg("eps4"));
  mod.def("refine_colmap", &refine_colmap, py::arg("model"), py::arg("hold_all"), py::arg("hold_poses"),
          py::arg("refine_focal_length"), py::arg("refine_principal_point"), py::arg("refine_extra_params"),
          py::arg("refine_rig_from_world"), py::arg("refine_sensor_from_rig"),
          py::arg("constant_rig_from_world_rotation"), py::arg("hold_intrinsics"), py::arg("hold_sensor_from_rig"),
          py::arg("hold_points"), py::arg("covariance_points"), py::arg("covariance_damping"),
          py::arg("database_path"), py::arg("pose_priors"), py::arg("prior_position_fallback_stddev"),
          py::arg("prior_position_loss"), py::arg("prior_position_loss_scale"), py::arg("alignment_max_error"),
          py::arg("hold_frames") = py::list(), py::arg("images") = py::none(), py::arg("variable_points") = py::list(),
          py::arg("min_track_length") = 0, py::arg("refine_points3D") = true, py::arg("gauge") = "",
          py::arg("point_errors") = true, py::arg("remove_behind") = true);
}

}  // namespace pysba
