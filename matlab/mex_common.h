// SPDX-License-Identifier: BSD-3-Clause
// What the parts of the MEX gateway share: the state of one call (Gateway, with the parsed
// arguments, the callbacks and how the solve ended) and the helpers that describe host values
// and report errors. The parts: mex_args.cpp parses the arguments, mex_callbacks.cpp bridges
// the library's callbacks to the host's functions and runs the solve, sba_mex.cpp is the
// gateway (mexFunction).
#ifndef SBA_MATLAB_MEX_COMMON_H
#define SBA_MATLAB_MEX_COMMON_H

#include <cstddef>
#include <exception>
#include <string>
#include <vector>

#include "mex.h"
#include "mex_error.h"
#include "mex_options.h"
#include "sba.h"
#include "sba_ext.h"

#if defined(HAVE_OCTAVE)  // defined by Octave's mex.h
// Octave: the interrupt flag (set by its SIGINT handler), the function that turns a pending
// interrupt into Octave's own interrupt exception, and the exception classes that its
// mexCallMATLAB lets through.
#include <octave/quit.h>
#define SBA_MEX_OCTAVE 1
#else
#define SBA_MEX_OCTAVE 0
#endif

// Hidden: the MEX file exports mexFunction only.
namespace sba_mex __attribute__((visibility("hidden"))) {

enum class RefType { MotStr, Mot, Str };

const char *reftype_name(RefType r);

// A Ctrl-C the host has not acted on yet.
bool interrupt_pending();

// "DIMS [sparse ][complex ]CLASS" of a host value, for messages.
std::string describe(const mxArray *a);

// Real, dense double.
bool is_real_double(const mxArray *a);

// A host string's text ("" if it is not one).
std::string string_arg(const mxArray *a);

// An open shared library, closed when the Library object goes.
class Library {
 public:
  Library() = default;
  Library(const Library &) = delete;
  Library &operator=(const Library &) = delete;
  ~Library();
  // Both raise bad_arg on failure; role ("proj", "projac") names the callback in messages.
  void open(const std::string &path, const char *role);
  void *symbol(const std::string &name, const std::string &path, const char *role);

 private:
  void *handle_ = nullptr;
};

struct Callback {
  enum Kind { kNone, kHost, kNative } kind = kNone;
  std::string text;  // as given
  std::string name;  // function name (host) or symbol (native)
  void *native = nullptr;
  Library library;
};

// A host function of a callback prior: called by name, or through feval when a handle.
struct HostFunction {
  std::string name;
  const mxArray *handle = nullptr;
  bool given() const { return handle || !name.empty(); }
};

// The functions of callback prior q, and how messages name it ("camera_priors(2)").
struct PriorCallbacks {
  std::string where;
  HostFunction func, jac;  // jac not given: forward differences
};

// Everything a solve needs, and how it ended. One per call of the gateway.
struct Gateway {
  // problem
  RefType reftype = RefType::MotStr;
  std::string strategy;  // 'strategy=NAME'; empty: the library's (SBA_STRATEGY, else sba)
  int n = 0, ncon = 0, m = 0, mcon = 0, cnp = 0, pnp = 0, mnp = 0, itmax = 0, verbose = 0;
  long long nvis = 0;
  std::vector<char> vmask;
  std::vector<double> p0;  // the whole (a, b) vector as given
  const mxArray *p0_arg = nullptr;
  const double *x = nullptr, *covx = nullptr;
  double opts[SBA_OPTSSZ] = {SBA_INIT_MU, SBA_STOP_THRESH, SBA_STOP_THRESH, SBA_STOP_THRESH, 0.0};
  // Camera parameters held or shared (the options struct, beyond 1.6), in sba_ext_options'
  // layout: cam_fixed has cnp flags (every camera) or m*cnp (camera j's at j*cnp), as
  // cam_param_group has its numbers.
  std::vector<char> cam_fixed;
  bool cam_fixed_per_camera = false;
  std::vector<int> cam_group;
  std::vector<char> cam_shared;
  std::vector<int> cam_param_group;
  // Priors (the options struct), the library's indices; prior_callbacks[q] are camera_priors[q]'s
  // functions.
  std::vector<PointPrior> point_priors;
  std::vector<LinearPrior> linear_priors;
  std::vector<CallbackPrior> camera_priors;
  std::vector<PriorCallbacks> prior_callbacks;
  std::vector<const mxArray *> extra;
  std::vector<double *> extra_ptrs;  // for NAME@LIBRARY callbacks
  Callback proj, projac;

  // how the solve ended
  enum class State { kRunning, kFailed, kInterrupted, kHostException } state = State::kRunning;
  std::string error_id, error_message;
  std::exception_ptr host_exception;  // an exception of the host (Octave) to rethrow
  std::string solver_errors;          // error lines of the library's log
  bool host_exception_is_interrupt = false;
  int last_iteration = 0;

  // An exception of the host (an interrupt, above all) must reach the host: it overrides a
  // failure recorded before. The first one is kept.
  void keep_host_exception(std::exception_ptr e) {
    if (state == State::kHostException) return;
    state = State::kHostException;
    host_exception = e;
  }

  const double *fixed_camera(int j) const { return p0.data() + static_cast<std::size_t>(j) * cnp; }
  const double *fixed_point(int i) const {
    return p0.data() + static_cast<std::size_t>(m) * cnp + static_cast<std::size_t>(i) * pnp;
  }
  bool p_is_row() const { return mxGetM(p0_arg) == 1; }

  void fail(const std::string &id, const std::string &message) {
    if (state != State::kRunning) return;  // the first failure is the one to report
    state = State::kFailed;
    error_id = id;
    error_message = message;
  }
  // True when the solve must stop (and the callback answer NaN).
  bool stopping() {
    if (state == State::kRunning && interrupt_pending()) state = State::kInterrupted;
    return state != State::kRunning;
  }
};

}  // namespace sba_mex

#endif
