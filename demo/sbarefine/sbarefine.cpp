// SPDX-License-Identifier: BSD-3-Clause
// sbarefine: bundle adjustment of a reconstruction as an SfM pipeline wrote it (a COLMAP
// sparse model, text or binary, a Bundler bundle.out or a VisualSFM NVM file), written back
// in its own format with every identifier, name and color unchanged. The solve is balsba's:
// same options, output and Ctrl-C behaviour.
#include <sys/stat.h>

#include <array>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <exception>
#include <functional>
#include <limits>
#include <memory>
#include <new>
#include <string>
#include <vector>

#include "cameras/bal_camera.h"
#include "cameras/camera_pose.h"
#include "cameras/colmap_camera.h"
#include "cameras/euclidean.h"
#include "cli/cli.h"
#include "cli/motstr_solve.h"
#include "cli/ply_options.h"
#include "cli/solve_options.h"
#include "cli/tty_progress.h"
#include "formats/bal_io.h"
#include "formats/bundler_io.h"
#include "formats/colmap_io.h"
#include "formats/colmap_priors.h"
#include "formats/colmap_problem.h"
#include "formats/colmap_sba.h"
#include "formats/nvm_io.h"
#include "formats/output_file.h"
#include "sba.h"
#include "sba_ext.h"

namespace colmap = sbaformats::colmap;
namespace bundler = sbaformats::bundler;
namespace nvm = sbaformats::nvm;
namespace eucsba = sbaformats::eucsba;
namespace bal = sbaformats::bal;
namespace euclidean = sbacameras::euclidean;
namespace colmap_camera = sbacameras::colmap_camera;
namespace bal_camera = sbacameras::bal;

namespace {

using sbacli::kExitFailure;
using sbacli::kExitUsage;

struct Options {
  std::string input;
  sbacli::SolveOptions solve;
  std::string write;         // output model directory; empty: none
  std::string write_format;  // text or binary; empty: the input's
  std::string intrinsics = "focal,distortion";
  bool intrinsics_given = false;  // --intrinsics or a --refine-* option
  colmap::RefineIntrinsics refine;
  colmap::RefinePoses poses;
  bool poses_given = false;          // a --refine-rig-from-world or the like
  std::string hold_poses;            // COLMAP: the images whose pose is held; empty: none
  std::string hold_poses_file;       // COLMAP: a file of the names of more of them; empty: none
  std::string gauge;                 // COLMAP: two-cams, three-points or none; empty: the default
  std::string hold_intrinsics;       // COLMAP: the cameras whose intrinsics are held; empty: none
  std::string hold_sensors;          // COLMAP: the cameras whose poses in their rigs are held; empty: none
  std::string hold_points;           // COLMAP: the points held; empty: none
  std::string hold_points_file;      // COLMAP: a file of the POINT3D_IDs of more of them; empty: none
  double function_tolerance = -1;    // < 0: not given
  double gradient_tolerance = -1;    // < 0: not given
  std::string initial_ply, final_ply;
  std::string write_eucsba;  // COLMAP, NVM: eucsbademo files PREFIX-cams.txt, PREFIX-pts.txt
  std::string covariance;    // COLMAP: the covariances' file; empty: none
  colmap::CovarianceOptions covariance_options;
  bool covariance_damping_given = false;
  // COLMAP: priors (docs/priors.md). Pose priors from COLMAP's database or a text file (at
  // most one of the two), ground control points, intrinsics; empty: none.
  std::string database_path, pose_priors, point_priors, intrinsics_priors;
  colmap::PosePriorOptions prior_options;
  bool prior_options_given = false;  // a --prior-position-* or --alignment-max-error
  std::string write_bal;     // Bundler: a BAL problem
  std::string bundler_list;  // Bundler: the image list read; empty: none
  std::string write_list;    // Bundler: where the image list is written back; empty: not
  bool help = false, version = false;

