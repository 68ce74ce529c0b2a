// SPDX-License-Identifier: BSD-3-Clause
#include "formats/bundler_io.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <utility>

#include "cameras/bal_camera.h"
#include "formats/colmap_io.h"
#include "formats/output_file.h"
#include "formats/text_tokens.h"

namespace sbaformats::bundler {

namespace {

bool fail(std::string *error, const std::string &msg) { return TextTokens::fail(error, msg); }

constexpr char kHeader[] = "# Bundle file v0.3";

}  // namespace

bool parse_bundle(const std::string &text, const std::string &name, Bundle *out, std::string *error) {
  if (text.compare(0, sizeof kHeader - 1, kHeader) != 0)
    return fail(error, name + ":1: expected the header '" + kHeader + "'");
  const std::size_t eol = text.find('\n');
  TextTokens t(text, name, eol == std::string::npos ? text.size() : eol + 1, 2);
  long long ncams, npts;
  if (!t.integer("the number of cameras", 0, 1 << 24, &ncams, error) ||
      !t.integer("the number of points", 0, 1 << 28, &npts, error))
    return false;
  Bundle b;
  // Every camera takes 15 numbers, every point at least 7: a count the text cannot hold is
  // found before the memory is taken.
  if (static_cast<unsigned long long>(ncams) * 30 + static_cast<unsigned long long>(npts) * 14 > text.size())
    return fail(error, name + ": the counts (" + std::to_string(ncams) + " cameras, " + std::to_string(npts) +
                           " points) need more numbers than the file holds");
  b.cameras.resize(static_cast<std::size_t>(ncams));
  for (long long j = 0; j < ncams; ++j) {
    Camera &c = b.cameras[static_cast<std::size_t>(j)];
    const std::string cam = "camera " + std::to_string(j) + " ";
    if (!t.real(cam + "f", &c.f, error) || !t.real(cam + "k1", &c.k1, error) || !t.real(cam + "k2", &c.k2, error))
      return false;
    for (int k = 0; k < 9; ++k)
      if (!t.real(cam + "R" + std::to_string(k / 3) + std::to_string(k % 3), &c.R[k], error)) return false;
    const std::string r_line = t.where();
    for (int k = 0; k < 3; ++k)
      if (!t.real(cam + "t" + std::to_string(k), &c.t[k], error)) return false;
    if (c.registered()) {
      double worst = 0;
      for (int r = 0; r < 3; ++r)
        for (int s = 0; s < 3; ++s) {
          const double d = c.R[r] * c.R[s] + c.R[3 + r] * c.R[3 + s] + c.R[6 + r] * c.R[6 + s];
          worst = std::max(worst, std::fabs(d - (r == s ? 1.0 : 0.0)));
        }
      const double det = c.R[0] * (c.R[4] * c.R[8] - c.R[5] * c.R[7]) - c.R[1] * (c.R[3] * c.R[8] - c.R[5] * c.R[6]) +
                         c.R[2] * (c.R[3] * c.R[7] - c.R[4] * c.R[6]);
      if (worst > 1e-6 || det < 0)
        return fail(error, r_line + "camera " + std::to_string(j) + ": R is not a rotation");
    }
  }
  b.points.resize(static_cast<std::size_t>(npts));
  std::vector<long long> seen(static_cast<std::size_t>(ncams), -1);
  for (long long i = 0; i < npts; ++i) {
    Point &p = b.points[static_cast<std::size_t>(i)];
    const std::string pt = "point " + std::to_string(i) + " ";
    for (int k = 0; k < 3; ++k)
      if (!t.real(pt + "XYZ"[k], &p.xyz[k], error)) return false;
    static const char *const kColor[] = {"red", "green", "blue"};
    for (int k = 0; k < 3; ++k) {
      long long v;
      if (!t.integer(pt + kColor[k], 0, 255, &v, error)) return false;
      p.rgb[k] = static_cast<int>(v);
    }
    long long nviews;
    if (!t.integer(pt + "view count", 0, ncams, &nviews, error)) return false;
    p.views.resize(static_cast<std::size_t>(nviews));
    for (View &v : p.views) {
      long long cam, key;
      if (!t.integer(pt + "camera index", 0, ncams - 1, &cam, error) ||
          !t.integer(pt + "key index", 0, 0x7fffffff, &key, error) || !t.real(pt + "x", &v.x, error) ||
          !t.real(pt + "y", &v.y, error))
        return false;
      if (seen[static_cast<std::size_t>(cam)] == i)
        return fail(error, t.where() + "point " + std::to_string(i) + " is seen twice by camera " + std::to_string(cam));
      seen[static_cast<std::size_t>(cam)] = i;
      if (!b.cameras[static_cast<std::size_t>(cam)].registered())
        return fail(error, t.where() + "point " + std::to_string(i) + " is seen by camera " + std::to_string(cam) +
                               ", which is not registered (f = 0)");
      v.camera = static_cast<int>(cam);
      v.key = static_cast<int>(key);
    }
  }
  std::string extra;
  if (t.next(&extra)) return fail(error, t.where() + "data after the last point");
  *out = std::move(b);
  return true;
}

bool read_bundle(const std::string &path, Bundle *out, std::string *error) {
  std::string text;
  return colmap::read_whole_file(path, true, &text, error) && parse_bundle(text, path, out, error);
}

std::string format_bundle(const Bundle &b) {
  std::string s = std::string(kHeader) + "\n" + std::to_string(b.cameras.size()) + " " +
                  std::to_string(b.points.size()) + "\n";
  for (const Camera &c : b.cameras) {
    s += g17(c.f) + " " + g17(c.k1) + " " + g17(c.k2) + "\n";
    for (int r = 0; r < 3; ++r) s += g17(c.R[3 * r]) + " " + g17(c.R[3 * r + 1]) + " " + g17(c.R[3 * r + 2]) + "\n";
    s += g17(c.t[0]) + " " + g17(c.t[1]) + " " + g17(c.t[2]) + "\n";
  }
  for (const Point &p : b.points) {
    s += g17(p.xyz[0]) + " " + g17(p.xyz[1]) + " " + g17(p.xyz[2]) + "\n";
    s += std::to_string(p.rgb[0]) + " " + std::to_string(p.rgb[1]) + " " + std::to_string(p.rgb[2]) + "\n";
    s += std::to_string(p.views.size());
    for (const View &v : p.views)
      s += " " + std::to_string(v.camera) + " " + std::to_string(v.key) + " " + g17(v.x) + " " + g17(v.y);
    s += "\n";
  }
  return s;
}

bool write_bundle(const std::string &path, const Bundle &b, std::string *error, OutputSet *outputs) {
  return write_whole_file(path, format_bundle(b), error, outputs);
}

void angle_axis(const std::array<double, 9> &R, double w[3]) {
  const double c = std::clamp((R[0] + R[4] + R[8] - 1) / 2, -1.0, 1.0);
  const double v[3] = {(R[7] - R[5]) / 2, (R[2] - R[6]) / 2, (R[3] - R[1]) / 2};
  const double s = std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
  const double angle = std::atan2(s, c);
  if (s > 1e-7 || c > 0) {
    // sin(angle) = s: w = v angle / s, with angle / s -> 1 for small angles.
    const double scale = s > 1e-7 ? angle / s : 1.0;
    for (int k = 0; k < 3; ++k) w[k] = v[k] * scale;
    return;
  }
  // Near a half turn v carries no direction: the axis from R + I = 2 a a^T (for angle pi).
  int big = 0;
  for (int k = 1; k < 3; ++k)
    if (R[4 * k] > R[4 * big]) big = k;
  double a[3];
  a[big] = std::sqrt(std::max(0.0, (R[4 * big] + 1) / 2));
  for (int k = 0; k < 3; ++k)
    if (k != big) a[k] = (R[3 * big + k] + R[3 * k + big]) / (4 * a[big]);
  for (int k = 0; k < 3; ++k) w[k] = a[k] * angle;
}

bool parse_list(const std::string &text, const std::string &name, ImageList *out, std::string *error) {
  ImageList list;
  std::size_t pos = 0;
  for (int lineno = 1; pos < text.size(); ++lineno) {
    std::size_t end = text.find('\n', pos);
    if (end == std::string::npos) end = text.size();
    std::string line = text.substr(pos, end - pos);
    pos = end + 1;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    std::vector<std::string> values;
    TextTokens t(line, name, 0, lineno);
    std::string tok;
    while (t.next(&tok)) values.push_back(tok);
    const std::string where = name + ":" + std::to_string(lineno) + ": ";
    if (values.size() != 1 && values.size() != 3)
      return fail(error, where + "expected PATH or PATH 0 FOCAL, found " + std::to_string(values.size()) + " values");
    if (values.size() == 3) {
      if (values[1] != "0")
        return fail(error, where + "expected 0 after the path, got '" + TextTokens::printable(values[1]) + "'");
      double f;
      if (!decimal_number(values[2], &f) || !std::isfinite(f) || f <= 0)
        return fail(error, where + "the focal length must be a finite positive number, got '" +
                               TextTokens::printable(values[2]) + "'");
    }
    list.names.push_back(values[0]);
  }
  list.text = text;
  *out = std::move(list);
  return true;
}

bool read_list(const std::string &path, ImageList *out, std::string *error) {
  std::string text;
  return colmap::read_whole_file(path, true, &text, error) && parse_list(text, path, out, error);
}

bool to_bal(const Bundle &b, const std::string &name, bal::Problem *out, std::vector<int> *cameras,
            std::string *error, const std::vector<std::string> &names) {
  std::vector<int> index(b.cameras.size(), -1), used(b.cameras.size(), 0);
  bal::Problem p;
  std::vector<int> order;
  for (std::size_t j = 0; j < b.cameras.size(); ++j) {
    const Camera &c = b.cameras[j];
    if (!c.registered()) continue;
    index[j] = static_cast<int>(order.size());
    order.push_back(static_cast<int>(j));
    double w[3];
    angle_axis(c.R, w);
    p.cameras.insert(p.cameras.end(), {w[0], w[1], w[2], c.t[0], c.t[1], c.t[2], c.f, c.k1, c.k2});
  }
  for (std::size_t i = 0; i < b.points.size(); ++i) {
    const Point &pt = b.points[i];
    p.points.insert(p.points.end(), pt.xyz.begin(), pt.xyz.end());
    for (const View &v : pt.views) {
      p.observations.push_back({index[static_cast<std::size_t>(v.camera)], static_cast<int>(i), v.x, v.y});
      used[static_cast<std::size_t>(v.camera)] = 1;
    }
  }
  for (int j : order) {
    if (used[static_cast<std::size_t>(j)]) continue;
    const std::string image =
        names.empty() ? "" : " (" + TextTokens::printable(names[static_cast<std::size_t>(j)]) + ")";
    return fail(error, name + ": camera " + std::to_string(j) + image + " is registered but sees no point");
  }
  if (order.empty() || b.points.empty()) return fail(error, name + ": no registered camera or no point");
  p.ncameras = static_cast<int>(order.size());
  p.npoints = static_cast<int>(b.points.size());
  *out = std::move(p);
  *cameras = std::move(order);
  return true;
}

void from_bal(const bal::Problem &p, const std::vector<int> &cameras, int mcon, int ncon, Bundle *b) {
  for (int k = mcon; k < p.ncameras; ++k) {
    Camera &c = b->cameras[static_cast<std::size_t>(cameras[static_cast<std::size_t>(k)])];
    const double *a = p.camera(k);
    sbacameras::bal::rotation_matrix(a, c.R.data());
    for (int i = 0; i < 3; ++i) c.t[i] = a[3 + i];
    c.f = a[6];
    c.k1 = a[7];
    c.k2 = a[8];
  }
  for (int i = ncon; i < p.npoints; ++i)
    for (int k = 0; k < 3; ++k) b->points[static_cast<std::size_t>(i)].xyz[k] = p.point(i)[k];
}

}  // namespace sbaformats::bundler

