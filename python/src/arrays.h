/* SPDX-License-Identifier: BSD-3-Clause */
// numpy arrays in and out of the extension, and the observations in sba's layout.
#ifndef PYSBA_ARRAYS_H
#define PYSBA_ARRAYS_H

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include "sba_ext.h"

#include <string>
#include <utility>
#include <vector>

namespace pysba {

namespace py = pybind11;

using Doubles = py::array_t<double, py::array::c_style | py::array::forcecast>;
using Indices = py::array_t<long long, py::array::c_style | py::array::forcecast>;

// Raises type (OSError, ValueError) with a reader's message, which names the file as the
// caller spelled it: bytes in the file system's encoding, decoded back as os.fsdecode does (a
// name that is not UTF-8 keeps its bytes as lone surrogates instead of failing to decode).
[[noreturn]] void raise_file_error(PyObject *type, const std::string &message);

// A numpy array over v's data without copying it: the array owns the vector from now on.
template <class T>
py::array_t<T> adopt(std::vector<T> &&v, std::vector<py::ssize_t> shape) {
  auto *owned = new std::vector<T>(std::move(v));
  py::capsule owner(owned, [](void *q) { delete static_cast<std::vector<T> *>(q); });
  return py::array_t<T>(std::move(shape), owned->data(), owner);
}

// A copy of len values at data, in a new array of the given shape.
py::array_t<double> copy_of(const double *data, std::vector<py::ssize_t> shape);

// What obj is, for a TypeError: "an array of float64" for an array, else its type's name.
std::string what_it_is(py::handle obj);

// obj as a C-contiguous float64 array: numbers (integers or floats) of any layout. TypeError
// naming `what` for anything else (a str, a path, an object()).
Doubles float_array(py::handle obj, const char *what);

// ValueError naming the first entry of a that is NaN or Inf by its place in the caller's
// array, as "observations[100, 1]".
void check_finite(const Doubles &a, const char *what);

// cameras or points: float_array of shape (rows, width) (width -1: any), all finite.
Doubles parameter_rows(py::handle obj, const char *what, py::ssize_t width);

// obj (one dimension) as indices in [0, bound): integers, or floats that hold integers.
// ValueError naming the first entry that is not one (a fraction such as 2.9999999999999996,
// NaN, Inf) or is out of range; TypeError for other types.
std::vector<long long> index_array(py::handle obj, const char *what, long long bound);

// A callback's result r as an array of the expected shape (a copy when it is not one of
// float64 already): ValueError for None or a wrong shape, TypeError for what is no array of
// floats, naming it as what.
Doubles result_array(const py::handle &r, const char *what, std::vector<py::ssize_t> shape);

// Checks that a has ndim dimensions and the given sizes (-1: any); what names it in the
// ValueError otherwise. Returns the sizes.
std::vector<py::ssize_t> check_shape(const py::array &a, const char *what,
                                     std::vector<py::ssize_t> expected);

// The observations as the drivers take them: sorted point by point, cameras ascending, the
// visibility as the list of (point, camera) pairs (sba_ext.h), never as an n*m vmask, so that
// memory follows the observations, not cameras times points.
struct Observations {
  int n = 0, m = 0, mnp = 0;
  std::vector<int> point, camera;  // of each sorted observation
  std::vector<double> x;          // mnp per observation, sorted
  std::vector<double> covx;       // empty, or mnp*mnp per observation, sorted
  std::vector<long long> order;   // order[k]: the caller's index of sorted observation k
  int nobs() const { return static_cast<int>(order.size()); }
  double *covx_or_null() { return covx.empty() ? nullptr : covx.data(); }
  sba_visibility vis() const { return {static_cast<long long>(point.size()), point.data(), camera.data()}; }
};

// From the caller's arrays: camera_index and point_index (nobs each), observations
// (nobs x mnp) and covariances (None or nobs x mnp x mnp). ValueError for indices that are
// not indices of the n points and m cameras, non-finite values, a (camera, point) pair given
// twice, or mismatched sizes, naming the caller's arrays and rows.
Observations sorted_observations(int n, int m, py::handle camera_index, py::handle point_index,
                                 py::handle observations, py::handle covariances);

}  // namespace pysba

#endif  // PYSBA_ARRAYS_H
