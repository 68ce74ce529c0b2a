// SPDX-License-Identifier: BSD-3-Clause
// sbarefine: bundle adjustment of a reconstruction as an SfM pipeline wrote it (a COLMAP
// sparse model, text or binary), written back in its own format with every identifier, name
// and color unchanged. The solve is balsba's: same options, output and Ctrl-C behaviour.
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <exception>
#include <new>
#include <string>
#include <vector>

#include "cli.h"
#include "colmap_io.h"
#include "colmap_sba.h"
#include "eucsba_model.h"
#include "output_file.h"
#include "report.h"
#include "run_control.h"
#include "sba.h"
#include "sba_ext.h"
#include "solve_options.h"
#include "tty_progress.h"

namespace {

using sbacli::kExitFailure;
using sbacli::kExitUsage;

struct Options {
  std::string input;
  sbademo::SolveOptions solve;
  std::string write;         // output model directory; empty: none
  std::string write_format;  // text or binary; empty: the input's
  std::string intrinsics = "focal,distortion";
  colmap::RefineIntrinsics refine;
  std::string initial_ply, final_ply;
  bool help = false, version = false;
};

std::vector<sbacli::Option> option_table(Options &o) {
  std::vector<sbacli::Option> t;
  sbademo::add_solve_options(
      &t, o.solve,
      {"write", "DIR", "write the refined model into DIR (created if missing), in the input's format",
       [&o](const std::string &v) { return sbacli::to_file(v, &o.write); }});
  t.push_back({"write-format", "F", "the format of --write: text or binary (default: the input's)",
               [&o](const std::string &v) { return sbacli::to_choice(v, {"text", "binary"}, &o.write_format); }});
  t.push_back({"intrinsics", "LIST",
               "the intrinsics refined: none, all, or a comma-separated list of focal, principal,\n"
               "distortion (default focal,distortion, as COLMAP: the principal point held)",
               [&o](const std::string &v) {
                 o.intrinsics = v;
                 return colmap::parse_refine_intrinsics(v, &o.refine);
               }});
  t.push_back({"initial-ply", "FILE", "write the initial points (with their colors) and camera centres (red) as PLY",
               [&o](const std::string &v) { return sbacli::to_file(v, &o.initial_ply); }});
  t.push_back({"final-ply", "FILE", "the same for the refined model",
               [&o](const std::string &v) { return sbacli::to_file(v, &o.final_ply); }});
  return t;
}

bool parse_command_line(int argc, char **argv, Options *options, std::string *error) {
  Options o;
  sbacli::Parsed parsed;
  if (!sbacli::parse(argc, argv, option_table(o), &parsed, error)) return false;
  o.help = parsed.help;
  o.version = parsed.version;
  if (!o.help && !o.version && parsed.positional.size() != 1) {
    *error = "expected 1 argument (a COLMAP model directory), got " + std::to_string(parsed.positional.size()) +
             " (see --help)";
    return false;
  }
  if (!parsed.positional.empty()) o.input = parsed.positional[0];
  *options = std::move(o);
  return true;
}

void print_usage(std::FILE *out) {
  std::fputs(
      "Usage: sbarefine [OPTION]... MODEL\n"
      "Bundle-adjusts a COLMAP sparse model (the directory holding cameras, images and points3D,\n"
      ".txt or .bin; camera models SIMPLE_PINHOLE, PINHOLE, SIMPLE_RADIAL, RADIAL, OPENCV) with\n"
      "sba_motstr_levmar_x_ext and eucsbademo's camera model, analytic Jacobian. Every image is an\n"
      "sba camera with its own intrinsics.\n"
      "\n"
      "Options (a value may follow as --opt=VALUE or --opt VALUE; '--' ends the options):\n",
      out);
  Options scratch;
  sbacli::print_options(out, option_table(scratch));
  std::fprintf(out, "\nLinear solvers (--solver): %s\n", sba_linsolver_names());
  std::fputs(
      "\n"
      "Prints what balsba prints: the sizes, sba 1.6's summary (mean squared reprojection error in\n"
      "pixels^2 per observation ...), the RMS reprojection error in pixels, the stop reason, the\n"
      "solver and threads used. The written model keeps every identifier, name, color and\n"
      "unrefined value; a refined point's ERROR becomes its mean reprojection error.\n"
      "Exit status: 0 done (--max-time included), 1 a file cannot be read or written or the solver\n"
      "fails, 2 bad options, 130 (SIGINT) or 143 (SIGTERM) when a signal stopped the solve.\n",
      out);
}

// Points with their colors, then the camera centres -R^T t in red, as an ASCII PLY file.
bool write_ply(const std::string &path, const colmap::Model &model, std::string *error) {
  sbademo::OutputFile file;
  if (!file.open(path, error)) return false;
  std::FILE *f = file.get();
  std::fprintf(f,
               "ply\nformat ascii 1.0\ncomment points, then camera centres (red)\nelement vertex %zu\n"
               "property double x\nproperty double y\nproperty double z\n"
               "property uchar red\nproperty uchar green\nproperty uchar blue\nend_header\n",
               model.points.size() + model.images.size());
  for (const colmap::Point3D &p : model.points)
    std::fprintf(f, "%.17g %.17g %.17g %d %d %d\n", p.xyz[0], p.xyz[1], p.xyz[2], p.rgb[0], p.rgb[1], p.rgb[2]);
  for (const colmap::Image &im : model.images) {
    double R[9];
    eucsba::rotation_matrix(eucsba::normalized_rotation({im.q[0], im.q[1], im.q[2], im.q[3]}), R);
    double c[3];
    for (int k = 0; k < 3; ++k) c[k] = -(R[k] * im.t[0] + R[3 + k] * im.t[1] + R[6 + k] * im.t[2]);
    std::fprintf(f, "%.17g %.17g %.17g 255 0 0\n", c[0], c[1], c[2]);
  }
  return file.commit(error);
}

int refine_main(int argc, char **argv) {
  Options o;
  std::string error;
  if (!parse_command_line(argc, argv, &o, &error)) {
    std::fprintf(stderr, "sbarefine: %s\n", error.c_str());
    return kExitUsage;
  }
  if (o.help) {
    print_usage(stdout);
    return 0;
  }
  if (o.version) {
    std::printf("%s\n", sbacli::version_line("sbarefine").c_str());
    return 0;
  }
  sbademo::SolveOptions &so = o.solve;
  // The output files must be writable before a long solve.
  for (const std::string *path : {&so.json, &o.initial_ply, &o.final_ply})
    if (!path->empty() && !sbademo::probe_writable(*path, &error)) {
      std::fprintf(stderr, "%s: %s\n", path->c_str(), error.c_str());
      return kExitFailure;
    }

  const auto read_start = std::chrono::steady_clock::now();
  colmap::Model model;
  colmap::Encoding encoding;
  colmap::SbaProblem problem;
  if (!colmap::read_model(o.input, &model, &encoding, &error) ||
      !colmap::to_sba(model, o.refine, o.input, &problem, &error)) {
    std::fprintf(stderr, "%s\n", error.c_str());
    return kExitFailure;
  }
  const double read_seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - read_start).count();
  const int m = problem.points.ncameras, n = problem.points.npoints();
  if (so.mcon > m) {
    std::fprintf(stderr, "sbarefine: --mcon %d is more than the %d images\n", so.mcon, m);
    return kExitUsage;
  }
  if (so.ncon > n) {
    std::fprintf(stderr, "sbarefine: --ncon %d is more than the %d points\n", so.ncon, n);
    return kExitUsage;
  }
  if (!o.initial_ply.empty() && !write_ply(o.initial_ply, model, &error)) {
    std::fprintf(stderr, "%s: %s\n", o.initial_ply.c_str(), error.c_str());
    return kExitFailure;
  }

