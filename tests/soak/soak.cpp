// SPDX-License-Identifier: BSD-3-Clause
// Soak test: many solves of random synthetic problems with random options and
// random fault injection. Every solve runs in a fork()ed child under alarm(), so that a crash
// or a hang is counted instead of ending the run. Counts and prints:
//   crashes        a child killed by a signal, or exiting other than through its report
//   hangs          a child that did not finish within --timeout seconds
//   leaks          a solve that did not give back every allocation: C++ allocations counted by
//                  a replacement operator new; in an AddressSanitizer build, LeakSanitizer
//                  run in the child after the solve
//   wrong results  an outcome outside what the API promises (below)
// and exits with status 0 only when all four are zero.
//
// What the API promises (sba.h, sba_ext.h, README):
//   no fault           a finite final error no larger than the initial one, reason 1..5, p
//                      finite, info[1] (or, with a robust loss, sq_error_final) equal to the
//                      error of the returned p; the covariance of the solution, when asked,
//                      computed
//   NaN/Inf from func  SBA_ERROR, reason 7, p the last accepted estimate (finite, scored by
//   or from fjac       info[1])
//   a throwing callback  SBA_ERROR, p finite
//   a wrong Jacobian   (negated, off by up to 50%, all zero) a valid stop (reason 1..6) with
//                      an error no larger than the initial one, or SBA_ERROR with reason 7/8
//   progress stop      reason 9, p the last accepted estimate
//   a bad argument     SBA_ERROR, reason 0, p untouched; among them sizes whose products
//                      exceed INT_MAX (refused before anything of that size is touched)
//                      and loss scales whose square overflows or underflows
//   a huge thread count  (INT_MAX, or hundreds) the solve as without it, with
//                      sba_ext_result.nthreads within the documented caps
//   a point seen once  in a covariance request: refused (SBA_ERROR), or a rank below the
//                      number of free parameters; never a full-rank success
// and, in some children instead of a solve of the synthetic problem, a COLMAP model with
// quaternions of any size and names that are not UTF-8, and a run's outputs written over it (the
// model, over it or into a new directory, a PLY file and a report) on a disk that may fill at
// any byte, with a report that may fail, read back and solved (model_files.h says what is
// promised there: above all, a run that fails leaves every file as it was and no new one).
//
// usage: sba_soak [--solves N] [--seed S] [--timeout SECONDS] [--jobs J] [--verbose]
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <climits>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include "counting_new.h"
#include "faults.h"
#include "sba.h"
#include "sba_ext.h"
#include "synth.h"
#ifdef SBA_SOAK_MODEL_FILES
#include "model_files.h"
#endif

// LeakSanitizer's interface, present only in sanitizer builds.
extern "C" int __lsan_do_recoverable_leak_check(void) __attribute__((weak));

namespace {

using namespace faults;

// ---------------------------------------------------------------- what one solve does

enum class Fault { None, Value, Jacobian, Throw, ProgressStop, BadArgument };

const char *const kBadArguments[] = {
    "n = 0",      "m < 0",         "cnp/pnp = 0",     "mnp = 0",        "mcon/ncon out of range",
    "vmask NULL", "p NULL",        "x NULL",          "func NULL",      "itmax < 0",
    "NaN in p",   "Inf in x",      "NaN in covx",     "covx not SPD",   "all-zero vmask",
    "unknown linear solver", "bad loss scale", "unknown loss", "too few measurements",
    "sizes beyond the int API", "absurd loss scale"};
constexpr int kNumBadArguments = int(sizeof kBadArguments / sizeof kBadArguments[0]);

struct Plan {
  unsigned seed = 0;
  // the problem
  int n = 0, m = 0;
  double sigma = 0, perturb = 0, vis = 0;
  // the call
  Driver driver = Driver::MotStrX;
  bool vis_api = false;  // sba_motstr_levmar_x_vis (pairs instead of vmask)
  bool analytic = true;
  bool use_ext = true;   // the _ext entry point with options, else exactly the 1.6 call
  std::string linsolver;
  int nthreads = 1;
  int mcon = 0, ncon = 0;
  bool covx = false;
  std::string loss;
  double loss_scale = 0;
  int itmax = 100;
  bool opts = false;
  double optv[SBA_OPTSSZ] = {};
  bool covariance = false;  // the covariance of the solution afterwards
  // the fault
  Fault fault = Fault::None;
  Sabotage::Kind kind = Sabotage::None;
  long after = 0;
  int bad = 0;  // index into kBadArguments
  int huge_threads = 0;     // nthreads asked for beyond any cap (0: not this case)
  bool once_seen = false;   // the covariance request has a point seen by one camera only
  bool model_files = false;  // the child runs the model files case below instead of the solve
#ifdef SBA_SOAK_MODEL_FILES
  soakfiles::Case files;
#endif

