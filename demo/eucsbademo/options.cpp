// SPDX-License-Identifier: BSD-3-Clause
#include "eucsbademo/options.h"

#include <algorithm>
#include <limits>

#include "cli/cli.h"
#include "cli/ply_options.h"
#include "sba_ext.h"

namespace eucsbademo {

namespace {

std::string flag(bool *field, bool value) {
  *field = value;
  return {};
}

// What is refined, by which driver, and what is held.
void add_problem_options(std::vector<sbacli::Option> *t, DemoOptions &o) {
  const int kIntMax = std::numeric_limits<int>::max();
  t->push_back({"refine", "MODE",
                "what to refine: motstr (motion and structure, the default), mot (motion only), str\n"
                "(structure only) or mot-motstr (motion, then motion and structure from the initial\n"
                "estimate if the mean squared error is still above 4 pixels^2)",
                [&o](const std::string &v) -> std::string {
                  std::string mode;
                  if (std::string why = sbacli::to_choice(v, {"motstr", "mot", "str", "mot-motstr"}, &mode);
                      !why.empty())
                    return why;
                  o.refine = mode == "motstr" ? RefineMode::MotionStructure
                             : mode == "mot"  ? RefineMode::Motion
                             : mode == "str"  ? RefineMode::Structure
                                              : RefineMode::MotionThenMotionStructure;
                  return {};
                }});
  t->push_back({"simple", "", "use the simple driver (per-projection callbacks)",
                [&o](const std::string &) { return flag(&o.expert, false); }});
  t->push_back({"expert", "", "use the expert driver (whole-vector callbacks; the default)",
                [&o](const std::string &) { return flag(&o.expert, true); }});
  t->push_back({"single-precision-jacobian", "",
                "store the Jacobian in single precision, half its memory (with --simple; every\n"
                "computation on it stays in double)",
                [&o](const std::string &) { return flag(&o.single_jacobian, true); }});
  t->push_back({"numeric-jacobian", "",
                "finite-difference Jacobian instead of the analytic one; as in sba 1.6's demo, whose\n"
                "differences see every parameter, no intrinsic or distortion term is then held unless\n"
                "--nccalib or --ncdist is given",
                [&o](const std::string &) { return flag(&o.analytic, false); }});
  t->push_back({"itmax", "N", "maximum iterations (default 150; 100 for mot and str)",
                [&o](const std::string &v) { return sbacli::to_int(v, 0, kIntMax, &o.itmax); }});
  sbacli::add_lm_options(t, &o.opts);
  t->push_back({"verbose", "N", "library verbosity (default 0)",
                [&o](const std::string &v) { return sbacli::to_int(v, 0, kIntMax, &o.verbose); }});
  t->push_back({"mcon", "N", "hold cameras 0..N-1 fixed (default 0; not used by --refine=str)",
                [&o](const std::string &v) { return sbacli::to_int(v, 0, kIntMax, &o.mcon); }});
  t->push_back({"ncon", "N", "hold points 0..N-1 fixed (default 0; not used by --refine=mot)",
                [&o](const std::string &v) { return sbacli::to_int(v, 0, kIntMax, &o.ncon); }});
  t->push_back({"nccalib", "N",
                "hold the last N of the intrinsics (fu u0 v0 ar s) fixed: 0 none, 1 s, 2 s and ar (the\n"
                "default), 3 also v0, 4 also u0, 5 all; used with per-camera intrinsics",
                [&o](const std::string &v) { o.held_given = true;
                  return sbacli::to_int(v, 0, 5, &o.nccalib); }});
  t->push_back({"ncdist", "N",
                "hold the last N of the distortion terms (kc0..kc4) fixed: 0 none, 1 kc4, 2 kc4 and kc3,\n"
                "3 kc4 kc3 kc2 (the default), 4 all but kc0, 5 all; used with distortion",
                [&o](const std::string &v) { o.held_given = true;
                  return sbacli::to_int(v, 0, 5, &o.ncdist); }});
}

// How the solve runs: the linear solver, the strategy, the threads, the loss, the time.
void add_solver_options(std::vector<sbacli::Option> *t, DemoOptions &o) {
  t->push_back({"solver", "NAME",
                "linear solver of the augmented normal equations, one of those listed below (default:\n"
                "the environment variable SBA_LINSOLVER if set, else chol as in sba 1.6; this option\n"
                "overrides SBA_LINSOLVER)",
                [&o](const std::string &v) { return sbacli::to_linsolver(v, &o.linsolver); }});
  t->push_back(sbacli::strategy_option(&o.strategy));
  t->push_back({"threads", "N",
                "threads for the normal equations and the Schur complement; 0 (the default): the\n"
                "environment variable SBA_NUM_THREADS if set, else every hardware thread, but at most\n"
                "one per 10,000 projections. The result does not depend on it. A worker that finds\n"
                "itself on the core of another of them moves to a free core (SBA_AVOID_SHARED_CORES=0:\n"
                "left to the scheduler)",
                [&o](const std::string &v) { return sbacli::to_threads(v, &o.nthreads); }});
  t->push_back({"loss", "NAME",
                "robust loss on each projection's squared residual: none (least squares, the default),\n"
                "huber, cauchy, soft-l1 or tukey; the errors printed are then the robust cost, and a\n"
                "last line gives the plain squared error",
                [&o](const std::string &v) { return sbacli::to_loss(v, &o.loss); }});
  t->push_back({"loss-scale", "S", "scale of the robust loss, in pixels (default 1)",
                [&o](const std::string &v) { return sbacli::to_real(v, 0.0, true, &o.loss_scale); }});
  t->push_back({"max-time", "SECONDS",
                "stop after the iteration that ends past SECONDS (as Ceres's max_solver_time_in_seconds);\n"
                "the results are then the last accepted estimate. SIGINT (Ctrl-C) or SIGTERM stop the same\n"
                "way, with exit status 130 or 143; a second one ends the program at once",
                [&o](const std::string &v) { return sbacli::to_seconds(v, &o.max_time); }});
  t->push_back({"no-progress", "",
                "no one-line progress display (shown on stderr for runs over half a second when stderr is\n"
                "a terminal)",
                [&o](const std::string &) { return flag(&o.progress, false); }});
}

// What is written.
void add_output_options(std::vector<sbacli::Option> *t, DemoOptions &o) {
  t->push_back({"write-stddev", "FILE",
                "after refining motion and structure, write the standard deviation of every camera and\n"
                "point parameter (square roots of the diagonal of the covariance of the solution, scaled\n"
                "by the residual variance; mcon/ncon hold the gauge, else a pseudo-inverse is used);\n"
                "Ctrl-C while they are computed skips them (the other results are written, status 130)",
                [&o](const std::string &v) { return sbacli::to_file(v, &o.write_stddev); }});
  t->push_back({"check-jacobian", "",
                "run with itmax 0: the library compares the analytic Jacobian with finite differences\n"
                "and reports suspicious gradients on stderr",
                [&o](const std::string &) { return flag(&o.check_jacobian, true); }});
  t->push_back({"write-cams", "FILE", "write the refined cameras, in the input camera format",
                [&o](const std::string &v) { return sbacli::to_file(v, &o.write_cams); }});
  t->push_back({"write-pts", "FILE", "write the refined points as X Y Z lines",
                [&o](const std::string &v) { return sbacli::to_file(v, &o.write_pts); }});
  t->push_back({"write-pts-tracks", "FILE",
                "write the refined points with their projections, in the input points format (a new\n"
                "pts.txt to restart from)",
                [&o](const std::string &v) { return sbacli::to_file(v, &o.write_pts_tracks); }});
  t->push_back({"json", "FILE",
                "write the run as one JSON object: sizes, options, every info[] value, the error and\n"
                "time of every iteration, and each camera's observations and RMS reprojection error",
                [&o](const std::string &v) { return sbacli::to_file(v, &o.json); }});
  sbacli::add_ply_options(t, &o.initial_ply, &o.final_ply, false);
}

// The options, bound to o. Adding an option (a linear solver, a thread count ...) is adding a row.
std::vector<sbacli::Option> option_table(DemoOptions &o) {
  std::vector<sbacli::Option> t;
  add_problem_options(&t, o);
  add_solver_options(&t, o);
  add_output_options(&t, o);
  return t;
}

}  // namespace

bool parse_command_line(int argc, const char *const *argv, DemoOptions *options, std::string *error) {
  DemoOptions o;
  sbacli::Parsed parsed;
  if (!sbacli::parse(argc, argv, option_table(o), &parsed, error)) return false;
  o.files = parsed.positional;
  o.help = parsed.help;
  o.version = parsed.version;
  if (!o.help && !o.version && (o.files.size() < 2 || o.files.size() > 3)) {
    *error = "expected 2 or 3 file arguments (cams.txt pts.txt [calib.txt]), got " +
             std::to_string(o.files.size()) + " (see --help)";
    return false;
  }
  if (std::count(o.files.begin(), o.files.end(), std::string("-")) > 1) {
    *error = "standard input ('-') can be only one of the files";
    return false;
  }
  if (o.check_jacobian && !o.analytic) {
    *error = "--check-jacobian checks the analytic Jacobian: it cannot go with --numeric-jacobian";
    return false;
  }
  *options = std::move(o);
  return true;
}

void print_usage(std::FILE *out) {
  std::fputs(
      "Usage: eucsbademo [OPTION]... CAMS PTS [CALIB]\n"
      "Euclidean sparse bundle adjustment of the cameras in CAMS and the points in PTS.\n"
      "\n"
      "  CAMS   one camera per line: 7 values (q0 q1 q2 q3 tx ty tz) with CALIB, the 3x3\n"
      "         intrinsics shared by all cameras; 12 values (fu u0 v0 ar s, then as before) for\n"
      "         per-camera intrinsics; 17 (fu u0 v0 ar s kc0..kc4 ...) with distortion\n"
      "  PTS    one point per line: X Y Z nframes, then nframes times 'frame x y', each\n"
      "         optionally followed by its 2x2 covariance (cxx cxy cxy cyy, or cxx cxy cyy)\n"
      "  Lines starting with '#' are comments. A file may be bzip2-compressed; '-' reads one of\n"
      "  them from standard input.\n"
      "\n"
      "Options (defaults are those of sba 1.6's eucsbademo; a value may follow as --opt=VALUE\n"
      "or --opt VALUE; '--' ends the options):\n",
      out);
  DemoOptions scratch;
  sbacli::print_options(out, option_table(scratch));
  std::fprintf(out, "\nLinear solvers (--solver): %s\n", sba_linsolver_names());
  std::fputs(
      "\n"
      "Output: a 'Starting BA ...' line on stderr, then the sba 1.6 summary on stdout, then the\n"
      "RMS reprojection error in pixels, the stop reason in words, the solver and threads used\n"
      "and the solve time.\n"
      "Exit status: 0 on success (--max-time included), 1 if a file cannot be read or written or\n"
      "the solver fails, 2 for a bad command line, 130 (SIGINT) or 143 (SIGTERM) when a signal\n"
      "stopped the solve or the standard deviations.\n",
      out);
}

}  // namespace eucsbademo