  const eucsba::CameraModel sba_model(eucsba::CameraKind::VaryingIntrinsicsDistortion, problem.cameras,
                                      problem.points.xyz, problem.nccalib, problem.ncdist);
  std::vector<double> p = sba_model.initial_camera_params();
  p.insert(p.end(), sba_model.initial_points().begin(), sba_model.initial_points().end());
  const int cnp = sba_model.cnp();

  sbademo::LogSink sink;
  sba_ext_result result;
  sba_ext_options ext;
  sbademo::init_ext(so, &sink, &result, &ext);
  const int nobs = problem.points.nprojections();
  std::array<double, SBA_INFOSZ> info{};
  sbademo::TtyProgress progress(so.progress, nobs);
  sbademo::RunControl control(so.max_time, &progress);
  sbademo::RunControl::catch_signals();
  control.attach(&ext);
  const eucsba::ExpertCallbacks cb =
      eucsba::expert_callbacks(sba_model.kind(), eucsba::Refinement::MotionStructure);
  const auto start = std::chrono::steady_clock::now();
  const int ret = sba_motstr_levmar_x_ext(n, so.ncon, m, so.mcon, problem.points.vmask.data(), p.data(), cnp,
                                          eucsba::kPointParams, problem.points.x.data(), nullptr,
                                          eucsba::kMeasurementParams, cb.func, cb.fjac, eucsba::as_adata(sba_model),
                                          so.itmax, so.verbose, so.opts.data(), info.data(), &ext);
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  progress.finish();
  if (ret == SBA_ERROR) {
    std::fprintf(stderr, "sbarefine: %s: the solve failed (SBA_ERROR, reason %g): %s\n", o.input.c_str(), info[6],
                 sink.first_error.empty() ? "no result" : sink.first_error.c_str());
    return kExitFailure;
  }

