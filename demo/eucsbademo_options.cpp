#include "eucsbademo_options.h"

#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <sstream>

#include "sba_ext.h"

namespace eucsba {

namespace {

// An option's value check and effect; returns an error message, empty when the value is good.
using Apply = std::string (*)(DemoOptions &, const std::string &value);

// One row per option: adding an option (a linear solver, a thread count ...) is adding a row.
struct OptionSpec {
  const char *name;  // without the leading "--"
  const char *arg;   // the value's name in --help, nullptr for a flag
  const char *help;
  Apply apply;
};

std::string parse_int(const std::string &value, int lo, int hi, int *out) {
  const char *s = value.c_str();
  char *end = nullptr;
  errno = 0;
  const long v = std::strtol(s, &end, 10);
  if (end == s || *end != '\0' || errno == ERANGE || v < lo || v > hi) {
    if (hi == std::numeric_limits<int>::max()) return "expected an integer >= " + std::to_string(lo);
    return "expected an integer from " + std::to_string(lo) + " to " + std::to_string(hi);
  }
  *out = static_cast<int>(v);
  return {};
}

// A finite number >= lo (or > lo when strict).
std::string parse_real(const std::string &value, double lo, bool strict, double *out) {
  const char *s = value.c_str();
  char *end = nullptr;
  const double v = std::strtod(s, &end);
  if (end == s || *end != '\0' || !std::isfinite(v) || v < lo || (strict && v == lo))
    return strict ? "expected a positive number" : "expected a non-negative number";
  *out = v;
  return {};
}

std::string set_opt(DemoOptions &o, int k, const std::string &v) {
  return parse_real(v, 0.0, k == 0, &o.opts[k]);
}

const OptionSpec kOptions[] = {
    {"refine", "MODE",
     "what to refine: motstr (motion and structure, the default), mot (motion only), str\n"
     "(structure only) or mot-motstr (motion, then motion and structure from the initial\n"
     "estimate if the mean squared error is still above 4 pixels^2)",
     [](DemoOptions &o, const std::string &v) -> std::string {
       if (v == "motstr") o.refine = RefineMode::MotionStructure;
       else if (v == "mot") o.refine = RefineMode::Motion;
       else if (v == "str") o.refine = RefineMode::Structure;
       else if (v == "mot-motstr") o.refine = RefineMode::MotionThenMotionStructure;
       else return "expected motstr, mot, str or mot-motstr";
       return {};
     }},
    {"simple", nullptr, "use the simple driver (per-projection callbacks)",
     [](DemoOptions &o, const std::string &) -> std::string {
       o.expert = false;
       return {};
     }},
    {"expert", nullptr, "use the expert driver (whole-vector callbacks; the default)",
     [](DemoOptions &o, const std::string &) -> std::string {
       o.expert = true;
       return {};
     }},
    {"numeric-jacobian", nullptr,
     "finite-difference Jacobian instead of the analytic one (intrinsics held by --nccalib and\n"
     "--ncdist stay held)",
     [](DemoOptions &o, const std::string &) -> std::string {
       o.analytic = false;
       return {};
     }},
    {"itmax", "N", "maximum iterations (default 150; 100 for mot and str)",
     [](DemoOptions &o, const std::string &v) { return parse_int(v, 0, std::numeric_limits<int>::max(), &o.itmax); }},
    {"opts", "TAU,EPS1,EPS2,EPS3,EPS4",
     "LM options: initial damping scale and the stopping thresholds on ||J^T e||_inf, the\n"
     "relative step, ||e||^2 and the relative error reduction (default 1e-3,1e-12,1e-12,1e-12,0)",
     [](DemoOptions &o, const std::string &v) -> std::string {
       std::array<double, 5> parsed{};
       std::size_t start = 0;
       for (int k = 0; k < 5; ++k) {
         const std::size_t comma = v.find(',', start);
         if ((comma == std::string::npos) != (k == 4)) return "expected 5 comma-separated numbers";
         const std::string item = v.substr(start, comma == std::string::npos ? comma : comma - start);
         if (std::string why = parse_real(item, 0.0, k == 0, &parsed[k]); !why.empty())
           return "number " + std::to_string(k + 1) + ": " + why;
         start = comma + 1;
       }
       o.opts = parsed;
       return {};
     }},
    {"tau", "X", "initial damping scale, opts[0] (default 1e-3)",
     [](DemoOptions &o, const std::string &v) { return set_opt(o, 0, v); }},
    {"eps1", "X", "stop when ||J^T e||_inf <= X, opts[1] (default 1e-12)",
     [](DemoOptions &o, const std::string &v) { return set_opt(o, 1, v); }},
    {"eps2", "X", "stop when ||dp||^2 <= X^2 ||p||^2, opts[2] (default 1e-12)",
     [](DemoOptions &o, const std::string &v) { return set_opt(o, 2, v); }},
    {"eps3", "X", "stop when ||e||^2 <= X^2, opts[3] (default 1e-12)",
     [](DemoOptions &o, const std::string &v) { return set_opt(o, 3, v); }},
    {"eps4", "X", "stop when the relative RMS error reduction is below X, opts[4] (default 0)",
     [](DemoOptions &o, const std::string &v) { return set_opt(o, 4, v); }},
    {"verbose", "N", "library verbosity (default 0)",
     [](DemoOptions &o, const std::string &v) { return parse_int(v, 0, std::numeric_limits<int>::max(), &o.verbose); }},
    {"mcon", "N", "hold cameras 0..N-1 fixed (default 0; not used by --refine=str)",
     [](DemoOptions &o, const std::string &v) { return parse_int(v, 0, std::numeric_limits<int>::max(), &o.mcon); }},
    {"ncon", "N", "hold points 0..N-1 fixed (default 0; not used by --refine=mot)",
     [](DemoOptions &o, const std::string &v) { return parse_int(v, 0, std::numeric_limits<int>::max(), &o.ncon); }},
    {"nccalib", "N",
     "hold the last N of the intrinsics (fu u0 v0 ar s) fixed: 0 none, 1 s, 2 s and ar (the\n"
     "default), 3 also v0, 4 also u0, 5 all; used with per-camera intrinsics",
     [](DemoOptions &o, const std::string &v) { return parse_int(v, 0, 5, &o.nccalib); }},
    {"ncdist", "N",
     "hold the last N of the distortion terms (kc0..kc4) fixed: 0 none, 1 kc4, 2 kc4 and kc3,\n"
     "3 kc4 kc3 kc2 (the default), 4 all but kc0, 5 all; used with distortion",
     [](DemoOptions &o, const std::string &v) { return parse_int(v, 0, 5, &o.ncdist); }},
    {"solver", "NAME",
     "linear solver of the augmented normal equations, one of those listed below (default:\n"
     "the environment variable SBA_LINSOLVER if set, else chol as in sba 1.6; this option\n"
     "overrides SBA_LINSOLVER)",
     [](DemoOptions &o, const std::string &v) -> std::string {
       if (!is_linsolver_name(v)) return std::string("expected one of: ") + sba_linsolver_names();
       o.linsolver = v;
       return {};
     }},
    {"strategy", "NAME",
     "how LM damps, accepts steps and stops: sba (sba 1.6's algorithm, the default) or\n"
     "trust-region (Marquardt's scaled damping and a relative cost tolerance: usually far\n"
     "fewer iterations); default: the environment variable SBA_STRATEGY if set, else sba",
     [](DemoOptions &o, const std::string &v) -> std::string {
       if (!sba_strategy_valid(v.c_str())) return std::string("expected one of: ") + sba_strategy_names();
       o.strategy = v;
       return {};
     }},
    {"threads", "N",
     "threads for the normal equations and the Schur complement; 0 (the default): the\n"
     "environment variable SBA_NUM_THREADS if set, else every hardware thread, but at most\n"
     "one per 10,000 projections. The result does not depend on it",
     [](DemoOptions &o, const std::string &v) { return parse_int(v, 0, kMaxThreads, &o.nthreads); }},
    {"loss", "NAME",
     "robust loss on each projection's squared residual: none (least squares, the default),\n"
     "huber, cauchy, soft-l1 or tukey; the errors printed are then the robust cost, and a\n"
     "last line gives the plain squared error",
     [](DemoOptions &o, const std::string &v) -> std::string {
       if (v != "none" && v != "huber" && v != "cauchy" && v != "soft-l1" && v != "tukey")
         return "expected none, huber, cauchy, soft-l1 or tukey";
       o.loss = v == "none" ? std::string() : v;
       return {};
     }},
    {"loss-scale", "S", "scale of the robust loss, in pixels (default 1)",
     [](DemoOptions &o, const std::string &v) { return parse_real(v, 0.0, true, &o.loss_scale); }},
    {"no-progress", nullptr,
     "no one-line progress display (shown on stderr for runs over half a second when stderr is\n"
     "a terminal)",
     [](DemoOptions &o, const std::string &) -> std::string {
       o.progress = false;
       return {};
     }},
    {"write-stddev", "FILE",
     "after refining motion and structure, write the standard deviation of every camera and\n"
     "point parameter (square roots of the diagonal of the covariance of the solution, scaled\n"
     "by the residual variance; mcon/ncon hold the gauge, else a pseudo-inverse is used)",
     [](DemoOptions &o, const std::string &v) -> std::string {
       if (v.empty()) return "expected a file name";
       o.write_stddev = v;
       return {};
     }},
    {"check-jacobian", nullptr,
     "run with itmax 0: the library compares the analytic Jacobian with finite differences\n"
     "and reports suspicious gradients on stderr",
     [](DemoOptions &o, const std::string &) -> std::string {
       o.check_jacobian = true;
       return {};
     }},
    {"write-cams", "FILE", "write the refined cameras, in the input camera format",
     [](DemoOptions &o, const std::string &v) -> std::string {
       if (v.empty()) return "expected a file name";
       o.write_cams = v;
       return {};
     }},
    {"write-pts", "FILE", "write the refined points as X Y Z lines",
     [](DemoOptions &o, const std::string &v) -> std::string {
       if (v.empty()) return "expected a file name";
       o.write_pts = v;
       return {};
     }},
    {"write-pts-tracks", "FILE",
     "write the refined points with their projections, in the input points format (a new\n"
     "pts.txt to restart from)",
     [](DemoOptions &o, const std::string &v) -> std::string {
       if (v.empty()) return "expected a file name";
       o.write_pts_tracks = v;
       return {};
     }},
    {"help", nullptr, "show this help and exit",
     [](DemoOptions &o, const std::string &) -> std::string {
       o.help = true;
       return {};
     }},
    {"version", nullptr, "show the library version and exit",
     [](DemoOptions &o, const std::string &) -> std::string {
       o.version = true;
       return {};
     }},
};

const OptionSpec *find_option(const std::string &name) {
  for (const OptionSpec &spec : kOptions)
    if (name == spec.name) return &spec;
  return nullptr;
}

}  // namespace

bool is_linsolver_name(const std::string &name) { return sba_linsolver_valid(name.c_str()) != 0; }

bool parse_command_line(int argc, const char *const *argv, DemoOptions *options, std::string *error) {
  DemoOptions o;
  bool only_files = false;  // after "--"
  for (int k = 1; k < argc; ++k) {
    const std::string arg = argv[k];
    if (only_files || arg.size() < 2 || arg[0] != '-') {
      o.files.push_back(arg);
      continue;
    }
    if (arg == "--") {
      only_files = true;
      continue;
    }
    if (arg == "-h") {
      o.help = true;
      continue;
    }
    if (arg[1] != '-') {
      *error = "unknown option '" + arg + "' (options are long: see --help)";
      return false;
    }
    const std::size_t eq = arg.find('=');
    const std::string name = arg.substr(2, eq == std::string::npos ? eq : eq - 2);
    const OptionSpec *spec = find_option(name);
    if (!spec) {
      *error = "unknown option '--" + name + "' (see --help)";
      return false;
    }
    std::string value;
    if (spec->arg) {
      if (eq != std::string::npos) {
        value = arg.substr(eq + 1);
      } else if (k + 1 < argc) {
        value = argv[++k];
      } else {
        *error = "option '--" + name + "' needs a value (" + spec->arg + ")";
        return false;
      }
    } else if (eq != std::string::npos) {
      *error = "option '--" + name + "' takes no value";
      return false;
    }
    if (std::string why = spec->apply(o, value); !why.empty()) {
      *error = "bad value '" + value + "' for --" + name + ": " + why;
      return false;
    }
  }
  if (!o.help && !o.version && (o.files.size() < 2 || o.files.size() > 3)) {
    *error = "expected 2 or 3 file arguments (cams.txt pts.txt [calib.txt]), got " +
             std::to_string(o.files.size()) + " (see --help)";
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
      "  Lines starting with '#' are comments.\n"
      "\n"
      "Options (defaults are those of sba 1.6's eucsbademo; a value may follow as --opt=VALUE\n"
      "or --opt VALUE; '--' ends the options):\n",
      out);
  for (const OptionSpec &spec : kOptions) {
    std::string head = std::string("  --") + spec.name;
    if (spec.arg) head += std::string("=") + spec.arg;
    std::fprintf(out, "%s\n", head.c_str());
    // Help texts carry their own line breaks; indent every line.
    const char *text = spec.help;
    while (*text) {
      const char *nl = std::strchr(text, '\n');
      const std::size_t len = nl ? static_cast<std::size_t>(nl - text) : std::strlen(text);
      std::fprintf(out, "        %.*s\n", static_cast<int>(len), text);
      text += len + (nl ? 1 : 0);
    }
  }
  std::fprintf(out, "\nLinear solvers (--solver): %s\n", sba_linsolver_names());
  std::fputs(
      "\n"
      "Output: a 'Starting BA ...' line on stderr, then the sba 1.6 summary on stdout.\n"
      "Exit status: 0 on success, 1 if a file cannot be read or written or the solver fails,\n"
      "2 for a bad command line.\n",
      out);
}

}  // namespace eucsba
