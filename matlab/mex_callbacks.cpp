// SPDX-License-Identifier: BSD-3-Clause
#include "mex_callbacks.h"

#include <cmath>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <string>

namespace sba_mex {
namespace {

// NAME@LIBRARY signatures (docs/mex.md, "Callbacks"); adata points to the extra arguments'
// doubles, one pointer per extra argument.
using NativeProj = void (*)(int j, int i, double *aj, double *bi, double *xij, double **adata);
using NativeJac2 = void (*)(int j, int i, double *aj, double *bi, double *Aij, double *Bij,
                            double **adata);
using NativeJac1 = void (*)(int j, int i, double *aj, double *bi, double *Xij, double **adata);

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

// Calls the host function fn (a name) on in (the first `owned` of them destroyed here), out
// its nout results. False if it failed: recorded in g, the message starting with failed(),
// which is only worded then.
template <class Failed>
bool call_function(Gateway &g, const char *fn, std::vector<mxArray *> &in, std::size_t owned, int nout, mxArray **out,
                   Failed failed) {
  for (int k = 0; k < nout; ++k) out[k] = nullptr;
  bool ok = true;
#if SBA_MEX_OCTAVE
  // Octave's mexCallMATLAB rethrows the callback's error as a C++ exception: caught here, so
  // that it never crosses the library. An interrupt (or anything else of Octave's) is kept
  // and rethrown by mexFunction() once the solve has unwound.
  try {
    mexCallMATLAB(nout, out, static_cast<int>(in.size()), in.data(), fn);
  } catch (const octave::execution_exception &e) {
    ok = false;
    g.fail("sba:callbackFailed", failed() + ": " + e.message());
  } catch (const octave::interrupt_exception &) {
    ok = false;
    g.host_exception_is_interrupt = true;
    g.keep_host_exception(std::current_exception());
  } catch (...) {
    ok = false;
    g.keep_host_exception(std::current_exception());
  }
#else
  mxArray *ex = mexCallMATLABWithTrap(nout, out, static_cast<int>(in.size()), in.data(), fn);
  if (ex) {
    ok = false;
    const std::string id = exception_text(ex, "identifier");
    if (id.find("interrupt") != std::string::npos) {
      if (g.state == Gateway::State::kRunning) g.state = Gateway::State::kInterrupted;
    } else {
      g.fail("sba:callbackFailed", failed() + ": " + exception_text(ex, "message"));
    }
    mxDestroyArray(ex);
  }
#endif
  for (std::size_t k = 0; k < owned; ++k) mxDestroyArray(in[k]);
  if (!ok)
    for (int k = 0; k < nout; ++k)
      if (out[k]) {
        mxDestroyArray(out[k]);
        out[k] = nullptr;
      }
  return ok;
}

// Calls a host function: out = fn(j, i, aj, bi, extra...). False if it failed (recorded in g).
bool call_host(Gateway &g, const Callback &cb, const char *role, int nout, mxArray **out, int j, int i,
               const double *aj, const double *bi) {
  std::vector<mxArray *> in(4 + g.extra.size());
  in[0] = mxCreateDoubleScalar(j);
  in[1] = mxCreateDoubleScalar(i);
  in[2] = host_vector(aj, g.cnp, g.p_is_row());
  in[3] = host_vector(bi, g.pnp, g.p_is_row());
  for (std::size_t k = 0; k < g.extra.size(); ++k) in[4 + k] = const_cast<mxArray *>(g.extra[k]);
  return call_function(g, cb.name.c_str(), in, 4, nout, out,
                       [&] { return format("%s '%s' failed at %s", role, cb.name.c_str(), where(j, i).c_str()); });
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

// The data of callback prior q's C callbacks.
struct PriorCall {
  Gateway *g;
  std::size_t q;
};

// A callback prior's function f (func or jac, role) at camera j (the library's index):
// f(j + 1, aj, extra...) into dst (rows x cols, row-major, as take_block reads it); NaN when
// it fails or returns another size, which ends the solve with the failure recorded in g.
void eval_prior_function(const PriorCall &c, const HostFunction &f, const char *role, int j, const double *aj,
                         double *dst, int rows, int cols) noexcept {
  Gateway &g = *c.g;
  const int len = rows * cols;
  try {
    if (g.stopping()) {
      fill_nan(dst, len);
      return;
    }
    const std::string &where_q = g.prior_callbacks[c.q].where;
    // The prior's camera is 1-based, as its camera field; a handle goes through feval.
    mxArray *jv = mxCreateDoubleScalar(j + 1), *av = host_vector(aj, g.cnp, g.p_is_row());
    std::vector<mxArray *> in;
    if (f.handle) in.push_back(const_cast<mxArray *>(f.handle));
    in.push_back(jv);
    in.push_back(av);
    for (const mxArray *e : g.extra) in.push_back(const_cast<mxArray *>(e));
    mxArray *out = nullptr;
    const bool ok = call_function(g, f.handle ? "feval" : f.name.c_str(), in, 0, 1, &out,
                                  [&] { return format("%s.%s failed at camera %d", where_q.c_str(), role, j + 1); });
    mxDestroyArray(jv);
    mxDestroyArray(av);
    if (!ok) {
      fill_nan(dst, len);
      return;
    }
    if (!take_block(out, rows, cols, dst)) {
      g.fail("sba:callbackSize", format("%s.%s returned %s at camera %d; expected %s.", where_q.c_str(), role,
                                        answer_text(out).c_str(), j + 1,
                                        cols == 1 ? format("a real vector of dim = %d values", rows).c_str()
                                                  : format("dim*cnp = %d values (%d x %d)", len, rows, cols).c_str()));
      fill_nan(dst, len);
    }
    if (out) mxDestroyArray(out);
  } catch (...) {
    g.fail("sba:outOfMemory", "out of memory in a camera prior's callback.");
    fill_nan(dst, len);
  }
}

void prior_func(int j, const double *aj, double *r, void *data) {
  const PriorCall &c = *static_cast<PriorCall *>(data);
  eval_prior_function(c, c.g->prior_callbacks[c.q].func, "func", j, aj, r, c.g->camera_priors[c.q].dim, 1);
}

void prior_jac(int j, const double *aj, double *jac, void *data) {
  const PriorCall &c = *static_cast<PriorCall *>(data);
  eval_prior_function(c, c.g->prior_callbacks[c.q].jac, "jac", j, aj, jac, c.g->camera_priors[c.q].dim, c.g->cnp);
}

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

// A library prior struct with p's weight and loss, everything else zero.
template <class Struct>
Struct prior_struct(const PriorBase &p) {
  Struct out;
  std::memset(&out, 0, sizeof out);
  const auto array = [](const std::vector<double> &v) { return v.empty() ? nullptr : v.data(); };
  out.weight.sigma = array(p.weight.sigma);
  out.weight.covariance = array(p.weight.covariance);
  out.weight.sqrt_info = array(p.weight.sqrt_info);
  out.loss = p.has_loss ? p.loss.c_str() : nullptr;
  out.loss_scale = p.loss_scale;
  return out;
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

}  // namespace

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

int solve(Gateway &g, std::vector<double> &p, double info[SBA_INFOSZ]) {
  sba_ext_options ext;
  sba_ext_options_init(&ext);
  ext.log = log_sink;
  ext.log_ctx = &g;
  ext.progress = progress;
  ext.progress_ctx = &g;
  // sba 1.6's calling convention keeps 1.6's solver, chol (the extension drivers' own
  // default for a caller that names none is auto), unless SBA_LINSOLVER names another.
  const char *env = std::getenv("SBA_LINSOLVER");
  ext.linsolver = env && *env && sba_linsolver_valid(env) ? env : "chol";
  if (env && *env && !sba_linsolver_valid(env))
    mexPrintf("sba: unknown SBA_LINSOLVER \"%s\" (known: %s); using chol\n", env, sba_linsolver_names());
  if (!g.strategy.empty()) ext.strategy = g.strategy.c_str();
  if (!g.cam_fixed.empty()) {
    ext.cam_fixed = g.cam_fixed.data();
    ext.cam_fixed_per_camera = g.cam_fixed_per_camera;
  }
  if (!g.cam_group.empty()) ext.cam_group = g.cam_group.data();
  if (!g.cam_shared.empty()) ext.cam_shared = g.cam_shared.data();
  if (!g.cam_param_group.empty()) ext.cam_param_group = g.cam_param_group.data();
  // The library's structs over the priors read from the options struct, alive for the solve.
  std::vector<sba_point_prior> point_priors(g.point_priors.size());
  for (std::size_t q = 0; q < point_priors.size(); ++q) {
    const PointPrior &p = g.point_priors[q];
    point_priors[q] = prior_struct<sba_point_prior>(p);
    point_priors[q].point = p.point;
    point_priors[q].mean = p.mean.data();
  }
  std::vector<sba_camera_linear_prior> linear_priors(g.linear_priors.size());
  for (std::size_t q = 0; q < linear_priors.size(); ++q) {
    const LinearPrior &p = g.linear_priors[q];
    linear_priors[q] = prior_struct<sba_camera_linear_prior>(p);
    linear_priors[q].camera = p.camera;
    linear_priors[q].k = static_cast<int>(p.params.size());
    linear_priors[q].params = p.params.data();
    linear_priors[q].mean = p.mean.data();
  }
  std::vector<sba_camera_prior> camera_priors(g.camera_priors.size());
  std::vector<PriorCall> calls(camera_priors.size());
  for (std::size_t q = 0; q < camera_priors.size(); ++q) {
    const CallbackPrior &p = g.camera_priors[q];
    calls[q] = PriorCall{&g, q};
    camera_priors[q] = prior_struct<sba_camera_prior>(p);
    camera_priors[q].camera = p.camera;
    camera_priors[q].dim = p.dim;
    camera_priors[q].func = prior_func;
    camera_priors[q].jacf = g.prior_callbacks[q].jac.given() ? prior_jac : nullptr;
    camera_priors[q].data = &calls[q];
  }
  ext.npoint_priors = static_cast<int>(point_priors.size());
  ext.point_priors = point_priors.empty() ? nullptr : point_priors.data();
  ext.ncamera_linear_priors = static_cast<int>(linear_priors.size());
  ext.camera_linear_priors = linear_priors.empty() ? nullptr : linear_priors.data();
  ext.ncamera_priors = static_cast<int>(camera_priors.size());
  ext.camera_priors = camera_priors.empty() ? nullptr : camera_priors.data();
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

}  // namespace sba_mex