  // The iteration limit depends on the format (see resolve_defaults): -1 until then.
  Options() { solve.itmax = -1; }
};

// A COLMAP model is refined as COLMAP refines it unless the command line says otherwise: its
// iteration limit and its stopping rule (colmap_stop_rule). The other formats keep sba's
// algorithm and the programs' limit, and take --function-tolerance as COLMAP's rule does
// (--gradient-tolerance alone is their --eps1).
void resolve_defaults(bool colmap_model, Options *o) {
  sbacli::SolveOptions &so = o->solve;
  if (so.itmax < 0) so.itmax = colmap_model ? colmap::kDefaultItmax : 150;
  if ((colmap_model || o->function_tolerance >= 0) &&
      colmap::colmap_stop_rule(o->function_tolerance, o->gradient_tolerance, !so.strategy.empty(), &so.opts[1],
                               &so.opts[4]) &&
      so.strategy.empty())
    so.strategy = colmap::kColmapStrategy;
  else if (o->gradient_tolerance >= 0)
    so.opts[1] = o->gradient_tolerance;
}

// A boolean option of COLMAP's, 0|1 or as COLMAP's command line takes it (sbacli::to_bool):
// flag `field` of *flags, and *given set.
template <class Flags>
sbacli::Apply zero_one(Flags *flags, bool Flags::*field, bool *given) {
  return [flags, field, given](const std::string &v) -> std::string {
    bool value = false;
    if (std::string why = sbacli::to_bool(v, &value); !why.empty()) return why;
    flags->*field = value;
    *given = true;
    return {};
  };
}

// --intrinsics, and COLMAP's names for the same choice, one flag each; the options apply in
// the order given, so a --refine-* after --intrinsics overrides that part of it, and one
// before is overridden.
void add_intrinsics_options(std::vector<sbacli::Option> *t, Options &o) {
  t->push_back({"intrinsics", "LIST",
                "the intrinsics refined: none, all, or a comma-separated list of focal, principal,\n"
                "distortion (default focal,distortion, as COLMAP: the principal point held); the\n"
                "--refine-* options below set one each, the last given winning. NVM: the focal length\n"
                "or nothing (its radial distortion is held, its principal point absent)",
                [&o](const std::string &v) {
                  o.intrinsics = v;
                  o.intrinsics_given = true;
                  return colmap::parse_refine_intrinsics(v, &o.refine);
                }});
  const auto flag = [&](bool colmap::RefineIntrinsics::*field) {
    return zero_one(&o.refine, field, &o.intrinsics_given);
  };
  t->push_back({"refine-focal-length", "0|1", "COLMAP's refine_focal_length: refine f (or fx and fy) (default 1)",
                flag(&colmap::RefineIntrinsics::focal)});
  t->push_back({"refine-principal-point", "0|1", "COLMAP's refine_principal_point: refine cx and cy (default 0)",
                flag(&colmap::RefineIntrinsics::principal)});
  t->push_back({"refine-extra-params", "0|1",
                "COLMAP's refine_extra_params: refine the parameters after the principal point (the\n"
                "distortion; FOV's omega) (default 1)",
                flag(&colmap::RefineIntrinsics::distortion)});
}

// COLMAP 4's names for what is refined of the poses, and the poses held.
void add_pose_options(std::vector<sbacli::Option> *t, Options &o) {
  const auto flag = [&](bool colmap::RefinePoses::*field) { return zero_one(&o.poses, field, &o.poses_given); };
  t->push_back({"refine-rig-from-world", "0|1",
                "COLMAP 4's refine_rig_from_world: refine the frames' poses (an image's, without rigs)\n"
                "(default 1)",
                flag(&colmap::RefinePoses::rig_from_world)});
  t->push_back({"refine-sensor-from-rig", "0|1",
                "COLMAP 4's refine_sensor_from_rig: refine the poses of the cameras in their rigs, one\n"
                "for all the frames of a rig (default 1; a rig's reference camera stays the identity)",
                flag(&colmap::RefinePoses::sensor_from_rig)});
  t->push_back({"constant-rig-from-world-rotation", "0|1",
                "COLMAP 4's constant_rig_from_world_rotation: hold the rotations of the frames' poses,\n"
                "refine their translations (default 0)",
                flag(&colmap::RefinePoses::constant_rig_from_world_rotation)});
  t->push_back({"hold-poses", "LIST",
                "COLMAP: hold the poses of these images (COLMAP's constant poses; in a rig, the pose of\n"
                "the image's frame and of its camera in the rig): all, or items separated by commas,\n"
                "matched as given (nothing trimmed): plain decimal digits without a leading zero name an\n"
                "IMAGE_ID (or, when no image has it, a NAME); anything else a NAME",
                [&o](const std::string &v) -> std::string {
                  if (v.empty()) return "expected all or a comma-separated list of images";
                  // The list is checked here; its items are looked up once the model is read.
                  std::vector<std::string> items;
                  if (std::string why = colmap::split_image_list(v, &items); !why.empty()) return why;
                  o.hold_poses = v;
                  return {};
                }});
  t->push_back({"hold-poses-file", "FILE",
                "COLMAP: hold the poses of the images named in FILE, one NAME a line, matched exactly (a\n"
                "name may hold commas; a line is never an IMAGE_ID; blank lines are skipped); with\n"
                "--hold-poses, the images of both",
                [&o](const std::string &v) { return sbacli::to_file(v, &o.hold_poses_file); }});
  t->push_back({"gauge", "NAME",
                "COLMAP: how the gauge is fixed, the similarity of the whole model that moves no\n"
                "projection: two-cams (COLMAP's TWO_CAMS_FROM_WORLD: the first image's pose held and one\n"
                "coordinate of the next image's translation, unless two poses are held already),\n"
                "three-points (THREE_POINTS: three points held) or none (free). Default two-cams, as\n"
                "COLMAP's bundle adjuster fixes it; none with position priors or ground control points,\n"
                "which fix it themselves",
                [&o](const std::string &v) -> std::string {
                  if (v != "two-cams" && v != "three-points" && v != "none")
                    return "expected two-cams, three-points or none";
                  o.gauge = v;
                  return {};
                }});
}

// COLMAP's other constants (colmap::Constants): the intrinsics of cameras, the poses of cameras
// in their rigs, points. The lists are checked here; their items are looked up once the model is
// read.
void add_constant_options(std::vector<sbacli::Option> *t, Options &o) {
  const auto id_list = [](std::string *out, const char *kind, std::uint64_t max) -> sbacli::Apply {
    return [out, kind, max](const std::string &v) -> std::string {
      if (v.empty()) return std::string("expected all or ") + kind + "s separated by commas";
      if (std::string why = colmap::check_id_list(v, kind, max); !why.empty()) return why;
      *out = v;
      return {};
    };
  };
  t->push_back({"hold-intrinsics", "LIST",
                "COLMAP: hold every intrinsic parameter of these cameras, in all their images (COLMAP's\n"
                "constant camera intrinsics): all, or CAMERA_IDs separated by commas, each plain decimal\n"
                "digits without a leading zero",
                id_list(&o.hold_intrinsics, "CAMERA_ID", UINT32_MAX)});
  t->push_back({"hold-sensor-from-rig", "LIST",
                "COLMAP 4: hold the poses of these cameras in their rigs, for all the frames (COLMAP's\n"
                "constant sensor_from_rig poses): all, or CAMERA_IDs as --hold-intrinsics's (a rig's\n"
                "reference camera is at the identity, held anyway)",
                id_list(&o.hold_sensors, "CAMERA_ID", UINT32_MAX)});
  t->push_back({"hold-points", "LIST",
                "COLMAP: hold these points (COLMAP's constant points): all, or POINT3D_IDs separated by\n"
                "commas, each plain decimal digits without a leading zero; with --ncon, the points of both",
                id_list(&o.hold_points, "POINT3D_ID", UINT64_MAX)});
  t->push_back({"hold-points-file", "FILE",
                "COLMAP: hold the points whose POINT3D_IDs FILE holds, one a line (blank lines are\n"
                "skipped); with --hold-points, the points of both",
                [&o](const std::string &v) { return sbacli::to_file(v, &o.hold_points_file); }});
}

// COLMAP 4's pose-prior bundle adjustment, and the other priors: their files and COLMAP's
// options for them, by COLMAP's names.
void add_prior_options(std::vector<sbacli::Option> *t, Options &o) {
  t->push_back({"database-path", "FILE",
                "COLMAP: the position priors of the images (GPS) from COLMAP's database FILE (its\n"
                "pose_priors table, COLMAP 4's or 3.x's), WGS84 ones in metres east, north and up of\n"
                "the first: with at least 3 on images of the model, the model is moved onto them by a\n"
                "robust similarity, then refined with each image's centre drawn to its prior, weighted\n"
                "by its covariance, as COLMAP 4's pose-prior bundle adjustment (docs/priors.md)",
                [&o](const std::string &v) { return sbacli::to_file(v, &o.database_path); }});
  t->push_back({"pose-priors", "FILE",
                "COLMAP: the same priors from a text file, a line per image: NAME X Y Z, then optionally\n"
                "the 9 values of a covariance (row-major) and CARTESIAN (the default) or WGS84",
                [&o](const std::string &v) { return sbacli::to_file(v, &o.pose_priors); }});
  const auto given = [&o](std::string why) {
    if (why.empty()) o.prior_options_given = true;
    return why;
  };
  t->push_back({"prior-position-fallback-stddev", "X",
                "COLMAP's prior_position_fallback_stddev: the standard deviation, in each axis, of a\n"
                "position prior without a covariance (default 1)",
                [&o, given](const std::string &v) {
                  return given(sbacli::to_real(v, 0.0, true, &o.prior_options.fallback_stddev));
                }});
  t->push_back({"prior-position-loss", "NAME",
                "COLMAP's prior_position_loss_function_type: trivial (least squares, the default) or\n"
                "cauchy, on each position prior's squared Mahalanobis distance",
                [&o, given](const std::string &v) {
                  std::string choice;
                  if (std::string why = sbacli::to_choice(v, {"trivial", "cauchy"}, &choice); !why.empty()) return why;
                  o.prior_options.loss = choice == "cauchy" ? "cauchy" : "";
                  return given({});
                }});
  t->push_back({"prior-position-loss-scale", "S",
                "COLMAP's prior_position_loss_scale: the scale of --prior-position-loss cauchy, in\n"
                "standard deviations (default 2.7954834829151074, the 95% quantile of chi with 3\n"
                "degrees of freedom)",
                [&o, given](const std::string &v) {
                  return given(sbacli::to_real(v, 0.0, true, &o.prior_options.loss_scale));
                }});
  t->push_back({"alignment-max-error", "E",
                "COLMAP's alignment_ransac max_error: the distance within which a prior agrees with\n"
                "the similarity moving the model onto the priors; 0 (the default): three times the\n"
                "priors' RMS standard deviation",
                [&o, given](const std::string &v) {
                  return given(sbacli::to_real(v, 0.0, false, &o.prior_options.alignment_max_error));
                }});
  t->push_back({"point-priors", "FILE",
                "COLMAP: ground control points, soft: a line per point, POINT3D_ID X Y Z SIGMA, or\n"
                "POINT3D_ID X Y Z and a covariance's 9 values; with at least 3 and no position priors,\n"
                "the model is first moved onto them by a robust similarity",
                [&o](const std::string &v) { return sbacli::to_file(v, &o.point_priors); }});
  t->push_back({"intrinsics-priors", "FILE",
                "COLMAP: priors on intrinsic parameters, a line each: CAMERA_ID PARAM MEAN STDDEV, PARAM\n"
                "the parameter's index in COLMAP's list for the camera's model, or f, fx, fy, cx, cy",
                [&o](const std::string &v) { return sbacli::to_file(v, &o.intrinsics_priors); }});
}

// The outputs and inputs of one format each.
void add_format_options(std::vector<sbacli::Option> *t, Options &o) {
  t->push_back({"write-eucsba", "PREFIX",
                "COLMAP, NVM: also write the refined model as eucsbademo files PREFIX-cams.txt (17\n"
                "values a line) and PREFIX-pts.txt",
                [&o](const std::string &v) { return sbacli::to_file(v, &o.write_eucsba); }});
  t->push_back({"covariance", "FILE",
                "COLMAP: also write the covariance of the refined poses (each image's cam_from_world;\n"
                "with rigs, also each frame's rig_from_world and camera's sensor_from_rig) and of each\n"
                "camera's refined parameters to FILE, in COLMAP's convention (pycolmap's\n"
                "estimate_ba_covariance: unit pixel noise, [rotation, translation] tangent, held\n"
                "coordinates left out; format in docs/formats.md)",
                [&o](const std::string &v) { return sbacli::to_file(v, &o.covariance); }});
  t->push_back({"covariance-points", "",
                "COLMAP: --covariance also writes every free point's 3x3 (marginal) covariance",
                [&o](const std::string &) {
                  o.covariance_options.points = true;
                  return std::string();
                }});
  t->push_back({"covariance-damping", "D",
                "COLMAP: --covariance adds D to the diagonal of each point's block of J^T J first, as\n"
                "pycolmap's BACovarianceOptions.damping does; 0: (J^T J)^-1 itself (default 1e-8, pycolmap's)",
                [&o](const std::string &v) {
                  o.covariance_damping_given = true;
                  return sbacli::to_real(v, 0.0, false, &o.covariance_options.point_damping);
                }});
  t->push_back({"write-bal", "FILE", "Bundler: also write the refined model as a BAL problem",
                [&o](const std::string &v) { return sbacli::to_file(v, &o.write_bal); }});
  t->push_back({"bundler-list", "FILE",
                "Bundler: the image list of the bundle (list.txt: PATH or PATH 0 FOCAL, a line per camera);\n"
                "its paths name the cameras in messages and in --json",
                [&o](const std::string &v) { return sbacli::to_file(v, &o.bundler_list); }});
  t->push_back({"write-list", "FILE", "Bundler: write the image list of --bundler-list to FILE as it was read",
                [&o](const std::string &v) { return sbacli::to_file(v, &o.write_list); }});
}

std::vector<sbacli::Option> option_table(Options &o) {
  std::vector<sbacli::Option> t;
  // What resolve_defaults makes of an option not given, for each format.
  sbacli::SolveDefaults defaults;
  defaults.strategy =
      "trust-region\n"
      "for a COLMAP model (COLMAP's bundle adjuster runs Ceres's Levenberg-Marquardt), unless\n"
      "--eps4 (or --opts) gives sba's relative error test; otherwise (a Bundler or NVM file) the\n"
      "environment variable SBA_STRATEGY if set, else sba";
  defaults.itmax = "default 100 for a COLMAP model, as COLMAP; 150 for a Bundler or NVM file";
  sbacli::add_solve_options(
      &t, o.solve,
      {"write", "OUT", "write the refined model in the input's format: a COLMAP model into the directory\n"
                        "OUT (created if missing), a Bundler or NVM file to the file OUT",
       [&o](const std::string &v) { return sbacli::to_file(v, &o.write); }},
      defaults);
  t.push_back({"write-format", "F", "the format of --write: text or binary (default: the input's)",
               [&o](const std::string &v) { return sbacli::to_choice(v, {"text", "binary"}, &o.write_format); }});
  add_intrinsics_options(&t, o);
  add_pose_options(&t, o);
  add_constant_options(&t, o);
  add_prior_options(&t, o);
  t.push_back({"max-num-iterations", "N",
               "COLMAP's name of --itmax (default 100 for a COLMAP model, as COLMAP; 150 for the others)",
               [&o](const std::string &v) {
                 return sbacli::to_int(v, 0, std::numeric_limits<int>::max(), &o.solve.itmax);
               }});
  t.push_back({"function-tolerance", "X",
               "COLMAP's (Ceres's) function_tolerance: stop when a step changes the cost by at most X\n"
               "relatively, up or down. Sets --eps4 X and, unless --strategy is given, the trust-region\n"
               "strategy, whose eps4 is this test (sba's eps4 is a relative RMS reduction instead).\n"
               "A COLMAP model is refined at COLMAP's default, 0: until a step changes the cost by no\n"
               "more than rounding (give --strategy or --eps4 for sba's tests instead)",
               [&o](const std::string &v) { return sbacli::to_real(v, 0.0, false, &o.function_tolerance); }});
  t.push_back({"gradient-tolerance", "X",
               "COLMAP's (Ceres's) gradient_tolerance: stop when the largest entry of the gradient,\n"
               "||J^T e||_inf, is at most X. Sets --eps1 X. A COLMAP model is refined at COLMAP 4's\n"
               "default, 1e-4, unless --eps1 (or --opts) is given or sba's tests are (see\n"
               "--function-tolerance); COLMAP 3's is 0",
               [&o](const std::string &v) { return sbacli::to_real(v, 0.0, false, &o.gradient_tolerance); }});
  add_format_options(&t, o);
  sbacli::add_ply_options(&t, &o.initial_ply, &o.final_ply, true);
  return t;
}

bool parse_command_line(int argc, char **argv, Options *options, std::string *error) {
  Options o;
  if (!sbacli::parse_one_input(argc, argv, option_table(o),
                                "argument (a COLMAP model directory, a Bundler or an NVM file)", &o.input, &o.help,
                                &o.version, error))
    return false;
  *options = std::move(o);
  return true;
}

void print_usage(std::FILE *out) {
  std::fputs(
      "Usage: sbarefine [OPTION]... MODEL\n"
      "Bundle-adjusts a reconstruction with sba_motstr_levmar_x_ext, analytic Jacobian. MODEL is\n"
      "- a COLMAP sparse model: the directory holding cameras, images and points3D (.bin or .txt,\n"
      "  .bin read first as COLMAP does; all eighteen camera models of COLMAP, ids 0..17), refined\n"
      "  with COLMAP's own camera models: every image that sees a point an sba camera, a camera\n"
      "  shared by several images refined once for all of them (one that sees none is written\n"
      "  back as read); by default the focal length and the extra parameters refined, the\n"
      "  principal point held, as COLMAP's bundle adjuster does; with COLMAP 4's rigs and frames,\n"
      "  as COLMAP 4 refines them: one pose per frame for its images, one pose per camera in its\n"
      "  rig for all the frames (the rig's reference camera at the identity), both written back\n"
      "  (an image that sees no point keeps its place in its frame and rig);\n"
      "- a Bundler file (bundle.out, v0.3), refined with the BAL camera model (f, k1, k2 per camera,\n"
      "  always refined: --intrinsics and --refine-* are refused); its image list (list.txt) with\n"
      "  --bundler-list;\n"
      "- a VisualSFM file (NVM_V3, its first model), refined with eucsbademo's camera model, the\n"
      "  focal length refined (--intrinsics focal or none) and the radial distortion held.\n"
      "\n"
      "Options (a value may follow as --opt=VALUE or --opt VALUE; '--' ends the options; an option\n"
      "of 0|1 also takes true|false, yes|no and on|off, in any case, as COLMAP's command line):\n",
      out);
  Options scratch;
  sbacli::print_options(out, option_table(scratch));
  std::fprintf(out, "\nLinear solvers (--solver): %s\n", sba_linsolver_names());
  std::fputs(
      "\n"
      "Prints the sizes and what is refined once the model is read, then what balsba prints: sba\n"
      "1.6's summary (mean squared reprojection error in pixels^2 per observation ...), the RMS\n"
      "reprojection error in pixels, COLMAP's mean reprojection error (each point's mean distance\n"
      "in pixels, averaged over the points), the stop reason, the solver and threads used. The\n"
      "written model keeps every identifier, name, color and unrefined value; a refined point's\n"
      "ERROR becomes its mean reprojection error. --itmax 0 writes the model as read (a\n"
      "conversion), without a solve and without a Jacobian check.\n"
      "Exit status: 0 done (--max-time included), 1 a file cannot be read or written or the solver\n"
      "fails, 2 bad options, 130 (SIGINT) or 143 (SIGTERM) when a signal stopped the solve.\n",
      out);
}

using sbaformats::Cloud;

Cloud cloud(const colmap::Model &model) {
  Cloud c;
  for (const colmap::Point3D &p : model.points) {
    c.points.push_back(p.xyz);
    c.colors.push_back({p.rgb[0], p.rgb[1], p.rgb[2]});
  }
  for (const colmap::Pose &pose : colmap::image_poses(model)) {
    double R[9];
    euclidean::rotation_matrix(euclidean::normalized_rotation({pose.q[0], pose.q[1], pose.q[2], pose.q[3]}), R);
    c.centres.push_back(sbacameras::camera_centre(R, pose.t.data()));
  }
  return c;
}

Cloud cloud(const nvm::Model &m) {
  Cloud c;
  for (const nvm::Point &p : m.points) {
    c.points.push_back(p.xyz);
    c.colors.push_back(p.rgb);
  }
  for (const nvm::Camera &cam : m.cameras) c.centres.push_back(cam.c);
  return c;
}

Cloud cloud(const bundler::Bundle &b) {
  Cloud c;
  for (const bundler::Point &p : b.points) {
    c.points.push_back(p.xyz);
    c.colors.push_back(p.rgb);
  }
  for (const bundler::Camera &cam : b.cameras)
    if (cam.registered()) c.centres.push_back(sbacameras::camera_centre(cam.R.data(), cam.t.data()));
  return c;
}

// A loaded reconstruction as sba takes it, and what to do with the result.
struct Job {
  std::string summary;  // the sizes line
  std::vector<double> p;
  sbacli::MotstrInputs in;  // in.p is pointed at p when the solve starts
  // The projection of point i in camera j with the parameters p; false where the camera model
  // refuses it (a point behind a COLMAP camera), whose cost is zero.
  std::function<bool(const double *p, int j, int i, double x[2])> project;
  Cloud initial;
  std::vector<std::string> camera_names;  // the image of each sba camera; empty: unnamed
  std::string model;                      // --json's "model": the camera models, what is refined
  // The points held at the start of the problem's (sba's ncon), when it is not --ncon (a COLMAP
  // model's constant points come first: colmap::Problem::held_points); -1: --ncon.
  int ncon = -1;
  // Writes the refined model (p) where --write says, and the files derived from it, into the
  // run's outputs, the model marked to be published last; returns it for --final-ply. With
  // --itmax 0 nothing was refined: the model is written as read, not as p, whose rotations and
  // centres went through sba's parametrisation and would come back changed in the last bits.
  std::function<bool(const double *p, Cloud *final_cloud, sbaformats::OutputSet *outputs, std::string *error)>
      finish;
  // --covariance: the covariances at p into the run's outputs (a COLMAP model's only); false
  // when the library refuses them (said through ext's sink) or the file cannot be written.
  std::function<bool(const double *p, const sba_ext_options &ext, sbaformats::OutputSet *outputs, std::string *error)>
      covariance;
};

enum class Format { Colmap, Bundler, Nvm };

// The input: a COLMAP model directory, or a file that is read once, so that standard input
// or a FIFO works as a file does: its first bytes tell the format, and the rest is read from
// the same stream once the options have been checked against that format.
struct Input {
  bool directory = false;  // a model directory (or nothing: its reader says what is missing)
  Format format = Format::Colmap;
  std::FILE *file = nullptr;  // a file input, once opened
  std::string text;           // what has been read of it
  Input() = default;
  Input(const Input &) = delete;
  Input &operator=(const Input &) = delete;
  ~Input() {
    if (file) std::fclose(file);
  }
};

// Whether path is a directory, without reading anything: false with "PATH: cannot open: REASON"
// when it cannot be looked at (a symbolic link loop, a permission).
bool look_at_input(const std::string &path, Input *in, std::string *error) {
  struct stat st {};
  if (::stat(path.c_str(), &st) == 0) {
    in->directory = S_ISDIR(st.st_mode);
    return true;
  }
  in->directory = errno == ENOENT;
  if (in->directory) return true;
  *error = path + ": cannot open: " + std::strerror(errno);
  return false;
}

// Opens a file input and tells its format from its first bytes.
bool open_input(const std::string &path, Input *in, std::string *error) {
  in->file = std::fopen(path.c_str(), "rb");
  if (!in->file) {
    *error = path + ": cannot open: " + std::strerror(errno);
    return false;
  }
  char head[13];
  in->text.assign(head, std::fread(head, 1, sizeof head, in->file));
  if (in->text.compare(0, 13, "# Bundle file") == 0) {
    in->format = Format::Bundler;
  } else if (in->text.compare(0, 6, "NVM_V3") == 0) {
    in->format = Format::Nvm;
  } else {
    *error = path + ": not a COLMAP model directory, a Bundler file (# Bundle file) or an NVM file (NVM_V3)";
    return false;
  }
  return true;
}

// The priors the options name, as read and checked against the model.
struct ModelPriors {
  std::vector<colmap::PosePrior> poses;  // usable_pose_priors'
  std::vector<colmap::PointPrior> points;
  std::vector<colmap::IntrinsicPrior> intrinsics;
};

// The state a job's callbacks point into, kept alive for the whole run.
struct Loaded {
  std::string warning;  // said once the input is read; empty: none
  colmap::Model model;
  colmap::Encoding encoding = colmap::Encoding::Text;
  nvm::SbaProblem problem;  // NVM
  std::unique_ptr<euclidean::CameraModel> sba_model;
  colmap::Problem colmap_problem;
  ModelPriors model_priors;  // read_priors'
  std::string priors_said;   // what read_priors did, for the summary
  colmap::ProblemPriors priors;
  nvm::Model nvm;
  bundler::Bundle bundle;
  bundler::ImageList list;
  bal::Problem bal;
  bal::SbaLayout layout;
  std::vector<int> bundle_cameras;
  bal_camera::CallbackData bal_data;
};

// The job of l->problem (an NVM file) through eucsbademo's camera model.
void eucsba_job(Loaded *l, Job *job) {
  nvm::SbaProblem &pr = l->problem;
  l->sba_model = std::make_unique<euclidean::CameraModel>(euclidean::CameraKind::VaryingIntrinsicsDistortion, pr.cameras,
                                                       pr.points.xyz, pr.nccalib, pr.ncdist);
  const euclidean::CameraModel &sm = *l->sba_model;
  job->in.m = pr.points.ncameras;
  job->in.n = pr.points.npoints();
  job->in.cnp = sm.cnp();
  job->in.vis = &pr.points.pairs;
  job->in.x = pr.points.x.data();
  job->p = sm.initial_camera_params();
  job->p.insert(job->p.end(), sm.initial_points().begin(), sm.initial_points().end());
  const euclidean::ExpertCallbacks cb = euclidean::expert_callbacks(sm.kind(), euclidean::Refinement::MotionStructure);
  job->in.func = cb.func;
  job->in.fjac = cb.fjac;
  job->in.adata = euclidean::as_adata(sm);
  job->in.cam_held_by_callbacks = pr.nccalib + pr.ncdist;
  const int m = job->in.m, cnp = job->in.cnp;
  job->project = [&sm, m, cnp](const double *p, int j, int i, double x[2]) {
    sm.project(j, p + static_cast<std::size_t>(j) * cnp, p + static_cast<std::size_t>(m) * cnp + 3 * static_cast<std::size_t>(i), x);
    return true;
  };
}

// --write-eucsba PREFIX: eucsbademo's cameras and the points p as eucsbademo files.
bool write_eucsba(const std::string &prefix, const std::vector<euclidean::Camera> &cams,
                  const eucsba::PointSet &pointset, const double *xyz, sbaformats::OutputSet *outputs,
                  std::string *why) {
  const std::vector<double> points(xyz, xyz + 3 * static_cast<std::size_t>(pointset.npoints()));
  const euclidean::CameraKind kind = euclidean::CameraKind::VaryingIntrinsicsDistortion;
  return eucsba::write_cameras(prefix + "-cams.txt", kind, cams, why, outputs) &&
         eucsba::write_points(prefix + "-pts.txt", pointset, points, why, outputs);
}

bool write_eucsba(const std::string &prefix, const Loaded &l, const double *p, sbaformats::OutputSet *outputs,
                  std::string *why) {
  const euclidean::CameraModel &model = *l.sba_model;
  std::vector<euclidean::Camera> cams;
  for (int j = 0; j < model.ncameras(); ++j)
    cams.push_back(model.camera(j, p + static_cast<std::size_t>(j) * model.cnp()));
  const double *xyz = p + static_cast<std::size_t>(model.ncameras()) * model.cnp();
  return write_eucsba(prefix, cams, l.problem.points, xyz, outputs, why);
}

// The same for a COLMAP model, whose cameras must be of the five models eucsbademo's camera
// expresses.
bool write_eucsba_colmap(const std::string &prefix, const colmap::Problem &problem, const double *p,
                         sbaformats::OutputSet *outputs, std::string *why) {
  const std::vector<colmap_camera::Camera> cameras = problem.cameras(p);
  std::vector<euclidean::Camera> cams(cameras.size());
  for (std::size_t j = 0; j < cameras.size(); ++j) {
    if (!colmap::to_euclidean(cameras[j], &cams[j])) {
      *why = prefix + "-cams.txt: eucsbademo's camera cannot express COLMAP's " +
             colmap_camera::model_name(cameras[j].model) +
             " (only SIMPLE_PINHOLE, PINHOLE, SIMPLE_RADIAL, RADIAL, OPENCV)";
      return false;
    }
  }
  const std::size_t m = cameras.size();
  return write_eucsba(prefix, cams, problem.points(), p + m * static_cast<std::size_t>(problem.cnp()), outputs,
                      why);
}

// The job of a COLMAP problem: its arrays and callbacks as the solve takes them.
void colmap_job(const colmap::Problem &pr, Job *job) {
  job->in.m = pr.ncameras();
  job->in.n = pr.npoints();
  job->in.cnp = pr.cnp();
  job->in.vis = &pr.points().pairs;
  job->in.x = const_cast<double *>(pr.points().x.data());  // sba's x is not const, but only read
  job->in.cam_fixed = pr.cam_fixed().data();
  job->in.cam_fixed_per_camera = 1;
  job->in.cam_param_group = pr.cam_param_group().data();
  job->in.func = pr.func();
  job->in.fjac = pr.fjac();
  job->in.adata = pr.adata();
  job->p = pr.initial_params();
  // The reports project every observation, one thread at a time.
  job->project = pr.cached_project();
}

// "OPENCV (3 cameras), PINHOLE (1 camera)": the models of the cameras the solve uses.
std::string camera_models(const colmap::Model &model, const colmap::Problem &pr) {
  std::vector<int> count(colmap_camera::kNumModels, 0);
  std::vector<char> seen(model.cameras.size(), 0);
  for (int j : pr.images())
    for (std::size_t c = 0; c < model.cameras.size(); ++c)
      if (model.cameras[c].id == model.images[static_cast<std::size_t>(j)].camera_id && !seen[c]) {
        seen[c] = 1;
        ++count[static_cast<std::size_t>(model.cameras[c].model)];
      }
  std::string out;
  for (int k = 0; k < colmap_camera::kNumModels; ++k)
    if (count[static_cast<std::size_t>(k)] > 0)
      out += std::string(out.empty() ? "" : ", ") + colmap_camera::model_name(k) + " (" +
             std::to_string(count[static_cast<std::size_t>(k)]) + (count[static_cast<std::size_t>(k)] == 1 ? " camera)" : " cameras)");
  return out;
}

// The images of --hold-poses and --hold-poses-file (one flag per image; empty when neither is given).
bool held_poses(const Options &o, const colmap::Model &model, std::vector<char> *held, std::string *error) {
  std::string why;
  if (!o.hold_poses.empty() && !(why = colmap::parse_image_list(model, o.hold_poses, held)).empty()) {
    *error = "sbarefine: --hold-poses: " + o.input + ": " + why;
    return false;
  }
  if (o.hold_poses_file.empty()) return true;
  std::string names;
  if (!colmap::read_whole_file(o.hold_poses_file, true, &names, &why)) {
    *error = "sbarefine: --hold-poses-file: " + why;
    return false;
  }
  if (!(why = colmap::parse_image_names(model, names, o.hold_poses_file, held)).empty()) {
    *error = "sbarefine: --hold-poses-file: " + o.input + ": " + why;
    return false;
  }
  return true;
}

// COLMAP's constants of the command line (--hold-poses and the like) looked up in the model.
bool constants_of(const Options &o, const colmap::Model &model, colmap::Constants *c, std::string *error) {
  if (!held_poses(o, model, &c->poses, error)) return false;
  const struct {
    const std::string &list;
    std::string (*parse)(const colmap::Model &, const std::string &, std::vector<char> *);
    std::vector<char> *held;
    const char *option;
  } lists[] = {{o.hold_intrinsics, colmap::parse_camera_list, &c->intrinsics, "--hold-intrinsics"},
               {o.hold_sensors, colmap::parse_camera_list, &c->sensor_from_rig, "--hold-sensor-from-rig"},
               {o.hold_points, colmap::parse_point_list, &c->points, "--hold-points"}};
  for (const auto &l : lists)
    if (std::string why; !l.list.empty() && !(why = l.parse(model, l.list, l.held)).empty()) {
      *error = std::string("sbarefine: ") + l.option + ": " + o.input + ": " + why;
      return false;
    }
  if (o.hold_points_file.empty()) return true;
  std::string ids, why;
  if (!colmap::read_whole_file(o.hold_points_file, true, &ids, &why)) {
    *error = "sbarefine: --hold-points-file: " + why;
    return false;
  }
  if (!(why = colmap::parse_point_ids(model, ids, o.hold_points_file, &c->points)).empty()) {
    *error = "sbarefine: --hold-points-file: " + o.input + ": " + why;
    return false;
  }
  return true;
}

// The summary's line on the images that see no point (none: empty): held out of the solve, and
// written back as read, or, in a rig, kept at their place in a frame or rig whose pose is
// refined, and moved with it.
std::string unseen_images(const colmap::Model &model, const colmap::Problem &pr) {
  const std::size_t unseen = model.images.size() - pr.images().size();
  if (unseen == 0) return {};
  std::string line = "\n" + std::to_string(unseen) + (unseen == 1 ? " image sees" : " images see") +
                     " no point: held out of the solve";
  if (pr.counts().unseen_moved == 0) return line + " and written back as read";
  const std::size_t moved = static_cast<std::size_t>(pr.counts().unseen_moved);
  return line + "; " + std::to_string(unseen - moved) + " written back as read, " + std::to_string(moved) +
         " moved with " + (moved == 1 ? "its" : "their") + " refined frame or rig (" + (moved == 1 ? "its" : "their") +
         " place there kept)";
}

// --covariance of a COLMAP model: its problem's covariances at p, in COLMAP's convention.
decltype(Job::covariance) colmap_covariance(const Options &o, Loaded *l) {
  return [&o, l](const double *p, const sba_ext_options &ext, sbaformats::OutputSet *outputs, std::string *why) {
    colmap::Covariances c;
    return l->colmap_problem.covariance(l->model, p, ext, o.covariance_options, &c) &&
           colmap::write_covariances(o.covariance, c, why, outputs);
  };
}


// The priors of the options (docs/priors.md), into *out, and the model moved onto them when there
// are enough to place it (not with --itmax 0, which rewrites the model as read): *said tells what
// was done, for the summary.
bool read_priors(const Options &o, colmap::Model *model, ModelPriors *out, std::string *said, std::string *error) {
  std::vector<colmap::PosePrior> read;
  int unknown = 0;
  const std::string &source = o.database_path.empty() ? o.pose_priors : o.database_path;
  if (!o.database_path.empty() && !colmap::read_pose_priors_database(o.database_path, &read, error)) return false;
  if (!o.pose_priors.empty() && !colmap::read_pose_priors_text(o.pose_priors, *model, &read, &unknown, error))
    return false;
  if (!o.point_priors.empty() && !colmap::read_point_priors(o.point_priors, *model, &out->points, error)) return false;
  if (!o.intrinsics_priors.empty() &&
      !colmap::read_intrinsic_priors(o.intrinsics_priors, *model, &out->intrinsics, error))
    return false;
  if (!colmap::place_on_priors(std::move(read), unknown, source, out->points, o.point_priors, o.prior_options,
                               o.solve.itmax > 0, model, &out->poses, said, error))
    return false;
  if (!out->intrinsics.empty())
    *said += "\nIntrinsics priors: " + std::to_string(out->intrinsics.size()) + " from " + o.intrinsics_priors;
  return true;
}
// The priors as the problem takes them, into the job's inputs.
bool attach_priors(const Options &o, const ModelPriors &priors, Loaded *l, Job *job, std::string *error) {
  if (!l->priors.build(l->colmap_problem, priors.poses, o.prior_options, priors.points, priors.intrinsics, error))
    return false;
  job->in.npriors = static_cast<int>(l->priors.size());
  if (job->in.npriors > 0) job->in.attach_priors = [l](sba_ext_options *ext) { l->priors.attach(ext); };
  return true;
}

// The model and its priors, less the observations behind their cameras: COLMAP's
// bundle_adjuster removes them before it solves, and writes the model without them.
bool read_colmap_input(const Options &o, Loaded *l, colmap::DepthFilter *behind, std::string *error) {
  if (!colmap::read_model(o.input, &l->model, &l->encoding, error)) return false;
  if (!read_priors(o, &l->model, &l->model_priors, &l->priors_said, error)) return false;
  *behind = colmap::filter_negative_depth(&l->model);
  return true;
}

// The summary's line on what read_colmap_input removed, empty when nothing.
std::string removed_behind(const colmap::DepthFilter &behind) {
  const std::size_t n = behind.observations.size();
  if (n == 0) return {};
  std::string said = "\n" + std::to_string(n) + (n == 1 ? " observation" : " observations") +
                     " behind their cameras removed, as COLMAP's bundle_adjuster removes them";
  if (behind.points > 0)
    said += ", and " + std::to_string(behind.points) + (behind.points == 1 ? " point" : " points") +
            " left seen fewer than twice";
  return said;
}

// The gauge of --gauge, else COLMAP's bundle adjuster's, unless priors that are used place the
// model: COLMAP's pose-prior adjustment holds no pose for the gauge, and ground control points
// fix it as position priors do.
colmap::Gauge gauge_of(const Options &o, const ModelPriors &priors) {
  if (o.gauge == "none") return colmap::Gauge::None;
  if (o.gauge == "three-points") return colmap::Gauge::ThreePoints;
  if (o.gauge.empty() && (!priors.poses.empty() || !priors.points.empty())) return colmap::Gauge::None;
  return colmap::Gauge::TwoCamsFromWorld;
}

// The summary's words on the gauge.
std::string gauge_said(colmap::Gauge g) {
  switch (g) {
    case colmap::Gauge::TwoCamsFromWorld:
      return "; gauge fixed by two images' poses (TWO_CAMS_FROM_WORLD)";
    case colmap::Gauge::ThreePoints:
      return "; gauge fixed by three points (THREE_POINTS)";
    case colmap::Gauge::None:
      break;
  }
  return "; gauge free";
}

// "N things", "1 thing".
std::string count(std::size_t n, const char *what) { return std::to_string(n) + " " + what + (n == 1 ? "" : "s"); }

// The summary's "Camera models:" line (and --json's "model"): the models, what is refined of
// them and of the poses, what is held, and the gauge.
std::string what_is_refined(const Options &o, const colmap::Model &model, const colmap::Problem &pr) {
  const colmap::Problem::Counts &n = pr.counts();
  const auto yes_no = [](bool b) { return b ? "refined" : "held"; };
  std::string said = camera_models(model, pr) + "; focal length " + yes_no(o.refine.focal) + ", principal point " +
                     yes_no(o.refine.principal) + ", extra parameters " + yes_no(o.refine.distortion) + "; " +
                     count(static_cast<std::size_t>(n.shared_cameras), "camera") +
                     " shared by several images, refined once; ";
  if (pr.rigged())
    said += "rig_from_world of " + count(static_cast<std::size_t>(n.frames), "frame") + " (" +
            std::to_string(n.held_frames) + " held), sensor_from_rig of " +
            count(static_cast<std::size_t>(n.sensors), "camera") + " (" + std::to_string(n.held_sensors) + " held); ";
  said += count(static_cast<std::size_t>(n.held_poses), "pose") + " held";
  if (!o.hold_intrinsics.empty())
    said += "; intrinsics of " + count(static_cast<std::size_t>(n.held_intrinsics), "camera") + " held";
  if (!o.hold_points.empty() || !o.hold_points_file.empty())
    said += "; " + count(static_cast<std::size_t>(pr.held_points()), "point") + " held";
  said += gauge_said(n.gauge);
  return said;
}

bool load_colmap(const Options &o, const std::string &, Loaded *l, Job *job, std::string *error) {
  colmap::DepthFilter behind;
  if (!read_colmap_input(o, l, &behind, error)) return false;
  colmap::Options options;
  options.intrinsics = o.refine;
  options.poses = o.poses;
  options.mcon = o.solve.mcon;
  options.ncon = o.solve.ncon;
  options.gauge = gauge_of(o, l->model_priors);
  if (!constants_of(o, l->model, &options.constants, error) ||
      !colmap::Problem::build(l->model, options, o.input, &l->colmap_problem, error))
    return false;
  const colmap::Problem &pr = l->colmap_problem;
  colmap_job(pr, job);
  job->ncon = pr.held_points();
  if (!attach_priors(o, l->model_priors, l, job, error)) return false;
  // The library can only say that the initial error is not finite; the model can say where.
  if (o.solve.itmax > 0) {
    *error = pr.nonfinite_error(l->model, o.input);
    if (!error->empty()) return false;
  }
  char line[512];
  std::snprintf(line, sizeof line, "COLMAP model %s (%s): %zu images, %zu cameras, %d points",
                o.input.c_str(), l->encoding == colmap::Encoding::Text ? "text" : "binary", l->model.images.size(),
                l->model.cameras.size(), job->in.n);
  job->summary = line;
  // A folder may hold both encodings: the one not read is named, so that no one takes its
  // values for the ones refined.
  if (l->encoding == colmap::Encoding::Binary && colmap::has_model(o.input, colmap::Encoding::Text))
    job->summary += "\nThe text model beside it is not read: binary is read first, as COLMAP does";
  job->summary += removed_behind(behind);
  job->summary += unseen_images(l->model, pr);
  job->summary += l->priors_said;
  if (pr.rigged())
    job->summary += "\nRigs and frames (COLMAP 4): " + count(l->model.rigs.size(), "rig") + ", " +
                    count(l->model.frames.size(), "frame") + ", " +
                    std::to_string(colmap::frames_of_several_images(l->model)) + " of several images: refined as COLMAP 4 refines them, a frame's pose once for its images, "
                    "a camera's pose in its rig once for its frames (a rig's reference camera at the identity), "
                    "written back to the frames and the rigs and composed into the images";
  else if (l->model.has_rigs)
    job->summary +=
        "\nRigs and frames (COLMAP 4): " + count(l->model.rigs.size(), "rig") + ", " +
        count(l->model.frames.size(), "frame") +
        " of one image at most: each image's pose is its frame's, refined and written back to both";
  job->model = what_is_refined(o, l->model, pr);
  job->summary += "\nCamera models: " + job->model;
  job->initial = cloud(l->model);
  for (int j : pr.images()) job->camera_names.push_back(l->model.images[static_cast<std::size_t>(j)].name);
  job->covariance = colmap_covariance(o, l);
  job->finish = [&o, l](const double *p, Cloud *final_cloud, sbaformats::OutputSet *outputs,
                        std::string *why) {
    const colmap::Problem &problem = l->colmap_problem;
    if (o.solve.itmax > 0) problem.apply(p, &l->model);
    *final_cloud = cloud(l->model);
    if (!o.write_eucsba.empty() && !write_eucsba_colmap(o.write_eucsba, problem, p, outputs, why)) return false;
    if (o.write.empty()) return true;
    const colmap::Encoding out =
        o.write_format.empty() ? l->encoding
                               : (o.write_format == "text" ? colmap::Encoding::Text : colmap::Encoding::Binary);
    return outputs->publish_last([&] { return colmap::write_model(o.write, l->model, out, why, outputs); });
  };
  return true;
}

bool load_nvm(const Options &o, const std::string &text, Loaded *l, Job *job, std::string *error) {
  if (!nvm::parse_nvm(text, o.input, &l->nvm, error) ||
      !nvm::to_sba(l->nvm, o.refine.focal, o.input, &l->problem, error))
    return false;
  // A warning, not a refusal: the solve still runs, and its error says how badly it fits.
  if (nvm::looks_uncentred(l->nvm))
    l->warning = "sbarefine: warning: " + o.input +
                 ": the measurements look measured from the image corner, not from its centre as NVM's are (99% "
                 "of them have x >= 0 and y >= 0); COLMAP writes NVM files so, and they do not refine to a small "
                 "error";
  eucsba_job(l, job);
  job->summary = "NVM file " + o.input + ": " + std::to_string(job->in.m) + " cameras, " + std::to_string(job->in.n) +
                 " points";
  job->summary += std::string("\nIntrinsics refined: ") + (o.refine.focal ? "focal" : "none") + " (nccalib " +
                  std::to_string(l->problem.nccalib) +
                  "); radial distortion held: VisualSFM applies it to the measurements, which sba takes as data";
  job->initial = cloud(l->nvm);
  for (const nvm::Camera &c : l->nvm.cameras) job->camera_names.push_back(c.name);
  job->finish = [&o, l](const double *p, Cloud *final_cloud, sbaformats::OutputSet *outputs,
                        std::string *why) {
    if (o.solve.itmax > 0) nvm::from_sba(*l->sba_model, p, o.solve.mcon, o.solve.ncon, &l->nvm);
    *final_cloud = cloud(l->nvm);
    if (!o.write_eucsba.empty() && !write_eucsba(o.write_eucsba, *l, p, outputs, why)) return false;
    return o.write.empty() ||
           outputs->publish_last([&] { return nvm::write_nvm(o.write, l->nvm, why, outputs); });
  };
  return true;
}

bool load_bundle(const Options &o, const std::string &text, Loaded *l, Job *job, std::string *error) {
  if (!bundler::parse_bundle(text, o.input, &l->bundle, error)) return false;
  if (!o.bundler_list.empty()) {
    if (!bundler::read_list(o.bundler_list, &l->list, error)) return false;
    if (l->list.names.size() != l->bundle.cameras.size()) {
      *error = o.bundler_list + ": " + std::to_string(l->list.names.size()) + " images for the " +
               std::to_string(l->bundle.cameras.size()) + " cameras of " + o.input;
      return false;
    }
  }
  if (!bundler::to_bal(l->bundle, o.input, &l->bal, &l->bundle_cameras, error, l->list.names) ||
      !bal::to_sba(l->bal, o.input, &l->layout, error))
    return false;
  job->in.m = l->layout.m;
  job->in.n = l->layout.n;
  job->in.cnp = bal_camera::kCameraParams;
  job->in.vis = &l->layout.vis;
  job->in.x = l->layout.x.data();
  job->p = l->layout.p;
  job->in.func = bal_camera::motstr_func;
  job->in.fjac = bal_camera::motstr_fjac;
  l->bal_data.ncameras = job->in.m;
  job->in.adata = &l->bal_data;
  const int m = job->in.m;
  job->project = [m](const double *p, int j, int i, double x[2]) {
    bal_camera::project(p + static_cast<std::size_t>(j) * bal_camera::kCameraParams,
                 p + static_cast<std::size_t>(m) * bal_camera::kCameraParams + 3 * static_cast<std::size_t>(i), x);
    return true;
  };
  job->summary = "Bundler file " + o.input + ": " + std::to_string(l->bundle.cameras.size()) + " cameras (" +
                 std::to_string(m) + " registered), " + std::to_string(job->in.n) + " points";
  if (!o.bundler_list.empty()) job->summary += ", images listed in " + o.bundler_list;
  if (!l->list.names.empty())
    for (int j : l->bundle_cameras) job->camera_names.push_back(l->list.names[static_cast<std::size_t>(j)]);
  job->initial = cloud(l->bundle);
  job->finish = [&o, l](const double *p, Cloud *final_cloud, sbaformats::OutputSet *outputs,
                        std::string *why) {
    if (o.solve.itmax > 0) {
      bal::from_sba_params(p, &l->bal);
      bundler::from_bal(l->bal, l->bundle_cameras, o.solve.mcon, o.solve.ncon, &l->bundle);
    }
    *final_cloud = cloud(l->bundle);
    if (!o.write_bal.empty() && !bal::write_problem(o.write_bal, l->bal, why, outputs)) return false;
    if (!o.write_list.empty() && !sbaformats::write_whole_file(o.write_list, l->list.text, why, outputs))
      return false;
    return o.write.empty() ||
           outputs->publish_last([&] { return bundler::write_bundle(o.write, l->bundle, why, outputs); });
  };
  return true;
}

// Every output, before anything is read (--write is a model directory for a directory):
// kExitFailure, said, if one cannot be written, else -1.
int check_outputs(const Options &o, const Input &input) {
  const std::string write_file = input.directory ? "" : o.write;
  const std::string eucsba_cams = o.write_eucsba.empty() ? "" : o.write_eucsba + "-cams.txt";
  const std::string eucsba_pts = o.write_eucsba.empty() ? "" : o.write_eucsba + "-pts.txt";
  if (!sbacli::outputs_writable({&write_file, &eucsba_cams, &eucsba_pts, &o.solve.json, &o.initial_ply,
                                  &o.final_ply, &o.write_bal, &o.write_list, &o.covariance}))
    return kExitFailure;
  if (input.directory && !o.write.empty()) {
    colmap::Encoding encoding = o.write_format == "binary" ? colmap::Encoding::Binary : colmap::Encoding::Text;
    std::string unknown, error;  // no model to write: its reader says why later
    if ((!o.write_format.empty() || colmap::model_encoding(o.input, &encoding, &unknown)) &&
        !colmap::model_writable(o.write, encoding, &error)) {
      std::fprintf(stderr, "%s\n", error.c_str());
      return kExitFailure;
    }
  }
  return -1;
}

// The options given for another format than the input's, or missing what they need:
// kExitUsage, said, else -1 with the defaults that depend on the format resolved.
int check_format_options(Format format, Options *o) {
  // An option of another format: named with the formats it is for.
  const struct {
    bool given, allowed;
    const char *option, *formats;
  } kFormatOptions[] = {
      {!o->write_format.empty(), format == Format::Colmap, "--write-format", "COLMAP models"},
      {!o->covariance.empty(), format == Format::Colmap, "--covariance", "COLMAP models"},
      {!o->write_eucsba.empty(), format != Format::Bundler, "--write-eucsba", "COLMAP models and NVM files"},
      {!o->write_bal.empty(), format == Format::Bundler, "--write-bal", "Bundler files"},
      {!o->bundler_list.empty(), format == Format::Bundler, "--bundler-list", "Bundler files"},
      {!o->write_list.empty(), format == Format::Bundler, "--write-list", "Bundler files"},
      {!o->hold_poses.empty(), format == Format::Colmap, "--hold-poses", "COLMAP models"},
      {!o->hold_poses_file.empty(), format == Format::Colmap, "--hold-poses-file", "COLMAP models"},
      {!o->gauge.empty(), format == Format::Colmap, "--gauge", "COLMAP models"},
      {!o->hold_intrinsics.empty(), format == Format::Colmap, "--hold-intrinsics", "COLMAP models"},
      {!o->hold_sensors.empty(), format == Format::Colmap, "--hold-sensor-from-rig", "COLMAP models"},
      {!o->hold_points.empty(), format == Format::Colmap, "--hold-points", "COLMAP models"},
      {!o->hold_points_file.empty(), format == Format::Colmap, "--hold-points-file", "COLMAP models"},
      {!o->database_path.empty(), format == Format::Colmap, "--database-path", "COLMAP models"},
      {!o->pose_priors.empty(), format == Format::Colmap, "--pose-priors", "COLMAP models"},
      {!o->point_priors.empty(), format == Format::Colmap, "--point-priors", "COLMAP models"},
      {!o->intrinsics_priors.empty(), format == Format::Colmap, "--intrinsics-priors", "COLMAP models"},
      {o->poses_given, format == Format::Colmap, "--refine-rig-from-world (or --refine-sensor-from-rig, "
       "--constant-rig-from-world-rotation)", "COLMAP models"},
      {o->intrinsics_given, format != Format::Bundler, "--intrinsics (or --refine-*)",
       "COLMAP models and NVM files (a bundle's f, k1 and k2 are always refined)"}};
  for (const auto &opt : kFormatOptions)
    if (opt.given && !opt.allowed) {
      std::fprintf(stderr, "sbarefine: %s is for %s\n", opt.option, opt.formats);
      return kExitUsage;
    }
  resolve_defaults(format == Format::Colmap, o);
  if ((o->covariance_options.points || o->covariance_damping_given) && o->covariance.empty()) {
    std::fprintf(stderr, "sbarefine: --covariance-points and --covariance-damping are for --covariance, which is "
                         "not given\n");
    return kExitUsage;
  }
  if (!o->database_path.empty() && !o->pose_priors.empty()) {
    std::fprintf(stderr, "sbarefine: --database-path and --pose-priors are two sources of the same priors: give one\n");
    return kExitUsage;
  }
  if (o->prior_options_given && o->database_path.empty() && o->pose_priors.empty()) {
    std::fprintf(stderr, "sbarefine: --prior-position-* and --alignment-max-error are for the position priors of "
                         "--database-path or --pose-priors, neither of which is given\n");
    return kExitUsage;
  }
  if (!o->write_list.empty() && o->bundler_list.empty()) {
    std::fprintf(stderr, "sbarefine: --write-list writes the list of --bundler-list, which is not given\n");
    return kExitUsage;
  }
  if (format == Format::Nvm && o->refine.principal) {
    std::fprintf(stderr, "sbarefine: --intrinsics %s: an NVM file has no principal point (its measurements are "
                         "relative to the image centre)\n", o->intrinsics.c_str());
    return kExitUsage;
  }
  return -1;
}

// The input's text (a file's rest, after open_input's look at its start) into the job.
bool load_input(const Options &o, Input *input, Loaded *loaded, Job *job, std::string *error) {
  bool (*const load)(const Options &, const std::string &, Loaded *, Job *, std::string *) =
      input->format == Format::Bundler ? load_bundle : input->format == Format::Nvm ? load_nvm : load_colmap;
  return (!input->file || colmap::read_rest(input->file, o.input, true, &input->text, error)) &&
         load(o, input->text, loaded, job, error);
}

// The solve (none with --itmax 0, which rewrites and converts the model as read), then every
// output: the program's exit status.
int solve_and_write(const Options &o, Job &job, double read_seconds) {
  job.in.p = job.p.data();
  sbacli::SolveOptions so = o.solve;
  if (job.ncon >= 0) so.ncon = job.ncon;
  sbacli::MotstrSolve solve("sbarefine", o.input, so, job.in);
  solve.describe(job.model);
  if (const int status = solve.check_fixed(); status >= 0) return status;
  // What was read, at once: a large model takes long to solve, and a user sees its sizes first.
  const std::size_t eol = job.summary.find('\n');
  std::printf("%s, %d observations, %lld unknowns (%lld parameters, held ones and each copy of a shared one "
              "included)%s\n",
              job.summary.substr(0, eol).c_str(), solve.observations(), solve.unknowns(), solve.variables(),
              eol == std::string::npos ? "" : job.summary.substr(eol).c_str());
  std::fflush(stdout);
  const std::vector<double> &p = job.p;
  const auto project = [&](int j, int i, double x[2]) { return job.project(p.data(), j, i, x); };
  solve.report_mean_error(project);
  // Every file of the run is published at its end, together, or none is (output_file.h).
  sbaformats::OutputSet outputs;
  if (!sbacli::write_ply_option(o.initial_ply, job.initial, &outputs)) return kExitFailure;
  if (o.solve.itmax == 0)
    solve.score(project);
  else if (!solve.run())
    return kExitFailure;

  Cloud final_cloud;
  std::string error;
  sbacli::TtyPhase writing(o.solve.progress && !o.write.empty(), "writing " + o.write);
  const bool written = job.finish(p.data(), &final_cloud, &outputs, &error);
  writing.end();
  if (!written) {
    std::fprintf(stderr, "%s\n", error.c_str());
    return kExitFailure;
  }
  if (!sbacli::write_ply_option(o.final_ply, final_cloud, &outputs)) return kExitFailure;
  if (!o.covariance.empty() && !solve.covariance(o.covariance, [&](const sba_ext_options &ext, std::string *why) {
        return job.covariance(p.data(), ext, &outputs, why);
      }))
    return kExitFailure;
  return solve.finish(read_seconds, project, job.camera_names, o.write, &outputs);
}

int refine_main(int argc, char **argv) {
  Options o;
  std::string error;
  const bool parsed = parse_command_line(argc, argv, &o, &error);
  if (const int status = sbacli::answer_command_line("sbarefine", parsed, error, o.help, o.version, print_usage);
      status >= 0)
    return status;
  Input input;
  if (!look_at_input(o.input, &input, &error)) {
    std::fprintf(stderr, "%s\n", error.c_str());
    return kExitFailure;
  }
  if (const int status = check_outputs(o, input); status >= 0) return status;

  const auto read_start = std::chrono::steady_clock::now();
  if (!input.directory && !open_input(o.input, &input, &error)) {
    std::fprintf(stderr, "%s\n", error.c_str());
    return kExitFailure;
  }
  if (const int status = check_format_options(input.format, &o); status >= 0) return status;
  Loaded loaded;
  Job job;
  sbacli::TtyPhase reading(o.solve.progress, "reading " + o.input);
  const bool read = load_input(o, &input, &loaded, &job, &error);
  reading.end();
  if (!read) {
    std::fprintf(stderr, "%s\n", error.c_str());
    return kExitFailure;
  }
  if (!loaded.warning.empty()) std::fprintf(stderr, "%s\n", loaded.warning.c_str());
  const double read_seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - read_start).count();
  return solve_and_write(o, job, read_seconds);
}

}  // namespace

int main(int argc, char **argv) { return sbacli::guarded_main("sbarefine", refine_main, argc, argv); }
