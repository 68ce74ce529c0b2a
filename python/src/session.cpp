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
#include "keywords.h"
#include "option_values.h"

namespace pysba {

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
  o.priors = read_priors(kw);
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
  d["projection_cost_initial"] = result_.projection_cost_initial;
  d["projection_cost_final"] = result_.projection_cost_final;
  d["prior_cost_initial"] = result_.prior_cost_initial;
  d["prior_cost_final"] = result_.prior_cost_final;
  d["outliers"] = result_.outliers_final;
  d["threads"] = result_.nthreads;
  d["solver"] = result_.linsolver ? py::object(py::str(result_.linsolver)) : py::object(py::none());
  d["robust"] = result_.robust != 0;
  d["strategy"] = result_.strategy ? py::object(py::str(result_.strategy)) : py::object(py::none());
  d["error"] = error();
  return d;
}

}  // namespace pysba
