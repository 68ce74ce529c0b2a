/* SPDX-License-Identifier: BSD-3-Clause */
// Reading the keyword arguments of the solves, and the dicts that describe priors, as Python
// callers expect them to be checked: TypeError for a value of the wrong type, ValueError for
// one out of range, each naming the argument (pybind11's casts raise a RuntimeError that
// names neither).
#ifndef PYSBA_KEYWORDS_H
#define PYSBA_KEYWORDS_H

#include <pybind11/pybind11.h>

#include <string>
#include <utility>
#include <vector>

#include "gil.h"
#include "option_values.h"

namespace pysba {

namespace py = pybind11;

class Keywords {
 public:
  // prefix names the dict in messages: "point_priors[2]" makes the key mean
  // "point_priors[2]['mean']"; empty for the keyword arguments themselves.
  explicit Keywords(const py::dict &kw, std::string prefix = std::string())
      : kw_(kw), prefix_(std::move(prefix)) {}

  std::string named(const char *name) const { return prefix_.empty() ? name : prefix_ + "['" + name + "']"; }

  py::handle get(const char *name) const {
    PyObject *v = PyDict_GetItemString(kw_.ptr(), name);
    return v ? py::handle(v) : py::handle(Py_None);
  }

  // An int (or what operator.index takes) in [lo, hi]; def when absent or None.
  long long integer(const char *name, long long def, long long lo, long long hi) const {
    const py::handle v = get(name);
    if (v.is_none()) return def;
    if (!PyIndex_Check(v.ptr())) throw wrong_type(named(name), "an int", v);
    const PyRef i(PyNumber_Index(v.ptr()));
    if (!i) throw py::error_already_set();
    int overflow = 0;
    const long long x = PyLong_AsLongLongAndOverflow(i.get(), &overflow);
    if (overflow != 0 || x < lo || x > hi)
      throw py::value_error(named(name) + " must be in [" + std::to_string(lo) + ", " + std::to_string(hi) +
                            "], got " + std::string(py::str(i.handle())));
    return x;
  }

  double number(const char *name, py::handle v) const {
    if (PyUnicode_Check(v.ptr()) || PyBytes_Check(v.ptr())) throw wrong_type(named(name), "a number", v);
    const double x = PyFloat_AsDouble(v.ptr());
    if (x == -1.0 && PyErr_Occurred()) {
      PyErr_Clear();
      throw wrong_type(named(name), "a number", v);
    }
    return x;
  }

  double number(const char *name, double def) const {
    const py::handle v = get(name);
    return v.is_none() ? def : number(name, v);
  }

  // A str, or None (empty).
  std::string text(const char *name) const {
    const py::handle v = get(name);
    if (v.is_none()) return std::string();
    if (!PyUnicode_Check(v.ptr())) throw wrong_type(named(name), "a str or None", v);
    return v.cast<std::string>();
  }

  // True or False (also numpy's).
  bool flag(const char *name, bool def) const {
    const py::handle v = get(name);
    if (v.is_none()) return def;
    const bool numpy_bool = std::string(Py_TYPE(v.ptr())->tp_name) == "numpy.bool_";
    if (!PyBool_Check(v.ptr()) && !numpy_bool) throw wrong_type(named(name), "a bool", v);
    return PyObject_IsTrue(v.ptr()) == 1;
  }

  static py::type_error wrong_type(const std::string &name, const char *what, py::handle v) {
    return py::type_error(name + " must be " + what + ", got " + Py_TYPE(v.ptr())->tp_name);
  }

 private:
  const py::dict &kw_;
  std::string prefix_;
};

// f(), an OptionError raised as the TypeError or ValueError it stands for.
template <class F>
auto python_errors(F f) -> decltype(f()) {
  try {
    return f();
  } catch (const OptionError &e) {
    if (e.wrong_type) throw py::type_error(e.message);
    throw py::value_error(e.message);
  }
}

// The flags named name (fixed_params, shared_params): bools, or integers that are 0 or 1, of
// any shape but none; the shape in *shape.
std::vector<char> flags(py::handle v, const char *name, std::vector<long long> *shape);

// The group numbers named name: camera_groups (`dims` 1), an array of one dimension, or
// param_groups (2), any array but a number: integers an int holds (which are groups is the
// library's rule), or floats that hold one. TypeError or ValueError naming the entry.
std::vector<int> groups(py::handle v, const char *name, size_t dims, std::vector<long long> *shape);

// An array of one dimension of integers that an int holds, read as camera_groups is.
std::vector<int> int_array(py::handle v, const std::string &name);

}  // namespace pysba

#endif  // PYSBA_KEYWORDS_H
