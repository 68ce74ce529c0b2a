// SPDX-License-Identifier: BSD-3-Clause
#include "keywords.h"

#include <pybind11/numpy.h>

#include "arrays.h"

namespace pysba {

namespace {

// The entries of a (C order), each as make(entry of type T).
template <class T, class Make>
std::vector<Value> read_as(const py::array &a, Make make) {
  const auto t = py::array_t<T, py::array::c_style | py::array::forcecast>::ensure(a);
  std::vector<Value> out;
  out.reserve(size_t(t.size()));
  for (py::ssize_t k = 0; k < t.size(); ++k) out.push_back(make(t.data()[k]));
  return out;
}

// obj's entries (C order) as Values, and its shape. A numpy array is read by its dtype, one
// of bools, integers or floats (`of` names what the option takes, for the TypeError
// otherwise: an object or a str array is not read by its entries' truth). Anything else
// (lists, tuples, nested ones) entry by entry, each by its Python type: numpy's conversion
// would make True a 1 among ints and '0' a str array.
std::vector<Value> option_values(py::handle obj, const char *name, const char *of,
                                 std::vector<long long> *shape) {
  std::vector<Value> out;
  if (py::isinstance<py::array>(obj)) {
    const py::array a = py::reinterpret_borrow<py::array>(obj);
    shape->assign(a.shape(), a.shape() + a.ndim());
    switch (a.dtype().kind()) {
      case 'b':
        return read_as<bool>(a, Value::boolean);
      case 'i':
        return read_as<long long>(a, Value::signed_integer);
      case 'u':
        return read_as<unsigned long long>(a, Value::unsigned_integer);
      case 'f':
        return read_as<double>(a, Value::floating);
      default:
        throw py::type_error(std::string(name) + " must be an array of " + of + ", got " + what_it_is(obj));
    }
  }
  const py::module_ np = py::module_::import("numpy");
  py::array a;
  try {
    a = np.attr("asarray")(obj, "object");
  } catch (const py::error_already_set &) {
    throw Keywords::wrong_type(name, (std::string("an array of ") + of).c_str(), obj);
  }
  shape->assign(a.shape(), a.shape() + a.ndim());
  const py::object np_bool = np.attr("bool_"), np_integer = np.attr("integer");
  const py::object np_floating = np.attr("floating");
  for (const py::handle e : a.attr("ravel")().attr("tolist")()) {
    if (PyBool_Check(e.ptr()) || py::isinstance(e, np_bool)) {
      out.push_back(Value::boolean(PyObject_IsTrue(e.ptr()) == 1));
    } else if (PyLong_Check(e.ptr()) || py::isinstance(e, np_integer)) {
      const PyRef i(PyNumber_Index(e.ptr()));
      if (!i) throw py::error_already_set();
      int overflow = 0;
      const long long x = PyLong_AsLongLongAndOverflow(i.get(), &overflow);
      if (x == -1 && PyErr_Occurred()) throw py::error_already_set();
      out.push_back(overflow ? Value::big_integer(py::str(i.handle())) : Value::signed_integer(x));
    } else if (PyFloat_Check(e.ptr()) || py::isinstance(e, np_floating)) {
      const double x = PyFloat_AsDouble(e.ptr());
      if (x == -1.0 && PyErr_Occurred()) throw py::error_already_set();
      out.push_back(Value::floating(x));
    } else {
      out.push_back(Value::other(py::repr(e)));
    }
  }
  return out;
}

}  // namespace

// The flags named name (fixed_params, shared_params): bools, or integers that are 0 or 1.
std::vector<char> flags(py::handle v, const char *name, std::vector<long long> *shape) {
  const std::vector<Value> values = option_values(v, name, "bools or integers", shape);
  if (shape->empty()) throw Keywords::wrong_type(name, "an array of bools or integers", v);
  return python_errors([&] { return flag_values(values, name, *shape); });
}

// The group numbers named name: camera_groups (`dims` 1), an array of one dimension, or
// param_groups (2), any array. What is no array (a number, a str) is a TypeError; param_groups'
// shape is checked against (m, cnp) once they are known (check_camera_params), and its
// ValueError says both shapes, whatever the dimensions of the one it got.
std::vector<int> groups(py::handle v, const char *name, size_t dims, std::vector<long long> *shape) {
  const std::vector<Value> values = option_values(v, name, "integers", shape);
  if (dims == 1 ? shape->size() != 1 : shape->empty())
    throw Keywords::wrong_type(name, dims == 1 ? "a 1-D array of ints" : "a 2-D array of ints", v);
  return python_errors([&] { return group_numbers(values, name, *shape); });
}

std::vector<int> int_array(py::handle v, const std::string &name) {
  std::vector<long long> shape;
  return groups(v, name.c_str(), 1, &shape);
}

}  // namespace pysba
