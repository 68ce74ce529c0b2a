// SPDX-License-Identifier: BSD-3-Clause
#include "arrays.h"

#include <algorithm>
#include <climits>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <numeric>

#include "option_values.h"

namespace pysba {

void raise_file_error(PyObject *type, const std::string &message) {
  PyObject *text = PyUnicode_DecodeFSDefaultAndSize(message.data(), Py_ssize_t(message.size()));
  if (text) {
    PyErr_SetObject(type, text);
    Py_DECREF(text);
  }
  throw py::error_already_set();
}

py::array_t<double> copy_of(const double *data, std::vector<py::ssize_t> shape) {
  py::array_t<double> out(std::move(shape));
  if (out.size() > 0) std::memcpy(out.mutable_data(), data, sizeof(double) * size_t(out.size()));
  return out;
}

std::vector<py::ssize_t> check_shape(const py::array &a, const char *what,
                                     std::vector<py::ssize_t> expected) {
  auto describe = [](const std::vector<py::ssize_t> &s) {
    std::string t = "(";
    for (size_t k = 0; k < s.size(); ++k)
      t += (k ? ", " : "") + (s[k] < 0 ? std::string("any") : std::to_string(s[k]));
    return t + (s.size() == 1 ? ",)" : ")");
  };
  std::vector<py::ssize_t> got(a.shape(), a.shape() + a.ndim());
  bool ok = got.size() == expected.size();
  for (size_t k = 0; ok && k < got.size(); ++k) ok = expected[k] < 0 || expected[k] == got[k];
  if (!ok)
    throw py::value_error(std::string(what) + " must have shape " + describe(expected) + ", got " +
                          describe(got));
  return got;
}

std::string what_it_is(py::handle obj) {
  if (py::isinstance<py::array>(obj))
    return "an array of " + std::string(py::str(py::reinterpret_borrow<py::array>(obj).dtype()));
  return Py_TYPE(obj.ptr())->tp_name;
}

namespace {

std::string number(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.17g", v);
  return buf;
}

// obj as an array of integers or floats, or TypeError: "`what` must be an array of `of`".
py::array numeric_array(py::handle obj, const char *what, const char *of) {
  py::array a = py::array::ensure(obj);
  const char kind = a ? a.dtype().kind() : '?';
  if (kind != 'i' && kind != 'u' && kind != 'f')
    throw py::type_error(std::string(what) + " must be an array of " + of + ", got " + what_it_is(obj));
  return a;
}

}  // namespace

Doubles float_array(py::handle obj, const char *what) { return Doubles::ensure(numeric_array(obj, what, "numbers")); }

void check_finite(const Doubles &a, const char *what) {
  const double *v = a.data();
  for (py::ssize_t k = 0; k < a.size(); ++k)
    if (!std::isfinite(v[k]))
      throw py::value_error(entry_name(what, std::vector<long long>(a.shape(), a.shape() + a.ndim()), k) +
                            " is not finite (" + number(v[k]) + ")");
}

Doubles parameter_rows(py::handle obj, const char *what, py::ssize_t width) {
  Doubles a = float_array(obj, what);
  check_shape(a, what, {-1, width});
  check_finite(a, what);
  return a;
}

Doubles result_array(const py::handle &r, const char *what, std::vector<py::ssize_t> shape) {
  if (r.is_none()) throw py::value_error(std::string(what) + " is None");
  Doubles a = Doubles::ensure(r);
  if (!a) throw py::type_error(std::string(what) + " must be an array of floats");
  check_shape(a, what, std::move(shape));
  return a;
}

std::vector<long long> index_array(py::handle obj, const char *what, long long bound) {
  const py::array a = numeric_array(obj, what, "integers");
  const char kind = a.dtype().kind();
  const py::ssize_t len = check_shape(a, what, {-1})[0];
  std::vector<long long> out(static_cast<size_t>(len));
  auto out_of_range = [&](py::ssize_t k, const std::string &value) {
    return py::value_error(std::string(what) + "[" + std::to_string(k) + "] = " + value + " is not in [0, " +
                           std::to_string(bound) + ")");
  };
  if (kind == 'f') {
    const Doubles f = Doubles::ensure(a);
    for (py::ssize_t k = 0; k < len; ++k) {
      const double v = f.data()[k];
      // Truncating a fraction (2.9999999999999996 to 2) would give the observation to another
      // camera or point without a word.
      if (!std::isfinite(v) || v != std::floor(v))
        throw py::value_error(std::string(what) + "[" + std::to_string(k) + "] = " + number(v) +
                              " is not an integer");
      if (v < 0 || v >= double(bound)) throw out_of_range(k, number(v));
      out[size_t(k)] = static_cast<long long>(v);
    }
  } else if (kind == 'u') {
    const auto u = py::array_t<unsigned long long, py::array::c_style | py::array::forcecast>::ensure(a);
    for (py::ssize_t k = 0; k < len; ++k) {
      if (u.data()[k] >= static_cast<unsigned long long>(bound)) throw out_of_range(k, std::to_string(u.data()[k]));
      out[size_t(k)] = static_cast<long long>(u.data()[k]);
    }
  } else {
    const Indices i = Indices::ensure(a);
    for (py::ssize_t k = 0; k < len; ++k) {
      if (i.data()[k] < 0 || i.data()[k] >= bound) throw out_of_range(k, std::to_string(i.data()[k]));
      out[size_t(k)] = i.data()[k];
    }
  }
  return out;
}

Observations sorted_observations(int n, int m, py::handle camera_index, py::handle point_index,
                                 py::handle observations, py::handle covariances) {
  Observations o;
  o.n = n;
  o.m = m;
  const std::vector<long long> cams = index_array(camera_index, "camera_index", m);
  const std::vector<long long> pts = index_array(point_index, "point_index", n);
  const py::ssize_t nobs = py::ssize_t(cams.size());
  if (py::ssize_t(pts.size()) != nobs)
    throw py::value_error("point_index must have shape (" + std::to_string(nobs) + ",), got (" +
                          std::to_string(pts.size()) + ",)");
  const Doubles xa = float_array(observations, "observations");
  const std::vector<py::ssize_t> xs = check_shape(xa, "observations", {nobs, -1});
  if (nobs == 0) throw py::value_error("there are no observations");
  if (nobs > INT_MAX) throw py::value_error("more than INT_MAX observations");
  if (xs[1] < 1 || xs[1] > 64) throw py::value_error("observations must have 1 to 64 columns");
  check_finite(xa, "observations");
  o.mnp = static_cast<int>(xs[1]);
  const int mnp = o.mnp;
  const long long *cam = cams.data(), *pt = pts.data();
  o.order.resize(size_t(nobs));
  std::iota(o.order.begin(), o.order.end(), 0LL);
  auto before = [&](long long a, long long b) {
    return pt[a] != pt[b] ? pt[a] < pt[b] : cam[a] < cam[b];
  };
  // Most callers already give sba's order (the readers do): then nothing moves.
  if (!std::is_sorted(o.order.begin(), o.order.end(), before))
    std::stable_sort(o.order.begin(), o.order.end(), before);
  o.point.resize(size_t(nobs));
  o.camera.resize(size_t(nobs));
  for (py::ssize_t k = 0; k < nobs; ++k) {
    const long long q = o.order[size_t(k)];
    o.point[size_t(k)] = static_cast<int>(pt[q]);
    o.camera[size_t(k)] = static_cast<int>(cam[q]);
    // Sorted, a pair given twice is given in a row.
    if (k > 0 && o.point[size_t(k)] == o.point[size_t(k) - 1] && o.camera[size_t(k)] == o.camera[size_t(k) - 1])
      throw py::value_error("camera " + std::to_string(cam[q]) + " observes point " + std::to_string(pt[q]) +
                            " more than once");
  }
  const double *x = xa.data();
  o.x.resize(size_t(nobs) * size_t(mnp));
  for (py::ssize_t k = 0; k < nobs; ++k)
    std::copy_n(x + o.order[size_t(k)] * mnp, mnp, o.x.data() + k * mnp);
  if (!covariances.is_none()) {
    const Doubles c = float_array(covariances, "covariances");
    check_shape(c, "covariances", {nobs, mnp, mnp});
    check_finite(c, "covariances");
    const size_t bs = size_t(mnp) * size_t(mnp);
    o.covx.resize(size_t(nobs) * bs);
    for (py::ssize_t k = 0; k < nobs; ++k)
      std::copy_n(c.data() + size_t(o.order[size_t(k)]) * bs, bs, o.covx.data() + size_t(k) * bs);
  }
  return o;
}

}  // namespace pysba
