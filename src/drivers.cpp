// SPDX-License-Identifier: BSD-3-Clause
// The C boundary: the six sba 1.6 drivers. Each one validates its arguments, builds the
// typed layout and callback model, and runs the shared LM core. Nothing escapes this file
// as an exception, and info is filled on every return path; only a forced unwind (the
// calling thread ended by pthread_exit or pthread_cancel in a callback) passes through,
// freeing everything on its way (catch_all in log.h).
#include <algorithm>
#include <cerrno>
#include <climits>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <thread>
#include <exception>
#include <new>
#include <string>

#include "covariance.h"
#include "finite.h"
#include "jacobian_check.h"
#include "layout.h"
#include "linear_solver.h"
#include "lm.h"
#include "model.h"
#include "options.h"
#include "sba_export.h"

namespace sba {
namespace {

// One entry point's arguments. The entry points build it with the problem builders below
// (one per prototype shape) and then solving() or estimating(), never field by field.
struct DriverArgs {
  const char *name = nullptr;  // the entry point as messages name it
  Mode mode = Mode::MotStr;
  int n = 0, ncon = 0, m = 0, mcon = 0, cnp = 0, pnp = 0, mnp = 0;
  char *vmask = nullptr;
  bool by_pairs = false;                // the _vis entry points: pairs instead of vmask
  const sba_visibility *vis = nullptr;
  double *p = nullptr, *x = nullptr, *covx = nullptr;
  bool have_func = false;               // the projection callback (func or proj) is given
  int itmax = 0, verbose = 0;
  const double *opts = nullptr;
  double *info = nullptr;
  const sba_ext_options *ext = nullptr;
  bool simple = false;                  // per-projection callbacks (the simple drivers)

