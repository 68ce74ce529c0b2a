// SPDX-License-Identifier: BSD-3-Clause
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
#include <utility>
#include <vector>

#include "cli/cli.h"
#include "formats/bundler_io.h"
#include "formats/colmap_io.h"
#include "formats/colmap_sba.h"
#include "formats/nvm_io.h"
#include "generator/sbagen.h"

namespace colmap = sbaformats::colmap;
namespace bundler = sbaformats::bundler;
namespace nvm = sbaformats::nvm;
namespace eucsba = sbaformats::eucsba;
namespace euclidean = sbacameras::euclidean;

namespace {

const char kUsage[] =
    "Usage: sbagen --out PREFIX [OPTION]...\n"
    "Writes a synthetic bundle adjustment problem for eucsbademo and its ground truth:\n"
    "  PREFIX-cams.txt PREFIX-pts.txt [PREFIX-calib.txt] PREFIX-truth-cams.txt PREFIX-truth-pts.txt\n"
    "  [PREFIX-outliers.txt]\n"
    "Lengths are in scene units: the radius of the point cloud (orbit) or the spacing of the\n"
    "cameras (path).\n"
    "\n"
    "Options (a value may follow as --opt=VALUE or --opt VALUE; '--' ends the options):\n";

// A bad command line: one line on stderr, exit status 2.
[[noreturn]] void usage_error(const std::string &message) {
  std::fprintf(stderr, "sbagen: %s\n", message.c_str());
  std::exit(sbacli::kExitUsage);
}

// Image size WIDTHxHEIGHT, each from 16 to 100000 pixels.
std::string to_image(const std::string &text, int *w, int *h) {
  const std::size_t x = text.find('x');
  int width = 0, height = 0;
  if (x == std::string::npos || !sbacli::to_int(text.substr(0, x), 16, 100000, &width).empty() ||
      !sbacli::to_int(text.substr(x + 1), 16, 100000, &height).empty())
    return "expected WIDTHxHEIGHT, each an integer from 16 to 100000";
  *w = width;
  *h = height;
  return {};
}

// A 64-bit unsigned seed.
std::string to_seed(const std::string &text, std::uint64_t *out) {
  errno = 0;
  char *end = nullptr;
  if (text.empty() || !std::isdigit(static_cast<unsigned char>(text[0])))
    return "expected an integer from 0 to 18446744073709551615";
  const unsigned long long v = std::strtoull(text.c_str(), &end, 10);
  if (*end != '\0') return "expected an integer from 0 to 18446744073709551615";
  if (errno == ERANGE) return "too large: the most is 18446744073709551615";
  *out = static_cast<std::uint64_t>(v);
  return {};
}

struct Cli {
  sbagen::Options options;
  std::string prefix;
  std::string colmap_text, colmap_binary;  // COLMAP model directories; empty: not written
  std::string bundler;                     // a Bundler file; empty: not written
  std::string nvm;                         // a VisualSFM NVM file; empty: not written
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

// A real option; ranges are checked by Options::IsValid, in the words of the options (see
// parse).
sbacli::Apply real_option(double *field) {
  return [field](const std::string &v) -> std::string {
    double x = 0;
    if (std::string why = sbacli::to_real(v, -HUGE_VAL, false, &x); !why.empty()) return "expected a finite number";
    *field = x;
    return {};
  };
}

sbacli::Apply flag_option(bool *field) {
  return [field](const std::string &) -> std::string {
    *field = true;
    return {};
  };
}

// The scene's size and shape.
void add_scene_options(std::vector<sbacli::Option> *t, sbagen::Options &o) {
  t->push_back({"cameras", "M", "number of cameras (default 20)",
                [&o](const std::string &v) { return sbacli::to_int(v, 2, INT_MAX, &o.cameras); }});
  t->push_back({"points", "N", "number of points (default 1500)",
                [&o](const std::string &v) { return sbacli::to_int(v, 1, INT_MAX, &o.points); }});
  t->push_back({"trajectory", "T",
                "orbit: cameras around the points looking at their centre; path: cameras moving along\n"
                "a road, each point seen by consecutive cameras; photo: a photo collection of a\n"
                "landmark, clusters of cameras that all see most points, heavy-tailed track lengths\n"
                "(default orbit)",
                [&o](const std::string &v) -> std::string {
                  std::string name;
                  if (std::string why = sbacli::to_choice(v, {"orbit", "path", "photo"}, &name); !why.empty())
                    return why;
                  sbagen::trajectory_from_name(name, &o.trajectory);
                  return {};
                }});
  t->push_back({"track-min", "K", "fewest cameras seeing a point, >= 2 (default 2)",
                [&o](const std::string &v) { return sbacli::to_int(v, 2, INT_MAX, &o.track_min); }});
  t->push_back({"track-max", "K", "most cameras seeing a point (default 10)",
                [&o](const std::string &v) { return sbacli::to_int(v, 2, INT_MAX, &o.track_max); }});
  t->push_back({"arc", "DEG", "orbit: arc the cameras spread over, (0, 360] (default 360)", real_option(&o.orbit_arc_deg)});
  t->push_back({"yaw", "DEG", "path: view direction off the road, -90..90 (default 0: ahead)", real_option(&o.path_yaw_deg)});
  t->push_back({"turn", "DEG", "path: largest heading change of the road's S-curve (default 10)",
                real_option(&o.path_turn_deg)});
}

// The cameras' model.
void add_camera_options(std::vector<sbacli::Option> *t, sbagen::Options &o) {
  t->push_back({"kind", "K",
                "fixed (one K, cnp 6), varK (per-camera K, cnp 11) or varKD (per-camera K and\n"
                "distortion, cnp 16) (default fixed)",
                [&o](const std::string &v) -> std::string {
                  std::string name;
                  if (std::string why = sbacli::to_choice(v, {"fixed", "varK", "varKD"}, &name); !why.empty())
                    return why;
                  o.kind = name == "fixed"  ? euclidean::CameraKind::FixedIntrinsics
                           : name == "varK" ? euclidean::CameraKind::VaryingIntrinsics
                                            : euclidean::CameraKind::VaryingIntrinsicsDistortion;
                  return {};
                }});
  t->push_back({"image", "WxH", "image size in pixels (default 640x480)",
                [&o](const std::string &v) { return to_image(v, &o.image_width, &o.image_height); }});
  t->push_back({"focal", "F", "focal length in pixels (default 800)", real_option(&o.focal)});
  t->push_back({"intrinsics-spread", "S", "varK/varKD: relative per-camera spread of K (default 0.01)",
                real_option(&o.intrinsics_spread)});
  t->push_back({"distortion", "D", "varKD: |kc0| <= D, |kc1| <= D/4 (default 0.1)", real_option(&o.distortion)});
}

// The measurements' noise and outliers, the initial estimate's perturbations, the seed.
void add_measurement_options(std::vector<sbacli::Option> *t, sbagen::Options &o) {
  t->push_back({"noise", "SIGMA", "Gaussian pixel noise (default 0.5)", real_option(&o.noise)});
  t->push_back({"covariances", "", "random SPD 2x2 covariance per measurement, noise drawn from it",
                flag_option(&o.covariances)});
  t->push_back({"outliers", "FRAC", "fraction of measurements replaced by gross outliers (default 0)",
                real_option(&o.outliers)});
  t->push_back({"perturb-rotation", "R", "initial estimate: radians per axis (default 0.01)",
                real_option(&o.perturb_rotation)});
  t->push_back({"perturb-translation", "T", "initial estimate: scene units per component of t (default 0.02)",
                real_option(&o.perturb_translation)});
  t->push_back({"perturb-points", "P", "initial estimate: scene units per coordinate (default 0.02)",
                real_option(&o.perturb_points)});
  t->push_back({"perturb-intrinsics", "I",
                "initial estimate, varK/varKD: relative fu u0 v0, absolute kc0 kc1 (default 0.01)",
                real_option(&o.perturb_intrinsics)});
  t->push_back({"no-perturb", "", "start at the truth (the four perturbations set to 0)",
                [&o](const std::string &) -> std::string {
                  o.perturb_rotation = o.perturb_translation = o.perturb_points = o.perturb_intrinsics = 0;
                  return {};
                }});
  t->push_back({"seed", "S", "random seed, a 64-bit unsigned integer (default 1)",
                [&o](const std::string &v) { return to_seed(v, &o.seed); }});
}

// The other formats the initial problem is written in, and the summary.
void add_output_options(std::vector<sbacli::Option> *t, Cli &cli) {
  t->push_back({"colmap", "DIR",
                "also write the initial problem as a COLMAP text model into DIR (not with --covariances)",
                [&cli](const std::string &v) { return sbacli::to_file(v, &cli.colmap_text); }});
  t->push_back({"colmap-binary", "DIR", "the same as a COLMAP binary model",
                [&cli](const std::string &v) { return sbacli::to_file(v, &cli.colmap_binary); }});
  t->push_back({"bundler", "FILE",
                "also write the initial problem as a Bundler bundle.out (--kind varK or fixed: Bundler\n"
                "has no tangential distortion; not with --covariances)",
                [&cli](const std::string &v) { return sbacli::to_file(v, &cli.bundler); }});
  t->push_back({"nvm", "FILE",
                "also write the initial problem as a VisualSFM NVM file (--kind varK or fixed: NVM's\n"
                "radial distortion is not eucsbademo's; not with --covariances)",
                [&cli](const std::string &v) { return sbacli::to_file(v, &cli.nvm); }});
  t->push_back({"quiet", "", "no summary on stdout", flag_option(&cli.quiet)});
}

std::vector<sbacli::Option> option_table(Cli &cli) {
  std::vector<sbacli::Option> t;
  t.push_back({"out", "PREFIX", "write PREFIX-cams.txt, PREFIX-pts.txt ... (required)",
               [&cli](const std::string &v) { return sbacli::to_file(v, &cli.prefix); }});
  add_scene_options(&t, cli.options);
  add_camera_options(&t, cli.options);
  add_measurement_options(&t, cli.options);
  add_output_options(&t, cli);
  return t;
}

void print_usage(std::FILE *out) {
  std::fputs(kUsage, out);
  Cli scratch;
  sbacli::print_options(out, option_table(scratch));
  std::fputs("\nExit status: 0 done, 1 the problem could not be generated or written, 2 bad options.\n", out);
}

Cli parse(int argc, char **argv) {
  Cli cli;
  sbacli::Parsed parsed;
  std::string error;
  if (!sbacli::parse(argc, argv, option_table(cli), &parsed, &error)) usage_error(error);
  if (parsed.help) {
    print_usage(stdout);
    std::exit(0);
  }
  if (parsed.version) {
    std::printf("%s\n", sbacli::version_line("sbagen").c_str());
    std::exit(0);
  }
  if (!parsed.positional.empty())
    usage_error("unexpected argument '" + parsed.positional[0] + "' (see --help)");
  if (cli.prefix.empty()) usage_error("--out PREFIX is required (see --help)");
  std::string why;
  if (!cli.options.IsValid(&why)) usage_error(in_option_names(why));
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
    if (!sbagen::write_problem(scene, cli.prefix, &why)) {
      std::fprintf(stderr, "sbagen: %s\n", why.c_str());
      return 1;
    }
    for (const auto &out : {std::make_pair(&cli.colmap_text, colmap::Encoding::Text),
                            std::make_pair(&cli.colmap_binary, colmap::Encoding::Binary)}) {
      if (out.first->empty()) continue;
      // COLMAP has no measurement covariances: such a problem would not be the same problem.
      if (scene.measurements.has_covariances()) {
        std::fprintf(stderr, "sbagen: a COLMAP model cannot hold --covariances\n");
        return 1;
      }
      eucsba::PointSet points = scene.measurements;
      if (points.vmask.empty()) points.vmask = sbagen::dense_vmask(scene);
      colmap::Model model;
      if (!colmap::from_problem(scene.kind, scene.initial_cameras, points, scene.image_width, scene.image_height,
                                &model, &why) ||
          !colmap::write_model(*out.first, model, out.second, &why)) {
        std::fprintf(stderr, "sbagen: %s\n", why.c_str());
        return 1;
      }
    }
    if (!cli.bundler.empty() || !cli.nvm.empty()) {
      eucsba::PointSet points = scene.measurements;
      if (points.vmask.empty()) points.vmask = sbagen::dense_vmask(scene);
      if (scene.measurements.has_covariances())
        why = std::string("a ") + (cli.bundler.empty() ? "NVM" : "Bundler") + " file cannot hold --covariances";
      bundler::Bundle bundle;
      nvm::Model model;
      if (!why.empty() ||
          (!cli.bundler.empty() && (!bundler::from_problem(scene.initial_cameras, points, &bundle, &why) ||
                                    !bundler::write_bundle(cli.bundler, bundle, &why))) ||
          (!cli.nvm.empty() && (!nvm::from_problem(scene.initial_cameras, points, &model, &why) ||
                                !nvm::write_nvm(cli.nvm, model, &why)))) {
        std::fprintf(stderr, "sbagen: %s\n", why.c_str());
        return 1;
      }
    }
    if (!cli.quiet) summary(scene, cli.options, sbagen::problem_files(cli.prefix, scene));
  } catch (const std::bad_alloc &) {
    std::fprintf(stderr, "sbagen: out of memory\n");
    return 1;
  }
  return 0;
}
