// SPDX-License-Identifier: BSD-3-Clause
#include "session.h"

#include <pybind11/stl.h>

#include <cmath>
#include <exception>
#include <new>
#include <stdexcept>

namespace pysba {

SolveOptions solve_options(const py::dict &kw) {
  SolveOptions o;
  auto get = [&](const char *name) -> py::object {
    return kw.contains(name) ? py::reinterpret_borrow<py::object>(kw[name]) : py::none();
  };
  auto text = [&](const char *name) {
    const py::object v = get(name);
    return v.is_none() ? std::string() : v.cast<std::string>();
  };
  if (py::object v = get("mcon"); !v.is_none()) o.mcon = v.cast<int>();
  if (py::object v = get("ncon"); !v.is_none()) o.ncon = v.cast<int>();
  if (py::object v = get("itmax"); !v.is_none()) o.itmax = v.cast<int>();
  if (py::object v = get("threads"); !v.is_none()) o.threads = v.cast<int>();
  if (py::object v = get("loss_scale"); !v.is_none()) o.loss_scale = v.cast<double>();
  if (py::object v = get("opts"); !v.is_none()) {
    const std::vector<double> opts = v.cast<std::vector<double>>();
    if (opts.size() != SBA_OPTSSZ)
      throw py::value_error("opts must hold 5 values (tau, eps1, eps2, eps3, eps4), got " +
                            std::to_string(opts.size()));
    std::copy(opts.begin(), opts.end(), o.opts.begin());
  }
  o.solver = text("solver");
  o.strategy = text("strategy");
  o.loss = text("loss");
  o.progress = kw.contains("progress") ? py::handle(kw["progress"]) : py::handle(Py_None);
  if (o.itmax < 0) throw py::value_error("itmax must be >= 0, got " + std::to_string(o.itmax));
  if (o.threads < 0) throw py::value_error("threads must be >= 0, got " + std::to_string(o.threads));
  if (!o.solver.empty() && !sba_linsolver_valid(o.solver.c_str()))
    throw py::value_error("unknown solver '" + o.solver + "' (known: " + sba_linsolver_names() + ")");
  if (!o.strategy.empty() && !sba_strategy_valid(o.strategy.c_str()))
    throw py::value_error("unknown strategy '" + o.strategy + "' (known: " + sba_strategy_names() + ")");
  if (!o.progress.is_none() && !PyCallable_Check(o.progress.ptr()))
    throw py::type_error("progress must be callable or None");
  return o;
}

Session::Session(const SolveOptions &o) : options_(o) {
  sba_ext_options_init(&ext_);
  sba_ext_result_init(&result_);
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
  // Always installed, with or without a Python callable: it is where Ctrl-C is noticed.
  ext_.progress = progress_trampoline;
  ext_.progress_ctx = this;
  ext_.parallel_callbacks = parallel ? 1 : 0;
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

int Session::progress_trampoline(void *ctx, const sba_progress *state) {
  Session *s = static_cast<Session *>(ctx);
  if (s->failed_) return 1;
  int stop = 0;
  with_gil(s->released_, [&] {
    try {
      // The signal handlers run here, in the main thread: Ctrl-C becomes a KeyboardInterrupt
      // that is kept and stops the solve at this iteration.
      if (PyErr_CheckSignals() != 0) throw py::error_already_set();
      if (!s->options_.progress.is_none()) {
        const PyRef r = call_python(s->options_.progress, {PyRef(py::cast(*state)).handle()});
        stop = PyObject_IsTrue(r.get());
        if (stop < 0) throw py::error_already_set();
      }
    }
    PYSBA_FORCED_UNWIND_PASSES_THROUGH
    catch (...) {
      s->keep_current_exception();
      stop = 1;
    }
  });
  return stop;
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
