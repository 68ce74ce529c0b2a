// SPDX-License-Identifier: BSD-3-Clause
// The MATLAB / GNU Octave gateway of sba (calling convention: docs/mex.md;
// help text: sba.m).
//
//   [ret, popt, info] = sba(n, ncon, m, mcon, vmask, p0, cnp, pnp, x, [covx,] mnp, proj,
//                           [projac,] itmax, [verbose,] [opts,] [reftype,] extra...)
//
// It keeps sba 1.6's calling convention and runs the simple drivers of the extension API
// (sba_ext.h) so that the library's messages go through the host's print function and a
// pending Ctrl-C stops the solve between callbacks.
//
// Error discipline. Raising a host error (mexErrMsgIdAndTxt) leaves the MEX file by a
// non-local exit: under MATLAB it may skip C++ destructors, and from inside a callback it would
// also cross the library's frames. So nothing here raises while a C++ object is alive or a
// solve is running. A failure is recorded in the Gateway state, the callbacks stop the solve
// (they answer NaN, which the library treats as fatal, and the progress callback asks it to
// stop), run_gateway() returns and destroys everything, and only then does mexFunction() raise
// the error, the warning or the host's own interrupt.
#include <dlfcn.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdarg>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <limits>
#include <new>
#include <string>
#include <vector>

#include "mex.h"
#include "sba.h"
#include "sba_ext.h"

#if defined(HAVE_OCTAVE)  // defined by Octave's mex.h
// Octave: the interrupt flag (set by its SIGINT handler), the function that turns a pending
// interrupt into Octave's own interrupt exception, and the exception classes that its
// mexCallMATLAB lets through.
#include <octave/quit.h>
#define SBA_MEX_OCTAVE 1
#else
// MATLAB: the undocumented but long-standing Ctrl-C query of libut. Weak, so that a MATLAB
// without it still loads the MEX file (Ctrl-C is then noticed only inside .m callbacks).
extern "C" bool utIsInterruptPending(void) __attribute__((weak));
#define SBA_MEX_OCTAVE 0
#endif

// Octave's mexErrMsgIdAndTxt and mexWarnMsgIdAndTxt put "sba: " (the MEX file's name) in front of
// the message themselves; MATLAB's do not.
#ifndef SBA_MEX_HOST_PREFIXES
#define SBA_MEX_HOST_PREFIXES SBA_MEX_OCTAVE
#endif

