// SPDX-License-Identifier: BSD-3-Clause
#include "arrays.h"

#include <algorithm>
#include <climits>
#include <cstring>
#include <numeric>

namespace pysba {

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

Observations sorted_observations(int n, int m, const Indices &camera_index, const Indices &point_index,
                                 const Doubles &observations, const py::object &covariances) {
  Observations o;
  o.n = n;
  o.m = m;
  const py::ssize_t nobs = check_shape(camera_index, "camera_index", {-1})[0];
  check_shape(point_index, "point_index", {nobs});
  const std::vector<py::ssize_t> xs = check_shape(observations, "observations", {nobs, -1});
  if (nobs == 0) throw py::value_error("there are no observations");
  if (nobs > INT_MAX) throw py::value_error("more than INT_MAX observations");
  if (xs[1] < 1 || xs[1] > 64) throw py::value_error("observations must have 1 to 64 columns");
  o.mnp = static_cast<int>(xs[1]);
  const int mnp = o.mnp;
  const long long *cam = camera_index.data(), *pt = point_index.data();
  for (py::ssize_t k = 0; k < nobs; ++k) {
    if (cam[k] < 0 || cam[k] >= m)
      throw py::value_error("camera_index[" + std::to_string(k) + "] = " + std::to_string(cam[k]) +
                            " is not in [0, " + std::to_string(m) + ")");
    if (pt[k] < 0 || pt[k] >= n)
      throw py::value_error("point_index[" + std::to_string(k) + "] = " + std::to_string(pt[k]) +
                            " is not in [0, " + std::to_string(n) + ")");
  }
  o.order.resize(size_t(nobs));
  std::iota(o.order.begin(), o.order.end(), 0LL);
  auto before = [&](long long a, long long b) {
    return pt[a] != pt[b] ? pt[a] < pt[b] : cam[a] < cam[b];
  };
  // Most callers already give sba's order (the readers do): then nothing moves.
  if (!std::is_sorted(o.order.begin(), o.order.end(), before))
    std::stable_sort(o.order.begin(), o.order.end(), before);
  o.vmask.assign(size_t(n) * size_t(m), 0);
  for (py::ssize_t k = 0; k < nobs; ++k) {
    const long long q = o.order[size_t(k)];
    char &seen = o.vmask[size_t(pt[q]) * size_t(m) + size_t(cam[q])];
    if (seen)
      throw py::value_error("camera " + std::to_string(cam[q]) + " observes point " + std::to_string(pt[q]) +
                            " more than once");
    seen = 1;
  }
  const double *x = observations.data();
  o.x.resize(size_t(nobs) * size_t(mnp));
  for (py::ssize_t k = 0; k < nobs; ++k)
    std::copy_n(x + o.order[size_t(k)] * mnp, mnp, o.x.data() + k * mnp);
  if (!covariances.is_none()) {
    const Doubles c = Doubles::ensure(covariances);
    if (!c) throw py::type_error("covariances must be None or an array of floats");
    check_shape(c, "covariances", {nobs, mnp, mnp});
    const size_t bs = size_t(mnp) * size_t(mnp);
    o.covx.resize(size_t(nobs) * bs);
    for (py::ssize_t k = 0; k < nobs; ++k)
      std::copy_n(c.data() + size_t(o.order[size_t(k)]) * bs, bs, o.covx.data() + size_t(k) * bs);
  }
  return o;
}

}  // namespace pysba
