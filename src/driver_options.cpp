// SPDX-License-Identifier: BSD-3-Clause
#include "driver_options.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstring>

#include "thread_policy.h"

namespace sba {
namespace {

std::string from_env(const char *name) {
  const char *value = std::getenv(name);
  return value ? value : "";
}

// The thread count: ext's, else SBA_NUM_THREADS's, else left to the library (auto_threads).
void choose_threads(const DriverArgs &a, const sba_ext_options &ext, const Environment &env,
                    const Logger &log, Options *o) {
  int threads = ext.nthreads;
  if (threads <= 0) {
    threads = parse_thread_count(env.num_threads.c_str());
    if (threads < 0) {
      log.notice("%s: SBA_NUM_THREADS=\"%s\" is not a positive integer: ignored (the library "
                 "chooses the thread count)",
                 a.name, env.num_threads.c_str());
      threads = 0;
    }
  }
  o->auto_threads = threads <= 0;  // fit_threads chooses (and caps an explicit count)
  o->nthreads = std::max(1, threads);
}

// What ext hands over as it is: the callbacks and the camera parameters' arrays.
void pass_through(const sba_ext_options &ext, Options *o) {
  o->progress = ext.progress;
  o->progress_ctx = ext.progress_ctx;
  o->cancel = ext.cancel;
  o->cancel_ctx = ext.cancel_ctx;
  o->parallel_callbacks = ext.parallel_callbacks != 0;
  o->cams.fixed = ext.cam_fixed;
  o->cams.fixed_per_camera = ext.cam_fixed_per_camera != 0;
  o->cams.param_group = ext.cam_param_group;
  o->cams.group = ext.cam_group;
  o->cams.shared = ext.cam_shared;
  o->memory_budget = double(ext.memory_budget);
  o->single_jacobian = ext.single_precision_jacobian != 0;
  o->priors.ncamera = ext.ncamera_priors;
  o->priors.camera = ext.camera_priors;
  o->priors.nlinear = ext.ncamera_linear_priors;
  o->priors.linear = ext.camera_linear_priors;
  o->priors.npoint = ext.npoint_priors;
  o->priors.point = ext.point_priors;
}

// Opt-in only: how the host's threads are scheduled is the host's business.
void choose_avoid_shared_cores(const DriverArgs &a, const sba_ext_options &ext, const Environment &env,
                               const Logger &log, Options *o) {
  o->avoid_shared_cores = ext.avoid_shared_cores != 0;
  if (!o->avoid_shared_cores && !env.avoid_shared_cores.empty()) {
    o->avoid_shared_cores = env.avoid_shared_cores == "1";
    if (!o->avoid_shared_cores && env.avoid_shared_cores != "0")
      log.notice("%s: SBA_AVOID_SHARED_CORES=\"%s\" is neither 0 nor 1: ignored (off)", a.name,
                 env.avoid_shared_cores.c_str());
  }
}

// ext's robust loss, if it names one (its scale is checked with the rest, Options::is_valid);
// false, with what is wrong in *error, for an unknown name.
bool choose_loss(const sba_ext_options &ext, Options *o, std::string *error) {
  if (!ext.loss) return true;
  LossKind kind;
  if (!loss_from_name(ext.loss, &kind)) {
    *error = std::string("unknown loss \"") + ext.loss + "\" (known: " + loss_names() + ")";
    return false;
  }
  const double scale = ext.loss_scale == 0.0 ? 1.0 : ext.loss_scale;
  o->loss = Loss(kind, scale);
  return true;
}

}  // namespace

Environment read_environment() {
  Environment env;
  env.linsolver = from_env("SBA_LINSOLVER");
  env.strategy = from_env("SBA_STRATEGY");
  env.num_threads = from_env("SBA_NUM_THREADS");
  env.avoid_shared_cores = from_env("SBA_AVOID_SHARED_CORES");
  return env;
}

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

bool options_from(const DriverArgs &a, const sba_ext_options &ext, const Environment &env,
                  const Logger &log, Options *o, std::string *error) {
  o->itmax = a.itmax;
  static_assert(SBA_OPTSSZ == 5, "opts[] is tau, eps1, eps2, eps3, eps4");
  if (a.opts) {
    // 1.6 uses the magnitudes: a negative tolerance is not a request for something else.
    o->tau = std::fabs(a.opts[0]);
    o->eps1 = std::fabs(a.opts[1]);
    o->eps2 = std::fabs(a.opts[2]);
    o->eps3 = std::fabs(a.opts[3]);
    o->eps4 = std::fabs(a.opts[4]);
  }

  // The solver no one names: sba 1.6's for its own entry points (an _ext call given no ext
  // is one of them); for a caller of the extensions, one chosen from the problem.
  const LinSolver by_default = a.ext || a.by_pairs ? LinSolver::Auto : LinSolver::Chol;
  o->solver = by_default;
  if (ext.linsolver) {
    if (!linsolver_from_name(ext.linsolver, &o->solver)) {
      *error = std::string("unknown linear solver \"") + ext.linsolver + "\" (known: " +
               linsolver_names() + ")";
      return false;
    }
  } else if (!env.linsolver.empty()) {
    // A typo is not an error of a call that succeeds: a warning.
    if (!linsolver_from_name(env.linsolver, &o->solver)) {
      o->solver = by_default;
      log.notice("%s: unknown SBA_LINSOLVER \"%s\" (known: %s); using %s", a.name,
                 env.linsolver.c_str(), linsolver_names(), linsolver_name(by_default));
    }
  }
  if (ext.strategy) {
    if (!strategy_from_name(ext.strategy, &o->strategy)) {
      *error = std::string("unknown strategy \"") + ext.strategy + "\" (known: " +
               strategy_names() + ")";
      return false;
    }
  } else if (!env.strategy.empty()) {
    if (!strategy_from_name(env.strategy, &o->strategy))
      log.notice("%s: unknown SBA_STRATEGY \"%s\" (known: %s); using sba", a.name,
                 env.strategy.c_str(), strategy_names());
  }
  choose_threads(a, ext, env, log, o);
  pass_through(ext, o);
  choose_avoid_shared_cores(a, ext, env, log, o);
  return choose_loss(ext, o, error);
}

}  // namespace sba
