// The C boundary: the six sba 1.6 drivers. Each one validates its arguments, builds the
// typed layout and callback model, and runs the shared LM core. Nothing escapes this file
// as an exception, and info is filled on every return path.
#include <cmath>
#include <cstring>
#include <exception>
#include <new>
#include <string>

#include "core.h"
#include "sba_export.h"

namespace sba {
namespace {

struct DriverArgs {
  const char *name;
  Mode mode;
  int n, ncon, m, mcon, cnp, pnp, mnp;
  char *vmask;
  double *p, *x, *covx;
  bool have_func;
  int itmax, verbose;
  const double *opts;
  double *info;
};

// First non-finite entry of v, or -1.
i64 first_nonfinite(const double *v, i64 len) {
  for (i64 k = 0; k < len; ++k)
    if (!std::isfinite(v[k])) return k;
  return -1;
}

// Checks what can be checked before the index exists. Empty string: all good.
std::string check_scalars(const DriverArgs &a) {
  auto positive = [](const char *what, int v) {
    return what + std::string(" must be positive (got ") + std::to_string(v) + ")";
  };
  if (a.n <= 0) return positive("n", a.n);
  if (a.m <= 0) return positive("m", a.m);
  if (a.mode != Mode::Str && a.cnp <= 0) return positive("cnp", a.cnp);
  if (a.mode != Mode::Mot && a.pnp <= 0) return positive("pnp", a.pnp);
  if (a.mnp <= 0) return positive("mnp", a.mnp);
  if (a.mcon < 0 || a.mcon > a.m)
    return "mcon must be in [0, m] = [0, " + std::to_string(a.m) + "] (got " +
           std::to_string(a.mcon) + ")";
  if (a.ncon < 0 || a.ncon > a.n)
    return "ncon must be in [0, n] = [0, " + std::to_string(a.n) + "] (got " +
           std::to_string(a.ncon) + ")";
  if (!a.vmask) return "vmask is NULL";
  if (!a.p) return "p is NULL";
  if (!a.x) return "x is NULL";
  if (!a.have_func) return "the projection function (func or proj) is NULL";
  if (a.itmax < 0) return "itmax must be >= 0 (got " + std::to_string(a.itmax) + ")";
  if (a.opts)
    for (int k = 0; k < SBA_OPTSSZ; ++k)
      if (!std::isfinite(a.opts[k])) return "opts[" + std::to_string(k) + "] is not finite";
  return {};
}

std::string check_data(const DriverArgs &a, const Layout &lay) {
  const i64 nobs = lay.nvis * lay.mnp;
  if (lay.free_vars() == 0) return "every camera and point is fixed (mcon/ncon): nothing to refine";
  if (nobs < lay.free_vars())
    return "fewer measurements (" + std::to_string(nobs) + ") than free parameters (" +
           std::to_string(lay.free_vars()) + ")";
  i64 bad = first_nonfinite(a.p, lay.nvars());
  if (bad >= 0) return "p[" + std::to_string(bad) + "] is not finite";
  bad = first_nonfinite(a.x, nobs);
  if (bad >= 0) return "x[" + std::to_string(bad) + "] is not finite";
  if (a.covx) {
    bad = first_nonfinite(a.covx, nobs * lay.mnp);
    if (bad >= 0) return "covx[" + std::to_string(bad) + "] is not finite";
  }
  return {};
}

Options make_options(const DriverArgs &a) {
  Options o;
  o.itmax = a.itmax;
  if (a.opts) {
    // 1.6 uses the magnitudes: a negative tolerance is not a request for something else.
    o.tau = std::fabs(a.opts[0]);
    o.eps1 = std::fabs(a.opts[1]);
    o.eps2 = std::fabs(a.opts[2]);
    o.eps3 = std::fabs(a.opts[3]);
    o.eps4 = std::fabs(a.opts[4]);
  }
  return o;
}

// make_model(Layout&) -> std::unique_ptr<Model>
template <class MakeModel>
int run_driver(const DriverArgs &a, MakeModel make_model) noexcept {
  Summary sum;
  const Logger log(a.verbose, nullptr, nullptr);
  try {
    std::string msg = check_scalars(a);
    Layout lay;
    if (msg.empty() &&
        !build_layout(lay, a.mode, a.n, a.m, a.mcon, a.ncon, a.mode == Mode::Str ? 0 : a.cnp,
                      a.mode == Mode::Mot ? 0 : a.pnp, a.mnp, a.vmask, &msg) &&
        msg.empty())
      msg = "invalid problem";
    if (msg.empty()) msg = check_data(a, lay);
    if (!msg.empty()) {
      log.error("%s: %s", a.name, msg.c_str());
      sum.to_info(a.info);
      return SBA_ERROR;
    }
    std::unique_ptr<Model> model = make_model(lay);
    if (a.itmax == 0) {
      if (!model->has_jacobian()) {
        log.report("%s: itmax == 0 asks for a Jacobian check, but no analytic Jacobian was "
                   "given: nothing to check",
                   a.name);
      } else {
        check_jacobian(lay, *model, a.p, log);
      }
      sum.to_info(a.info);
      return 0;
    }
    const bool ok = solve(lay, *model, a.p, a.x, a.covx, make_options(a), log, sum);
    sum.to_info(a.info);
    return ok ? sum.iterations : SBA_ERROR;
  } catch (const std::bad_alloc &) {
    log.error("%s: out of memory", a.name);
  } catch (const std::exception &e) {
    log.error("%s: internal error: %s", a.name, e.what());
  } catch (...) {
    log.error("%s: unknown exception from a callback", a.name);
  }
  sum.ok = false;
  sum.to_info(a.info);
  return SBA_ERROR;
}

// ---- simple-driver adapters: the three 1.6 callback shapes onto one ----
using MotStrProj = void (*)(int, int, double *, double *, double *, void *);
using MotStrJac = void (*)(int, int, double *, double *, double *, double *, void *);
using OneBlockProj = void (*)(int, int, double *, double *, void *);  // mot: aj; str: bi
using OneBlockJac = void (*)(int, int, double *, double *, void *);

void motstr_proj(const SimpleCallbacks &cb, int j, int i, double *aj, double *bi, double *xij) {
  reinterpret_cast<MotStrProj>(cb.user_proj)(j, i, aj, bi, xij, cb.adata);
}
void motstr_jac(const SimpleCallbacks &cb, int j, int i, double *aj, double *bi, double *A,
                double *B) {
  reinterpret_cast<MotStrJac>(cb.user_projac)(j, i, aj, bi, A, B, cb.adata);
}
void mot_proj(const SimpleCallbacks &cb, int j, int i, double *aj, double *, double *xij) {
  reinterpret_cast<OneBlockProj>(cb.user_proj)(j, i, aj, xij, cb.adata);
}
void mot_jac(const SimpleCallbacks &cb, int j, int i, double *aj, double *, double *A, double *) {
  reinterpret_cast<OneBlockJac>(cb.user_projac)(j, i, aj, A, cb.adata);
}
void str_proj(const SimpleCallbacks &cb, int j, int i, double *, double *bi, double *xij) {
  reinterpret_cast<OneBlockProj>(cb.user_proj)(j, i, bi, xij, cb.adata);
}
void str_jac(const SimpleCallbacks &cb, int j, int i, double *, double *bi, double *, double *B) {
  reinterpret_cast<OneBlockJac>(cb.user_projac)(j, i, bi, B, cb.adata);
}

template <class Proj, class Jac>
int run_simple(const DriverArgs &a, Proj proj, Jac projac, void *adata,
               decltype(SimpleCallbacks::proj) tproj, decltype(SimpleCallbacks::projac) tjac) {
  SimpleCallbacks cb{tproj, projac ? tjac : nullptr, reinterpret_cast<AnyFn>(proj),
                     reinterpret_cast<AnyFn>(projac), adata};
  return run_driver(a, [&](Layout &lay) { return make_simple_model(lay, cb); });
}

}  // namespace
}  // namespace sba