namespace sbaformats::bundler {

bool from_problem(const std::vector<sbacameras::euclidean::Camera> &cameras, const eucsba::PointSet &points, Bundle *out,
                  std::string *error) {
  const int m = static_cast<int>(cameras.size()), n = points.npoints();
  if (points.ncameras != m || points.vmask.size() != static_cast<std::size_t>(n) * static_cast<std::size_t>(m))
    return fail(error, "a bundle needs the points' dense visibility mask");
  Bundle b;
  for (int j = 0; j < m; ++j) {
    const sbacameras::euclidean::Camera &e = cameras[static_cast<std::size_t>(j)];
    if (e.k.ar != 1 || e.k.s != 0 || e.kc[2] != 0 || e.kc[3] != 0 || e.kc[4] != 0)
      return fail(error, "camera " + std::to_string(j) +
                             " has an aspect ratio, a skew or distortion terms beyond k1 k2, which Bundler cannot hold");
    Camera c;
    c.f = e.k.fu;
    c.k1 = e.kc[0];
    c.k2 = e.kc[1];
    double R[9];
    sbacameras::euclidean::rotation_matrix(sbacameras::euclidean::normalized_rotation(e.q), R);
    // Bundler's camera axes are (x, -y, -z) of eucsbademo's.
    for (int k = 0; k < 9; ++k) c.R[k] = k < 3 ? R[k] : -R[k];
    c.t = {e.t[0], -e.t[1], -e.t[2]};
    b.cameras.push_back(c);
  }
  b.points.resize(static_cast<std::size_t>(n));
  for (int i = 0; i < n; ++i) {
    Point &p = b.points[static_cast<std::size_t>(i)];
    for (int c = 0; c < 3; ++c) p.xyz[c] = points.xyz[3 * static_cast<std::size_t>(i) + c];
    p.rgb = eucsba::generated_color(i);
  }
  eucsba::for_each_projection(points, [&](int i, int j, const double *x) {
    const sbacameras::euclidean::Camera &e = cameras[static_cast<std::size_t>(j)];
    b.points[static_cast<std::size_t>(i)].views.push_back({j, i, x[0] - e.k.u0, e.k.v0 - x[1]});
  });
  *out = std::move(b);
  return true;
}

}  // namespace sbaformats::bundler