  std::string describe() const {
#ifdef SBA_SOAK_MODEL_FILES
    if (model_files) {
      static const char *const failing[] = {"no report fails", "the PLY file on a full disk",
                                            "the PLY file's name taken at the rename"};
      char buf[384];
      std::snprintf(buf, sizeof buf,
                    "seed %u: model files, %d cameras, %d points, quaternions x %g%s, %s %s %s, "
                    "file size limit %ld, %s%s",
                    seed, files.cameras, files.points, files.q_scale,
                    files.odd_names ? ", names not UTF-8" : "", files.rewrite_binary ? "binary" : "text",
                    files.new_directory ? "into a new directory beside" : "over",
                    files.binary ? "binary" : "text", files.file_limit, failing[files.failing],
                    files.old_report ? ", an old report replaced" : "");
      return buf;
    }
#endif
    char buf[512];
    std::snprintf(buf, sizeof buf,
                  "seed %u: %s%s n=%d m=%d sigma=%g vis=%.2f %s %s%s threads=%d mcon=%d ncon=%d "
                  "covx=%d loss=%s/%g itmax=%d opts=%d covariance=%d%s fault=%s",
                  seed, name_of(driver), vis_api ? "_vis" : "", n, m, sigma, vis,
                  analytic ? "analytic" : "finite-differences", use_ext ? "ext " : "1.6-entry",
                  use_ext ? (linsolver.empty() ? "default-solver" : linsolver.c_str()) : "",
                  huge_threads ? huge_threads : nthreads, mcon, ncon, int(covx), loss.empty() ? "none" : loss.c_str(), loss_scale,
                  itmax, int(opts), int(covariance), once_seen ? " (a point seen once)" : "",
                  fault_name().c_str());
    return buf;
  }
  std::string fault_name() const {
    switch (fault) {
      case Fault::None: return "none";
      case Fault::Value:
      case Fault::Jacobian: {
        static const char *const names[] = {"none", "NaN-value", "Inf-value", "throw",
                                            "NaN-Jacobian", "negated-Jacobian", "wrong-Jacobian",
                                            "zero-Jacobian"};
        return std::string(names[int(kind)]) + " after " + std::to_string(after) + " calls";
      }
      case Fault::Throw: return "throw after " + std::to_string(after) + " calls";
      case Fault::ProgressStop: return "progress-stop at iteration " + std::to_string(after);
      case Fault::BadArgument: return std::string("bad argument: ") + kBadArguments[bad];
    }
    return "?";
  }
};

// Everything random about solve number k, from the run's seed.
Plan make_plan(unsigned run_seed, int k) {
  std::mt19937 rng(run_seed * 1000003u + unsigned(k));
  auto pick = [&](int lo, int hi) { return std::uniform_int_distribution<int>(lo, hi)(rng); };
  auto coin = [&](double p) { return std::uniform_real_distribution<double>(0, 1)(rng) < p; };
  auto real = [&](double lo, double hi) { return std::uniform_real_distribution<double>(lo, hi)(rng); };
  static const char *const solvers[] = {"chol", "ldlt", "bk", "lu", "qr", "qrnoq",
                                        "svd", "cg", "ldl-amd", "sparse-chol", "iterative-schur", ""};
  static const char *const losses[] = {"huber", "cauchy", "soft-l1", "tukey"};
  Plan p;
  p.seed = run_seed * 1000003u + unsigned(k);
  p.n = pick(15, 120);
  p.m = pick(3, 9);
  p.sigma = coin(0.2) ? 0.0 : real(0.1, 1.0);
  p.perturb = real(0.005, 0.06);
  p.vis = real(0.4, 1.0);
  const int d = pick(0, 9);  // motion and structure most of the time
  p.driver = d < 3 ? Driver::MotStrX : d < 6 ? Driver::MotStr : kAllDrivers[size_t(d - 5)];
  p.vis_api = p.driver == Driver::MotStrX && coin(0.2);
  p.analytic = coin(0.75);
  p.use_ext = p.vis_api || coin(0.7);
  if (p.use_ext) {
    p.linsolver = solvers[pick(0, 11)];
    p.nthreads = pick(1, 3);
    if (coin(0.25)) {
      p.loss = losses[pick(0, 3)];
      p.loss_scale = real(0.5, 4.0);
    }
  }
  if (has_cameras(p.driver) && coin(0.4)) p.mcon = pick(0, 2);
  if (has_points(p.driver) && coin(0.4)) p.ncon = pick(0, 5);
  p.covx = coin(0.3);
  p.itmax = pick(5, 150);
  if (coin(0.3)) {
    p.opts = true;
    p.optv[0] = std::pow(10.0, real(-6, 0));
    p.optv[1] = coin(0.5) ? 1e-12 : 0.0;
    p.optv[2] = coin(0.5) ? 1e-12 : std::pow(10.0, real(-15, -6));
    p.optv[3] = coin(0.5) ? 1e-12 : 0.0;
    p.optv[4] = coin(0.7) ? 0.0 : std::pow(10.0, real(-8, -2));
  }
  // Not with Tukey's loss: it gives zero weight to far-off projections, which can leave a
  // point undetermined, and then its covariance is rightly refused.
  p.covariance = p.driver == Driver::MotStrX && !p.vis_api && p.loss != "tukey" && coin(0.15);

  const long per_call = is_expert(p.driver) ? 1 : 0;  // simple drivers: scaled below
  if (coin(0.45)) {
    switch (pick(0, 9)) {
      case 0: case 1: p.fault = Fault::Value; p.kind = coin(0.5) ? Sabotage::NanValue : Sabotage::InfValue; break;
      case 2: p.fault = Fault::Jacobian; p.kind = Sabotage::NanJac; break;
      case 3: p.fault = Fault::Jacobian; p.kind = Sabotage::NegatedJac; break;
      case 4: p.fault = Fault::Jacobian; p.kind = Sabotage::WrongJac; break;
      case 5: p.fault = Fault::Jacobian; p.kind = Sabotage::ZeroJac; break;
      case 6: p.fault = Fault::Throw; p.kind = Sabotage::ThrowValue; break;
      case 7: p.fault = Fault::ProgressStop; break;
      default: p.fault = Fault::BadArgument; p.bad = pick(0, kNumBadArguments - 1); break;
    }
    p.after = pick(0, 12);
    (void)per_call;
    if (p.fault == Fault::ProgressStop) {
      p.use_ext = true;
      p.after = pick(1, 10);
    }
    if (p.fault == Fault::BadArgument && ((p.bad >= 15 && p.bad <= 17) || p.bad == 20)) p.use_ext = true;
    if (p.fault == Fault::Jacobian && !p.analytic) p.analytic = true;  // a fault needs the callback
  }
  // Drawn last, so that the plans above stay those of earlier versions for the same seed.
  if (p.use_ext && coin(0.06)) p.huge_threads = coin(0.5) ? INT_MAX : pick(100, 5000);
  if (p.covariance && coin(0.5)) p.once_seen = true;
#ifdef SBA_SOAK_MODEL_FILES
  if (coin(0.1)) {
    static const double scales[] = {1, 1e300, 1e-200, -3.5};
    p.model_files = true;
    p.files.seed = p.seed;
    p.files.cameras = pick(3, 6);
    p.files.points = 15 * p.files.cameras;
    p.files.q_scale = scales[pick(0, 3)];
    p.files.odd_names = coin(0.5);
    p.files.binary = coin(0.5);
    p.files.rewrite_binary = coin(0.5);
    p.files.file_limit = coin(0.6) ? pick(1, 8000) : 0;  // the disk fills at that byte of a file
    p.files.new_directory = coin(0.3);
    p.files.old_report = coin(0.5);
    p.files.failing = std::max(0, pick(-1, 2));  // half of them with no report failing
  }
#endif
  return p;
}

// ---------------------------------------------------------------- the child's report

struct Report {
  int ret = 0;
  double info[SBA_INFOSZ] = {};
  int fired = 0;            // the fault happened (value and Jacobian faults, progress stop)
  int p_finite = 1;
  int p_untouched = 1;
  double error_of_p = 0;    // the weighted squared error of the returned p, recomputed
  double reported_sq = 0;   // what the library says it is (info[1], or sq_error_final)
  int covariance_ret = 0;   // sba_motstr_covariance_x, when asked
  int covariance_finite = 1;
  long leaked = 0;          // C++ allocations not given back by the solve
  int lsan_leak = 0;        // LeakSanitizer found a leak after the solve
  int underdetermined = 0;  // the random problem has fewer measurements than free parameters
  int threads_used = 0;     // sba_ext_result.nthreads (0: not written)
  int threads_cap = 0;      // the documented cap on a count asked for, for this problem
  int covariance_asked = 0;  // the covariance was computed (plan.covariance, no fault planned)
  int covariance_rank = 0, covariance_nfree = 0;
#ifdef SBA_SOAK_MODEL_FILES
  soakfiles::Outcome files;  // the model files case
#endif
  int done = 0;             // the report is complete
};

// The squared error of p as the library weighs it: e^T Sigma^-1 e per projection.
double weighted_sq_error(const Rig &rig, const std::vector<double> &q, const std::vector<double> *covx) {
  const synth::Problem &pb = rig.pb;
  std::vector<double> full = pb.truth;
  if (q.size() == pb.p0.size())
    full = q;
  else if (q.size() == size_t(pb.m) * kCnp)
    std::copy(q.begin(), q.end(), full.begin());
  else
    std::copy(q.begin(), q.end(), full.begin() + long(pb.m) * kCnp);
  double s = 0.0, x[2];
  int k = 0;
  for (int i = 0; i < pb.n; ++i)
    for (int j = 0; j < pb.m; ++j)
      if (pb.vmask[size_t(i) * pb.m + j]) {
        synth::project(full.data() + j * kCnp, full.data() + size_t(pb.m) * kCnp + i * kPnp, x, nullptr, nullptr);
        const double e0 = pb.x[2 * size_t(k)] - x[0], e1 = pb.x[2 * size_t(k) + 1] - x[1];
        if (covx) {
          const double *c = covx->data() + 4 * size_t(k);
          const double det = c[0] * c[3] - c[1] * c[2];
          s += (c[3] * e0 * e0 - (c[1] + c[2]) * e0 * e1 + c[0] * e1 * e1) / det;
        } else {
          s += e0 * e0 + e1 * e1;
        }
        ++k;
      }
  return s;
}

int progress_stop(void *ctx, const sba_progress *state) {
  const Plan &plan = *static_cast<const Plan *>(ctx);
  return state->iteration >= plan.after ? 1 : 0;
}

// One solve as the plan says; fills r. Runs in the child.
void run_plan(const Plan &plan, Report &r) {
  Rig rig(plan.driver, plan.n, plan.m, plan.sigma, plan.seed, plan.vis);
  // Some covariances that are not the identity: random SPD 2x2 per projection.
  std::mt19937 rng(plan.seed + 7);
  std::uniform_real_distribution<double> U(0.5, 2.0), A(0.0, 3.14159);
  for (int k = 0; k < rig.pb.nvis; ++k) {
    const double s1 = U(rng), s2 = U(rng), a = A(rng), c = std::cos(a), s = std::sin(a);
    double *cv = rig.covx.data() + 4 * size_t(k);
    cv[0] = c * c * s1 + s * s * s2;
    cv[1] = cv[2] = c * s * (s1 - s2);
    cv[3] = s * s * s1 + c * c * s2;
  }
  rig.sab.kind = plan.kind;
  rig.sab.after = plan.after * (is_expert(plan.driver) ? 1 : rig.pb.nvis);
  if (plan.fault == Fault::ProgressStop || plan.fault == Fault::BadArgument) rig.sab.kind = Sabotage::None;

  sba_ext_options ext;
  sba_ext_options_init(&ext);
  sba_ext_result result;
  sba_ext_result_init(&result);
  ext.linsolver = plan.linsolver.empty() ? nullptr : plan.linsolver.c_str();
  ext.nthreads = plan.huge_threads ? plan.huge_threads : plan.nthreads;
  {
    const int hw = std::max(1, int(std::thread::hardware_concurrency()));
    r.threads_cap = std::min(4 * hw, std::max(1, rig.pb.nvis / 64));
  }
  ext.loss = plan.loss.empty() ? nullptr : plan.loss.c_str();
  ext.loss_scale = plan.loss_scale;
  ext.result = &result;
  if (plan.fault == Fault::ProgressStop) {
    ext.progress = progress_stop;
    ext.progress_ctx = const_cast<Plan *>(&plan);
  }

  Call c = rig.base();
  c.mcon = plan.mcon;
  c.ncon = plan.ncon;
  c.itmax = plan.itmax;
  c.jac = plan.analytic;
  c.covx = plan.covx ? rig.covx.data() : nullptr;
  c.opts = plan.opts ? plan.optv : nullptr;
  c.ext = plan.use_ext ? &ext : nullptr;

  // A bad argument, spoiling copies so that the problem stays intact.
  std::vector<char> vm = rig.pb.vmask;
  std::vector<double> xcopy = rig.pb.x, ccopy = rig.covx;
  if (plan.fault == Fault::BadArgument) {
    switch (plan.bad) {
      case 0: c.n = 0; break;
      case 1: c.m = -1; break;
      case 2: if (has_cameras(plan.driver)) c.cnp = 0; else c.pnp = 0; break;
      case 3: c.mnp = 0; break;
      case 4: if (has_cameras(plan.driver)) c.mcon = c.m + 1; else c.ncon = -1; break;
      case 5: c.vmask = nullptr; break;
      case 6: c.p = nullptr; break;
      case 7: c.x = nullptr; break;
      case 8: c.func = false; break;
      case 9: c.itmax = -1; break;
      case 10: rig.p[rig.p.size() / 2] = std::numeric_limits<double>::quiet_NaN(); break;
      case 11: xcopy[xcopy.size() - 1] = std::numeric_limits<double>::infinity(); c.x = xcopy.data(); break;
      case 12: ccopy[5] = std::numeric_limits<double>::quiet_NaN(); c.covx = ccopy.data(); break;
      case 13: ccopy[4 * 2 + 1] = ccopy[4 * 2 + 2] = 10.0; c.covx = ccopy.data(); break;
      case 14: std::fill(vm.begin(), vm.end(), 0); c.vmask = vm.data(); break;
      case 15: ext.linsolver = "no-such-solver"; break;
      case 16: ext.loss = "huber"; ext.loss_scale = -1.0; break;
      case 17: ext.loss = "no-such-loss"; break;
      case 18: std::fill(vm.begin(), vm.end(), 0); vm[0] = vm[1] = 1; c.vmask = vm.data(); break;
      case 19:  // a projection's Jacobian block of 2^20 x 4096: 2^32, 0 in int arithmetic
        c.mnp = 1 << 20;
        if (has_cameras(plan.driver) && has_points(plan.driver)) c.cnp = c.pnp = 2048;
        else if (has_cameras(plan.driver)) c.cnp = 4096;
        else c.pnp = 4096;
        break;
      default: {  // 20: a loss scale whose square overflows or underflows
        static const char *const losses[] = {"huber", "cauchy", "soft-l1", "tukey"};
        static const double scales[] = {1e160, 1e-300, 0x1p512, 0x1p-512, 1.7e308, 4.9e-324};
        ext.loss = losses[plan.seed % 4];
        ext.loss_scale = scales[(plan.seed / 4) % 6];
        break;
      }
    }
  }
  const std::vector<double> p_before = rig.p;
  {
    const long nfree = (has_cameras(plan.driver) ? long(rig.pb.m - plan.mcon) * kCnp : 0) +
                       (has_points(plan.driver) ? long(rig.pb.n - plan.ncon) * kPnp : 0);
    r.underdetermined = 2L * rig.pb.nvis < nfree;
  }

  const long live = g_live_news.load();
  if (plan.vis_api && c.vmask && plan.bad != 14 && plan.bad != 18) {
    std::vector<int> pt, cam;
    for (int i = 0; i < rig.pb.n; ++i)
      for (int j = 0; j < rig.pb.m; ++j)
        if (rig.pb.vmask[size_t(i) * rig.pb.m + j]) pt.push_back(i), cam.push_back(j);
    sba_visibility vis{(long long)pt.size(), pt.data(), cam.data()};
    r.ret = sba_motstr_levmar_x_vis(c.n, c.ncon, c.m, c.mcon, &vis, c.p, c.cnp, c.pnp, c.x, c.covx, c.mnp,
                                    c.func ? x_func_motstr : nullptr, c.jac ? x_fjac_motstr : nullptr,
                                    &rig.sab, c.itmax, 0, c.opts, rig.info, c.ext);
  } else {
    r.ret = call(plan.driver, c, &rig.sab);
  }
  std::copy(rig.info, rig.info + SBA_INFOSZ, r.info);
  r.fired = rig.sab.fired ? 1 : 0;
  if (plan.fault == Fault::ProgressStop) r.fired = r.info[6] == 9;
  r.p_finite = all_finite(rig.p);
  r.p_untouched = std::memcmp(rig.p.data(), p_before.data(), sizeof(double) * p_before.size()) == 0;
  if (r.p_finite && plan.fault != Fault::BadArgument)
    r.error_of_p = weighted_sq_error(rig, rig.p, c.covx ? &rig.covx : nullptr);
  // With a robust loss info[1] is the robust cost; the plain squared error is in the result.
  r.reported_sq = plan.use_ext && !plan.loss.empty() ? result.sq_error_final : r.info[1];
  r.threads_used = plan.use_ext ? result.nthreads : 0;

  if (plan.covariance && r.ret > 0 && plan.fault == Fault::None) {
    std::vector<double> camcov(size_t(rig.pb.m) * kCnp * kCnp), ptcov(size_t(3) * kPnp * kPnp);
    std::vector<int> cams(size_t(rig.pb.m));
    for (int j = 0; j < rig.pb.m; ++j) cams[size_t(j)] = j;
    const int pts[3] = {0, rig.pb.n / 2, rig.pb.n - 1};
    // A point seen by one camera: the last one (never fixed: ncon <= 5 < n) keeps only its
    // first projection, in vmask, x and covx alike.
    std::vector<char> vm1 = rig.pb.vmask;
    std::vector<double> x1, covx1;
    if (plan.once_seen) {
      const int q = rig.pb.n - 1;
      int k = 0;
      bool kept = false;
      for (int i = 0; i < rig.pb.n; ++i)
        for (int j = 0; j < rig.pb.m; ++j) {
          char &v = vm1[size_t(i) * rig.pb.m + j];
          if (!v) continue;
          if (i == q && kept) {
            v = 0;
          } else {
            kept = kept || i == q;
            x1.insert(x1.end(), rig.pb.x.begin() + 2 * k, rig.pb.x.begin() + 2 * k + 2);
            covx1.insert(covx1.end(), rig.covx.begin() + 4 * k, rig.covx.begin() + 4 * k + 4);
          }
          ++k;
        }
    }
    sba_covariance_request req;
    sba_covariance_request_init(&req);
    req.ncams = rig.pb.m;
    req.cams = cams.data();
    req.camcov = camcov.data();
    req.npts = 3;
    req.pts = pts;
    req.ptcov = ptcov.data();
    if (plan.once_seen)
      r.covariance_ret = sba_motstr_covariance_x(c.n, c.ncon, c.m, c.mcon, vm1.data(), rig.p.data(), kCnp,
                                                 kPnp, x1.data(), c.covx ? covx1.data() : nullptr, kMnp,
                                                 x_func_motstr, c.jac ? x_fjac_motstr : nullptr, &rig.sab,
                                                 &req, c.ext);
    else
      r.covariance_ret = sba_motstr_covariance_x(c.n, c.ncon, c.m, c.mcon, c.vmask, rig.p.data(), kCnp,
                                                 kPnp, c.x, c.covx, kMnp, x_func_motstr,
                                                 c.jac ? x_fjac_motstr : nullptr, &rig.sab, &req, c.ext);
    r.covariance_finite = all_finite(camcov) && all_finite(ptcov) && std::isfinite(req.sigma2);
    r.covariance_asked = 1;
    r.covariance_rank = req.rank;
    r.covariance_nfree = req.nfree;
  }
  r.leaked = g_live_news.load() - live;
}

// ---------------------------------------------------------------- judging an outcome

// Empty when the outcome is one the API promises for this plan; else what is wrong.
std::string judge(const Plan &plan, const Report &r) {
#ifdef SBA_SOAK_MODEL_FILES
  if (plan.model_files) return soakfiles::judge(r.files);
#endif
  const double *info = r.info;
  const int reason = int(info[6]);
  auto consistent = [&]() {
    const double ref = std::max(std::fabs(r.reported_sq), 1e-300);
    return std::fabs(r.error_of_p - r.reported_sq) <= 1e-6 * ref + 1e-12;
  };
  auto descent = [&]() { return std::isfinite(info[1]) && info[1] <= info[0] * (1 + 1e-12); };
  const bool fault = plan.fault != Fault::None && (plan.fault == Fault::BadArgument || r.fired);
  if (r.underdetermined && (!fault || plan.fault != Fault::BadArgument)) {
    // The random problem is a bad argument by itself: too few measurements.
    if (r.ret != SBA_ERROR || reason != 0) return "an underdetermined problem was not refused";
    if (!r.p_untouched) return "p was changed despite too few measurements";
    return {};
  }
  if (!fault) {
    if (r.ret < 0) return "SBA_ERROR without a fault (reason " + std::to_string(reason) + ")";
    if (reason < 1 || reason > 5) return "reason " + std::to_string(reason) + " without a fault";
    if (!descent()) return "the final error is not finite or above the initial one";
    if (!r.p_finite) return "p is not finite";
    if (!consistent()) return "the reported error does not match the returned p";
    if (plan.huge_threads && r.threads_used > r.threads_cap)
      return "a thread count of " + std::to_string(plan.huge_threads) + " was not capped (" +
             std::to_string(r.threads_used) + " used, cap " + std::to_string(r.threads_cap) + ")";
    if (plan.once_seen && r.covariance_asked) {
      if (r.covariance_ret == 0 && r.covariance_rank >= r.covariance_nfree)
        return "a point seen once got a full-rank covariance";
      if (r.covariance_ret == 0 && !r.covariance_finite) return "the covariance of the solution is not finite";
      return {};
    }
    if (plan.covariance && r.covariance_ret != 0) return "the covariance of the solution failed";
    if (plan.covariance && !r.covariance_finite) return "the covariance of the solution is not finite";
    return {};
  }
  switch (plan.fault) {
    case Fault::Value:
    case Fault::Throw:
      if (r.ret != SBA_ERROR) return "a failing callback was not reported";
      if (!r.p_finite) return "p is not finite after a failing callback";
      if (plan.fault == Fault::Value && reason != 7) return "reason " + std::to_string(reason) + " for NaN/Inf";
      // p is the last accepted estimate; when f(p0) itself failed, that is p0, untouched.
      if (plan.fault == Fault::Value && !consistent() && !(info[5] == 0 && r.p_untouched))
        return "p is not the last accepted estimate";
      return {};
    case Fault::Jacobian:
      if (plan.kind == Sabotage::NanJac && plan.mcon == 0 && plan.ncon == 0) {
        if (r.ret != SBA_ERROR || reason != 7) return "a NaN Jacobian was not reported with reason 7";
      } else if (plan.kind == Sabotage::NanJac && r.ret == SBA_ERROR) {
        // With fixed cameras or points the NaN may sit in a block that is ignored by design.
        if (reason != 7) return "a NaN Jacobian gave reason " + std::to_string(reason);
      } else if (r.ret == SBA_ERROR) {
        if (reason != 7 && reason != 8) return "a wrong Jacobian gave SBA_ERROR with reason " + std::to_string(reason);
      } else if (reason < 1 || reason > 6) {
        return "a wrong Jacobian gave reason " + std::to_string(reason);
      }
      if (!r.p_finite) return "p is not finite after a wrong Jacobian";
      if (!descent()) return "the error grew with a wrong Jacobian";
      if (!consistent()) return "the reported error does not match the returned p";
      return {};
    case Fault::ProgressStop:
      if (r.ret < 0 || reason != 9) return "the progress callback's stop gave reason " + std::to_string(reason);
      if (!descent() || !consistent()) return "p after a progress stop is not the last accepted estimate";
      return {};
    case Fault::BadArgument:
      if (r.ret != SBA_ERROR) return "a bad argument was accepted";
      if (reason != 0) return "reason " + std::to_string(reason) + " for a bad argument";
      if (!r.p_untouched) return "p was changed despite a bad argument";
      return {};
    case Fault::None:
      break;
  }
  return {};
}

// ---------------------------------------------------------------- the run

struct Child {
  pid_t pid = -1;
  int k = 0;
  int fd = -1;
  std::FILE *err = nullptr;
  std::chrono::steady_clock::time_point t0;
};

struct Tally {
  int solves = 0, with_fault = 0, faults_fired = 0, bad_arguments = 0;
  int crashes = 0, hangs = 0, leaks = 0, wrong = 0;
  int sba_errors = 0, successes = 0;
  double slowest = 0;
  std::vector<std::string> problems;
};

std::string read_all(std::FILE *f) {
  std::string s;
  char buf[4096];
  std::rewind(f);
  for (size_t got; (got = std::fread(buf, 1, sizeof buf, f)) > 0;) s.append(buf, got);
  return s;
}

Child start(unsigned seed, int k, unsigned timeout) {
  Child ch;
  ch.k = k;
  ch.err = std::tmpfile();
  int fds[2];
  if (!ch.err || pipe(fds) != 0) {
    std::perror("sba_soak: tmpfile/pipe");
    std::exit(2);
  }
  std::fflush(stdout);
  std::fflush(stderr);
  ch.t0 = std::chrono::steady_clock::now();
  ch.pid = fork();
  if (ch.pid < 0) {
    std::perror("sba_soak: fork");
    std::exit(2);
  }
  if (ch.pid == 0) {
    close(fds[0]);
    dup2(fileno(ch.err), 1);
    dup2(fileno(ch.err), 2);
    alarm(timeout);
    const Plan plan = make_plan(seed, k);
    Report r;
#ifdef SBA_SOAK_MODEL_FILES
    if (plan.model_files) {
      const long live = g_live_news.load();
      soakfiles::run(plan.files, &r.files);
      r.leaked = g_live_news.load() - live;
    } else {
      run_plan(plan, r);
    }
#else
    run_plan(plan, r);
#endif
    if (__lsan_do_recoverable_leak_check) r.lsan_leak = __lsan_do_recoverable_leak_check() != 0;
    r.done = 1;
    const char *b = reinterpret_cast<const char *>(&r);
    for (size_t done = 0; done < sizeof r;) {
      const ssize_t w = write(fds[1], b + done, sizeof r - done);
      if (w <= 0) break;
      done += size_t(w);
    }
    _exit(0);
  }
  close(fds[1]);
  ch.fd = fds[0];
  return ch;
}

void finish(unsigned seed, Child &ch, int status, Tally &t, bool verbose) {
  const double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - ch.t0).count();
  t.slowest = std::max(t.slowest, secs);
  Report r;
  std::string data;
  char buf[sizeof(Report)];
  for (ssize_t got; (got = read(ch.fd, buf, sizeof buf)) != 0;) {
    if (got < 0 && errno == EINTR) continue;
    if (got < 0) break;
    data.append(buf, size_t(got));
  }
  close(ch.fd);
  const bool have = data.size() == sizeof r;
  if (have) std::memcpy(static_cast<void *>(&r), data.data(), sizeof r);
  const Plan plan = make_plan(seed, ch.k);
  ++t.solves;
  if (plan.fault != Fault::None) ++t.with_fault;
  if (plan.fault == Fault::BadArgument) ++t.bad_arguments;
  std::string what;
  if (WIFSIGNALED(status) && WTERMSIG(status) == SIGALRM) {
    ++t.hangs;
    what = "hang: no result within the time limit";
  } else if (WIFSIGNALED(status)) {
    ++t.crashes;
    what = "crash: killed by signal " + std::to_string(WTERMSIG(status));
  } else if (!WIFEXITED(status) || WEXITSTATUS(status) != 0 || !have || !r.done) {
    ++t.crashes;
    what = "crash: the child exited with status " + std::to_string(WEXITSTATUS(status)) + " without its report";
  } else {
    if (r.fired && plan.fault != Fault::BadArgument) ++t.faults_fired;
    (r.ret == SBA_ERROR ? t.sba_errors : t.successes)++;
    if (r.leaked != 0 || r.lsan_leak) {
      ++t.leaks;
      what = "leak: " + std::to_string(r.leaked) + " C++ allocations not given back" +
             (r.lsan_leak ? ", LeakSanitizer report" : "");
    }
    const std::string wrong = judge(plan, r);
    if (!wrong.empty()) {
      ++t.wrong;
      what += (what.empty() ? "" : "; ") + std::string("wrong result: ") + wrong + " (ret " +
              std::to_string(r.ret) + ", reason " + std::to_string(int(r.info[6])) + ", error " +
              std::to_string(r.info[0]) + " -> " + std::to_string(r.info[1]) + ", p scores " +
              std::to_string(r.error_of_p) + " vs reported " + std::to_string(r.reported_sq) + ")";
    }
  }
  if (!what.empty()) {
    std::string err = read_all(ch.err);
    if (err.size() > 1500) err = err.substr(0, 1500) + "...";
    if (t.problems.size() < 30)
      t.problems.push_back("solve " + std::to_string(ch.k) + " [" + plan.describe() + "]: " + what +
                           (err.empty() ? "" : "\n    output: " + err));
  } else if (verbose) {
    std::printf("solve %d ok (%.3f s): %s -> ret %d reason %d\n", ch.k, secs, plan.describe().c_str(),
                r.ret, int(r.info[6]));
  }
  std::fclose(ch.err);
}

}  // namespace

