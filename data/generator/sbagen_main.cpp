// sbagen: writes a synthetic eucsbademo problem with its ground truth (see sbagen.h).
#include <algorithm>
#include <cctype>
#include <cerrno>
#include <climits>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <new>
#include <string>
#include <vector>

#include "sbagen.h"

namespace {

const char kUsage[] =
    "usage: sbagen --out PREFIX [options]\n"
    "Writes a synthetic bundle adjustment problem for eucsbademo and its ground truth:\n"
    "  PREFIX-cams.txt PREFIX-pts.txt [PREFIX-calib.txt] PREFIX-truth-cams.txt PREFIX-truth-pts.txt\n"
    "  [PREFIX-outliers.txt]\n"
    "Lengths are in scene units: the radius of the point cloud (orbit) or the spacing of the\n"
    "cameras (path).\n"
    "\n"
    "scene:\n"
    "  --cameras M             number of cameras (default 20)\n"
    "  --points N              number of points (default 1500)\n"
    "  --trajectory T          orbit: cameras around the points looking at their centre;\n"
    "                          path: cameras moving along a road, each point seen by\n"
    "                          consecutive cameras (default orbit)\n"
    "  --track-min K           fewest cameras seeing a point, >= 2 (default 2)\n"
    "  --track-max K           most cameras seeing a point (default 10)\n"
    "  --arc DEG               orbit: arc the cameras spread over, (0, 360] (default 360)\n"
    "  --yaw DEG               path: view direction off the road, -90..90 (default 0: ahead)\n"
    "  --turn DEG              path: largest heading change of the road's S-curve (default 10)\n"
    "cameras:\n"
    "  --kind K                fixed (one K, cnp 6), varK (per-camera K, cnp 11) or varKD\n"
    "                          (per-camera K and distortion, cnp 16) (default fixed)\n"
    "  --image WxH             image size in pixels (default 640x480)\n"
    "  --focal F               focal length in pixels (default 800)\n"
    "  --intrinsics-spread S   varK/varKD: relative per-camera spread of K (default 0.01)\n"
    "  --distortion D          varKD: |kc0| <= D, |kc1| <= D/4 (default 0.1)\n"
    "measurements:\n"
    "  --noise SIGMA           Gaussian pixel noise (default 0.5)\n"
    "  --covariances           random SPD 2x2 covariance per measurement, noise drawn from it\n"
    "  --outliers FRAC         fraction of measurements replaced by gross outliers (default 0)\n"
    "initial estimate (standard deviations):\n"
    "  --perturb-rotation R    radians per axis (default 0.01)\n"
    "  --perturb-translation T scene units per component of t (default 0.02)\n"
    "  --perturb-points P      scene units per coordinate (default 0.02)\n"
    "  --perturb-intrinsics I  varK/varKD: relative fu u0 v0, absolute kc0 kc1 (default 0.01)\n"
    "  --no-perturb            start at the truth (all four set to 0)\n"
    "other:\n"
    "  --seed S                random seed, a 64-bit unsigned integer (default 1)\n"
    "  --quiet                 no summary on stdout\n"
    "  --help                  this text\n"
    "\n"
    "Exit status: 0 done, 1 the problem could not be generated or written, 2 bad options.\n";

// A bad command line: one line on stderr, exit status 2.
[[noreturn]] void usage_error(const std::string &message) {
  std::fprintf(stderr, "sbagen: %s (try --help)\n", message.c_str());
  std::exit(2);
}

double parse_real(const std::string &opt, const std::string &text) {
  errno = 0;
  char *end = nullptr;
  const double v = std::strtod(text.c_str(), &end);
  if (text.empty() || *end != '\0' || errno == ERANGE || !std::isfinite(v))
    usage_error(opt + " needs a finite number, got '" + text + "'");
  return v;
}

long long parse_integer(const std::string &opt, const std::string &text, long long lo, long long hi) {
  errno = 0;
  char *end = nullptr;
  const long long v = std::strtoll(text.c_str(), &end, 10);
  if (text.empty() || *end != '\0' || errno == ERANGE)
    usage_error(opt + " needs an integer, got '" + text + "'");
  if (v < lo || v > hi)
    usage_error(opt + " must be between " + std::to_string(lo) + " and " + std::to_string(hi) + ", got " + text);
  return v;
}

std::uint64_t parse_seed(const std::string &opt, const std::string &text) {
  errno = 0;
  char *end = nullptr;
  if (text.empty() || text[0] == '-' || text[0] == '+') usage_error(opt + " needs an unsigned integer, got '" + text + "'");
  const unsigned long long v = std::strtoull(text.c_str(), &end, 10);
  if (*end != '\0' || errno == ERANGE) usage_error(opt + " needs an unsigned 64-bit integer, got '" + text + "'");
  return static_cast<std::uint64_t>(v);
}

void parse_image(const std::string &opt, const std::string &text, int *w, int *h) {
  const std::size_t x = text.find('x');
  if (x == std::string::npos) usage_error(opt + " needs WIDTHxHEIGHT, got '" + text + "'");
  *w = static_cast<int>(parse_integer(opt, text.substr(0, x), 16, 100000));
  *h = static_cast<int>(parse_integer(opt, text.substr(x + 1), 16, 100000));
}

struct Cli {
  sbagen::Options options;
  std::string prefix;
  bool quiet = false;
};

// An Options::IsValid message in the words of the command line: the field names it uses
// become the options that set them.
std::string in_option_names(const std::string &message) {
  static const char *const kNames[][2] = {
      {"cameras", "--cameras"}, {"points", "--points"}, {"track_min", "--track-min"}, {"track_max", "--track-max"},
      {"focal", "--focal"}, {"intrinsics_spread", "--intrinsics-spread"}, {"distortion", "--distortion"},
      {"orbit_arc_deg", "--arc"}, {"path_yaw_deg", "--yaw"}, {"path_turn_deg", "--turn"}, {"noise", "--noise"},
      {"covariances", "--covariances"}, {"outliers", "--outliers"}, {"perturb_rotation", "--perturb-rotation"},
      {"perturb_translation", "--perturb-translation"}, {"perturb_points", "--perturb-points"},
      {"perturb_intrinsics", "--perturb-intrinsics"}};
  auto word_char = [](char c) { return std::isalnum(static_cast<unsigned char>(c)) || c == '_'; };
  std::string out;
  std::size_t i = 0;
  while (i < message.size()) {
    if (!word_char(message[i])) {
      out += message[i++];
      continue;
    }
    std::size_t e = i;
    while (e < message.size() && word_char(message[e])) ++e;
    const std::string word = message.substr(i, e - i);
    const char *replacement = nullptr;
    for (const auto &n : kNames)
      if (word == n[0]) replacement = n[1];
    out += replacement ? replacement : word;
    i = e;
  }
  return out;
}

Cli parse(int argc, char **argv) {
  Cli cli;
  sbagen::Options &o = cli.options;
  for (int a = 1; a < argc; ++a) {
    std::string opt = argv[a], value;
    bool has_value = false;
    if (opt.rfind("--", 0) == 0) {
      const std::size_t eq = opt.find('=');
      if (eq != std::string::npos) {
        value = opt.substr(eq + 1);
        opt = opt.substr(0, eq);
        has_value = true;
      }
    } else {
      usage_error("unexpected argument '" + opt + "'");
    }
    auto flag = [&]() {
      if (has_value) usage_error(opt + " takes no value");
    };
    auto arg = [&]() -> std::string {
      if (has_value) return value;
      if (a + 1 >= argc) usage_error(opt + " needs a value");
      return argv[++a];
    };
    if (opt == "--help") {
      flag();
      std::fputs(kUsage, stdout);
      std::exit(0);
    } else if (opt == "--cameras") {
      o.cameras = static_cast<int>(parse_integer(opt, arg(), 2, INT_MAX));
    } else if (opt == "--points") {
      o.points = static_cast<int>(parse_integer(opt, arg(), 1, INT_MAX));
    } else if (opt == "--trajectory") {
      const std::string v = arg();
      if (v == "orbit")
        o.trajectory = sbagen::Trajectory::Orbit;
      else if (v == "path")
        o.trajectory = sbagen::Trajectory::Path;
      else
        usage_error(opt + " must be orbit or path, got '" + v + "'");
    } else if (opt == "--track-min") {
      o.track_min = static_cast<int>(parse_integer(opt, arg(), 2, INT_MAX));
    } else if (opt == "--track-max") {
      o.track_max = static_cast<int>(parse_integer(opt, arg(), 2, INT_MAX));
    } else if (opt == "--arc") {
      o.orbit_arc_deg = parse_real(opt, arg());
    } else if (opt == "--yaw") {
      o.path_yaw_deg = parse_real(opt, arg());
    } else if (opt == "--turn") {
      o.path_turn_deg = parse_real(opt, arg());
    } else if (opt == "--kind") {
      const std::string v = arg();
      if (v == "fixed")
        o.kind = eucsba::CameraKind::FixedIntrinsics;
      else if (v == "varK")
        o.kind = eucsba::CameraKind::VaryingIntrinsics;
      else if (v == "varKD")
        o.kind = eucsba::CameraKind::VaryingIntrinsicsDistortion;
      else
        usage_error(opt + " must be fixed, varK or varKD, got '" + v + "'");
    } else if (opt == "--image") {
      parse_image(opt, arg(), &o.image_width, &o.image_height);
    } else if (opt == "--focal") {
      o.focal = parse_real(opt, arg());
    } else if (opt == "--intrinsics-spread") {
      o.intrinsics_spread = parse_real(opt, arg());
    } else if (opt == "--distortion") {
      o.distortion = parse_real(opt, arg());
    } else if (opt == "--noise") {
      o.noise = parse_real(opt, arg());
    } else if (opt == "--covariances") {
      flag();
      o.covariances = true;
    } else if (opt == "--outliers") {
      o.outliers = parse_real(opt, arg());
    } else if (opt == "--perturb-rotation") {
      o.perturb_rotation = parse_real(opt, arg());
    } else if (opt == "--perturb-translation") {
      o.perturb_translation = parse_real(opt, arg());
    } else if (opt == "--perturb-points") {
      o.perturb_points = parse_real(opt, arg());
    } else if (opt == "--perturb-intrinsics") {
      o.perturb_intrinsics = parse_real(opt, arg());
    } else if (opt == "--no-perturb") {
      flag();
      o.perturb_rotation = o.perturb_translation = o.perturb_points = o.perturb_intrinsics = 0;
    } else if (opt == "--seed") {
      o.seed = parse_seed(opt, arg());
    } else if (opt == "--out") {
      cli.prefix = arg();
      if (cli.prefix.empty()) usage_error("--out needs a non-empty prefix");
    } else if (opt == "--quiet") {
      flag();
      cli.quiet = true;
    } else {
      usage_error("unknown option " + opt);
    }
  }
  if (cli.prefix.empty()) usage_error("--out PREFIX is required");
  std::string why;
  if (!o.IsValid(&why)) usage_error(in_option_names(why));
  return cli;
}

void summary(const sbagen::Scene &s, const sbagen::Options &o, const sbagen::ProblemFiles &f) {
  std::vector<int> per_camera(s.ncameras(), 0);
  for (int j : s.track_cameras) ++per_camera[j];
  int least = s.nprojections() > 0 ? per_camera[0] : 0, most = 0;
  for (int c : per_camera) {
    least = std::min(least, c);
    most = std::max(most, c);
  }
  std::printf("sbagen: %s, %s K: %d cameras, %d points, %zu projections (mean track %.2f), %zu outliers; "
              "%d..%d projections per camera; seed %llu\n",
              sbagen::trajectory_name(o.trajectory), sbagen::camera_kind_name(s.kind), s.ncameras(), s.npoints(),
              s.nprojections(), static_cast<double>(s.nprojections()) / s.npoints(), s.noutliers(), least, most,
              static_cast<unsigned long long>(o.seed));
  std::printf("sbagen: wrote %s %s", f.cams.c_str(), f.pts.c_str());
  if (!f.calib.empty()) std::printf(" %s", f.calib.c_str());
  std::printf(" %s %s", f.truth_cams.c_str(), f.truth_pts.c_str());
  if (!f.outliers.empty()) std::printf(" %s", f.outliers.c_str());
  std::printf("\n");
}

}  // namespace

int main(int argc, char **argv) {
  const Cli cli = parse(argc, argv);
  try {
    sbagen::Scene scene;
    std::string why;
    if (!sbagen::generate(cli.options, &scene, &why)) {
      std::fprintf(stderr, "sbagen: %s\n", why.c_str());
      return 1;
    }
    if (eucsba::Status st = sbagen::write_problem(scene, cli.prefix); !st) {
      std::fprintf(stderr, "sbagen: %s\n", st.to_string().c_str());
      return 1;
    }
    if (!cli.quiet) summary(scene, cli.options, sbagen::problem_files(cli.prefix, scene));
  } catch (const std::bad_alloc &) {
    std::fprintf(stderr, "sbagen: out of memory\n");
    return 1;
  }
  return 0;
}
