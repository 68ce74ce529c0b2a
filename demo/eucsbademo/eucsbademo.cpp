// SPDX-License-Identifier: BSD-3-Clause
// eucsbademo: Euclidean bundle adjustment of camera and point files with sba, keeping the
// command line, file formats and printed lines of sba 1.6's demo
// (docs/formats.md). Options cover what 1.6 fixed at compile time.
#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

#include "cameras/camera_pose.h"
#include "cameras/euclidean.h"
#include "cli/cli.h"
#include "cli/ply_options.h"
#include "cli/report.h"
#include "cli/run_control.h"
#include "cli/solve_options.h"
#include "cli/tty_progress.h"
#include "eucsbademo/options.h"
#include "formats/eucsba_io.h"
#include "formats/output_file.h"
#include "sba.h"
#include "sba_ext.h"

namespace eucsbademo {
namespace {

// The program puts the Euclidean camera and its files to work.
using namespace sbacameras::euclidean;
using namespace sbaformats::eucsba;
using sbacli::kExitFailure;
using sbacli::kExitUsage;

// 1.6 switches to motion and structure when motion alone leaves more than this mean squared
// error (pixels^2).
constexpr double kMotionOnlyErrorLimit = 4.0;

// Everything one run of a driver needs.
struct Solve {
  const DemoOptions &options;
  const CameraModel &model;
  PointSet &points;  // sba takes x, covx and vmask as non-const pointers
  sbacli::RunControl &control;  // progress, Ctrl-C, --max-time
};

struct Outcome {
  Refinement refinement = Refinement::MotionStructure;
  int ret = SBA_ERROR;
  std::array<double, SBA_INFOSZ> info{};
  std::vector<double> p;  // the refined parameters, laid out as refinement says
  sba_ext_result result{};
};

// The initial parameter vector for a refinement: cameras (v = 0) and/or points.
std::vector<double> initial_params(const CameraModel &model, Refinement refinement) {
  std::vector<double> p;
  if (refinement != Refinement::Structure) p = model.initial_camera_params();
  if (refinement != Refinement::Motion)
    p.insert(p.end(), model.initial_points().begin(), model.initial_points().end());
  return p;
}

const char *driver_name(Refinement r, bool expert) {
  switch (r) {
    case Refinement::MotionStructure: return expert ? "sba_motstr_levmar_x_ext" : "sba_motstr_levmar_ext";
    case Refinement::Motion: return expert ? "sba_mot_levmar_x_ext" : "sba_mot_levmar_ext";
    case Refinement::Structure: return expert ? "sba_str_levmar_x_ext" : "sba_str_levmar_ext";
  }
  return "";
}

Outcome run(const Solve &s, Refinement refinement, int itmax) {
  const DemoOptions &o = s.options;
  Outcome out;
  out.refinement = refinement;
  out.p = initial_params(s.model, refinement);
  const int n = s.points.npoints(), m = s.points.ncameras;
  const int cnp = s.model.cnp(), pnp = kPointParams, mnp = kMeasurementParams;
  char *vmask = s.points.vmask.data();
  double *p = out.p.data(), *x = s.points.x.data();
  double *covx = s.points.has_covariances() ? s.points.covx.data() : nullptr;
  void *adata = as_adata(s.model);
  const double *opts = o.opts.data();
  double *info = out.info.data();
  // Always the extension drivers; with the defaults they are the 1.6 entry points, whose
  // solver is 1.6's chol (the extension drivers' own default is auto), or SBA_LINSOLVER.
  sba_ext_options ext;
  sba_ext_options_init(&ext);
  ext.linsolver = sbacli::linsolver_of(o.linsolver, "eucsbademo", "chol");
  if (!o.strategy.empty()) ext.strategy = o.strategy.c_str();
  ext.nthreads = o.nthreads;
  ext.avoid_shared_cores = sbacli::avoids_shared_cores();
  ext.single_precision_jacobian = o.single_jacobian;
  // The model's callbacks are re-entrant and walk the index by rows: let the threads share them.
  ext.parallel_callbacks = 1;
  if (!o.loss.empty()) {
    ext.loss = o.loss.c_str();
    ext.loss_scale = o.loss_scale;
  }
  ext.result = &out.result;
  sba_ext_result_init(&out.result);
  s.control.attach(&ext);

  if (o.expert) {
    const ExpertCallbacks cb = expert_callbacks(s.model.kind(), refinement);
    const auto fjac = o.analytic ? cb.fjac : nullptr;
    switch (refinement) {
      case Refinement::MotionStructure:
        out.ret = sba_motstr_levmar_x_ext(n, o.ncon, m, o.mcon, vmask, p, cnp, pnp, x, covx, mnp,
                                          cb.func, fjac, adata, itmax, o.verbose, opts, info, &ext);
        break;
      case Refinement::Motion:
        out.ret = sba_mot_levmar_x_ext(n, m, o.mcon, vmask, p, cnp, x, covx, mnp, cb.func, fjac, adata,
                                       itmax, o.verbose, opts, info, &ext);
        break;
      case Refinement::Structure:
        out.ret = sba_str_levmar_x_ext(n, o.ncon, m, vmask, p, pnp, x, covx, mnp, cb.func, fjac, adata,
                                       itmax, o.verbose, opts, info, &ext);
        break;
    }
    return out;
  }
  switch (refinement) {
    case Refinement::MotionStructure: {
      const MotStrCallbacks cb = motstr_callbacks(s.model.kind());
      out.ret = sba_motstr_levmar_ext(n, o.ncon, m, o.mcon, vmask, p, cnp, pnp, x, covx, mnp, cb.proj,
                                      o.analytic ? cb.projac : nullptr, adata, itmax, o.verbose, opts,
                                      info, &ext);
      break;
    }
    case Refinement::Motion: {
      const MotCallbacks cb = mot_callbacks(s.model.kind());
      out.ret = sba_mot_levmar_ext(n, m, o.mcon, vmask, p, cnp, x, covx, mnp, cb.proj,
                                   o.analytic ? cb.projac : nullptr, adata, itmax, o.verbose, opts, info,
                                   &ext);
      break;
    }
    case Refinement::Structure: {
      const StrCallbacks cb = str_callbacks(s.model.kind());
      out.ret = sba_str_levmar_ext(n, o.ncon, m, vmask, p, pnp, x, covx, mnp, cb.proj,
                                   o.analytic ? cb.projac : nullptr, adata, itmax, o.verbose, opts, info,
                                   &ext);
      break;
    }
  }
  return out;
}

int itmax_for(const DemoOptions &o, Refinement r) {
  if (o.check_jacobian) return 0;
  if (o.itmax >= 0) return o.itmax;
  return r == Refinement::MotionStructure ? 150 : 100;
}

const char *method_name(RefineMode mode) {
  switch (mode) {
    case RefineMode::MotionStructure: return "BA_MOTSTRUCT";
    case RefineMode::Motion: return "BA_MOT";
    case RefineMode::Structure: return "BA_STRUCT";
    case RefineMode::MotionThenMotionStructure: return "BA_MOT_MOTSTRUCT";
  }
  return "";
}

const char *kind_banner(CameraKind kind) {
  switch (kind) {
    case CameraKind::FixedIntrinsics: return "Starting BA with fixed intrinsic parameters";
    case CameraKind::VaryingIntrinsics: return "Starting BA with varying intrinsic parameters";
    case CameraKind::VaryingIntrinsicsDistortion:
      return "Starting BA with varying intrinsic parameters & distortion";
  }
  return "";
}

// Writes the files --write-* asked for into the run's outputs, from the refined (or, for what a
// refinement left alone, the initial) cameras and points.
bool write_results(const DemoOptions &o, const CameraModel &model, const PointSet &points, CameraKind kind,
                   const Outcome &out, sbaformats::OutputSet *outputs, std::string *error) {
  const int m = model.ncameras(), cnp = model.cnp();
  const bool has_cams = out.refinement != Refinement::Structure;
  const bool has_pts = out.refinement != Refinement::Motion;
  if (!o.write_cams.empty()) {
    std::vector<Camera> cams;
    cams.reserve(m);
    for (int j = 0; j < m; ++j)
      cams.push_back(model.camera(j, has_cams ? out.p.data() + j * cnp : model.initial_camera(j)));
    if (!write_cameras(o.write_cams, kind, cams, error, outputs)) return false;
  }
  std::vector<double> xyz = model.initial_points();
  if (has_pts) std::copy(out.p.end() - xyz.size(), out.p.end(), xyz.begin());
  if (!o.write_pts.empty())
    if (!write_points_xyz(o.write_pts, xyz, error, outputs)) return false;
  if (!o.write_pts_tracks.empty())
    if (!write_points(o.write_pts_tracks, points, xyz, error, outputs)) return false;
  return true;
}

// The covariance's messages as the library prints them by default, but for its error once a
// stop signal came: the program says in its own words what the signal abandoned.
void covariance_log(void *, int level, const char *line) {
  if (level == SBA_LOG_ERROR && sbacli::g_stop_signal != 0) return;
  std::fprintf(level == SBA_LOG_INFO ? stdout : stderr, "%s\n", line);
}

// --write-stddev: the square roots of the diagonal of the covariance of the solution, one
// line per camera (cnp values) then one per point (3), after a motion-and-structure run.
// Computed into *text before any file is written, so that a covariance the library refuses
// (a point seen by one camera only) leaves no result files behind. A stop signal (Ctrl-C),
// before or during it, abandons it: *abandoned is then true, *text empty, and the result true,
// since the solve's result stands without it. False, with the file and why in *error, when the
// covariance cannot be had.
bool stddev_text(const DemoOptions &o, const CameraModel &model, PointSet &points, const Outcome &out,
                 std::string *text, bool *abandoned, std::string *error) {
  const std::string &path = o.write_stddev;
  if (out.refinement != Refinement::MotionStructure) {
    *error = path + ": standard deviations need a motion-and-structure refinement";
    return false;
  }
  const int n = points.npoints(), m = points.ncameras, cnp = model.cnp();
  std::vector<int> cams(static_cast<size_t>(m)), pts(static_cast<size_t>(n));
  for (int j = 0; j < m; ++j) cams[size_t(j)] = j;
  for (int i = 0; i < n; ++i) pts[size_t(i)] = i;
  std::vector<double> camcov(size_t(m) * cnp * cnp), ptcov(size_t(n) * 9), p = out.p;
  sba_covariance_request req;
  sba_covariance_request_init(&req);
  req.ncams = m;
  req.cams = cams.data();
  req.camcov = camcov.data();
  req.npts = n;
  req.pts = pts.data();
  req.ptcov = ptcov.data();
  sba_ext_options ext;
  sba_ext_options_init(&ext);
  ext.nthreads = o.nthreads;
  ext.avoid_shared_cores = sbacli::avoids_shared_cores();
  ext.parallel_callbacks = 1;
  if (!o.loss.empty()) {
    ext.loss = o.loss.c_str();
    ext.loss_scale = o.loss_scale;
  }
  ext.log = covariance_log;
  sbacli::RunControl::attach_cancel(&ext);
  const ExpertCallbacks cb = expert_callbacks(model.kind(), Refinement::MotionStructure);
  // The library prints why on stderr (covariance_log); this adds the demo's own line.
  *abandoned = false;
  if (sba_motstr_covariance_x(n, o.ncon, m, o.mcon, points.vmask.data(), p.data(), cnp, kPointParams,
                              points.x.data(), points.has_covariances() ? points.covx.data() : nullptr,
                              kMeasurementParams, cb.func, cb.fjac, as_adata(model), &req, &ext) != 0) {
    *abandoned = sbacli::g_stop_signal != 0;
    if (*abandoned) return true;
    *error = path + ": the covariance of the solution could not be computed: no file written";
    return false;
  }
  char buf[160];
  auto add = [&](const char *fmt, auto... args) {
    const int len = std::snprintf(buf, sizeof buf, fmt, args...);
    text->append(buf, static_cast<size_t>(std::max(0, std::min<int>(len, int(sizeof buf) - 1))));
  };
  text->clear();
  add("# standard deviations: sigma^2 = %.6e, rank %d of %d free parameters\n", req.sigma2, req.rank,
      req.nfree);
  add("# one line per camera (its %d parameters), then one per point (X Y Z)\n", cnp);
  for (int j = 0; j < m; ++j) {
    for (int a = 0; a < cnp; ++a)
      add("%s%.6e", a ? " " : "", std::sqrt(std::max(0.0, camcov[size_t(j) * cnp * cnp + a * (cnp + 1)])));
    text->push_back('\n');
  }
  for (int i = 0; i < n; ++i)
    add("%.6e %.6e %.6e\n", std::sqrt(std::max(0.0, ptcov[size_t(i) * 9])),
        std::sqrt(std::max(0.0, ptcov[size_t(i) * 9 + 4])), std::sqrt(std::max(0.0, ptcov[size_t(i) * 9 + 8])));
  return true;
}

// The points and camera centres for --initial-ply and --final-ply: cams and pts are the
// parameters of all cameras and points, null for those at their initial values.
sbaformats::Cloud cloud(const CameraModel &model, const double *cams, const double *pts) {
  sbaformats::Cloud c;
  const double *xyz = pts ? pts : model.initial_points().data();
  for (int i = 0; i < model.npoints(); ++i) {
    const double *x = xyz + std::size_t(i) * kPointParams;
    c.points.push_back({x[0], x[1], x[2]});
  }
  for (int j = 0; j < model.ncameras(); ++j) {
    const Camera cam = model.camera(j, cams ? cams + std::size_t(j) * model.cnp() : model.initial_camera(j));
    double R[9];
    rotation_matrix(cam.q, R);
    c.centres.push_back(sbacameras::camera_centre(R, cam.t.data()));
  }
  return c;
}

// Where a refinement's result holds the cameras and the points, null for those it left alone
// at their initial values.
struct ResultParams {
  const double *cams, *pts;
};
ResultParams result_params(const CameraModel &model, const Outcome &out) {
  const bool has_cams = out.refinement != Refinement::Structure;
  const bool has_pts = out.refinement != Refinement::Motion;
  return {has_cams ? out.p.data() : nullptr,
          has_pts ? out.p.data() + (has_cams ? std::size_t(model.ncameras()) * model.cnp() : 0) : nullptr};
}

sbaformats::Cloud final_cloud(const CameraModel &model, const Outcome &out) {
  const ResultParams r = result_params(model, out);
  return cloud(model, r.cams, r.pts);
}

// Each camera's observations and squared pixel distances at the result (cameras and points
// a refinement left alone at their initial values).
std::vector<sbacli::CameraResidual> camera_residuals(const CameraModel &model, const PointSet &points,
                                                      const Outcome &out) {
  const int n = points.npoints(), m = points.ncameras, cnp = model.cnp();
  const ResultParams r = result_params(model, out);
  std::vector<sbacli::CameraResidual> per_camera(static_cast<std::size_t>(m));
  std::size_t k = 0;  // measurement ordinal: point by point, cameras ascending
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < m; ++j) {
      if (!points.vmask[std::size_t(i) * m + j]) continue;
      double x[kMeasurementParams];
      model.project(j, r.cams ? r.cams + std::size_t(j) * cnp : model.initial_camera(j),
                    r.pts ? r.pts + std::size_t(i) * kPointParams : model.initial_point(i), x);
      const double dx = x[0] - points.x[2 * k], dy = x[1] - points.x[2 * k + 1];
      per_camera[size_t(j)].observations += 1;
      per_camera[size_t(j)].sum_sq += dx * dx + dy * dy;
      ++k;
    }
  return per_camera;
}

// --mcon and --ncon within the problem, and every output writable, before anything is
// solved: the exit status, said, or -1.
int check_run(const DemoOptions &o, const PointSet &points) {
  if (o.mcon > points.ncameras) {
    std::fprintf(stderr, "eucsbademo: --mcon %d is more than the %d cameras\n", o.mcon, points.ncameras);
    return kExitUsage;
  }
  if (o.ncon > points.npoints()) {
    std::fprintf(stderr, "eucsbademo: --ncon %d is more than the %d points\n", o.ncon, points.npoints());
    return kExitUsage;
  }
  // Writable before a long solve, without truncating an existing file and without leaving a
  // new one behind.
  if (!sbacli::outputs_writable(
          {&o.write_cams, &o.write_pts, &o.write_pts_tracks, &o.write_stddev, &o.json, &o.initial_ply, &o.final_ply}))
    return kExitFailure;
  return -1;
}

// The refinement --refine asks for: 1.6's motion first, then motion and structure if motion
// alone leaves more than kMotionOnlyErrorLimit.
Outcome refine(const Solve &solve, int nprojs) {
  const DemoOptions &o = solve.options;
  switch (o.refine) {
    case RefineMode::MotionStructure:
      return run(solve, Refinement::MotionStructure, itmax_for(o, Refinement::MotionStructure));
    case RefineMode::Motion: return run(solve, Refinement::Motion, itmax_for(o, Refinement::Motion));
    case RefineMode::Structure: return run(solve, Refinement::Structure, itmax_for(o, Refinement::Structure));
    case RefineMode::MotionThenMotionStructure: break;
  }
  Outcome out = run(solve, Refinement::Motion, itmax_for(o, Refinement::Motion));
  if (out.ret != SBA_ERROR && !solve.control.stop_requested() && out.info[1] / nprojs > kMotionOnlyErrorLimit) {
    if (o.verbose > 0)
      std::fprintf(stderr, "motion only left a mean squared error of %g: refining motion and structure\n",
                   out.info[1] / nprojs);
    solve.control.next_solve();
    out = run(solve, Refinement::MotionStructure, itmax_for(o, Refinement::MotionStructure));
  }
  return out;
}

// The result files into outputs. Files first: if one cannot be written, the run failed and
// says nothing that looks like success. The standard deviations are computed before any
// file is written: when the library refuses them, no result file appears; when a stop signal
// abandons them (*stddev_abandoned), the result is written without them.
bool write_outputs(const DemoOptions &o, const CameraModel &model, PointSet &points, CameraKind kind,
                   const Outcome &out, sbaformats::OutputSet *outputs, bool *stddev_abandoned) {
  std::string stddev, error;
  *stddev_abandoned = false;
  if (!o.write_stddev.empty())
    if (!stddev_text(o, model, points, out, &stddev, stddev_abandoned, &error)) {
      std::fprintf(stderr, "%s\n", error.c_str());
      return false;
    }
  if (!outputs->publish_last([&] { return write_results(o, model, points, kind, out, outputs, &error); })) {
    std::fprintf(stderr, "%s\n", error.c_str());
    return false;
  }
  if (!o.write_stddev.empty() && !*stddev_abandoned &&
      !sbaformats::write_whole_file(o.write_stddev, stddev, &error, outputs)) {
    std::fprintf(stderr, "%s\n", error.c_str());
    return false;
  }
  return sbacli::write_ply_option(o.final_ply, final_cloud(model, out), outputs);
}

// The variables of the refinement that produced the result.
long long variables(const Outcome &out, const CameraModel &model, const PointSet &points) {
  long long nvars = 0;
  if (out.refinement != Refinement::Structure) nvars += static_cast<long long>(points.ncameras) * model.cnp();
  if (out.refinement != Refinement::Motion) nvars += static_cast<long long>(points.npoints()) * kPointParams;
  return nvars;
}

// sba 1.6's demo's lines: the sizes, the method, the result and the time.
void print_result(const DemoOptions &o, const PointSet &points, CameraKind kind, const Outcome &out,
                  long long nvars, double seconds) {
  const int nprojs = points.nprojections();
  std::string distortion = "without distortion", intrinsics = "fixed intrinsics";
  if (kind == CameraKind::VaryingIntrinsicsDistortion)
    distortion = "variable distortion (" + std::to_string(o.ncdist) + " fixed)";
  if (kind != CameraKind::FixedIntrinsics) intrinsics = "variable intrinsics (" + std::to_string(o.nccalib) + " fixed)";

  const std::array<double, SBA_INFOSZ> &info = out.info;
  std::printf("SBA using %d 3D pts, %d frames and %d image projections, %lld variables\n", points.npoints(),
              points.ncameras, nprojs, nvars);
  std::printf("\nMethod %s, %s driver, %s Jacobian, %s covariances, %s, %s\n", method_name(o.refine),
              o.expert ? "expert" : "simple", o.analytic ? "analytic" : "approximate",
              points.has_covariances() ? "with" : "without", distortion.c_str(), intrinsics.c_str());
  std::printf("\nSBA returned %d in %g iter, reason %g, error %g [initial %g], %d/%d func/fjac evals, "
              "%d lin. systems\n",
              out.ret, info[5], info[6], info[1] / nprojs, info[0] / nprojs, static_cast<int>(info[7]),
              static_cast<int>(info[8]), static_cast<int>(info[9]));
  std::printf("Elapsed time: %.2f seconds, %.2f msecs\n", seconds, seconds * 1000.0);
  if (out.result.robust)
    std::printf("Robust loss %s (scale %g): the errors above are its cost; squared error %g "
                "[initial %g], %lld projections beyond the scale\n",
                o.loss.c_str(), o.loss_scale, out.result.sq_error_final / nprojs,
                out.result.sq_error_initial / nprojs, out.result.outliers_final);
}

// The run's report (the summary lines after 1.6's, and --json).
sbacli::Report make_report(const DemoOptions &o, const PointSet &points, const Outcome &out, long long nvars,
                           double seconds, const sbacli::RunControl &control) {
  sbacli::Report report;
  report.program = "eucsbademo";
  report.inputs = o.files;
  report.cameras = points.ncameras;
  report.points = points.npoints();
  report.observations = points.nprojections();
  report.variables = nvars;
  report.solver_requested = o.linsolver;
  report.strategy_requested = o.strategy;
  report.threads_requested = o.nthreads;
  report.avoid_shared_cores = sbacli::avoids_shared_cores();
  report.itmax = itmax_for(o, out.refinement);
  report.opts = o.opts;
  report.loss = o.loss;
  report.loss_scale = o.loss_scale;
  report.mcon = o.mcon;
  report.ncon = o.ncon;
  report.max_time = o.max_time;
  report.single_jacobian = o.single_jacobian;
  report.ret = out.ret;
  report.info = out.info;
  report.result = out.result;
  report.seconds = seconds;
  report.iterations = control.iterations();
  return report;
}

// A stopped solve is a result (written), but the status says it was cut short by a signal;
// a time limit the user set is an ordinary end. A covariance a signal abandoned is said the
// same way: the result is written without it, the status is the signal's.
int exit_status(const DemoOptions &o, const Outcome &out, const sbacli::RunControl &control, bool stddev_abandoned) {
  int status = 0;
  if (out.info[6] == SBA_STOP_USER)
    status = sbacli::stopped_status("eucsbademo", control, o.max_time, static_cast<int>(out.info[5]));
  if (stddev_abandoned) {
    std::fprintf(stderr, "eucsbademo: %s: the covariance is abandoned, %s is not written\n",
                 control.stop_signal_name(), o.write_stddev.c_str());
    status = 128 + control.stop_signal();
  }
  return status;
}

int demo_main(int argc, char **argv) {
  DemoOptions o;
  std::string error;
  const bool parsed = parse_command_line(argc, argv, &o, &error);
  if (const int status = sbacli::answer_command_line("eucsbademo", parsed, error, o.help, o.version, print_usage);
      status >= 0)
    return status;
  Problem problem;
  if (!load_problem(o.files[0], o.files[1], o.files.size() > 2 ? o.files[2] : "", &problem, &error)) {
    std::fprintf(stderr, "%s\n", error.c_str());
    return kExitFailure;
  }
  PointSet &points = problem.points;
  if (const int status = check_run(o, points); status >= 0) return status;

  // sba 1.6's demo holds intrinsics by zeroing their columns of the analytic Jacobian, so
  // its finite differences refine every one of them, while its Method line still names
  // nccalib and ncdist. Asked for on the command line, they are held with differences too.
  const bool hold = o.analytic || o.held_given;
  const CameraModel model(problem.kind, problem.cameras, points.xyz, hold ? o.nccalib : 0, hold ? o.ncdist : 0);
  // Every file of the run is published at its end, together, or none is (output_file.h).
  sbaformats::OutputSet outputs;
  if (!sbacli::write_ply_option(o.initial_ply, cloud(model, nullptr, nullptr), &outputs)) return kExitFailure;
  std::fprintf(stderr, "%s\n", kind_banner(problem.kind));

  sbacli::TtyProgress progress(o.progress, points.nprojections());
  sbacli::RunControl control(o.max_time, &progress);
  sbacli::RunControl::catch_signals("eucsbademo");
  const auto start = std::chrono::steady_clock::now();
  const Outcome out = refine(Solve{o, model, points, control}, points.nprojections());
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  progress.finish();
  if (out.ret == SBA_ERROR) {
    std::fprintf(stderr, "eucsbademo: %s failed (SBA_ERROR): no result\n", driver_name(out.refinement, o.expert));
    return kExitFailure;
  }

  bool stddev_abandoned = false;
  if (!write_outputs(o, model, points, problem.kind, out, &outputs, &stddev_abandoned)) return kExitFailure;
  const long long nvars = variables(out, model, points);
  print_result(o, points, problem.kind, out, nvars, seconds);
  sbacli::Report report = make_report(o, points, out, nvars, seconds, control);
  sbacli::print_report(stdout, report);
  if (!o.json.empty()) {
    report.per_camera = camera_residuals(model, points, out);
    if (!sbacli::write_json(o.json, report, &error, &outputs)) {
      std::fprintf(stderr, "%s\n", error.c_str());
      return kExitFailure;
    }
  }
  const bool stopped = out.info[6] == SBA_STOP_USER || stddev_abandoned;
  if (const int status = control.late_signal("eucsbademo", stopped, &outputs)) return status;
  if (!sbaformats::publish_outputs("eucsbademo", &outputs)) return kExitFailure;
  return exit_status(o, out, control, stddev_abandoned);
}

}  // namespace
}  // namespace eucsbademo

int main(int argc, char **argv) { return sbacli::guarded_main("eucsbademo", eucsbademo::demo_main, argc, argv); }