  colmap::from_sba(sba_model, problem, p.data(), so.mcon, so.ncon, &model);
  if (!o.write.empty()) {
    const colmap::Encoding out_encoding =
        o.write_format.empty() ? encoding
                               : (o.write_format == "text" ? colmap::Encoding::Text : colmap::Encoding::Binary);
    if (!colmap::write_model(o.write, model, out_encoding, &error)) {
      std::fprintf(stderr, "%s\n", error.c_str());
      return kExitFailure;
    }
  }
  if (!o.final_ply.empty() && !write_ply(o.final_ply, model, &error)) {
    std::fprintf(stderr, "%s: %s\n", o.final_ply.c_str(), error.c_str());
    return kExitFailure;
  }

  const long long nvars = static_cast<long long>(m) * cnp + static_cast<long long>(n) * eucsba::kPointParams;
  std::printf("COLMAP model %s (%s): %d images, %d cameras, %d points, %d observations, %lld variables\n",
              o.input.c_str(), encoding == colmap::Encoding::Text ? "text" : "binary", m,
              static_cast<int>(model.cameras.size()), n, nobs, nvars);
  std::printf("Intrinsics refined: %s (nccalib %d, ncdist %d)\n", o.intrinsics.c_str(), problem.nccalib,
              problem.ncdist);
  std::printf("\nSBA returned %d in %g iter, reason %g, error %g [initial %g], %d/%d func/fjac evals, "
              "%d lin. systems\n",
              ret, info[5], info[6], info[1] / nobs, info[0] / nobs, static_cast<int>(info[7]),
              static_cast<int>(info[8]), static_cast<int>(info[9]));
  std::printf("Elapsed time: %.2f seconds, %.2f msecs (reading the model: %.2f seconds)\n", seconds,
              seconds * 1000.0, read_seconds);
  if (result.robust)
    std::printf("Robust loss %s (scale %g): the errors above are its cost; squared error %g "
                "[initial %g], %lld observations beyond the scale\n",
                so.loss.c_str(), so.loss_scale, result.sq_error_final / nobs, result.sq_error_initial / nobs,
                result.outliers_final);

  sbademo::Report report;
  report.program = "sbarefine";
  report.inputs = {o.input};
  report.cameras = m;
  report.points = n;
  report.observations = nobs;
  report.variables = nvars;
  sbademo::report_options(so, &report);
  report.ret = ret;
  report.info = info;
  report.result = result;
  report.seconds = seconds;
  report.iterations = control.iterations();
  sbademo::print_report(stdout, report);
  if (!so.json.empty()) {
    report.per_camera.resize(static_cast<std::size_t>(m));
    const double *points = p.data() + static_cast<std::size_t>(m) * cnp;
    std::size_t k = 0;
    for (int i = 0; i < n; ++i)
      for (int j = 0; j < m; ++j) {
        if (!problem.points.vmask[static_cast<std::size_t>(i) * m + j]) continue;
        double x[2];
        sba_model.project(j, p.data() + static_cast<std::size_t>(j) * cnp, points + 3 * static_cast<std::size_t>(i),
                          x);
        const double dx = x[0] - problem.points.x[2 * k], dy = x[1] - problem.points.x[2 * k + 1];
        report.per_camera[static_cast<std::size_t>(j)].observations += 1;
        report.per_camera[static_cast<std::size_t>(j)].sum_sq += dx * dx + dy * dy;
        ++k;
      }
    if (!sbademo::write_json(so.json, report, &error)) {
      std::fprintf(stderr, "%s: %s\n", so.json.c_str(), error.c_str());
      return kExitFailure;
    }
  }
  if (!o.write.empty()) std::printf("Wrote %s\n", o.write.c_str());
  if (info[6] == SBA_STOP_USER) return sbademo::stopped_status("sbarefine", control, so.max_time, static_cast<int>(info[5]));
  return 0;
}

}  // namespace

int main(int argc, char **argv) {
  try {
    const int status = refine_main(argc, argv);
    if (status == 0 && !sbademo::stdout_written("sbarefine")) return kExitFailure;
    return status;
  } catch (const std::bad_alloc &) {
    std::fprintf(stderr, "sbarefine: out of memory\n");
  } catch (const std::exception &e) {
    std::fprintf(stderr, "sbarefine: %s\n", e.what());
  } catch (...) {
    std::fprintf(stderr, "sbarefine: unexpected error\n");
  }
  return kExitFailure;
}