namespace {

constexpr int kMaxMessage = 2048;

enum class RefType { MotStr, Mot, Str };

const char *reftype_name(RefType r) {
  switch (r) {
    case RefType::MotStr:
      return "motstr";
    case RefType::Mot:
      return "mot";
    case RefType::Str:
      return "str";
  }
  return "";
}

// What mexFunction() does after run_gateway() has returned and freed everything. Plain data:
// it outlives the C++ objects and survives a non-local exit.
struct Outcome {
  enum Kind { kOk, kError, kInterrupt } kind = kOk;
  char id[64] = {0};
  char message[kMaxMessage] = {0};
  char warning_id[64] = {0};
  char warning[kMaxMessage] = {0};
  char solver_warning[kMaxMessage] = {0};  // id sba:solverFailed
};

void copy_text(char *dst, std::size_t size, const std::string &src) {
  std::snprintf(dst, size, "%s", src.c_str());
}

std::string format(const char *fmt, ...) __attribute__((format(printf, 1, 2)));
std::string format(const char *fmt, ...) {
  char buf[kMaxMessage];
  va_list ap;
  va_start(ap, fmt);
  std::vsnprintf(buf, sizeof buf, fmt, ap);
  va_end(ap);
  return buf;
}

// A bad argument: thrown while parsing (before any solve), caught in run_gateway().
struct ArgError {
  std::string id, message;
};

[[noreturn]] void bad_arg(const std::string &id, const std::string &message) {
  throw ArgError{"sba:" + id, message};
}

bool interrupt_pending() {
#if SBA_MEX_OCTAVE
  return octave_interrupt_state > 0;
#else
  return utIsInterruptPending != nullptr && utIsInterruptPending();
#endif
}

// ---------------------------------------------------------------- argument checks

std::string describe(const mxArray *a) {
  std::string dims;
  const mwSize nd = mxGetNumberOfDimensions(a);
  const mwSize *d = mxGetDimensions(a);
  for (mwSize k = 0; k < nd; ++k) dims += (k ? "x" : "") + std::to_string(d[k]);
  std::string what = mxIsSparse(a) ? "sparse " : "";
  if (mxIsComplex(a)) what += "complex ";
  return dims + " " + what + mxGetClassName(a);
}

bool is_real_numeric(const mxArray *a) {
  return (mxIsNumeric(a) || mxIsLogical(a)) && !mxIsComplex(a);
}

bool is_scalar_value(const mxArray *a) {
  return is_real_numeric(a) && mxGetNumberOfElements(a) == 1;
}

bool is_string(const mxArray *a) {
  return mxIsChar(a) && mxGetNumberOfDimensions(a) == 2 && (mxGetM(a) <= 1);
}

bool is_vector_shape(const mxArray *a) {
  return mxGetNumberOfDimensions(a) == 2 && (mxGetM(a) == 1 || mxGetN(a) == 1);
}

// Real, dense double.
bool is_real_double(const mxArray *a) { return mxIsDouble(a) && !mxIsComplex(a) && !mxIsSparse(a); }

int int_arg(const mxArray *a, const char *name, int lo, int hi, const char *what) {
  if (!is_scalar_value(a))
    bad_arg("invalidArgument",
            format("%s must be %s scalar (got a %s).", name, what, describe(a).c_str()));
  const double v = mxGetScalar(a);
  if (!std::isfinite(v) || v != std::floor(v) || v < lo || v > hi) {
    if (hi == std::numeric_limits<int>::max())
      bad_arg("invalidArgument", format("%s must be %s scalar >= %d (got %g).", name, what, lo, v));
    bad_arg("invalidArgument",
            format("%s must be %s scalar in [%d, %d] (got %g).", name, what, lo, hi, v));
  }
  return static_cast<int>(v);
}

std::string string_arg(const mxArray *a) {
  char *s = mxArrayToString(a);
  std::string out = s ? s : "";
  if (s) mxFree(s);
  return out;
}

// A real double vector with exactly len values, all finite.
const double *vector_arg(const mxArray *a, const char *name, std::size_t len,
                         const char *len_text) {
  if (!is_real_double(a) || !(is_vector_shape(a) || mxGetNumberOfElements(a) == 0))
    bad_arg("invalidArgument",
            format("%s must be a real vector (got a %s).", name, describe(a).c_str()));
  const std::size_t got = mxGetNumberOfElements(a);
  if (got != len)
    bad_arg("wrongSize",
            format("%s must have %s = %zu values (got %zu).", name, len_text, len, got));
  const double *v = mxGetPr(a);
  for (std::size_t k = 0; k < len; ++k)
    if (!std::isfinite(v[k]))
      bad_arg("invalidArgument", format("%s(%zu) is not finite.", name, k + 1));
  return v;
}

// vmask as 1.6's n*m chars (vmask[i*m + j]: point i seen by camera j), dense or sparse.
std::vector<char> read_vmask(const mxArray *a, int n, int m, long long *nvis) {
  if (!is_real_numeric(a) || mxGetNumberOfDimensions(a) != 2)
    bad_arg("invalidArgument",
            format("vmask must be a real n x m matrix (got a %s).", describe(a).c_str()));
  if (mxGetM(a) != static_cast<std::size_t>(n) || mxGetN(a) != static_cast<std::size_t>(m))
    bad_arg("wrongSize",
            format("vmask must be n x m = %d x %d (got %zu x %zu).", n, m,
                   static_cast<std::size_t>(mxGetM(a)), static_cast<std::size_t>(mxGetN(a))));
  std::vector<char> mask(static_cast<std::size_t>(n) * m, 0);
  if (mxIsSparse(a)) {
    const mwIndex *ir = mxGetIr(a), *jc = mxGetJc(a);
    const bool logical = mxIsLogical(a);
    const mxLogical *lv = logical ? mxGetLogicals(a) : nullptr;
    const double *dv = logical ? nullptr : mxGetPr(a);
    for (int j = 0; j < m; ++j)
      for (mwIndex k = jc[j]; k < jc[j + 1]; ++k)
        if (logical ? lv[k] != 0 : dv[k] != 0.0) mask[ir[k] * m + j] = 1;
  } else {
    const std::size_t esize = mxGetElementSize(a);
    const unsigned char *base = static_cast<const unsigned char *>(mxGetData(a));
    const mxClassID cls = mxGetClassID(a);
    for (int j = 0; j < m; ++j)
      for (int i = 0; i < n; ++i) {
        const unsigned char *e = base + (static_cast<std::size_t>(j) * n + i) * esize;
        bool nz = false;
        if (cls == mxDOUBLE_CLASS) {
          double v;
          std::memcpy(&v, e, sizeof v);
          nz = v != 0.0;
        } else if (cls == mxSINGLE_CLASS) {
          float v;
          std::memcpy(&v, e, sizeof v);
          nz = v != 0.0f;
        } else {  // logical and the integer classes: nonzero iff some byte is
          for (std::size_t b = 0; b < esize; ++b) nz = nz || e[b] != 0;
        }
        mask[static_cast<std::size_t>(i) * m + j] = nz ? 1 : 0;
      }
  }
  long long count = 0;
  for (char c : mask) count += c != 0;
  *nvis = count;
  return mask;
}

// ---------------------------------------------------------------- callbacks

// NAME@LIBRARY signatures (spec: MEX.md, "Callbacks"); adata points to the extra arguments'
// doubles, one pointer per extra argument.
using NativeProj = void (*)(int j, int i, double *aj, double *bi, double *xij, double **adata);
using NativeJac2 = void (*)(int j, int i, double *aj, double *bi, double *Aij, double *Bij,
                            double **adata);
using NativeJac1 = void (*)(int j, int i, double *aj, double *bi, double *Xij, double **adata);

// An open shared library, closed when the Library object goes.
class Library {
 public:
  Library() = default;
  Library(const Library &) = delete;
  Library &operator=(const Library &) = delete;
  ~Library() {
    if (handle_) dlclose(handle_);
  }
  void open(const std::string &path, const char *role) {
    // A bare file name is looked up in the current directory first, as MATLAB users expect;
    // dlopen alone would search only the system's library path.
    std::string file = path;
    if (path.find('/') == std::string::npos && access(path.c_str(), F_OK) == 0) file = "./" + path;
    dlerror();
    handle_ = dlopen(file.c_str(), RTLD_NOW | RTLD_LOCAL);
    if (!handle_) {
      const char *why = dlerror();
      bad_arg("libraryNotFound", format("cannot load the library '%s' of %s: %s", path.c_str(),
                                        role, why ? why : "unknown dlopen error"));
    }
  }
  void *symbol(const std::string &name, const std::string &path, const char *role) {
    dlerror();
    void *fn = dlsym(handle_, name.c_str());
    const char *why = dlerror();
    if (why || !fn)
      bad_arg("functionNotFound",
              format("the function '%s' of %s is not in the library '%s'%s%s", name.c_str(), role,
                     path.c_str(), why ? ": " : ".", why ? why : ""));
    return fn;
  }

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

std::string where(int j, int i) { return format("camera %d, point %d", j, i); }

// A host vector for aj or bi, in p0's orientation.
mxArray *host_vector(const double *v, int len, bool row) {
  mxArray *a = row ? mxCreateDoubleMatrix(1, len, mxREAL) : mxCreateDoubleMatrix(len, 1, mxREAL);
  if (len > 0) std::memcpy(mxGetPr(a), v, sizeof(double) * len);
  return a;
}

// The message (and identifier) of a trapped MATLAB error: an MException object.
#if !SBA_MEX_OCTAVE
std::string exception_text(const mxArray *ex, const char *what) {
  std::string out;
  if (mxIsStruct(ex)) {
    if (const mxArray *f = mxGetField(ex, 0, what)) out = string_arg(f);
  } else if (mxArray *f = mxGetProperty(ex, 0, what)) {
    out = string_arg(f);
    mxDestroyArray(f);
  }
  return out;
}
#endif

// Calls a host function: out = fn(j, i, aj, bi, extra...). False if it failed (recorded in g).
bool call_host(Gateway &g, const Callback &cb, const char *role, int nout, mxArray **out, int j,
               int i, const double *aj, const double *bi) {
  std::vector<mxArray *> in(4 + g.extra.size());
  in[0] = mxCreateDoubleScalar(j);
  in[1] = mxCreateDoubleScalar(i);
  in[2] = host_vector(aj, g.cnp, g.p_is_row());
  in[3] = host_vector(bi, g.pnp, g.p_is_row());
  for (std::size_t k = 0; k < g.extra.size(); ++k) in[4 + k] = const_cast<mxArray *>(g.extra[k]);
  for (int k = 0; k < nout; ++k) out[k] = nullptr;
  bool ok = true;
#if SBA_MEX_OCTAVE
  // Octave's mexCallMATLAB rethrows the callback's error as a C++ exception: caught here, so
  // that it never crosses the library. An interrupt (or anything else of Octave's) is kept
  // and rethrown by mexFunction() once the solve has unwound.
  try {
    mexCallMATLAB(nout, out, static_cast<int>(in.size()), in.data(), cb.name.c_str());
  } catch (const octave::execution_exception &e) {
    ok = false;
    g.fail("sba:callbackFailed", format("%s '%s' failed at %s: %s", role, cb.name.c_str(),
                                        where(j, i).c_str(), e.message().c_str()));
  } catch (const octave::interrupt_exception &) {
    ok = false;
    g.host_exception_is_interrupt = true;
    g.keep_host_exception(std::current_exception());
  } catch (...) {
    ok = false;
    g.keep_host_exception(std::current_exception());
  }
#else
  mxArray *ex =
      mexCallMATLABWithTrap(nout, out, static_cast<int>(in.size()), in.data(), cb.name.c_str());
  if (ex) {
    ok = false;
    const std::string id = exception_text(ex, "identifier");
    if (id.find("interrupt") != std::string::npos) {
      if (g.state == Gateway::State::kRunning) g.state = Gateway::State::kInterrupted;
    } else {
      g.fail("sba:callbackFailed",
             format("%s '%s' failed at %s: %s", role, cb.name.c_str(), where(j, i).c_str(),
                    exception_text(ex, "message").c_str()));
    }
    mxDestroyArray(ex);
  }
#endif
  for (int k = 0; k < 4; ++k) mxDestroyArray(in[k]);
  if (!ok)
    for (int k = 0; k < nout; ++k)
      if (out[k]) {
        mxDestroyArray(out[k]);
        out[k] = nullptr;
      }
  return ok;
}

// Copies a callback's answer into dst (rows x cols, row-major). A rows x cols matrix is taken as
// that matrix; anything else with rows*cols values as the row-major vector of the spec.
bool take_block(const mxArray *a, int rows, int cols, double *dst) {
  if (!a || !is_real_double(a)) return false;
  const std::size_t len = static_cast<std::size_t>(rows) * cols;
  if (mxGetNumberOfElements(a) != len) return false;
  const double *src = mxGetPr(a);
  if (rows > 1 && cols > 1 && mxGetNumberOfDimensions(a) == 2 &&
      mxGetM(a) == static_cast<std::size_t>(rows) && mxGetN(a) == static_cast<std::size_t>(cols)) {
    for (int r = 0; r < rows; ++r)
      for (int c = 0; c < cols; ++c)
        dst[r * cols + c] = src[r + static_cast<std::size_t>(c) * rows];
  } else if (len > 0) {
    std::memcpy(dst, src, sizeof(double) * len);
  }
  return true;
}

std::string answer_text(const mxArray *a) {
  return a ? "a " + describe(a) : std::string("nothing");
}

void fill_nan(double *v, int len) {
  if (v)
    for (int k = 0; k < len; ++k) v[k] = std::numeric_limits<double>::quiet_NaN();
}

// x_ij = proj(j, i, a_j, b_i) through either route.
void eval_proj(Gateway &g, int j, int i, double *aj, double *bi, double *xij) noexcept {
  try {
    if (g.stopping()) {
      fill_nan(xij, g.mnp);
      return;
    }
    if (g.proj.kind == Callback::kNative) {
      reinterpret_cast<NativeProj>(g.proj.native)(j, i, aj, bi, xij, g.extra_ptrs.data());
      return;
    }
    mxArray *out = nullptr;
    if (!call_host(g, g.proj, "proj", 1, &out, j, i, aj, bi)) {
      fill_nan(xij, g.mnp);
      return;
    }
    if (!take_block(out, g.mnp, 1, xij)) {
      g.fail("sba:callbackSize",
             format("proj '%s' returned %s at %s; expected a real vector of "
                    "mnp = %d values.",
                    g.proj.name.c_str(), answer_text(out).c_str(), where(j, i).c_str(), g.mnp));
      fill_nan(xij, g.mnp);
    }
    if (out) mxDestroyArray(out);
  } catch (...) {  // std::bad_alloc from a std::string: nothing may reach the library
    g.fail("sba:outOfMemory", "out of memory in the projection callback.");
    fill_nan(xij, g.mnp);
  }
}

// The Jacobian blocks of x_ij: A = dx_ij/da_j (mnp x cnp) unless null, B = dx_ij/db_i
// (mnp x pnp) unless null, as reftype asks.
void eval_jac(Gateway &g, int j, int i, double *aj, double *bi, double *A, double *B) noexcept {
  const int asz = g.mnp * g.cnp, bsz = g.mnp * g.pnp;
  try {
    if (g.stopping()) {
      fill_nan(A, asz);
      fill_nan(B, bsz);
      return;
    }
    if (g.projac.kind == Callback::kNative) {
      double **ad = g.extra_ptrs.data();
      if (A && B)
        reinterpret_cast<NativeJac2>(g.projac.native)(j, i, aj, bi, A, B, ad);
      else
        reinterpret_cast<NativeJac1>(g.projac.native)(j, i, aj, bi, A ? A : B, ad);
      return;
    }
    const int nout = (A && B) ? 2 : 1;
    mxArray *out[2] = {nullptr, nullptr};
    if (!call_host(g, g.projac, "projac", nout, out, j, i, aj, bi)) {
      fill_nan(A, asz);
      fill_nan(B, bsz);
      return;
    }
    const mxArray *a_out = A ? out[0] : nullptr;
    const mxArray *b_out = B ? out[nout - 1] : nullptr;
    std::string problem;
    if (A && !take_block(a_out, g.mnp, g.cnp, A))
      problem = format("returned %s as Aij at %s; expected mnp*cnp = %d values (%d x %d)",
                       answer_text(a_out).c_str(), where(j, i).c_str(), asz, g.mnp, g.cnp);
    else if (B && !take_block(b_out, g.mnp, g.pnp, B))
      problem = format("returned %s as Bij at %s; expected mnp*pnp = %d values (%d x %d)",
                       answer_text(b_out).c_str(), where(j, i).c_str(), bsz, g.mnp, g.pnp);
    if (!problem.empty()) {
      g.fail("sba:callbackSize", format("projac '%s' %s.", g.projac.name.c_str(), problem.c_str()));
      fill_nan(A, asz);
      fill_nan(B, bsz);
    }
    for (mxArray *o : out)
      if (o) mxDestroyArray(o);
  } catch (...) {
    g.fail("sba:outOfMemory", "out of memory in the Jacobian callback.");
    fill_nan(A, asz);
    fill_nan(B, bsz);
  }
}

Gateway &gw(void *adata) { return *static_cast<Gateway *>(adata); }

// The three shapes of the simple drivers' callbacks; the fixed half comes from p0.
void motstr_proj(int j, int i, double *aj, double *bi, double *xij, void *adata) {
  eval_proj(gw(adata), j, i, aj, bi, xij);
}
void motstr_projac(int j, int i, double *aj, double *bi, double *A, double *B, void *adata) {
  eval_jac(gw(adata), j, i, aj, bi, A, B);
}
void mot_proj(int j, int i, double *aj, double *xij, void *adata) {
  Gateway &g = gw(adata);
  eval_proj(g, j, i, aj, const_cast<double *>(g.fixed_point(i)), xij);
}
void mot_projac(int j, int i, double *aj, double *A, void *adata) {
  Gateway &g = gw(adata);
  eval_jac(g, j, i, aj, const_cast<double *>(g.fixed_point(i)), A, nullptr);
}
void str_proj(int j, int i, double *bi, double *xij, void *adata) {
  Gateway &g = gw(adata);
  eval_proj(g, j, i, const_cast<double *>(g.fixed_camera(j)), bi, xij);
}
void str_projac(int j, int i, double *bi, double *B, void *adata) {
  Gateway &g = gw(adata);
  eval_jac(g, j, i, const_cast<double *>(g.fixed_camera(j)), bi, nullptr, B);
}

void log_sink(void *ctx, int level, const char *line) {
  Gateway &g = *static_cast<Gateway *>(ctx);
  if (level == SBA_LOG_ERROR) {
    try {
      // The library starts most lines with "sba: ", which the host prefix already says.
      g.solver_errors += std::strncmp(line, "sba: ", 5) == 0 ? line + 5 : line;
      g.solver_errors += '\n';
    } catch (...) {
    }
    return;
  }
  mexPrintf("%s\n", line);
}

int progress(void *ctx, const struct sba_progress *state) {
  Gateway &g = *static_cast<Gateway *>(ctx);
  g.last_iteration = state->iteration;
  return g.stopping() ? 1 : 0;
}

// ---------------------------------------------------------------- parsing

void parse_callback(Callback &cb, const std::string &text, const char *role) {
  cb.text = text;
  const std::size_t at = text.find('@');
  if (at == std::string::npos) {
    cb.kind = Callback::kHost;
    cb.name = text;
    if (text.empty()) bad_arg("invalidArgument", format("%s must name a function.", role));
    return;
  }
  cb.kind = Callback::kNative;
  cb.name = text.substr(0, at);
  const std::string lib = text.substr(at + 1);
  if (cb.name.empty() || lib.empty())
    bad_arg("invalidArgument",
            format("%s '%s' must be NAME@LIBRARY with both parts given.", role, text.c_str()));
  cb.library.open(lib, role);
  cb.native = cb.library.symbol(cb.name, lib, role);
}

// Checks that a host function exists, so that a typo is reported as such.
void check_host_function(const Callback &cb, const char *role) {
  if (cb.kind != Callback::kHost) return;
  mxArray *name = mxCreateString(cb.name.c_str());
  mxArray *out = nullptr;
  bool found = true;
#if SBA_MEX_OCTAVE
  try {
    if (mexCallMATLAB(1, &out, 1, &name, "exist") == 0 && out) found = mxGetScalar(out) != 0;
  } catch (const octave::execution_exception &) {
    found = true;  // cannot tell: the trial call reports what goes wrong
  }
#else
  mxArray *ex = mexCallMATLABWithTrap(1, &out, 1, &name, "exist");
  if (ex)
    mxDestroyArray(ex);
  else if (out)
    found = mxGetScalar(out) != 0;
#endif
  if (out) mxDestroyArray(out);
  mxDestroyArray(name);
  if (!found)
    bad_arg("functionNotFound",
            format("%s: no function named '%s' was found.", role, cb.name.c_str()));
}

// The argument list of 1.6 (spec: MEX.md, "Call").
void parse(Gateway &g, int nrhs, const mxArray *prhs[], std::string *warning) {
  if (nrhs < 12)
    bad_arg("notEnoughInputs",
            format("at least 12 input arguments are needed (n, ncon, m, mcon, vmask, p0, cnp, pnp, "
                   "x, mnp, proj, itmax); got %d.",
                   nrhs));
  const int kIntMax = std::numeric_limits<int>::max();
  g.n = int_arg(prhs[0], "n", 1, kIntMax, "a positive integer");
  g.ncon = int_arg(prhs[1], "ncon", 0, g.n, "an integer");
  g.m = int_arg(prhs[2], "m", 1, kIntMax, "a positive integer");
  g.mcon = int_arg(prhs[3], "mcon", 0, g.m, "an integer");
  g.vmask = read_vmask(prhs[4], g.n, g.m, &g.nvis);
  const mxArray *p0 = prhs[5];
  g.cnp = int_arg(prhs[6], "cnp", 0, 1 << 20, "a non-negative integer");
  g.pnp = int_arg(prhs[7], "pnp", 0, 1 << 20, "a non-negative integer");
  const mxArray *x = prhs[8];

  int k = 9;
  const mxArray *covx = nullptr;
  if (!is_scalar_value(prhs[k])) covx = prhs[k++];  // a scalar right after x is mnp
  if (k >= nrhs) bad_arg("notEnoughInputs", "mnp, proj and itmax are missing.");
  g.mnp = int_arg(prhs[k++], "mnp", 1, 1 << 20, "a positive integer");

  if (k >= nrhs || !is_string(prhs[k]))
    bad_arg("invalidArgument", format("proj must be a function name or 'NAME@LIBRARY' (got %s).",
                                      k < nrhs ? ("a " + describe(prhs[k])).c_str() : "nothing"));
  const std::string proj = string_arg(prhs[k++]);
  std::string projac;
  if (k < nrhs && is_string(prhs[k])) projac = string_arg(prhs[k++]);
  if (k >= nrhs) bad_arg("notEnoughInputs", "itmax is missing.");
  g.itmax = int_arg(prhs[k++], "itmax", 0, kIntMax, "a non-negative integer");
  if (k < nrhs && is_scalar_value(prhs[k])) {
    const double v = mxGetScalar(prhs[k++]);
    if (!std::isfinite(v)) bad_arg("invalidArgument", "verbose must be a finite scalar.");
    g.verbose = v > 100 ? 100 : (v < 0 ? 0 : static_cast<int>(v));
  }
  if (k < nrhs && is_real_double(prhs[k]) && mxGetNumberOfElements(prhs[k]) <= SBA_OPTSSZ &&
      (is_vector_shape(prhs[k]) || mxGetNumberOfElements(prhs[k]) == 0)) {
    const mxArray *o = prhs[k++];
    const std::size_t len = mxGetNumberOfElements(o);
    const double *v = mxGetPr(o);
    for (std::size_t q = 0; q < len; ++q) {
      if (!std::isfinite(v[q]))
        bad_arg("invalidArgument", format("opts(%zu) is not finite.", q + 1));
      g.opts[q] = v[q];
    }
    if (len > 0 && len < SBA_OPTSSZ)
      *warning = format(
          "opts has %zu of the %d values; the defaults are used for the rest "
          "(tau 1e-03, eps1 to eps3 1e-12, eps4 0).",
          len, SBA_OPTSSZ);
  }
  // 'strategy=NAME' (beyond 1.6) may come just before or just after reftype; no reftype or
  // problem data of a 1.6 call begins so.
  auto strategy_option = [&](int at) {
    if (at >= nrhs || !mxIsChar(prhs[at])) return false;
    const std::string v = string_arg(prhs[at]);
    if (v.compare(0, 9, "strategy=") != 0) return false;
    g.strategy = v.substr(9);
    if (!sba_strategy_valid(g.strategy.c_str()))
      bad_arg("unknownStrategy", format("unknown strategy '%s' (expected one of: %s).",
                                        g.strategy.c_str(), sba_strategy_names()));
    return true;
  };
  if (strategy_option(k)) ++k;
  if (k < nrhs && mxIsChar(prhs[k])) {
    std::string r = string_arg(prhs[k++]);
    for (char &c : r) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    if (r == "motstr")
      g.reftype = RefType::MotStr;
    else if (r == "mot")
      g.reftype = RefType::Mot;
    else if (r == "str")
      g.reftype = RefType::Str;
    else
      bad_arg("unknownReftype",
              format("unknown reftype '%s' (expected 'motstr', 'mot' or 'str').", r.c_str()));
  }
  if (g.strategy.empty() && strategy_option(k)) ++k;
  for (; k < nrhs; ++k) g.extra.push_back(prhs[k]);

  // Sizes that depend on what came before.
  if (g.reftype != RefType::Str && g.cnp == 0)
    bad_arg("invalidArgument",
            format("cnp must be positive for reftype '%s'.", reftype_name(g.reftype)));
  if (g.reftype != RefType::Mot && g.pnp == 0)
    bad_arg("invalidArgument",
            format("pnp must be positive for reftype '%s'.", reftype_name(g.reftype)));
  if (g.nvis == 0)
    bad_arg("invalidArgument", "vmask has no nonzero entry: there is nothing to fit.");
  const std::size_t nvars =
      static_cast<std::size_t>(g.m) * g.cnp + static_cast<std::size_t>(g.n) * g.pnp;
  const double *pv = vector_arg(p0, "p0", nvars, "m*cnp + n*pnp");
  g.p0.assign(pv, pv + nvars);
  g.p0_arg = p0;
  const std::size_t nobs = static_cast<std::size_t>(g.nvis) * g.mnp;
  g.x = vector_arg(x, "x", nobs, "nvis*mnp (nvis: the nonzeros of vmask)");
  if (covx && mxGetNumberOfElements(covx) > 0)
    g.covx = vector_arg(covx, "covx", nobs * g.mnp, "nvis*mnp*mnp");

  parse_callback(g.proj, proj, "proj");
  if (!projac.empty()) parse_callback(g.projac, projac, "projac");
  if (g.proj.kind == Callback::kNative || g.projac.kind == Callback::kNative) {
    for (std::size_t q = 0; q < g.extra.size(); ++q) {
      const mxArray *e = g.extra[q];
      if (!mxIsDouble(e) || mxIsComplex(e) || mxIsSparse(e))
        bad_arg("invalidArgument",
                format("extra argument %zu must be a real dense double array for NAME@LIBRARY "
                       "callbacks (got a %s).",
                       q + 1, describe(e).c_str()));
      g.extra_ptrs.push_back(mxGetPr(e));
    }
  }
  g.extra_ptrs.push_back(nullptr);  // never empty: data() is valid even without extra data
  check_host_function(g.proj, "proj");
  check_host_function(g.projac, "projac");
}

// The trial call on camera 0 and point 0: wrong sizes and failing callbacks are reported as
// argument errors before the solve.
void trial_call(Gateway &g) {
  std::vector<double> a(g.fixed_camera(0), g.fixed_camera(0) + g.cnp);
  std::vector<double> b(g.fixed_point(0), g.fixed_point(0) + g.pnp);
  std::vector<double> xij(g.mnp), A(static_cast<std::size_t>(g.mnp) * g.cnp),
      B(static_cast<std::size_t>(g.mnp) * g.pnp);
  if (g.proj.kind == Callback::kHost) eval_proj(g, 0, 0, a.data(), b.data(), xij.data());
  if (g.state == Gateway::State::kRunning && g.projac.kind == Callback::kHost)
    eval_jac(g, 0, 0, a.data(), b.data(), g.reftype == RefType::Str ? nullptr : A.data(),
             g.reftype == RefType::Mot ? nullptr : B.data());
}

// ---------------------------------------------------------------- the solve

int solve(Gateway &g, std::vector<double> &p, double info[SBA_INFOSZ]) {
  sba_ext_options ext;
  sba_ext_options_init(&ext);
  ext.log = log_sink;
  ext.log_ctx = &g;
  ext.progress = progress;
  ext.progress_ctx = &g;
  if (!g.strategy.empty()) ext.strategy = g.strategy.c_str();
  const bool jac = g.projac.kind != Callback::kNone;
  double *covx = const_cast<double *>(g.covx), *x = const_cast<double *>(g.x);
  char *vmask = g.vmask.data();
  switch (g.reftype) {
    case RefType::MotStr:
      return sba_motstr_levmar_ext(g.n, g.ncon, g.m, g.mcon, vmask, p.data(), g.cnp, g.pnp, x, covx,
                                   g.mnp, motstr_proj, jac ? motstr_projac : nullptr, &g, g.itmax,
                                   g.verbose, g.opts, info, &ext);
    case RefType::Mot:
      return sba_mot_levmar_ext(g.n, g.m, g.mcon, vmask, p.data(), g.cnp, x, covx, g.mnp, mot_proj,
                                jac ? mot_projac : nullptr, &g, g.itmax, g.verbose, g.opts, info,
                                &ext);
    case RefType::Str:
      return sba_str_levmar_ext(g.n, g.ncon, g.m, vmask, p.data(), g.pnp, x, covx, g.mnp, str_proj,
                                jac ? str_projac : nullptr, &g, g.itmax, g.verbose, g.opts, info,
                                &ext);
  }
  return SBA_ERROR;
}

// The first line of a block of text.
std::string first_line(const std::string &s) { return s.substr(0, s.find('\n')); }

// Does the whole call. Every C++ object lives in here; what is left to raise goes to *out, and
// an exception of the host to *rethrow.
void run_gateway(int nlhs, mxArray *plhs[], int nrhs, const mxArray *prhs[], Outcome *out,
                 std::exception_ptr *rethrow) {
  auto error = [&](const std::string &id, const std::string &message) {
    out->kind = Outcome::kError;
    copy_text(out->id, sizeof out->id, id);
    copy_text(out->message, sizeof out->message, message);
  };
  try {
    if (nlhs > 3) return error("sba:tooManyOutputs", "at most 3 outputs: [ret, popt, info].");
    Gateway g;
    std::string warning;
    parse(g, nrhs, prhs, &warning);
    if (!warning.empty()) {
      copy_text(out->warning_id, sizeof out->warning_id, "sba:shortOpts");
      copy_text(out->warning, sizeof out->warning, warning);
    }

    trial_call(g);

    // The parameters the driver refines: all of p0, its cameras or its points.
    std::vector<double> p;
    const std::size_t acount = static_cast<std::size_t>(g.m) * g.cnp;
    if (g.reftype == RefType::MotStr) p = g.p0;
    if (g.reftype == RefType::Mot) p.assign(g.p0.begin(), g.p0.begin() + acount);
    if (g.reftype == RefType::Str) p.assign(g.p0.begin() + acount, g.p0.end());
    double info[SBA_INFOSZ] = {0};
    int ret = SBA_ERROR;
    double seconds = 0;
    if (g.state == Gateway::State::kRunning) {
      const auto t0 = std::chrono::steady_clock::now();
      ret = solve(g, p, info);
      seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    }

    switch (g.state) {
      case Gateway::State::kRunning:
        break;
      case Gateway::State::kFailed:
        return error(g.error_id, g.error_message);
      case Gateway::State::kInterrupted:
      case Gateway::State::kHostException:
        if (g.state == Gateway::State::kInterrupted || g.host_exception_is_interrupt)
          mexPrintf("sba: interrupted after %d iterations; no result is returned.\n",
                    g.last_iteration);
        if (g.state == Gateway::State::kHostException) {
          *rethrow = g.host_exception;
        } else {
          out->kind = Outcome::kInterrupt;
        }
        return;
    }
    if (ret == SBA_ERROR && info[6] == SBA_STOP_NONE)  // nothing ran: the solver refused the input
      return error("sba:invalidProblem",
                   "the solver refused the problem: " + (g.solver_errors.empty()
                                                             ? std::string("unknown reason")
                                                             : first_line(g.solver_errors)));
    if (!g.solver_errors.empty()) {
      std::string text = g.solver_errors;
      if (text.back() == '\n') text.pop_back();
      copy_text(out->solver_warning, sizeof out->solver_warning, text);
    }

    if (g.verbose) {
      long long nvars = 0;
      if (g.reftype != RefType::Str) nvars += static_cast<long long>(g.m) * g.cnp;
      if (g.reftype != RefType::Mot) nvars += static_cast<long long>(g.n) * g.pnp;
      mexPrintf("SBA using %d 3D pts, %d frames and %lld image projections, %lld variables\n", g.n,
                g.m, g.nvis, nvars);
      mexPrintf(
          "\nSBA returned %d in %g iter, reason %g, error %g [initial %g], %d/%d func/fjac "
          "evals, %d lin. systems\n",
          ret, info[5], info[6], info[1] / double(g.nvis), info[0] / double(g.nvis),
          static_cast<int>(info[7]), static_cast<int>(info[8]), static_cast<int>(info[9]));
      mexPrintf("Elapsed time: %.2f seconds, %.2f msecs\n", seconds, seconds * 1000.0);
    }

    // Outputs: popt is p0 with the refined part replaced, in p0's orientation.
    plhs[0] = mxCreateDoubleScalar(ret);
    if (nlhs > 1) {
      std::vector<double> popt = g.p0;
      const std::size_t off = g.reftype == RefType::Str ? acount : 0;
      std::copy(p.begin(), p.end(), popt.begin() + off);
      mxArray *po = mxCreateDoubleMatrix(mxGetM(g.p0_arg), mxGetN(g.p0_arg), mxREAL);
      std::memcpy(mxGetPr(po), popt.data(), sizeof(double) * popt.size());
      plhs[1] = po;
    }
    if (nlhs > 2) {
      mxArray *io = mxCreateDoubleMatrix(1, SBA_INFOSZ, mxREAL);
      std::memcpy(mxGetPr(io), info, sizeof info);
      plhs[2] = io;
    }
  } catch (const ArgError &e) {
    error(e.id, e.message);
  } catch (const std::bad_alloc &) {
    error("sba:outOfMemory", "out of memory.");
  } catch (const std::exception &e) {
    error("sba:internal", std::string("internal error: ") + e.what());
  } catch (...) {
    // Something of the host's outside a callback (e.g. an interrupt during a host call made
    // while parsing): let the host handle it once everything here is gone.
    *rethrow = std::current_exception();
  }
}

[[noreturn]] void raise_interrupt() {
#if SBA_MEX_OCTAVE
  // Octave's own interrupt, as if a builtin had been interrupted: back to the prompt.
  octave_quit();
  octave_handle_signal();
#endif
  mexErrMsgIdAndTxt("sba:interrupted", "%sinterrupted by the user.",
                    SBA_MEX_HOST_PREFIXES ? "" : "sba: ");
  std::abort();  // not reached: mexErrMsgIdAndTxt does not return
}

}  // namespace

void mexFunction(int nlhs, mxArray *plhs[], int nrhs, const mxArray *prhs[]) {
  Outcome out;
  {
    std::exception_ptr rethrow;
    run_gateway(nlhs, plhs, nrhs, prhs, &out, &rethrow);
    if (rethrow) std::rethrow_exception(rethrow);
  }
  // Nothing with a destructor is alive from here on.
  const char *prefix = SBA_MEX_HOST_PREFIXES ? "" : "sba: ";
  if (out.warning[0]) mexWarnMsgIdAndTxt(out.warning_id, "%s%s", prefix, out.warning);
  if (out.solver_warning[0])
    mexWarnMsgIdAndTxt("sba:solverFailed", "%s%s", prefix, out.solver_warning);
  if (out.kind == Outcome::kInterrupt) raise_interrupt();
  if (out.kind == Outcome::kError) mexErrMsgIdAndTxt(out.id, "%s%s", prefix, out.message);
}