using sba::DriverArgs;
using sba::Mode;

extern "C" {

int sba_motstr_levmar_x(const int n, const int ncon, const int m, const int mcon, char *vmask,
                        double *p, const int cnp, const int pnp, double *x, double *covx,
                        const int mnp, sba::ExpertFunc func, sba::ExpertFunc fjac, void *adata,
                        const int itmax, const int verbose, const double opts[SBA_OPTSSZ],
                        double info[SBA_INFOSZ]) {
  const DriverArgs a{"sba_motstr_levmar_x", Mode::MotStr, n, ncon, m, mcon, cnp, pnp, mnp,
                     vmask, p, x, covx, func != nullptr, itmax, verbose, opts, info};
  return sba::run_driver(a, [&](sba::Layout &lay) { return sba::make_expert_model(lay, func, fjac, adata); });
}

int sba_mot_levmar_x(const int n, const int m, const int mcon, char *vmask, double *p,
                     const int cnp, double *x, double *covx, const int mnp, sba::ExpertFunc func,
                     sba::ExpertFunc fjac, void *adata, const int itmax, const int verbose,
                     const double opts[SBA_OPTSSZ], double info[SBA_INFOSZ]) {
  const DriverArgs a{"sba_mot_levmar_x", Mode::Mot, n, 0, m, mcon, cnp, 0, mnp,
                     vmask, p, x, covx, func != nullptr, itmax, verbose, opts, info};
  return sba::run_driver(a, [&](sba::Layout &lay) { return sba::make_expert_model(lay, func, fjac, adata); });
}

int sba_str_levmar_x(const int n, const int ncon, const int m, char *vmask, double *p,
                     const int pnp, double *x, double *covx, const int mnp, sba::ExpertFunc func,
                     sba::ExpertFunc fjac, void *adata, const int itmax, const int verbose,
                     const double opts[SBA_OPTSSZ], double info[SBA_INFOSZ]) {
  const DriverArgs a{"sba_str_levmar_x", Mode::Str, n, ncon, m, 0, 0, pnp, mnp,
                     vmask, p, x, covx, func != nullptr, itmax, verbose, opts, info};
  return sba::run_driver(a, [&](sba::Layout &lay) { return sba::make_expert_model(lay, func, fjac, adata); });
}

int sba_motstr_levmar(const int n, const int ncon, const int m, const int mcon, char *vmask,
                      double *p, const int cnp, const int pnp, double *x, double *covx,
                      const int mnp,
                      void (*proj)(int j, int i, double *aj, double *bi, double *xij, void *adata),
                      void (*projac)(int j, int i, double *aj, double *bi, double *Aij,
                                     double *Bij, void *adata),
                      void *adata, const int itmax, const int verbose,
                      const double opts[SBA_OPTSSZ], double info[SBA_INFOSZ]) {
  const DriverArgs a{"sba_motstr_levmar", Mode::MotStr, n, ncon, m, mcon, cnp, pnp, mnp,
                     vmask, p, x, covx, proj != nullptr, itmax, verbose, opts, info};
  return sba::run_simple(a, proj, projac, adata, sba::motstr_proj, sba::motstr_jac);
}

int sba_mot_levmar(const int n, const int m, const int mcon, char *vmask, double *p,
                   const int cnp, double *x, double *covx, const int mnp,
                   void (*proj)(int j, int i, double *aj, double *xij, void *adata),
                   void (*projac)(int j, int i, double *aj, double *Aij, void *adata),
                   void *adata, const int itmax, const int verbose,
                   const double opts[SBA_OPTSSZ], double info[SBA_INFOSZ]) {
  const DriverArgs a{"sba_mot_levmar", Mode::Mot, n, 0, m, mcon, cnp, 0, mnp,
                     vmask, p, x, covx, proj != nullptr, itmax, verbose, opts, info};
  return sba::run_simple(a, proj, projac, adata, sba::mot_proj, sba::mot_jac);
}

int sba_str_levmar(const int n, const int ncon, const int m, char *vmask, double *p,
                   const int pnp, double *x, double *covx, const int mnp,
                   void (*proj)(int j, int i, double *bi, double *xij, void *adata),
                   void (*projac)(int j, int i, double *bi, double *Bij, void *adata),
                   void *adata, const int itmax, const int verbose,
                   const double opts[SBA_OPTSSZ], double info[SBA_INFOSZ]) {
  const DriverArgs a{"sba_str_levmar", Mode::Str, n, ncon, m, 0, 0, pnp, mnp,
                     vmask, p, x, covx, proj != nullptr, itmax, verbose, opts, info};
  return sba::run_simple(a, proj, projac, adata, sba::str_proj, sba::str_jac);
}

}  // extern "C"
