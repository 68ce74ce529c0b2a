/* SPDX-License-Identifier: BSD-3-Clause */
// The motion-and-structure solve as balsba and sbarefine run it, from the check of --mcon and
// --ncon to the exit status: the expert driver by visibility pairs with the extension options,
// a progress line, Ctrl-C and --max-time, then sba 1.6's summary, the report and --json. What
// differs between the programs (reading, writing, the sizes line) stays in them.
#ifndef SBA_DEMO_MOTSTR_SOLVE_H
#define SBA_DEMO_MOTSTR_SOLVE_H

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstddef>
#include <cstdio>
#include <functional>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "cli/cli.h"
#include "cli/report.h"
#include "cli/run_control.h"
#include "cli/solve_options.h"
#include "cli/tty_progress.h"
#include "formats/output_file.h"
#include "formats/visibility.h"
#include "sba.h"
#include "sba_ext.h"

namespace sbacli {

// sba_motstr_levmar_x_vis's arguments that are not options; p is refined in place. The
// visibility is given as pairs: memory then follows the observations, not n*m.
struct MotstrInputs {
  int n = 0, m = 0, cnp = 0, pnp = 3;
  const sbaformats::Visibility *vis = nullptr;
  double *p = nullptr;
  double *x = nullptr;
  void (*func)(double *p, struct sba_crsm *idxij, int *rcidxs, int *rcsubs, double *hx, void *adata) = nullptr;
  void (*fjac)(double *p, struct sba_crsm *idxij, int *rcidxs, int *rcsubs, double *jac, void *adata) = nullptr;
  void *adata = nullptr;
  // sba_ext_options' held and shared camera parameters (see sba_ext.h); null: none.
  const char *cam_fixed = nullptr;
  int cam_fixed_per_camera = 0;
  const int *cam_group = nullptr;
  const char *cam_shared = nullptr;
  const int *cam_param_group = nullptr;
  // Parameters of each camera that the callbacks hold rather than cam_fixed (eucsbademo's camera
  // model holds its trailing intrinsics by a zero derivative): not unknowns either.
  int cam_held_by_callbacks = 0;
  // Priors (sba_ext.h), residuals beside the projections: how many, and what sets an
  // sba_ext_options' prior fields to them (empty: none).
  int npriors = 0;
  std::function<void(sba_ext_options *)> attach_priors;
  // The same model's per-projection callbacks, on the same adata: with single_jacobian the
  // solve runs the simple driver (sba_motstr_levmar_vis) with the Jacobian stored in single
  // precision (sba_ext_options.single_precision_jacobian), which the expert driver refuses.
  void (*proj)(int j, int i, double *aj, double *bi, double *xij, void *adata) = nullptr;
  void (*projac)(int j, int i, double *aj, double *bi, double *Aij, double *Bij, void *adata) = nullptr;
  bool single_jacobian = false;
};

class MotstrSolve {
 public:
  MotstrSolve(const char *program, const std::string &input, const SolveOptions &so, const MotstrInputs &in)
      : program_(program),
        input_(input),
        so_(so),
        in_(in),
        nobs_(static_cast<int>(in.vis->size())),
        progress_(so.progress, nobs_) {}
  MotstrSolve(const MotstrSolve &) = delete;
  MotstrSolve &operator=(const MotstrSolve &) = delete;

  // -1 when --mcon and --ncon fit the cameras and points; else the usage status, said why.
  int check_fixed() const {
    const int m = in_.m, n = in_.n;
    if (so_.mcon > m) {
      std::fprintf(stderr, "%s: --mcon %d is more than the %d cameras\n", program_, so_.mcon, m);
      return kExitUsage;
    }
    if (so_.ncon > n) {
      std::fprintf(stderr, "%s: --ncon %d is more than the %d points\n", program_, so_.ncon, n);
      return kExitUsage;
    }
    return -1;
  }