  // The levmar entry points' controls.
  DriverArgs &solving(bool func_given, int itmax_arg, int verbose_arg, const double *opts_arg,
                      double *info_arg, const sba_ext_options *ext_arg) {
    have_func = func_given;
    itmax = itmax_arg;
    verbose = verbose_arg;
    opts = opts_arg;
    info = info_arg;
    ext = ext_arg;
    return *this;
  }
  // The covariance entry points': no iterations and no opts or info, but itmax = 1, since
  // itmax = 0 would ask for a Jacobian check.
  DriverArgs &estimating(bool func_given, const sba_ext_options *ext_arg) {
    return solving(func_given, 1, 0, nullptr, nullptr, ext_arg);
  }
};

// The problem builders: one per shape of prototype, their parameters in the prototype's
// order, so that an entry point passes its own arguments as they come. The sizes a mode has
// no use for stay 0.
DriverArgs motstr_problem(const char *name, int n, int ncon, int m, int mcon, char *vmask,
                          double *p, int cnp, int pnp, double *x, double *covx, int mnp) {
  DriverArgs a;
  a.name = name;
  a.mode = Mode::MotStr;
  a.n = n;
  a.ncon = ncon;
  a.m = m;
  a.mcon = mcon;
  a.vmask = vmask;
  a.p = p;
  a.cnp = cnp;
  a.pnp = pnp;
  a.x = x;
  a.covx = covx;
  a.mnp = mnp;
  return a;
}

DriverArgs mot_problem(const char *name, int n, int m, int mcon, char *vmask, double *p, int cnp,
                       double *x, double *covx, int mnp) {
  DriverArgs a = motstr_problem(name, n, 0, m, mcon, vmask, p, cnp, 0, x, covx, mnp);
  a.mode = Mode::Mot;
  return a;
}

DriverArgs str_problem(const char *name, int n, int ncon, int m, char *vmask, double *p, int pnp,
                       double *x, double *covx, int mnp) {
  DriverArgs a = motstr_problem(name, n, ncon, m, 0, vmask, p, 0, pnp, x, covx, mnp);
  a.mode = Mode::Str;
  return a;
}

// A problem of the pairs entry points: one of the builders above, vis for its vmask.
DriverArgs by_pairs(DriverArgs a, const sba_visibility *vis) {
  a.by_pairs = true;
  a.vis = vis;
  return a;
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
  if (a.by_pairs ? !a.vis : !a.vmask) return a.by_pairs ? "vis is NULL" : "vmask is NULL";
  if (!a.p) return "p is NULL";
  if (!a.x) return "x is NULL";
  if (!a.have_func) return "the projection function (func or proj) is NULL";
  if (a.itmax < 0) return "itmax must be >= 0 (got " + std::to_string(a.itmax) + ")";
  if (a.opts)
    for (int k = 0; k < SBA_OPTSSZ; ++k)
      if (!std::isfinite(a.opts[k])) return "opts[" + std::to_string(k) + "] is not finite";
  // 1.6 takes |tau|; tau = 0 makes the initial damping 0, which no failed step can grow.
  if (a.opts && a.opts[0] == 0.0)
    return "opts[0] (tau: the initial damping is |tau| * max diag(J^T J)) must be nonzero";
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

// The index from vmask or from the pairs; msg set on failure.
void make_layout(const DriverArgs &a, Layout &lay, std::string *msg) {
  const int cnp = a.mode == Mode::Str ? 0 : a.cnp, pnp = a.mode == Mode::Mot ? 0 : a.pnp;
  const bool ok = a.by_pairs
                      ? build_layout(lay, a.mode, a.n, a.m, a.mcon, a.ncon, cnp, pnp, a.mnp, *a.vis, msg,
                                     a.covx != nullptr)
                      : build_layout(lay, a.mode, a.n, a.m, a.mcon, a.ncon, cnp, pnp, a.mnp, a.vmask, msg,
                                     a.covx != nullptr);
  if (!ok && msg->empty()) *msg = "invalid problem";
}

// The caller's extension options, read only as far as the caller's struct goes (older
// programs pass a shorter one), the rest at their defaults.
sba_ext_options read_ext(const sba_ext_options *ext) {
  sba_ext_options o;
  sba_ext_options_init(&o);
  if (ext && ext->size >= sizeof(size_t)) {
    const size_t n = std::min(ext->size, sizeof o);
    std::memcpy(static_cast<void *>(&o), ext, n);
    o.size = sizeof o;
  }
  return o;
}

void quiet_sink(void *, int, const char *) {}

// Projections per thread below which a thread left to the library is not started: each
// kernel of an iteration wakes the pool, and on a small problem that costs more than the
// thread saves. Each thread also holds its stack and the libraries' thread-local storage.
constexpr i64 kProjectionsPerThread = 10000;
// Caps on a count the caller asks for. Threads beyond the hardware's only take turns, and a
// few per hardware thread are allowed (running more threads than cores is how the
// thread-count independence of the results is tested, and harmless at that scale); beyond
// that each one is pure cost: an absurd request (INT_MAX) would otherwise start threads until
// the system refuses, taking seconds and gigabytes. Threads with fewer projections than
// kMinProjectionsPerThread each have nothing to do between their wake-ups.
constexpr int kThreadsPerHardwareThread = 4;
constexpr i64 kMinProjectionsPerThread = 64;

int hardware_threads() { return std::max(1, int(std::thread::hardware_concurrency())); }

// The threads a solve runs: with the count left to the library (no nthreads, no
// SBA_NUM_THREADS), the hardware's count as far as the problem's size warrants; a count that
// was asked for, as asked up to the caps above. Either way the results are the same bits.
void fit_threads(const Layout &lay, Options *o) {
  const int hw = hardware_threads();
  if (o->auto_threads) {
    o->nthreads = int(std::clamp<i64>(lay.nvis / kProjectionsPerThread, 1, hw));
    return;
  }
  const i64 cap = std::min<i64>(i64(hw) * kThreadsPerHardwareThread,
                                std::max<i64>(1, lay.nvis / kMinProjectionsPerThread));
  o->nthreads = int(std::clamp<i64>(o->nthreads, 1, cap));
}

// SBA_NUM_THREADS as a thread count: a positive decimal integer, the whole string (counts
// beyond INT_MAX are just large requests, capped like any other). 0 when unset, empty or
// invalid; an invalid value is reported as a warning (verbose or not: the environment is
// the only way to set it for an unmodified 1.6 program) and otherwise ignored, so that a
// typo does not stop the program.
int threads_from_env(const char *who, const Logger &log) {
  const char *env = std::getenv("SBA_NUM_THREADS");
  if (!env || !*env) return 0;
  errno = 0;
  char *end = nullptr;
  const long v = std::strtol(env, &end, 10);
  const bool whole = end != env && *end == '\0';
  if (!whole || v <= 0) {
    log.notice("%s: SBA_NUM_THREADS=\"%s\" is not a positive integer: ignored (the library "
                "chooses the thread count)",
                who, env);
    return 0;
  }
  return errno == ERANGE || v > INT_MAX ? INT_MAX : int(v);  // beyond long: huge, capped
}

// Options from opts and the extension options; msg is set on a bad setting.
void make_options(const DriverArgs &a, const sba_ext_options &ext, const Logger &log,
                  Options *o, std::string *msg) {
  o->itmax = a.itmax;
  if (a.opts) {
    // 1.6 uses the magnitudes: a negative tolerance is not a request for something else.
    o->tau = std::fabs(a.opts[0]);
    o->eps1 = std::fabs(a.opts[1]);
    o->eps2 = std::fabs(a.opts[2]);
    o->eps3 = std::fabs(a.opts[3]);
    o->eps4 = std::fabs(a.opts[4]);
  }
  if (a.by_pairs && !ext.linsolver) {
    // A problem given by pairs is one whose dense structures would not fit.
    o->solver = LinSolver::SparseChol;
  } else if (ext.linsolver) {
    if (!linsolver_from_name(ext.linsolver, &o->solver)) {
      *msg = std::string("unknown linear solver \"") + ext.linsolver + "\" (known: " +
             linsolver_names() + ")";
      return;
    }
  } else if (const char *env = std::getenv("SBA_LINSOLVER"); env && *env) {
    // Unmodified 1.6 programs choose their solver this way; a typo must not stop them, and
    // is not an error of a call that succeeds: a warning, shown verbose or not.
    if (!linsolver_from_name(env, &o->solver))
      log.notice("%s: unknown SBA_LINSOLVER \"%s\" (known: %s); using chol", a.name, env,
                linsolver_names());
  }
  if (ext.strategy) {
    if (!strategy_from_name(ext.strategy, &o->strategy)) {
      *msg = std::string("unknown strategy \"") + ext.strategy + "\" (known: " +
             strategy_names() + ")";
      return;
    }
  } else if (const char *env = std::getenv("SBA_STRATEGY"); env && *env) {
    if (!strategy_from_name(env, &o->strategy))
      log.notice("%s: unknown SBA_STRATEGY \"%s\" (known: %s); using sba", a.name, env,
                 strategy_names());
  }
  int threads = ext.nthreads;
  if (threads <= 0) threads = threads_from_env(a.name, log);
  o->auto_threads = threads <= 0;  // fit_threads chooses (and caps an explicit count)
  o->nthreads = std::max(1, threads);
  o->progress = ext.progress;
  o->progress_ctx = ext.progress_ctx;
  o->cancel = ext.cancel;
  o->cancel_ctx = ext.cancel_ctx;
  o->parallel_callbacks = ext.parallel_callbacks != 0;
  // Opt-in only: how the host's threads are scheduled is the host's business.
  o->avoid_shared_cores = ext.avoid_shared_cores != 0;
  if (const char *env = std::getenv("SBA_AVOID_SHARED_CORES"); !o->avoid_shared_cores && env && *env) {
    o->avoid_shared_cores = std::strcmp(env, "1") == 0;
    if (!o->avoid_shared_cores && std::strcmp(env, "0") != 0)
      log.notice("%s: SBA_AVOID_SHARED_CORES=\"%s\" is neither 0 nor 1: ignored (off)", a.name, env);
  }
  if (ext.loss) {
    LossKind kind;
    if (!loss_from_name(ext.loss, &kind)) {
      *msg = std::string("unknown loss \"") + ext.loss + "\" (known: " + loss_names() + ")";
      return;
    }
    const double scale = ext.loss_scale == 0.0 ? 1.0 : ext.loss_scale;
    // The losses divide and multiply by scale^2; outside this range it overflows or
    // underflows, and the solve would fail for a reason that blames x or stop at once.
    if (!(scale >= kMinLossScale && scale <= kMaxLossScale)) {
      char buf[160];
      std::snprintf(buf, sizeof buf,
                    "loss_scale must be positive and within [%.3g, %.3g], where its square and "
                    "inverse square are normal numbers (got %g)",
                    kMinLossScale, kMaxLossScale, ext.loss_scale);
      *msg = buf;
      return;
    }
    o->loss = Loss(kind, scale);
  }
}

// The caller's result struct, filled as far as the caller's struct goes.
void write_result(const sba_ext_options &ext, const Options &opt, const Summary &sum) {
  if (!ext.result || ext.result->size < sizeof(size_t)) return;
  sba_ext_result r;
  sba_ext_result_init(&r);
  r.sq_error_initial = sum.sq_err0;
  r.sq_error_final = sum.sq_err;
  r.cost_initial = sum.err0;
  r.cost_final = sum.err;
  r.outliers_final = sum.outliers;
  r.nthreads = opt.nthreads;
  r.linsolver = linsolver_name(opt.solver);
  r.robust = opt.loss.robust();
  r.strategy = strategy_name(opt.strategy);
  const size_t n = std::min(ext.result->size, sizeof r);
  r.size = ext.result->size;
  std::memcpy(static_cast<void *>(ext.result), &r, n);
}

// info[7..9] as sba 1.6 counts them: each func or fjac call of a simple driver is nvis proj or
// projac calls, and the motion-only and structure-only drivers solve one small system per free
// camera (point) where the others solve one augmented system.
void count_as_1_6(const DriverArgs &a, const Layout &lay, Summary &sum) {
  if (a.simple) {
    sum.nfev *= lay.nvis;
    sum.njev *= lay.nvis;
  }
  if (a.mode == Mode::Mot) sum.nlinsys *= lay.free_cams();
  if (a.mode == Mode::Str) sum.nlinsys *= lay.free_pts();
}

Logger make_logger(const DriverArgs &a, const sba_ext_options &ext) {
  return Logger(a.verbose, ext.quiet ? quiet_sink : ext.log, ext.quiet ? nullptr : ext.log_ctx);
}

// What every entry point checks and builds before a model exists, in this order; `extra`
// checks what one entry point adds once the options are known. Logs the first problem found
// and returns false.
template <class Extra>
bool prepare(const DriverArgs &a, const sba_ext_options &ext, const Logger &log, Options *opt,
             Layout *lay, Extra extra) {
  std::string msg = check_scalars(a);
  if (msg.empty()) make_options(a, ext, log, opt, &msg);
  if (msg.empty()) msg = extra();
  if (msg.empty()) make_layout(a, *lay, &msg);
  if (msg.empty()) fit_threads(*lay, opt);
  if (msg.empty()) msg = check_data(a, *lay);
  if (msg.empty()) return true;
  log.error("%s: %s", a.name, msg.c_str());
  return false;
}

// What every entry point does around its own work, inside catch_all: read the extension
// options, make the logger, run prepare (with `extra`), make the model (make_model(const
// Layout&, bool concurrent) -> std::unique_ptr<Model>), then work(ext, log, opt, lay, model).
// False if an exception escaped (it is logged).
template <class Extra, class MakeModel, class Work>
bool with_model(const DriverArgs &a, Extra extra, MakeModel make_model, Work work) {
  const sba_ext_options ext = read_ext(a.ext);
  const Logger log = make_logger(a, ext);
  return catch_all(log, a.name, [&] {
    Options opt;
    Layout lay;
    if (!prepare(a, ext, log, &opt, &lay, extra)) return;
    std::unique_ptr<Model> model = make_model(lay, ext.parallel_callbacks != 0);
    work(ext, log, opt, lay, *model);
  });
}

template <class MakeModel>
int run_driver(const DriverArgs &a, MakeModel make_model) {
  Summary sum;
  int ret = SBA_ERROR;
  const auto no_extra_check = [] { return std::string(); };
  const bool finished = with_model(a, no_extra_check, make_model,
                                   [&](const sba_ext_options &ext, const Logger &log,
                                       const Options &opt, const Layout &lay, Model &model) {
    // itmax == 0: check the Jacobian; the solve below then only scores p (info[0] == info[1]).
    if (a.itmax == 0) {
      if (!model.has_jacobian())
        log.report("%s: itmax == 0 asks for a Jacobian check, but no analytic Jacobian was "
                   "given: nothing to check",
                   a.name);
      else
        check_jacobian(lay, model, a.p, log);
    }
    const bool ok = solve(lay, model, a.p, a.x, a.covx, opt, log, sum);
    count_as_1_6(a, lay, sum);
    write_result(ext, opt, sum);
    if (ok) ret = sum.iterations;
  });
  if (!finished) sum.ok = false;
  sum.to_info(a.info);
  return ret;
}

// The covariance entry points: the drivers' validation and the request's, then
// sba::covariance.
template <class MakeModel>
int run_covariance(const DriverArgs &a, sba_covariance_request *user,
                   MakeModel make_model) {
  int ret = SBA_ERROR;
  CovarianceRequest req;
  const auto check_request = [&]() -> std::string {
    if (!user || user->size < sizeof(sba_covariance_request))
      return "req is NULL or not initialised by sba_covariance_request_init";
    std::string msg;
    req.ncams = user->ncams;
    req.cams = user->cams;
    req.camcov = user->camcov;
    req.npts = user->npts;
    req.pts = user->pts;
    req.ptcov = user->ptcov;
    if (req.ncams < 0 || req.npts < 0)
      msg = "req->ncams and req->npts must be >= 0";
    else if (req.ncams > 0 && (!req.cams || !req.camcov))
      msg = "req->cams and req->camcov must be given for ncams > 0";
    else if (req.npts > 0 && (!req.pts || !req.ptcov))
      msg = "req->pts and req->ptcov must be given for npts > 0";
    for (int q = 0; msg.empty() && q < req.ncams; ++q)
      if (req.cams[q] < 0 || req.cams[q] >= a.m)
        msg = "req->cams[" + std::to_string(q) + "] is not a camera index";
    for (int q = 0; msg.empty() && q < req.npts; ++q)
      if (req.pts[q] < 0 || req.pts[q] >= a.n)
        msg = "req->pts[" + std::to_string(q) + "] is not a point index";
    return msg;
  };
  with_model(a, check_request, make_model,
             [&](const sba_ext_options &, const Logger &log, const Options &opt,
                 const Layout &lay, Model &model) {
    if (!covariance(lay, model, a.p, a.x, a.covx, opt, log, req)) return;
    user->sigma2 = req.sigma2;
    user->rank = req.rank;
    user->nfree = req.nfree;
    ret = 0;
  });
  return ret;
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

// The model factories that run_driver and run_covariance call once the problem is valid.
auto expert_model(ExpertFunc func, ExpertFunc fjac, void *adata) {
  return [=](const Layout &lay, bool conc) {
    return make_expert_model(lay, func, fjac, adata, conc);
  };
}

// proj and projac of one of the three simple shapes, called through tproj and tjac (the
// adapters above).
template <class Proj, class Jac>
auto simple_model(Proj proj, Jac projac, void *adata, decltype(SimpleCallbacks::proj) tproj,
                  decltype(SimpleCallbacks::projac) tjac) {
  const SimpleCallbacks cb{tproj, projac ? tjac : nullptr, reinterpret_cast<AnyFn>(proj),
                           reinterpret_cast<AnyFn>(projac), adata};
  return [cb](const Layout &lay, bool conc) { return make_simple_model(lay, cb, conc); };
}

// A simple driver's solve: its calls are counted per projection, as 1.6 counts them.
template <class MakeModel>
int run_simple(DriverArgs a, MakeModel make_model) {
  a.simple = true;
  return run_driver(a, make_model);
}

}  // namespace
}  // namespace sba

using sba::DriverArgs;

extern "C" {

void sba_ext_options_init(struct sba_ext_options *opt) {
  if (!opt) return;
  std::memset(static_cast<void *>(opt), 0, sizeof *opt);
  opt->size = sizeof *opt;
}

void sba_ext_result_init(struct sba_ext_result *res) {
  if (!res) return;
  std::memset(static_cast<void *>(res), 0, sizeof *res);
  res->size = sizeof *res;
}

const char *sba_linsolver_names(void) { return sba::linsolver_names(); }

int sba_linsolver_valid(const char *name) {
  sba::LinSolver kind;
  return name && sba::linsolver_from_name(name, &kind) ? 1 : 0;
}

const char *sba_strategy_names(void) { return sba::strategy_names(); }

int sba_strategy_valid(const char *name) {
  sba::StrategyKind kind;
  return name && sba::strategy_from_name(name, &kind) ? 1 : 0;
}

const char *sba_loss_names(void) { return sba::loss_names(); }

int sba_loss_valid(const char *name) {
  sba::LossKind kind;
  return name && sba::loss_from_name(name, &kind) ? 1 : 0;
}

void sba_covariance_request_init(struct sba_covariance_request *req) {
  if (!req) return;
  std::memset(static_cast<void *>(req), 0, sizeof *req);
  req->size = sizeof *req;
}

int sba_motstr_covariance_x(const int n, const int ncon, const int m, const int mcon, char *vmask,
                            double *p, const int cnp, const int pnp, double *x, double *covx,
                            const int mnp, sba::ExpertFunc func, sba::ExpertFunc fjac, void *adata,
                            struct sba_covariance_request *req, const struct sba_ext_options *ext) {
  const DriverArgs a = sba::motstr_problem("sba_motstr_covariance_x", n, ncon, m, mcon, vmask, p,
                                           cnp, pnp, x, covx, mnp)
                           .estimating(func != nullptr, ext);
  return sba::run_covariance(a, req, sba::expert_model(func, fjac, adata));
}

int sba_motstr_covariance(const int n, const int ncon, const int m, const int mcon, char *vmask,
                          double *p, const int cnp, const int pnp, double *x, double *covx,
                          const int mnp, sba::MotStrProj proj, sba::MotStrJac projac, void *adata,
                          struct sba_covariance_request *req, const struct sba_ext_options *ext) {
  const DriverArgs a = sba::motstr_problem("sba_motstr_covariance", n, ncon, m, mcon, vmask, p,
                                           cnp, pnp, x, covx, mnp)
                           .estimating(proj != nullptr, ext);
  return sba::run_covariance(
      a, req, sba::simple_model(proj, projac, adata, sba::motstr_proj, sba::motstr_jac));
}

int sba_motstr_levmar_x_ext(const int n, const int ncon, const int m, const int mcon, char *vmask,
                            double *p, const int cnp, const int pnp, double *x, double *covx,
                            const int mnp, sba::ExpertFunc func, sba::ExpertFunc fjac, void *adata,
                            const int itmax, const int verbose, const double opts[SBA_OPTSSZ],
                            double info[SBA_INFOSZ], const struct sba_ext_options *ext) {
  const DriverArgs a = sba::motstr_problem("sba_motstr_levmar_x", n, ncon, m, mcon, vmask, p, cnp,
                                           pnp, x, covx, mnp)
                           .solving(func != nullptr, itmax, verbose, opts, info, ext);
  return sba::run_driver(a, sba::expert_model(func, fjac, adata));
}

int sba_mot_levmar_x_ext(const int n, const int m, const int mcon, char *vmask, double *p,
                         const int cnp, double *x, double *covx, const int mnp,
                         sba::ExpertFunc func, sba::ExpertFunc fjac, void *adata, const int itmax,
                         const int verbose, const double opts[SBA_OPTSSZ], double info[SBA_INFOSZ],
                         const struct sba_ext_options *ext) {
  const DriverArgs a = sba::mot_problem("sba_mot_levmar_x", n, m, mcon, vmask, p, cnp, x, covx, mnp)
                           .solving(func != nullptr, itmax, verbose, opts, info, ext);
  return sba::run_driver(a, sba::expert_model(func, fjac, adata));
}

int sba_str_levmar_x_ext(const int n, const int ncon, const int m, char *vmask, double *p,
                         const int pnp, double *x, double *covx, const int mnp,
                         sba::ExpertFunc func, sba::ExpertFunc fjac, void *adata, const int itmax,
                         const int verbose, const double opts[SBA_OPTSSZ], double info[SBA_INFOSZ],
                         const struct sba_ext_options *ext) {
  const DriverArgs a = sba::str_problem("sba_str_levmar_x", n, ncon, m, vmask, p, pnp, x, covx, mnp)
                           .solving(func != nullptr, itmax, verbose, opts, info, ext);
  return sba::run_driver(a, sba::expert_model(func, fjac, adata));
}

int sba_motstr_levmar_ext(const int n, const int ncon, const int m, const int mcon, char *vmask,
                          double *p, const int cnp, const int pnp, double *x, double *covx,
                          const int mnp, sba::MotStrProj proj, sba::MotStrJac projac, void *adata,
                          const int itmax, const int verbose, const double opts[SBA_OPTSSZ],
                          double info[SBA_INFOSZ], const struct sba_ext_options *ext) {
  const DriverArgs a = sba::motstr_problem("sba_motstr_levmar", n, ncon, m, mcon, vmask, p, cnp,
                                           pnp, x, covx, mnp)
                           .solving(proj != nullptr, itmax, verbose, opts, info, ext);
  return sba::run_simple(
      a, sba::simple_model(proj, projac, adata, sba::motstr_proj, sba::motstr_jac));
}

int sba_mot_levmar_ext(const int n, const int m, const int mcon, char *vmask, double *p,
                       const int cnp, double *x, double *covx, const int mnp,
                       sba::OneBlockProj proj, sba::OneBlockJac projac, void *adata,
                       const int itmax, const int verbose, const double opts[SBA_OPTSSZ],
                       double info[SBA_INFOSZ], const struct sba_ext_options *ext) {
  const DriverArgs a = sba::mot_problem("sba_mot_levmar", n, m, mcon, vmask, p, cnp, x, covx, mnp)
                           .solving(proj != nullptr, itmax, verbose, opts, info, ext);
  return sba::run_simple(a, sba::simple_model(proj, projac, adata, sba::mot_proj, sba::mot_jac));
}

int sba_str_levmar_ext(const int n, const int ncon, const int m, char *vmask, double *p,
                       const int pnp, double *x, double *covx, const int mnp,
                       sba::OneBlockProj proj, sba::OneBlockJac projac, void *adata,
                       const int itmax, const int verbose, const double opts[SBA_OPTSSZ],
                       double info[SBA_INFOSZ], const struct sba_ext_options *ext) {
  const DriverArgs a = sba::str_problem("sba_str_levmar", n, ncon, m, vmask, p, pnp, x, covx, mnp)
                           .solving(proj != nullptr, itmax, verbose, opts, info, ext);
  return sba::run_simple(a, sba::simple_model(proj, projac, adata, sba::str_proj, sba::str_jac));
}

int sba_motstr_levmar_x_vis(const int n, const int ncon, const int m, const int mcon,
                            const struct sba_visibility *vis, double *p, const int cnp,
                            const int pnp, double *x, double *covx, const int mnp,
                            sba::ExpertFunc func, sba::ExpertFunc fjac, void *adata,
                            const int itmax, const int verbose, const double opts[SBA_OPTSSZ],
                            double info[SBA_INFOSZ], const struct sba_ext_options *ext) {
  const DriverArgs a = sba::by_pairs(sba::motstr_problem("sba_motstr_levmar_x_vis", n, ncon, m, mcon, nullptr, p,
                                                         cnp, pnp, x, covx, mnp),
                                     vis)
                           .solving(func != nullptr, itmax, verbose, opts, info, ext);
  return sba::run_driver(a, sba::expert_model(func, fjac, adata));
}

int sba_motstr_levmar_vis(const int n, const int ncon, const int m, const int mcon,
                          const struct sba_visibility *vis, double *p, const int cnp,
                          const int pnp, double *x, double *covx, const int mnp,
                          sba::MotStrProj proj, sba::MotStrJac projac, void *adata,
                          const int itmax, const int verbose, const double opts[SBA_OPTSSZ],
                          double info[SBA_INFOSZ], const struct sba_ext_options *ext) {
  const DriverArgs a = sba::by_pairs(sba::motstr_problem("sba_motstr_levmar_vis", n, ncon, m, mcon, nullptr, p,
                                                         cnp, pnp, x, covx, mnp),
                                     vis)
                           .solving(proj != nullptr, itmax, verbose, opts, info, ext);
  return sba::run_simple(
      a, sba::simple_model(proj, projac, adata, sba::motstr_proj, sba::motstr_jac));
}

int sba_mot_levmar_x_vis(const int n, const int m, const int mcon, const struct sba_visibility *vis,
                         double *p, const int cnp, double *x, double *covx, const int mnp,
                         sba::ExpertFunc func, sba::ExpertFunc fjac, void *adata, const int itmax,
                         const int verbose, const double opts[SBA_OPTSSZ], double info[SBA_INFOSZ],
                         const struct sba_ext_options *ext) {
  const DriverArgs a =
      sba::by_pairs(sba::mot_problem("sba_mot_levmar_x_vis", n, m, mcon, nullptr, p, cnp, x, covx, mnp), vis)
          .solving(func != nullptr, itmax, verbose, opts, info, ext);
  return sba::run_driver(a, sba::expert_model(func, fjac, adata));
}

int sba_str_levmar_x_vis(const int n, const int ncon, const int m, const struct sba_visibility *vis,
                         double *p, const int pnp, double *x, double *covx, const int mnp,
                         sba::ExpertFunc func, sba::ExpertFunc fjac, void *adata, const int itmax,
                         const int verbose, const double opts[SBA_OPTSSZ], double info[SBA_INFOSZ],
                         const struct sba_ext_options *ext) {
  const DriverArgs a =
      sba::by_pairs(sba::str_problem("sba_str_levmar_x_vis", n, ncon, m, nullptr, p, pnp, x, covx, mnp), vis)
          .solving(func != nullptr, itmax, verbose, opts, info, ext);
  return sba::run_driver(a, sba::expert_model(func, fjac, adata));
}

int sba_motstr_covariance_x_vis(const int n, const int ncon, const int m, const int mcon,
                                const struct sba_visibility *vis, double *p, const int cnp,
                                const int pnp, double *x, double *covx, const int mnp,
                                sba::ExpertFunc func, sba::ExpertFunc fjac, void *adata,
                                struct sba_covariance_request *req, const struct sba_ext_options *ext) {
  const DriverArgs a = sba::by_pairs(sba::motstr_problem("sba_motstr_covariance_x_vis", n, ncon, m, mcon, nullptr,
                                                         p, cnp, pnp, x, covx, mnp),
                                     vis)
                           .estimating(func != nullptr, ext);
  return sba::run_covariance(a, req, sba::expert_model(func, fjac, adata));
}

// ---- the 1.6 entry points: the extension ones with the defaults ----

int sba_motstr_levmar_x(const int n, const int ncon, const int m, const int mcon, char *vmask,
                        double *p, const int cnp, const int pnp, double *x, double *covx,
                        const int mnp, sba::ExpertFunc func, sba::ExpertFunc fjac, void *adata,
                        const int itmax, const int verbose, const double opts[SBA_OPTSSZ],
                        double info[SBA_INFOSZ]) {
  return sba_motstr_levmar_x_ext(n, ncon, m, mcon, vmask, p, cnp, pnp, x, covx, mnp, func, fjac,
                                 adata, itmax, verbose, opts, info, nullptr);
}

int sba_mot_levmar_x(const int n, const int m, const int mcon, char *vmask, double *p,
                     const int cnp, double *x, double *covx, const int mnp, sba::ExpertFunc func,
                     sba::ExpertFunc fjac, void *adata, const int itmax, const int verbose,
                     const double opts[SBA_OPTSSZ], double info[SBA_INFOSZ]) {
  return sba_mot_levmar_x_ext(n, m, mcon, vmask, p, cnp, x, covx, mnp, func, fjac, adata, itmax,
                              verbose, opts, info, nullptr);
}

int sba_str_levmar_x(const int n, const int ncon, const int m, char *vmask, double *p,
                     const int pnp, double *x, double *covx, const int mnp, sba::ExpertFunc func,
                     sba::ExpertFunc fjac, void *adata, const int itmax, const int verbose,
                     const double opts[SBA_OPTSSZ], double info[SBA_INFOSZ]) {
  return sba_str_levmar_x_ext(n, ncon, m, vmask, p, pnp, x, covx, mnp, func, fjac, adata, itmax,
                              verbose, opts, info, nullptr);
}

int sba_motstr_levmar(const int n, const int ncon, const int m, const int mcon, char *vmask,
                      double *p, const int cnp, const int pnp, double *x, double *covx,
                      const int mnp, sba::MotStrProj proj, sba::MotStrJac projac, void *adata,
                      const int itmax, const int verbose, const double opts[SBA_OPTSSZ],
                      double info[SBA_INFOSZ]) {
  return sba_motstr_levmar_ext(n, ncon, m, mcon, vmask, p, cnp, pnp, x, covx, mnp, proj, projac,
                               adata, itmax, verbose, opts, info, nullptr);
}

int sba_mot_levmar(const int n, const int m, const int mcon, char *vmask, double *p,
                   const int cnp, double *x, double *covx, const int mnp, sba::OneBlockProj proj,
                   sba::OneBlockJac projac, void *adata, const int itmax, const int verbose,
                   const double opts[SBA_OPTSSZ], double info[SBA_INFOSZ]) {
  return sba_mot_levmar_ext(n, m, mcon, vmask, p, cnp, x, covx, mnp, proj, projac, adata, itmax,
                            verbose, opts, info, nullptr);
}

int sba_str_levmar(const int n, const int ncon, const int m, char *vmask, double *p,
                   const int pnp, double *x, double *covx, const int mnp, sba::OneBlockProj proj,
                   sba::OneBlockJac projac, void *adata, const int itmax, const int verbose,
                   const double opts[SBA_OPTSSZ], double info[SBA_INFOSZ]) {
  return sba_str_levmar_ext(n, ncon, m, vmask, p, pnp, x, covx, mnp, proj, projac, adata, itmax,
                            verbose, opts, info, nullptr);
}

}  // extern "C"
