/* SPDX-License-Identifier: BSD-3-Clause */
// What one solve called from Python shares between the caller and the library's callbacks:
// the options handed to the library, its log lines, the first Python exception raised by a
// callback (or by a signal handler), and the progress callback that turns both into a stop.
//
// The library's callbacks must return normally: a Python exception is never thrown through
// the C frames. It is kept here, the callback returns a stop request (progress) or NaN
// (projections), later callbacks do nothing, and the exception is raised again once the
// driver has returned.
#ifndef PYSBA_SESSION_H
#define PYSBA_SESSION_H

#include <pybind11/pybind11.h>

#include <array>
#include <atomic>
#include <mutex>
#include <string>
#include <utility>
#include <vector>

#include "gil.h"
#include "priors.h"
#include "sba.h"
#include "sba_ext.h"

namespace pysba {

namespace py = pybind11;

// The options of pysba.solve, motstr, mot and str that go to the library.
struct SolveOptions {
  int mcon = 0, ncon = 0;
  int itmax = 150;
  std::array<double, SBA_OPTSSZ> opts{SBA_INIT_MU, SBA_STOP_THRESH, SBA_STOP_THRESH,
                                      SBA_STOP_THRESH, 0.0};
  std::string solver;  // as given, else $SBA_LINSOLVER if valid, else "auto" (see solve_options)
  std::string notice;  // why $SBA_LINSOLVER was not used, for the result's log
  int threads = 0;
  std::string strategy;  // empty: the library's choice
  std::string loss;    // empty: least squares
  double loss_scale = 1.0;
  py::handle progress;  // None or a callable taking a pysba.Progress (the caller holds it)
  bool covariance = false;  // also the covariance blocks of every camera and point
  int nccalib = 2, ncdist = 3;  // eucsbademo cameras: trailing intrinsics and distortion held fixed
  // Camera parameters held (fixed_params: cnp flags, or m x cnp) and shared by groups
  // (camera_groups: m group numbers, -1 for none; shared_params: cnp flags) or parameter by
  // parameter (param_groups: m x cnp group numbers, in C order as the library takes them), as
  // given: their sizes are checked against the cameras by check_camera_params; which
  // combinations and group numbers are valid is the library's one check, whose message the
  // caller sees.
  bool has_fixed = false, has_groups = false, has_shared = false, has_param_groups = false;
  std::vector<char> fixed, shared;
  std::vector<long long> fixed_shape, param_groups_shape;
  std::vector<int> groups, param_groups;
  Priors priors;  // their shapes checked by check_prior_shapes, their values by the library
};

// ValueError unless the camera parameter options of o have the shapes of m cameras of cnp
// parameters.
void check_camera_params(const SolveOptions &o, int m, int cnp);

// Reads the keyword arguments the extension functions share (see pysba/__init__.py): TypeError
// for a value of the wrong type, ValueError for one out of range, naming the argument.
SolveOptions solve_options(const py::dict &kw);

class Session {
 public:
  explicit Session(const SolveOptions &o);
  Session(const Session &) = delete;
  Session &operator=(const Session &) = delete;

  // The options for the library, pointing into this session. parallel: whether the
  // callbacks may run on several threads at once. Without the priors (PriorStructs).
  const sba_ext_options *ext(bool parallel);

  // Keeps the Python exception that is set (the GIL held), unless one is kept already.
  void keep_python_error();
  // Keeps the C++ exception being handled as a Python one (inside a catch block, GIL held).
  void keep_current_exception();
  bool failed() const { return failed_; }
  // Where the thread that runs the solve keeps its Python state while the library works
  // (without_gil, with_gil in gil.h): the Python callbacks run on that thread.
  PyThreadState *&released_thread() { return released_; }
  py::object error() const { return failed_ ? error_.object() : py::object(py::none()); }
  const std::vector<std::string> &errors() const { return errors_; }

  // The library's result in a dict for the Python side: ret, info, the log's errors and
  // warnings, the extension result, and "error" (the kept exception or None; with one,
  // info[6] is SBA_STOP_USER).
  py::dict report(int ret, const double info[SBA_INFOSZ]) const;

 private:
  static int progress_trampoline(void *ctx, const sba_progress *state);
  static int cancel_trampoline(void *ctx);
  static void log_trampoline(void *ctx, int level, const char *line);

  SolveOptions options_;
  sba_ext_options ext_;
  sba_ext_result result_;
  std::mutex log_mutex_;
  std::vector<std::string> errors_, warnings_;
  // Set with the GIL held; read by callbacks without it, to skip work once a solve is doomed.
  std::atomic<bool> failed_{false};
  PyThreadState *released_ = nullptr;
  PyRef error_;
};

}  // namespace pysba

#endif  // PYSBA_SESSION_H