  // Solves; false when the driver failed (said on stderr). A solve stopped by a signal or
  // the time limit is a result: finish() gives its status.
  bool run() {
    const MotstrInputs &in = in_;
    // The callbacks are re-entrant and walk the index by rows: the threads share them.
    sba_ext_options ext;
    init_ext(so_, program_, &sink_, &result_, &ext);
    solver_ = ext.linsolver;
    ext.cam_fixed = in.cam_fixed;
    ext.cam_fixed_per_camera = in.cam_fixed_per_camera;
    ext.cam_group = in.cam_group;
    ext.cam_shared = in.cam_shared;
    ext.cam_param_group = in.cam_param_group;
    if (in.attach_priors) in.attach_priors(&ext);
    // The time limit and the iteration times count from the solve's start, not from what the
    // program did before it (an initial PLY file, say).
    control_.emplace(so_.max_time, &progress_);
    RunControl::catch_signals(program_);
    control_->attach(&ext);
    const auto start = std::chrono::steady_clock::now();
    const sba_visibility vis{static_cast<long long>(in.vis->size()), in.vis->point.data(), in.vis->camera.data()};
    ext.single_precision_jacobian = in.single_jacobian;
    if (in.single_jacobian)
      ret_ = sba_motstr_levmar_vis(in.n, so_.ncon, in.m, so_.mcon, &vis, in.p, in.cnp, in.pnp, in.x, nullptr, 2, in.proj,
                                   in.projac, in.adata, so_.itmax, so_.verbose, so_.opts.data(), info_.data(), &ext);
    else
      ret_ = sba_motstr_levmar_x_vis(in.n, so_.ncon, in.m, so_.mcon, &vis, in.p, in.cnp, in.pnp, in.x, nullptr, 2,
                                     in.func, in.fjac, in.adata, so_.itmax, so_.verbose, so_.opts.data(), info_.data(),
                                     &ext);
    seconds_ = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    progress_.finish();
    if (ret_ != SBA_ERROR) return true;
    std::fprintf(stderr, "%s: %s: the solve failed (SBA_ERROR, reason %g): %s\n", program_, input_.c_str(), info_[6],
                 sink_.first_error.empty() ? "no result" : sink_.first_error.c_str());
    return false;
  }

  // In place of run() for a program whose --itmax 0 rewrites its input: no solve and no
  // Jacobian check (the driver's itmax == 0 mode, whose finite differences cost far more than
  // a solve on a large model), only the squared error of p through project(j, i, x) reported
  // as the result of zero iterations. A robust loss is not applied: nothing is fitted.
  template <class Project>
  void score(Project project) {
    control_.emplace(so_.max_time, &progress_);
    const auto start = std::chrono::steady_clock::now();
    double sq = 0;
    for (std::size_t k = 0; k < in_.vis->size(); ++k) {
      double xp[2];
      projection_or_measurement(project, in_.vis->camera[k], in_.vis->point[k], in_.x + 2 * k, xp);
      const double dx = xp[0] - in_.x[2 * k], dy = xp[1] - in_.x[2 * k + 1];
      sq += dx * dx + dy * dy;
    }
    seconds_ = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    info_.fill(0);
    info_[0] = info_[1] = sq;
    info_[6] = SBA_STOP_ITMAX;
    info_[7] = 1;
    result_.sq_error_initial = result_.sq_error_final = sq;
    result_.cost_initial = result_.cost_final = sq;
    result_.nthreads = 1;
    ret_ = 0;
  }

  // A covariance at the result into `path` by compute(ext, error), with the solve's options
  // (threads, loss, the log sink) and a stop signal's cancel: false, said on stderr, when it
  // fails (the library's reason, else compute's error). A stop signal abandons it: true, the
  // run then ends as a late signal ends it (finish), without its files.
  template <class Compute>
  bool covariance(const std::string &path, Compute compute) {
    sba_ext_options ext;
    sba_ext_result scratch;
    init_ext(so_, program_, &sink_, &scratch, &ext);
    ext.result = nullptr;
    // The priors are residuals of the problem: their information is part of J^T J.
    if (in_.attach_priors) in_.attach_priors(&ext);
    RunControl::attach_cancel(&ext);
    sink_.first_error.clear();
    std::string error;
    if (compute(ext, &error) || g_stop_signal != 0) return true;
    std::fprintf(stderr, "%s: %s: no covariance: %s\n", program_, path.c_str(),
                 error.empty() ? sink_.first_error.c_str() : error.c_str());
    return false;
  }

  // The report's "model" (see Report::model).
  void describe(const std::string &model) { model_ = model; }

  // COLMAP's mean reprojection error (mean_error_by_point) at p as it is, before the solve:
  // finish() then reports it, initial and final, beside the RMS error.
  template <class Project>
  void report_mean_error(Project project) {
    mean_initial_ = mean_error_by_point(*in_.vis, in_.x, project);
  }

