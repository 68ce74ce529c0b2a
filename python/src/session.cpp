// SPDX-License-Identifier: BSD-3-Clause
#include "session.h"

#include <pybind11/numpy.h>
#include <pybind11/stl.h>

#include <climits>
#include <cstdlib>
#include <cmath>
#include <exception>
#include <new>
#include <stdexcept>

#include "arrays.h"
#include "option_values.h"

namespace pysba {

namespace {

// The keyword arguments as Python callers expect them to be checked: TypeError for a value of
// the wrong type, ValueError for one out of range, each naming the argument (pybind11's casts
// raise a RuntimeError that names neither).
class Keywords {
 public:
  explicit Keywords(const py::dict &kw) : kw_(kw) {}

  py::handle get(const char *name) const {
    PyObject *v = PyDict_GetItemString(kw_.ptr(), name);
    return v ? py::handle(v) : py::handle(Py_None);
  }

  // An int (or what operator.index takes) in [lo, hi]; def when absent or None.
  long long integer(const char *name, long long def, long long lo, long long hi) const {
    const py::handle v = get(name);
    if (v.is_none()) return def;
    if (!PyIndex_Check(v.ptr())) throw wrong_type(name, "an int", v);
    const PyRef i(PyNumber_Index(v.ptr()));
    if (!i) throw py::error_already_set();
    int overflow = 0;
    const long long x = PyLong_AsLongLongAndOverflow(i.get(), &overflow);
    if (overflow != 0 || x < lo || x > hi)
      throw py::value_error(std::string(name) + " must be in [" + std::to_string(lo) + ", " + std::to_string(hi) +
                            "], got " + std::string(py::str(i.handle())));
    return x;
  }