int main(int argc, char **argv) {
  int solves = 1000, jobs = 2;
  unsigned seed = 1, timeout = 60;
  bool verbose = false;
  for (int a = 1; a < argc; ++a) {
    const std::string arg = argv[a];
    auto value = [&]() -> const char * {
      if (a + 1 >= argc) {
        std::fprintf(stderr, "sba_soak: %s needs a value\n", arg.c_str());
        std::exit(2);
      }
      return argv[++a];
    };
    if (arg == "--solves") solves = std::atoi(value());
    else if (arg == "--seed") seed = unsigned(std::strtoul(value(), nullptr, 10));
    else if (arg == "--timeout") timeout = unsigned(std::atoi(value()));
    else if (arg == "--jobs") jobs = std::max(1, std::atoi(value()));
    else if (arg == "--verbose") verbose = true;
    else {
      std::fprintf(stderr, "usage: sba_soak [--solves N] [--seed S] [--timeout SECONDS] [--jobs J] [--verbose]\n");
      return 2;
    }
  }
  const bool lsan = __lsan_do_recoverable_leak_check != nullptr;
  const auto t0 = std::chrono::steady_clock::now();
  Tally t;
  std::vector<Child> running;
  int next = 0;
  while (next < solves || !running.empty()) {
    while (next < solves && int(running.size()) < jobs) running.push_back(start(seed, next++, timeout));
    int status = 0;
    const pid_t pid = waitpid(-1, &status, 0);
    if (pid < 0) {
      if (errno == EINTR) continue;
      std::perror("sba_soak: waitpid");
      return 2;
    }
    for (size_t q = 0; q < running.size(); ++q)
      if (running[q].pid == pid) {
        finish(seed, running[q], status, t, verbose);
        running.erase(running.begin() + long(q));
        break;
      }
  }
  const double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  for (const std::string &p : t.problems) std::printf("sba_soak: %s\n", p.c_str());
  std::printf("sba_soak: %d solves (seed %u, %d at a time, %.1f s, slowest %.2f s): %d without a fault, "
              "%d with one (%d faults fired in the callbacks, %d bad arguments); %d returned "
              "SBA_ERROR, %d succeeded\n",
              t.solves, seed, jobs, secs, t.slowest, t.solves - t.with_fault, t.with_fault,
              t.faults_fired, t.bad_arguments, t.sba_errors, t.successes);
  std::printf("sba_soak: crashes %d, hangs %d, leaks %d (%s), wrong results %d\n", t.crashes,
              t.hangs, t.leaks, lsan ? "LeakSanitizer in every child" : "counted C++ allocations",
              t.wrong);
  return t.crashes + t.hangs + t.leaks + t.wrong == 0 ? 0 : 1;
}