  int observations() const { return nobs_; }
  // The parameters as sba 1.6 counts them: every camera's cnp and every point's pnp, held ones
  // and each camera's copy of a shared one included.
  long long variables() const {
    return static_cast<long long>(in_.m) * in_.cnp + static_cast<long long>(in_.n) * in_.pnp;
  }
  // What the solve estimates, as sba_ext.h defines the unknowns: the parameters of the cameras
  // from mcon on that are not held (cam_fixed, or by the callbacks), a shared one once for its
  // group (cam_group and cam_shared, or cam_param_group), and the points from ncon on.
  long long unknowns() const {
    const MotstrInputs &in = in_;
    long long count = static_cast<long long>(in.n - so_.ncon) * in.pnp -
                      static_cast<long long>(in.m - so_.mcon) * in.cam_held_by_callbacks;
    std::vector<std::pair<int, int>> shared;  // (parameter, group) of each shared unknown, once
    for (int j = so_.mcon; j < in.m; ++j)
      for (int c = 0; c < in.cnp; ++c) {
        const std::size_t jc = static_cast<std::size_t>(j) * static_cast<std::size_t>(in.cnp) + static_cast<std::size_t>(c);
        if (in.cam_fixed && in.cam_fixed[in.cam_fixed_per_camera ? jc : static_cast<std::size_t>(c)]) continue;
        int group = -1;
        if (in.cam_param_group) group = in.cam_param_group[jc];
        else if (in.cam_group && in.cam_shared && in.cam_shared[c]) group = in.cam_group[j];
        if (group < 0) ++count;
        else shared.emplace_back(c, group);
      }
    std::sort(shared.begin(), shared.end());
    return count + (std::unique(shared.begin(), shared.end()) - shared.begin());
  }

  // After the program's sizes line: sba 1.6's summary, the report, --json (each camera's
  // error through project(j, i, x) at the result, named by `names` where given) into the
  // run's outputs, which are then published (publish_outputs), "Wrote OUT" when `written` is
  // not empty, and a line for the files publishing removed (print_removed); the exit status.
  template <class Project>
  int finish(double read_seconds, Project project, const std::vector<std::string> &names,
             const std::string &written, sbaformats::OutputSet *outputs) {
    print_summary(nobs_, ret_, info_, seconds_, read_seconds, result_, so_);
    Report report = make_report(program_, input_, in_.m, in_.n, nobs_, variables(), so_, ret_, info_, result_,
                                seconds_, *control_);
    report.unknowns = unknowns();
    report.priors = in_.npriors;
    report.model = model_;
    report.solver_requested = solver_;
    report.single_jacobian = in_.single_jacobian;
    if (!std::isnan(mean_initial_)) {
      report.mean_initial = mean_initial_;
      report.mean_final = mean_error_by_point(*in_.vis, in_.x, project);
    }
    print_report(stdout, report);
    if (!so_.json.empty()) {
      add_per_camera(in_.m, *in_.vis, in_.x, project, &report);
      for (std::size_t j = 0; j < names.size() && j < report.per_camera.size(); ++j)
        report.per_camera[j].name = names[j];
      std::string error;
      if (!write_json(so_.json, report, &error, outputs)) {
        std::fprintf(stderr, "%s\n", error.c_str());
        return kExitFailure;
      }
    }
    if (const int status = control_->late_signal(program_, info_[6] == SBA_STOP_USER, outputs)) return status;
    if (!sbaformats::publish_outputs(program_, outputs)) return kExitFailure;
    if (!written.empty()) std::printf("Wrote %s\n", written.c_str());
    print_removed(stdout, *outputs);
    // A stopped solve is a result (written above), but the status says it was cut short by a
    // signal; a time limit the user set is an ordinary end.
    if (info_[6] == SBA_STOP_USER) return stopped_status(program_, *control_, so_.max_time, static_cast<int>(info_[5]));
    return 0;
  }

 private:
  const char *program_;
  const std::string &input_;
  const SolveOptions &so_;
  const MotstrInputs in_;
  const int nobs_;
  TtyProgress progress_;
  std::optional<RunControl> control_;  // made when the solve starts
  LogSink sink_;
  sba_ext_result result_{};
  std::array<double, SBA_INFOSZ> info_{};
  int ret_ = 0;
  double seconds_ = 0;
  std::string model_;
  double mean_initial_ = NAN;  // report_mean_error's; NaN: not reported
  std::string solver_;  // the solver asked for, the program's default included; empty: none ran
};

}  // namespace sbacli

#endif  // SBA_DEMO_MOTSTR_SOLVE_H