  double number(const char *name, py::handle v) const {
    if (PyUnicode_Check(v.ptr()) || PyBytes_Check(v.ptr())) throw wrong_type(name, "a number", v);
    const double x = PyFloat_AsDouble(v.ptr());
    if (x == -1.0 && PyErr_Occurred()) {
      PyErr_Clear();
      throw wrong_type(name, "a number", v);
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
    if (!PyUnicode_Check(v.ptr())) throw wrong_type(name, "a str or None", v);
    return v.cast<std::string>();
  }

  // True or False (also numpy's).
  bool flag(const char *name, bool def) const {
    const py::handle v = get(name);
    if (v.is_none()) return def;
    const bool numpy_bool = std::string(Py_TYPE(v.ptr())->tp_name) == "numpy.bool_";
    if (!PyBool_Check(v.ptr()) && !numpy_bool) throw wrong_type(name, "a bool", v);
    return PyObject_IsTrue(v.ptr()) == 1;
  }

  static py::type_error wrong_type(const std::string &name, const char *what, py::handle v) {
    return py::type_error(name + " must be " + what + ", got " + Py_TYPE(v.ptr())->tp_name);
  }

 private:
  const py::dict &kw_;
};

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

}  // namespace

void check_camera_params(const SolveOptions &o, int m, int cnp) {
  const std::string per = std::to_string(cnp);
  const std::vector<long long> all{m, cnp};
  if (o.has_fixed && o.fixed_shape != std::vector<long long>{cnp} && o.fixed_shape != all)
    throw py::value_error("fixed_params must have shape (" + per + ",) or " + shape_text(all) + ", got " +
                          shape_text(o.fixed_shape));
  if (o.has_shared && o.shared.size() != size_t(cnp))
    throw py::value_error("shared_params must hold " + per + " flags, got " + std::to_string(o.shared.size()));
  if (o.has_groups && o.groups.size() != size_t(m))
    throw py::value_error("camera_groups must hold one group per camera (" + std::to_string(m) + "), got " +
                          std::to_string(o.groups.size()));
  if (o.has_param_groups) python_errors([&] { require_shape("param_groups", o.param_groups_shape, all); });
}

SolveOptions solve_options(const py::dict &kw) {
  const Keywords k(kw);
  SolveOptions o;
  o.mcon = int(k.integer("mcon", 0, 0, INT_MAX));
  o.ncon = int(k.integer("ncon", 0, 0, INT_MAX));
  o.itmax = int(k.integer("itmax", o.itmax, 0, INT_MAX));
  o.threads = int(k.integer("threads", 0, 0, INT_MAX));
  o.nccalib = int(k.integer("nccalib", o.nccalib, INT_MIN, INT_MAX));
  o.ncdist = int(k.integer("ncdist", o.ncdist, INT_MIN, INT_MAX));
  o.loss_scale = k.number("loss_scale", o.loss_scale);
  o.covariance = k.flag("covariance", false);
  if (const py::handle v = k.get("opts"); !v.is_none()) {
    if (!PySequence_Check(v.ptr()) || PyUnicode_Check(v.ptr()) || PyBytes_Check(v.ptr()))
      throw Keywords::wrong_type("opts", "a sequence of 5 numbers or None", v);
    const py::sequence seq = py::reinterpret_borrow<py::sequence>(v);
    if (seq.size() != SBA_OPTSSZ)
      throw py::value_error("opts must hold 5 values (tau, eps1, eps2, eps3, eps4), got " +
                            std::to_string(seq.size()));
    for (size_t q = 0; q < SBA_OPTSSZ; ++q)
      o.opts[q] = k.number(("opts[" + std::to_string(q) + "]").c_str(), seq[q]);
  }
  o.solver = k.text("solver");
  if (o.solver.empty()) {
    // Named here rather than left to the library, so that the notice about a bad
    // SBA_LINSOLVER reaches the result's log: the variable, else auto (the library chooses,
    // and the result says what).
    const char *env = std::getenv("SBA_LINSOLVER");
    o.solver = env && *env && sba_linsolver_valid(env) ? env : "auto";
    if (env && *env && !sba_linsolver_valid(env))
      o.notice = std::string("pysba: unknown SBA_LINSOLVER \"") + env + "\" (known: " + sba_linsolver_names() +
                 "); using auto";
  }
  if (const py::handle v = k.get("fixed_params"); !v.is_none()) {
    o.fixed = flags(v, "fixed_params", &o.fixed_shape);
    o.has_fixed = true;
  }
  if (const py::handle v = k.get("shared_params"); !v.is_none()) {
    std::vector<long long> shape;
    o.shared = flags(v, "shared_params", &shape);
    o.has_shared = true;
  }
  if (const py::handle v = k.get("camera_groups"); !v.is_none()) {
    std::vector<long long> shape;
    o.groups = groups(v, "camera_groups", 1, &shape);
    o.has_groups = true;
  }
  if (const py::handle v = k.get("param_groups"); !v.is_none()) {
    o.param_groups = groups(v, "param_groups", 2, &o.param_groups_shape);
    o.has_param_groups = true;
  }
  o.strategy = k.text("strategy");
  o.loss = k.text("loss");
  o.progress = k.get("progress");
  if (!o.solver.empty() && !sba_linsolver_valid(o.solver.c_str()))
    throw py::value_error("unknown solver '" + o.solver + "' (known: " + sba_linsolver_names() + ")");
  if (!o.strategy.empty() && !sba_strategy_valid(o.strategy.c_str()))
    throw py::value_error("unknown strategy '" + o.strategy + "' (known: " + sba_strategy_names() + ")");
  // Named here too, as the keyword: the library's refusal would name its C driver.
  if (!o.loss.empty() && !sba_loss_valid(o.loss.c_str()))
    throw py::value_error("unknown loss '" + o.loss + "' (known: " + sba_loss_names() + ")");
  if (!o.progress.is_none() && !PyCallable_Check(o.progress.ptr()))
    throw Keywords::wrong_type("progress", "callable or None", o.progress);
  return o;
}

Session::Session(const SolveOptions &o) : options_(o) {
  sba_ext_options_init(&ext_);
  sba_ext_result_init(&result_);
  if (!o.notice.empty()) warnings_.push_back(o.notice);
}

const sba_ext_options *Session::ext(bool parallel) {
  sba_ext_options_init(&ext_);
  if (!options_.solver.empty()) ext_.linsolver = options_.solver.c_str();
  ext_.nthreads = options_.threads;
  if (!options_.strategy.empty()) ext_.strategy = options_.strategy.c_str();
  if (!options_.loss.empty()) {
    ext_.loss = options_.loss.c_str();
    ext_.loss_scale = options_.loss_scale;
  }
  ext_.log = log_trampoline;
  ext_.log_ctx = this;
  // Always installed, with or without a Python callable: they are where Ctrl-C is noticed,
  // progress in a solve, cancel in a covariance.
  ext_.progress = progress_trampoline;
  ext_.progress_ctx = this;
  ext_.cancel = cancel_trampoline;
  ext_.cancel_ctx = this;
  ext_.parallel_callbacks = parallel ? 1 : 0;
  if (options_.has_fixed) {
    ext_.cam_fixed = options_.fixed.data();
    ext_.cam_fixed_per_camera = options_.fixed_shape.size() == 2;
  }
  if (options_.has_groups) ext_.cam_group = options_.groups.data();
  if (options_.has_shared) ext_.cam_shared = options_.shared.data();
  // In C order, row j is camera j's: the library's layout (camera j's parameter c at j*cnp + c).
  if (options_.has_param_groups) ext_.cam_param_group = options_.param_groups.data();
  sba_ext_result_init(&result_);
  ext_.result = &result_;
  return &ext_;
}

void Session::keep_python_error() {
  PyObject *type = nullptr, *value = nullptr, *trace = nullptr;
  PyErr_Fetch(&type, &value, &trace);
  if (!type) return;
  PyErr_NormalizeException(&type, &value, &trace);
  // The traceback travels with the exception object, so that raising it again later shows
  // where in the callback it came from.
  if (trace && value) PyException_SetTraceback(value, trace);
  if (!failed_ && value) {
    error_ = PyRef(py::reinterpret_borrow<py::object>(value));
    failed_ = true;
  }
  Py_XDECREF(type);
  Py_XDECREF(value);
  Py_XDECREF(trace);
}

void Session::keep_current_exception() {
  try {
    throw;
  }
  PYSBA_FORCED_UNWIND_PASSES_THROUGH
  catch (py::error_already_set &e) {
    e.restore();
  } catch (py::builtin_exception &e) {
    e.set_error();
  } catch (const std::bad_alloc &) {
    PyErr_NoMemory();
  } catch (const std::exception &e) {
    PyErr_SetString(PyExc_RuntimeError, e.what());
  } catch (...) {
    PyErr_SetString(PyExc_RuntimeError, "unknown C++ exception in a pysba callback");
  }
  keep_python_error();
}

namespace {

// Whether the library's work is to stop, for the progress and cancel callbacks: with the GIL,
// Python's signal handlers run first (in the main thread; Ctrl-C becomes a KeyboardInterrupt
// that is kept and stops the work), then body() (GIL held), whose true return stops it too,
// as does an exception, which is kept.
template <class Body>
int stop_requested(Session &s, Body body) {
  if (s.failed()) return 1;
  bool stop = false;
  with_gil(s.released_thread(), [&] {
    try {
      if (PyErr_CheckSignals() != 0) throw py::error_already_set();
      stop = body();
    }
    PYSBA_FORCED_UNWIND_PASSES_THROUGH
    catch (...) {
      s.keep_current_exception();
      stop = true;
    }
  });
  return stop ? 1 : 0;
}

}  // namespace

int Session::progress_trampoline(void *ctx, const sba_progress *state) {
  Session *s = static_cast<Session *>(ctx);
  return stop_requested(*s, [&] {
    if (s->options_.progress.is_none()) return false;
    const PyRef r = call_python(s->options_.progress, {PyRef(py::cast(*state)).handle()});
    const int truth = PyObject_IsTrue(r.get());
    if (truth < 0) throw py::error_already_set();
    return truth == 1;
  });
}

int Session::cancel_trampoline(void *ctx) {
  return stop_requested(*static_cast<Session *>(ctx), [] { return false; });
}

void Session::log_trampoline(void *ctx, int level, const char *line) {
  Session *s = static_cast<Session *>(ctx);
  try {
    std::lock_guard<std::mutex> lock(s->log_mutex_);
    if (level == SBA_LOG_ERROR) s->errors_.emplace_back(line);
    else if (level == SBA_LOG_WARNING) s->warnings_.emplace_back(line);
  } catch (...) {
    // A log line that cannot be kept is lost; the solve goes on.
  }
}

py::dict Session::report(int ret, const double info[SBA_INFOSZ]) const {
  py::dict d;
  d["ret"] = ret;
  py::list inf;
  for (int k = 0; k < SBA_INFOSZ; ++k) inf.append(info[k]);
  // A callback's exception (Ctrl-C included) reaches the library as NaN projections, which
  // it reports as reason 7; what stopped the solve was the exception, as a stop request.
  if (failed_) inf[6] = double(SBA_STOP_USER);
  d["info"] = inf;
  d["errors"] = errors_;
  d["warnings"] = warnings_;
  d["sq_error_initial"] = result_.sq_error_initial;
  d["sq_error_final"] = result_.sq_error_final;
  d["cost_initial"] = result_.cost_initial;
  d["cost_final"] = result_.cost_final;
  d["outliers"] = result_.outliers_final;
  d["threads"] = result_.nthreads;
  d["solver"] = result_.linsolver ? py::object(py::str(result_.linsolver)) : py::object(py::none());
  d["robust"] = result_.robust != 0;
  d["strategy"] = result_.strategy ? py::object(py::str(result_.strategy)) : py::object(py::none());
  d["error"] = error();
  return d;
}

}  // namespace pysba
