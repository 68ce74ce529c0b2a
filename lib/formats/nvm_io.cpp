// SPDX-License-Identifier: BSD-3-Clause
#include "formats/nvm_io.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <utility>

#include "cameras/camera_pose.h"
#include "formats/colmap_io.h"
#include "formats/output_file.h"
#include "formats/text_tokens.h"

namespace sbaformats::nvm {

namespace {

bool fail(std::string *error, const std::string &msg) { return TextTokens::fail(error, msg); }

constexpr char kVersion[] = "NVM_V3";

bool parse_camera(TextTokens *t, long long j, Camera *c, std::string *error) {
  const std::string cam = "camera " + std::to_string(j) + " ";
  if (!t->next(&c->name)) return fail(error, t->ends_before(cam + "file name"));
  if (!t->real(cam + "focal length", &c->f, error)) return false;
  if (c->f <= 0) return fail(error, t->where() + cam + "focal length must be positive, got " + g17(c->f));
  static const char *const kQ[] = {"qw", "qx", "qy", "qz"};
  for (int k = 0; k < 4; ++k)
    if (!t->real(cam + kQ[k], &c->q[k], error)) return false;
  if (c->q[0] == 0 && c->q[1] == 0 && c->q[2] == 0 && c->q[3] == 0)
    return fail(error, t->where() + cam + "quaternion is zero");
  static const char *const kC[] = {"cx", "cy", "cz"};
  for (int k = 0; k < 3; ++k)
    if (!t->real(cam + kC[k], &c->c[k], error)) return false;
  if (!t->real(cam + "radial distortion", &c->k, error)) return false;
  std::string end;
  if (!t->next(&end)) return fail(error, t->ends_before(cam + "closing 0"));
  if (end != "0")
    return fail(error, t->where() + cam + "must end with 0, got '" + TextTokens::printable(end) + "'");
  return true;
}

bool parse_point(TextTokens *t, long long i, long long ncams, std::vector<long long> *seen, Point *p,
                 std::string *error) {
  const std::string pt = "point " + std::to_string(i) + " ";
  for (int k = 0; k < 3; ++k)
    if (!t->real(pt + "XYZ"[k], &p->xyz[k], error)) return false;
  static const char *const kColor[] = {"red", "green", "blue"};
  for (int k = 0; k < 3; ++k) {
    long long v;
    if (!t->integer(pt + kColor[k], 0, 255, &v, error)) return false;
    p->rgb[k] = static_cast<int>(v);
  }
  long long n;
  if (!t->integer(pt + "measurement count", 1, ncams, &n, error)) return false;
  p->measurements.resize(static_cast<std::size_t>(n));
  for (Measurement &m : p->measurements) {
    long long cam, feature;
    if (!t->integer(pt + "image index", 0, ncams - 1, &cam, error) ||
        !t->integer(pt + "feature index", 0, 0x7fffffff, &feature, error) || !t->real(pt + "x", &m.x, error) ||
        !t->real(pt + "y", &m.y, error))
      return false;
    if ((*seen)[static_cast<std::size_t>(cam)] == i)
      return fail(error, t->where() + "point " + std::to_string(i) + " is seen twice by camera " + std::to_string(cam));
    (*seen)[static_cast<std::size_t>(cam)] = i;
    m.camera = static_cast<int>(cam);
    m.feature = static_cast<int>(feature);
  }
  return true;
}

}  // namespace

bool parse_nvm(const std::string &text, const std::string &name, Model *out, std::string *error) {
  const std::size_t eol = std::min(text.find('\n'), text.size());
  Model m;
  m.header = text.substr(0, eol);
  const std::string version = m.header.substr(0, m.header.find_first_of(" \t\r"));
  if (version != kVersion)
    return fail(error, name + ":1: expected the header '" + kVersion + "', got '" + TextTokens::printable(version) +
                           "'");
  TextTokens t(text, name, std::min(eol + 1, text.size()), 2);
  long long ncams, npts;
  if (!t.integer("the number of cameras", 0, 1 << 24, &ncams, error)) return false;
  if (ncams == 0) return fail(error, t.where() + "the first model has no camera (a count of 0 ends the models)");
  // Every camera takes 11 values, at least 22 characters: a count the text cannot hold is
  // found before the memory is taken.
  if (static_cast<unsigned long long>(ncams) * 22 > text.size())
    return fail(error, name + ": " + std::to_string(ncams) + " cameras need more values than the file holds");
  m.cameras.resize(static_cast<std::size_t>(ncams));
  for (long long j = 0; j < ncams; ++j)
    if (!parse_camera(&t, j, &m.cameras[static_cast<std::size_t>(j)], error)) return false;
  if (!t.integer("the number of points", 0, 1 << 28, &npts, error)) return false;
  // Every point takes at least 11 values.
  if (static_cast<unsigned long long>(npts) * 22 > text.size())
    return fail(error, name + ": " + std::to_string(npts) + " points need more values than the file holds");
  m.points.resize(static_cast<std::size_t>(npts));
  std::vector<long long> seen(static_cast<std::size_t>(ncams), -1);
  for (long long i = 0; i < npts; ++i)
    if (!parse_point(&t, i, ncams, &seen, &m.points[static_cast<std::size_t>(i)], error)) return false;
  // The rest starts on the line after the model's last value.
  std::size_t at = t.pos();
  while (at < text.size() && (text[at] == ' ' || text[at] == '\t' || text[at] == '\r')) ++at;
  if (at < text.size() && text[at] == '\n') ++at;
  m.rest = text.substr(at);
  *out = std::move(m);
  return true;
}

bool read_nvm(const std::string &path, Model *out, std::string *error) {
  std::string text;
  return colmap::read_whole_file(path, true, &text, error) && parse_nvm(text, path, out, error);
}

std::string format_nvm(const Model &m) {
  std::string s = m.header + "\n\n" + std::to_string(m.cameras.size()) + "\n";
  for (const Camera &c : m.cameras) {
    s += c.name + " " + g17(c.f);
    for (double v : c.q) s += " " + g17(v);
    for (double v : c.c) s += " " + g17(v);
    s += " " + g17(c.k) + " 0\n";
  }
  s += "\n" + std::to_string(m.points.size()) + "\n";
  for (const Point &p : m.points) {
    s += g17(p.xyz[0]) + " " + g17(p.xyz[1]) + " " + g17(p.xyz[2]) + " " + std::to_string(p.rgb[0]) + " " +
         std::to_string(p.rgb[1]) + " " + std::to_string(p.rgb[2]) + " " + std::to_string(p.measurements.size());
    for (const Measurement &v : p.measurements)
      s += " " + std::to_string(v.camera) + " " + std::to_string(v.feature) + " " + g17(v.x) + " " + g17(v.y);
    s += "\n";
  }
  return s + m.rest;
}

bool write_nvm(const std::string &path, const Model &m, std::string *error, OutputSet *outputs) {
  return write_whole_file(path, format_nvm(m), error, outputs);
}

bool looks_uncentred(const Model &m) {
  long long count = 0, positive = 0;
  double sum[2] = {0, 0}, sum_sq[2] = {0, 0};
  for (const Point &pt : m.points)
    for (const Measurement &v : pt.measurements) {
      ++count;
      if (v.x >= 0 && v.y >= 0) ++positive;
      const double xy[2] = {v.x, v.y};
      for (int a = 0; a < 2; ++a) {
        sum[a] += xy[a];
        sum_sq[a] += xy[a] * xy[a];
      }
    }
  if (count < 100 || positive < 0.99 * static_cast<double>(count)) return false;
  for (int a = 0; a < 2; ++a) {
    const double mean = sum[a] / static_cast<double>(count);
    const double variance = std::max(0.0, sum_sq[a] / static_cast<double>(count) - mean * mean);
    if (!(mean * mean > variance)) return false;
  }
  return true;
}

bool to_sba(const Model &m, bool refine_focal, const std::string &name, SbaProblem *out,
            std::string *error) {
  const int ncams = static_cast<int>(m.cameras.size()), n = static_cast<int>(m.points.size());
  if (ncams == 0 || n == 0) return fail(error, name + ": the first model has no cameras or no points");
  SbaProblem p;
  p.nccalib = refine_focal ? 4 : 5;
  p.ncdist = sbacameras::euclidean::kDistortionParams;
  for (std::size_t j = 0; j < m.cameras.size(); ++j) {
    const Camera &c = m.cameras[j];
    sbacameras::euclidean::Camera e;
    e.k.fu = c.f;
    e.k.u0 = e.k.v0 = 0;
    e.q = sbacameras::euclidean::normalized_rotation({c.q[0], c.q[1], c.q[2], c.q[3]});
    double R[9];
    sbacameras::euclidean::rotation_matrix(e.q, R);
    sbacameras::camera_translation(R, c.c, e.t.data());
    if (!std::isfinite(e.t[0]) || !std::isfinite(e.t[1]) || !std::isfinite(e.t[2]))
      return fail(error, name + ": camera " + std::to_string(j) + ": its translation -R C overflows");
    p.cameras.push_back(e);
  }
  eucsba::PointSet &s = p.points;
  s.ncameras = ncams;
  s.xyz.reserve(static_cast<std::size_t>(n) * 3);
  std::vector<bool> used(static_cast<std::size_t>(ncams), false);
  std::vector<Measurement> track;
  for (int i = 0; i < n; ++i) {
    const Point &pt = m.points[static_cast<std::size_t>(i)];
    s.xyz.insert(s.xyz.end(), pt.xyz.begin(), pt.xyz.end());
    // sba's layout: a point's projections with the cameras ascending.
    track = pt.measurements;
    std::sort(track.begin(), track.end(),
              [](const Measurement &a, const Measurement &b) { return a.camera < b.camera; });
    for (const Measurement &v : track) {
      const std::size_t j = static_cast<std::size_t>(v.camera);
      s.pairs.add(i, static_cast<int>(j));
      const double scale = 1 + m.cameras[j].k * (v.x * v.x + v.y * v.y);
      s.x.push_back(v.x * scale);
      s.x.push_back(v.y * scale);
      if (!std::isfinite(s.x[s.x.size() - 2]) || !std::isfinite(s.x.back()))
        return fail(error, name + ": point " + std::to_string(i) + ": its measurement in camera " + std::to_string(j) +
                               " undistorts to a value that overflows");
      used[j] = true;
    }
  }
  for (int j = 0; j < ncams; ++j)
    if (!used[static_cast<std::size_t>(j)])
      return fail(error, name + ": camera " + std::to_string(j) + " (" +
                             TextTokens::printable(m.cameras[static_cast<std::size_t>(j)].name) +
                             ") sees no point: sba cannot place it");
  *out = std::move(p);
  return true;
}

void from_sba(const sbacameras::euclidean::CameraModel &sba_model, const double *p, int mcon, int ncon, Model *m) {
  const int ncams = static_cast<int>(m->cameras.size()), n = static_cast<int>(m->points.size());
  const int cnp = sba_model.cnp();
  for (int j = mcon; j < ncams; ++j) {
    const sbacameras::euclidean::Camera e = sba_model.camera(j, p + static_cast<std::size_t>(j) * cnp);
    Camera &c = m->cameras[static_cast<std::size_t>(j)];
    c.f = e.k.fu;
    c.q = {e.q.w, e.q.x, e.q.y, e.q.z};
    double R[9];
    sbacameras::euclidean::rotation_matrix(e.q, R);
    c.c = sbacameras::camera_centre(R, e.t.data());
  }
  const double *points = p + static_cast<std::size_t>(ncams) * cnp;
  for (int i = ncon; i < n; ++i)
    for (int k = 0; k < 3; ++k)
      m->points[static_cast<std::size_t>(i)].xyz[k] = points[3 * static_cast<std::size_t>(i) + k];
}

bool from_problem(const std::vector<sbacameras::euclidean::Camera> &cameras, const eucsba::PointSet &points, Model *out,
                  std::string *error) {
  const int ncams = static_cast<int>(cameras.size()), n = points.npoints();
  if (points.ncameras != ncams ||
      points.vmask.size() != static_cast<std::size_t>(n) * static_cast<std::size_t>(ncams))
    return fail(error, "an NVM model needs the points' dense visibility mask");
  Model m;
  for (int j = 0; j < ncams; ++j) {
    const sbacameras::euclidean::Camera &e = cameras[static_cast<std::size_t>(j)];
    if (e.k.ar != 1 || e.k.s != 0 || std::any_of(e.kc.begin(), e.kc.end(), [](double v) { return v != 0; }))
      return fail(error, "camera " + std::to_string(j) +
                             " has an aspect ratio, a skew or distortion terms, which NVM cannot hold");
    Camera c;
    char name[32];
    std::snprintf(name, sizeof name, "img_%04d.jpg", j);
    c.name = name;
    c.f = e.k.fu;
    const sbacameras::euclidean::Quaternion q = sbacameras::euclidean::normalized_rotation(e.q);
    c.q = {q.w, q.x, q.y, q.z};
    double R[9];
    sbacameras::euclidean::rotation_matrix(q, R);
    c.c = sbacameras::camera_centre(R, e.t.data());
    m.cameras.push_back(std::move(c));
  }
  m.points.resize(static_cast<std::size_t>(n));
  for (int i = 0; i < n; ++i) {
    Point &p = m.points[static_cast<std::size_t>(i)];
    for (int c = 0; c < 3; ++c) p.xyz[c] = points.xyz[3 * static_cast<std::size_t>(i) + c];
    p.rgb = eucsba::generated_color(i);
  }
  eucsba::for_each_projection(points, [&](int i, int j, const double *x) {
    const sbacameras::euclidean::Camera &e = cameras[static_cast<std::size_t>(j)];
    m.points[static_cast<std::size_t>(i)].measurements.push_back({j, i, x[0] - e.k.u0, x[1] - e.k.v0});
  });
  *out = std::move(m);
  return true;
}

}  // namespace sbaformats::nvm
