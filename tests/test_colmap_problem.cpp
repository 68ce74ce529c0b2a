// SPDX-License-Identifier: BSD-3-Clause
// The COLMAP problem (formats/colmap_problem.h) on small models made in memory: what the builder
// gives the solve (p0, the held flags, the parameter groups, the counts), apply writing by id
// with held values keeping their bits, the pose an image derives from its frame, COLMAP's
// stopping rule, and one solve through the problem's arrays and callbacks.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include "cameras/colmap_camera.h"
#include "cameras/rigid_pose.h"
#include "colmap_tangent.h"
#include "formats/colmap_io.h"
#include "formats/colmap_problem.h"
#include "sba.h"
#include "sba_ext.h"

namespace {

namespace colmap = sbaformats::colmap;
namespace cc = sbacameras::colmap_camera;

std::array<double, 4> turn(double angle, double x, double y, double z) {
  const double s = std::sin(angle / 2);
  return {std::cos(angle / 2), s * x, s * y, s * z};
}

// Two cameras: PINHOLE 7 shared by images 20 and 11, SIMPLE_RADIAL 3 of image 5; image 9 (of
// camera 3) sees no point. Six points, ids 1000 + 7k, each seen by images 20, 11 and 5 (in that
// order in its track, the images' order being 20, 11, 5, 9). The measurements are placeholders
// until observe() sets them.
colmap::Model plain_model() {
  colmap::Model m;
  m.cameras = {{7, colmap::kPinhole, 640, 480, {500, 510, 320, 240}},
               {3, colmap::kSimpleRadial, 640, 480, {450, 320, 240, 0.01}}};
  const std::uint32_t ids[] = {20, 11, 5, 9}, cameras[] = {7, 7, 3, 3};
  for (int k = 0; k < 4; ++k) {
    colmap::Image im;
    im.id = ids[k];
    im.camera_id = cameras[k];
    im.name = "image" + std::to_string(ids[k]) + ".png";
    im.q = turn(0.05 * k, 0, 1, 0);
    im.t = {-0.4 * k, 0.05 * k, 0.1};
    m.images.push_back(im);
  }
  for (int i = 0; i < 6; ++i) {
    colmap::Point3D pt;
    pt.id = 1000 + 7 * static_cast<std::uint64_t>(i);
    pt.xyz = {-0.5 + 0.3 * i, 0.2 * (i % 3) - 0.2, 5 + 0.25 * i};
    pt.rgb = {10, 20, 30};
    pt.error = 1;
    for (int k = 0; k < 3; ++k) {
      colmap::Image &im = m.images[static_cast<std::size_t>(k)];
      pt.track.push_back({im.id, static_cast<std::uint32_t>(im.points.size())});
      im.points.push_back({0, 0, pt.id});
    }
    m.points.push_back(pt);
  }
  return m;
}

// The model with a rig of its two cameras (camera 7 the reference, camera 3 at a pose in the
// rig) and two frames: frame 40 of images 20 and 5, frame 41 of images 11 and 9.
colmap::Model rig_model() {
  colmap::Model m = plain_model();
  m.has_rigs = true;
  colmap::Rig rig;
  rig.id = 2;
  rig.sensors.push_back({{colmap::SensorType::Camera, 7}, false, {}});
  rig.sensors.push_back({{colmap::SensorType::Camera, 3}, true, {turn(0.1, 0, 1, 0), {-0.5, 0, 0.02}}});
  m.rigs.push_back(rig);
  m.frames.push_back({40, 2, {turn(0.02, 1, 0, 0), {0.1, 0, 0.05}}, {}});
  m.frames.push_back({41, 2, {turn(0.03, 0, 1, 0), {-0.3, 0.05, 0.1}}, {}});
  m.frames[0].data = {{{colmap::SensorType::Camera, 7}, 20}, {{colmap::SensorType::Camera, 3}, 5}};
  m.frames[1].data = {{{colmap::SensorType::Camera, 7}, 11}, {{colmap::SensorType::Camera, 3}, 9}};
  return m;
}

colmap::Problem build(const colmap::Model &m, const colmap::Options &o = {}) {
  std::string error;
  EXPECT_TRUE(colmap::check_model(m, "model", &error)) << error;
  colmap::Problem pr;
  EXPECT_TRUE(colmap::Problem::build(m, o, "model", &pr, &error)) << error;
  return pr;
}

// The model's measurements set to the projections of its points at the start, so that the
// start is a solution.
void observe(colmap::Model *m) {
  const colmap::Problem pr = build(*m);
  const colmap::Problem &p = pr;
  const sbaformats::Visibility &v = p.points().pairs;
  for (std::size_t k = 0; k < v.size(); ++k) {
    const int i = v.point[k], j = v.camera[k];
    const colmap::Image &seen = m->images[static_cast<std::size_t>(p.images()[static_cast<std::size_t>(j)])];
    for (const colmap::TrackElement &e : m->points[static_cast<std::size_t>(i)].track) {
      if (e.image_id != seen.id) continue;
      double x[2];
      p.project(p.initial_params().data(), j, i, x);
      for (colmap::Image &im : m->images)
        if (im.id == e.image_id) im.points[e.point2d_idx] = {x[0], x[1], m->points[static_cast<std::size_t>(i)].id};
    }
  }
}

TEST(ColmapProblem, PlainModelLayout) {
  const colmap::Model m = plain_model();
  const colmap::Problem pr = build(m);
  EXPECT_FALSE(pr.rigged());
  EXPECT_EQ(pr.images(), (std::vector<int>{0, 1, 2}));  // image 9 sees no point
  EXPECT_EQ(pr.ncameras(), 3);
  EXPECT_EQ(pr.npoints(), 6);
  // A camera's vector carries the parameters refined: PINHOLE's fx, fy, SIMPLE_RADIAL's f, k.
  const int cnp = pr.cnp();
  EXPECT_EQ(cnp, cc::camera_params(2));
  ASSERT_EQ(pr.initial_params().size(), static_cast<std::size_t>(3 * cnp + 18));
  // The start: v = 0, the translations, the cameras' parameters, the points.
  EXPECT_EQ(pr.initial_params()[5], 0.1);  // image 20's t: (0, 0, 0.1)
  EXPECT_EQ(pr.initial_params()[static_cast<std::size_t>(cnp) + 3], -0.4);
  EXPECT_EQ(pr.initial_params()[static_cast<std::size_t>(2 * cnp) + 6], 450);
  EXPECT_EQ(pr.initial_params()[static_cast<std::size_t>(3 * cnp) + 2], 5);
  // Camera 7's parameters are one group, of its first sba camera (0); the poses are in none.
  const std::vector<int> &g = pr.cam_param_group();
  for (int j = 0; j < 3; ++j)
    for (int c = 0; c < cnp; ++c)
      EXPECT_EQ(g[static_cast<std::size_t>(j * cnp + c)], c >= 6 && j < 2 ? 0 : -1) << j << " " << c;
  // COLMAP's defaults: the focal length and the extra parameters refined, the principal point
  // held, and so not carried; the padding held.
  const std::vector<char> &f = pr.cam_fixed();
  const std::vector<char> pinhole = {0, 0, 0, 0, 0, 0, 0, 0, 1}, radial = {0, 0, 0, 0, 0, 0, 0, 0, 1};
  ASSERT_EQ(cnp, 9);
  EXPECT_EQ(std::vector<char>(f.begin(), f.begin() + cnp), pinhole);
  EXPECT_EQ(std::vector<char>(f.begin() + 2 * cnp, f.end()), radial);
  EXPECT_EQ(pr.initial_params()[static_cast<std::size_t>(2 * cnp) + 7], 0.01);  // camera 3's k
  // Where each COLMAP parameter is: camera 7's (PINHOLE) fx fy at 6, 7, its cx cy nowhere;
  // camera 3's (SIMPLE_RADIAL) f at 6, k at 7, of its sba camera 2.
  int j = -1, column = -2;
  const std::pair<int, int> pinhole_at[] = {{0, 6}, {1, 7}, {2, -1}, {3, -1}};
  for (const auto &[k, at] : pinhole_at) {
    ASSERT_TRUE(pr.camera_parameter(7, k, &j, &column));
    EXPECT_EQ(j, 0);
    EXPECT_EQ(column, at) << k;
    EXPECT_EQ(pr.held(j, column), at < 0) << k;
  }
  const std::pair<int, int> radial_at[] = {{0, 6}, {1, -1}, {2, -1}, {3, 7}};
  for (const auto &[k, at] : radial_at) {
    ASSERT_TRUE(pr.camera_parameter(3, k, &j, &column));
    EXPECT_EQ(j, 2);
    EXPECT_EQ(column, at) << k;
  }
  EXPECT_EQ(pr.counts().shared_cameras, 1);
  EXPECT_EQ(pr.counts().held_poses, 0);
  EXPECT_EQ(pr.held_points(), 0);
  EXPECT_EQ(pr.func(), cc::motstr_func);
  EXPECT_EQ(pr.nonfinite_error(m, "model"), "");
}

TEST(ColmapProblem, HeldPosesAndConstants) {
  const colmap::Model m = plain_model();
  colmap::Options o;
  o.constants.poses = {0, 1, 0, 1};       // images 11 (seen) and 9 (unseen)
  o.constants.intrinsics = {1, 0};        // camera 7
  o.constants.points = {0, 0, 0, 1, 0, 0};  // point 1021
  o.ncon = 1;
  const colmap::Problem pr = build(m, o);
  const int cnp = pr.cnp();
  const std::vector<char> &f = pr.cam_fixed();
  for (int c = 0; c < 6; ++c) {
    EXPECT_EQ(f[static_cast<std::size_t>(c)], 0) << c;
    EXPECT_EQ(f[static_cast<std::size_t>(cnp + c)], 1) << c;
  }
  // Camera 7 held in both its images, and then in no group.
  for (int c = 6; c < cnp; ++c) {
    EXPECT_EQ(f[static_cast<std::size_t>(c)], 1) << c;
    EXPECT_EQ(pr.cam_param_group()[static_cast<std::size_t>(c)], -1) << c;
  }
  EXPECT_EQ(pr.counts().held_poses, 2);
  EXPECT_EQ(pr.counts().held_intrinsics, 1);
  EXPECT_EQ(pr.counts().shared_cameras, 0);
  // The first point and the constant one lead, held.
  EXPECT_EQ(pr.held_points(), 2);
  const double *b = pr.initial_params().data() + 3 * cnp;
  EXPECT_EQ(b[3 * 1 + 2], m.points[3].xyz[2]);
  EXPECT_EQ(b[3 * 2 + 2], m.points[1].xyz[2]);
}

// apply writes by id: into a copy of the model whose records are in another order, the same
// values as into the model itself; held values keep their bits, however p moved them.
TEST(ColmapProblem, ApplyWritesById) {
  colmap::Model m = plain_model();
  observe(&m);
  colmap::Options o;
  o.constants.poses = {0, 1, 0, 0};  // image 11
  const colmap::Problem pr = build(m, o);
  const int cnp = pr.cnp();
  std::vector<double> p = pr.initial_params();
  for (double &v : p) v += 1e-3;  // every parameter, held ones too
  colmap::Model in_order = m, shuffled = m;
  std::reverse(shuffled.cameras.begin(), shuffled.cameras.end());
  std::reverse(shuffled.images.begin(), shuffled.images.end());
  std::reverse(shuffled.points.begin(), shuffled.points.end());
  pr.apply(p.data(), &in_order);
  pr.apply(p.data(), &shuffled);
  std::reverse(shuffled.cameras.begin(), shuffled.cameras.end());
  std::reverse(shuffled.images.begin(), shuffled.images.end());
  std::reverse(shuffled.points.begin(), shuffled.points.end());
  EXPECT_EQ(colmap::format_model(in_order, colmap::Encoding::Binary).images,
            colmap::format_model(shuffled, colmap::Encoding::Binary).images);
  EXPECT_EQ(colmap::format_model(in_order, colmap::Encoding::Binary).cameras,
            colmap::format_model(shuffled, colmap::Encoding::Binary).cameras);
  EXPECT_EQ(colmap::format_model(in_order, colmap::Encoding::Binary).points,
            colmap::format_model(shuffled, colmap::Encoding::Binary).points);
  // Image 20 moved: its translation is p's.
  EXPECT_EQ(in_order.images[0].t[2], p[5]);
  // Image 11 held, and image 9 unseen: their bits as read.
  for (std::size_t i : {1, 3}) {
    EXPECT_EQ(in_order.images[i].q, m.images[i].q) << i;
    EXPECT_EQ(in_order.images[i].t, m.images[i].t) << i;
  }
  // Camera 7 from its first sba camera: f, fy refined, cx cy held; camera 3's k refined.
  EXPECT_EQ(in_order.cameras[0].params[0], p[6]);
  EXPECT_EQ(in_order.cameras[0].params[1], p[7]);
  EXPECT_EQ(in_order.cameras[0].params[2], 320);
  EXPECT_EQ(in_order.cameras[1].params[3], p[static_cast<std::size_t>(2 * cnp) + 7]);
  EXPECT_EQ(in_order.cameras[1].params[1], 320);
  // The points and their errors: each point's mean distance to its measurements.
  EXPECT_EQ(in_order.points[2].xyz[0], p[static_cast<std::size_t>(3 * cnp) + 6]);
  EXPECT_GT(in_order.points[2].error, 0);
  EXPECT_LT(in_order.points[2].error, 50);
  // At p0 a point's error is that of a model observed at the start: 0 to rounding.
  colmap::Model at_start = m;
  pr.apply(pr.initial_params().data(), &at_start);
  for (const colmap::Point3D &pt : at_start.points) EXPECT_LT(pt.error, 1e-9);
}

TEST(ColmapProblem, ApplyRefusesAModelWithoutTheIds) {
  const colmap::Model m = plain_model();
  const colmap::Problem pr = build(m);
  colmap::Model other = m;
  other.images[0].id = 21;
  EXPECT_THROW(pr.apply(pr.initial_params().data(), &other), std::invalid_argument);
}

TEST(ColmapProblem, RigLayout) {
  const colmap::Model m = rig_model();
  const colmap::Problem pr = build(m);
  ASSERT_TRUE(pr.rigged());
  EXPECT_EQ(pr.func(), cc::rig_motstr_func);
  EXPECT_EQ(pr.images(), (std::vector<int>{0, 1, 2}));
  const int cnp = pr.cnp();
  EXPECT_EQ(cnp, cc::rig_camera_params(4));
  const std::vector<int> &g = pr.cam_param_group();
  const std::vector<char> &f = pr.cam_fixed();
  const auto at = [&](int j, int c) { return static_cast<std::size_t>(j * cnp + c); };
  // The frame pose by frame (20 and 5 in frame 40, index 0; 11 in frame 41, index 1).
  const int frame[] = {0, 1, 0};
  for (int j = 0; j < 3; ++j)
    for (int c = 0; c < 6; ++c) EXPECT_EQ(g[at(j, c)], frame[j]) << j << " " << c;
  // The sensor pose: the reference camera's held at the identity, camera 3's in its group.
  for (int c = 6; c < 12; ++c) {
    EXPECT_EQ(f[at(0, c)], 1);
    EXPECT_EQ(g[at(0, c)], -1);
    EXPECT_EQ(f[at(2, c)], 0);
    EXPECT_EQ(g[at(2, c)], 1);  // camera 3's index among the cameras
  }
  EXPECT_EQ(g[at(0, 12)], 0);
  EXPECT_EQ(g[at(1, 12)], 0);
  EXPECT_EQ(g[at(2, 12)], 1);
  const colmap::Problem::Counts &n = pr.counts();
  EXPECT_EQ(n.frames, 2);
  EXPECT_EQ(n.sensors, 1);
  EXPECT_EQ(n.held_frames, 0);
  EXPECT_EQ(n.unseen_moved, 1);  // image 9 moves with frame 41
  EXPECT_EQ(n.shared_cameras, 1);
}

// An image's pose in a rig model is its frame's and its camera's, composed: it follows what
// apply writes, for the unseen image too; a held image holds its frame and its camera's pose in
// the rig bit for bit.
TEST(ColmapProblem, RigApplyAndDerivedPoses) {
  colmap::Model m = rig_model();
  observe(&m);
  colmap::Options o;
  o.constants.poses = {0, 1, 0, 0};  // image 11: frame 41 held
  const colmap::Problem pr = build(m, o);
  std::vector<double> p = pr.initial_params();
  for (double &v : p) v += 1e-3;
  colmap::Model out = m;
  pr.apply(p.data(), &out);
  EXPECT_EQ(out.frames[1].rig_from_world.q, m.frames[1].rig_from_world.q);
  EXPECT_EQ(out.frames[1].rig_from_world.t, m.frames[1].rig_from_world.t);
  EXPECT_EQ(out.frames[0].rig_from_world.t[0], p[3]);  // frame 40 from image 20
  // Image 11's camera 7 is the reference; camera 3's pose in the rig is refined (image 5).
  EXPECT_NE(out.rigs[0].sensors[1].sensor_from_rig.t, m.rigs[0].sensors[1].sensor_from_rig.t);
  const std::vector<colmap::Pose> poses = colmap::image_poses(out);
  for (std::size_t i = 0; i < 4; ++i) {
    const std::size_t frame = i == 0 || i == 2 ? 0 : 1;
    const colmap::Pose want = i < 2 ? out.frames[frame].rig_from_world
                                    : sbacameras::compose(out.rigs[0].sensors[1].sensor_from_rig,
                                                          out.frames[frame].rig_from_world);
    EXPECT_EQ(poses[i].q, want.q) << i;
    EXPECT_EQ(poses[i].t, want.t) << i;
  }
  // The refined cameras project as the problem does.
  const colmap::Problem again = build(out);
  for (int j = 0; j < 3; ++j) {
    double a[2], b[2];
    pr.project(p.data(), j, 0, a);
    again.project(again.initial_params().data(), j, 0, b);
    EXPECT_NEAR(a[0], b[0], 1e-9);
    EXPECT_NEAR(a[1], b[1], 1e-9);
  }
}

// A model whose frames hold one image each, all refined, is refined as one without rigs: apply
// gives each frame the pose that composes to the refined image pose (the same bits for the
// reference camera).
TEST(ColmapProblem, FramesOfOneImage) {
  colmap::Model m = plain_model();
  m.has_rigs = true;
  m.rigs.push_back({2, {{{colmap::SensorType::Camera, 7}, false, {}},
                        {{colmap::SensorType::Camera, 3}, true, {turn(0.1, 0, 1, 0), {-0.5, 0, 0.02}}}}});
  for (const colmap::Image &im : m.images)
    m.frames.push_back({100 + im.id, 2, {im.q, im.t}, {{{colmap::SensorType::Camera, im.camera_id}, im.id}}});
  observe(&m);
  const colmap::Problem pr = build(m);
  ASSERT_FALSE(pr.rigged());
  std::vector<double> p = pr.initial_params();
  for (double &v : p) v += 1e-3;
  colmap::Model out = m;
  pr.apply(p.data(), &out);
  const std::vector<cc::Camera> cameras = pr.cameras(p.data());
  const std::vector<colmap::Pose> poses = colmap::image_poses(out);
  EXPECT_EQ(out.frames[0].rig_from_world.q, (std::array<double, 4>{cameras[0].q.w, cameras[0].q.x,
                                                                    cameras[0].q.y, cameras[0].q.z}));
  EXPECT_EQ(out.frames[0].rig_from_world.t, cameras[0].t);
  for (int k = 0; k < 3; ++k) {
    EXPECT_NEAR(poses[2].t[static_cast<std::size_t>(k)], cameras[2].t[static_cast<std::size_t>(k)], 1e-14);
    EXPECT_NEAR(poses[2].q[static_cast<std::size_t>(k) + 1],
                (std::array<double, 3>{cameras[2].q.x, cameras[2].q.y, cameras[2].q.z})[static_cast<std::size_t>(k)],
                1e-15);
  }
  // Image 9 sees no point: its frame as it was.
  EXPECT_EQ(out.frames[3].rig_from_world.t, m.frames[3].rig_from_world.t);
}

// A constant rig_from_world holds the frame's pose alone: the pose in the rig of a camera of the
// frame stays refined, where holding one of its images (constants.poses) holds that too. A frame
// of one image held while its camera's pose in the rig is refined makes the problem a rig's.
TEST(ColmapProblem, ConstantFramePoseAlone) {
  const colmap::Model m = rig_model();
  colmap::Options o;
  o.constants.frames = {1, 0};  // frame 40: images 20 and 5
  const colmap::Problem pr = build(m, o);
  ASSERT_TRUE(pr.rigged());
  for (int c = 0; c < 6; ++c) {
    EXPECT_TRUE(pr.held(0, c)) << c;
    EXPECT_TRUE(pr.held(2, c)) << c;
    EXPECT_FALSE(pr.held(1, c)) << c;
    EXPECT_FALSE(pr.held(2, 6 + c)) << c;  // camera 3's pose in the rig
  }
  colmap::Options image_held;
  image_held.constants.poses = {0, 0, 1, 0};  // image 5
  const colmap::Problem whole = build(m, image_held);
  for (int c = 0; c < 12; ++c) EXPECT_TRUE(whole.held(2, c)) << c;

  colmap::Model one = plain_model();
  one.has_rigs = true;
  one.rigs.push_back({2, {{{colmap::SensorType::Camera, 7}, false, {}},
                          {{colmap::SensorType::Camera, 3}, true, {turn(0.1, 0, 1, 0), {-0.5, 0, 0.02}}}}});
  for (const colmap::Image &im : one.images)
    one.frames.push_back({100 + im.id, 2, {im.q, im.t}, {{{colmap::SensorType::Camera, im.camera_id}, im.id}}});
  EXPECT_FALSE(build(one).rigged());
  colmap::Options frame_held;
  frame_held.constants.frames = {0, 0, 1, 0};  // image 5's frame
  const colmap::Problem rigged = build(one, frame_held);
  ASSERT_TRUE(rigged.rigged());
  for (int c = 0; c < 6; ++c) {
    EXPECT_TRUE(rigged.held(2, c)) << c;
    EXPECT_FALSE(rigged.held(2, 6 + c)) << c;
  }
}

// COLMAP's BundleAdjustmentConfig's images and points: each point of plain_model is seen by
// images 20, 11 and 5 (sba cameras in the model's order of the images that take part).
TEST(ColmapProblem, SelectionOfImagesAndPoints) {
  const colmap::Model m = plain_model();
  colmap::Options o;
  o.selection.images = {1, 0, 0, 0};  // image 20
  // Every point is seen beyond the config: held, with image 20's observations.
  colmap::Problem pr = build(m, o);
  EXPECT_EQ(pr.images(), (std::vector<int>{0}));
  EXPECT_EQ(pr.npoints(), 6);
  EXPECT_EQ(pr.held_points(), 6);
  EXPECT_EQ(pr.points().pairs.size(), 6u);
  // Variable points take every observation: images 11 and 5 join, their poses held, camera 7
  // (image 20's) refined in image 11 too, camera 3 (image 5's alone) held.
  o.selection.variable_points = {1, 1, 0, 0, 0, 0};
  // A constant point takes the observations of images with something refined: image 11's
  // (camera 7), not image 5's.
  o.constants.points = {0, 0, 1, 0, 0, 0};
  pr = build(m, o);
  EXPECT_EQ(pr.images(), (std::vector<int>{0, 1, 2}));
  EXPECT_EQ(pr.npoints(), 6);
  EXPECT_EQ(pr.held_points(), 4);
  EXPECT_EQ(pr.points().pairs.size(), 6u + 2 * 2 + 1);
  EXPECT_EQ(pr.point_id(4), 1000u);
  EXPECT_EQ(pr.point_id(5), 1007u);
  for (int c = 0; c < pr.cnp(); ++c) {
    EXPECT_EQ(pr.held(0, c), c >= 8) << c;            // PINHOLE: cx, cy and padding held
    EXPECT_EQ(pr.held(1, c), c < 6 || c >= 8) << c;   // the pose held, camera 7 refined
    EXPECT_TRUE(pr.held(2, c)) << c;                   // outside, camera 3 held
  }
  // apply writes only what the problem refines: point 1014 (held) keeps its bits.
  colmap::Model out = m;
  std::vector<double> p = pr.initial_params();
  for (double &v : p) v += 1e-3;
  pr.apply(p.data(), &out);
  EXPECT_EQ(out.points[2].xyz, m.points[2].xyz);
  EXPECT_EQ(out.points[2].error, m.points[2].error);
  EXPECT_NE(out.points[0].xyz, m.points[0].xyz);
  EXPECT_EQ(out.images[1].q, m.images[1].q);
  EXPECT_EQ(out.images[1].t, m.images[1].t);
  // A track shorter than min_track_length leaves its point out, whatever the lists say.
  o.selection.min_track_length = 4;
  colmap::Problem none;
  std::string error;
  EXPECT_FALSE(colmap::Problem::build(m, o, "model", &none, &error));
  EXPECT_EQ(error, "model: the configuration leaves no observation to refine");
}

// TWO_CAMS_FROM_WORLD over plain_model (images by IMAGE_ID: 5, 11, 20): image 5's pose held,
// and the coordinate of image 11's translation along which its centre lies farthest from image
// 5's, in image 5's camera coordinates; nothing when two poses are held already. THREE_POINTS
// holds the first three points (every track has three observations).
TEST(ColmapProblem, Gauges) {
  const colmap::Model m = plain_model();
  colmap::Options o;
  o.gauge = colmap::Gauge::TwoCamsFromWorld;
  const colmap::Problem pr = build(m, o);
  const colmap::Pose five{m.images[2].q, m.images[2].t}, eleven{m.images[1].q, m.images[1].t};
  const std::array<double, 3> centre = sbacameras::compose(five, sbacameras::inverse(eleven)).t;
  std::size_t k = 0;
  for (std::size_t c = 1; c < 3; ++c)
    if (std::abs(centre[c]) > std::abs(centre[k])) k = c;
  for (int c = 0; c < 6; ++c) {
    EXPECT_TRUE(pr.held(2, c)) << c;
    EXPECT_EQ(pr.held(1, c), c == 3 + static_cast<int>(k)) << c;
    EXPECT_FALSE(pr.held(0, c)) << c;
  }
  colmap::Model out = m;
  std::vector<double> p = pr.initial_params();
  for (double &v : p) v += 1e-3;
  pr.apply(p.data(), &out);
  EXPECT_EQ(out.images[1].t[k], m.images[1].t[k]);
  EXPECT_NE(out.images[1].t[(k + 1) % 3], m.images[1].t[(k + 1) % 3]);
  EXPECT_EQ(out.images[2].q, m.images[2].q);
  EXPECT_EQ(out.images[2].t, m.images[2].t);

  o.constants.poses = {1, 1, 0, 0};  // images 20 and 11: the gauge is fixed
  const colmap::Problem fixed = build(m, o);
  for (int c = 0; c < 6; ++c) EXPECT_FALSE(fixed.held(2, c)) << c;

  colmap::Options three;
  three.gauge = colmap::Gauge::ThreePoints;
  const colmap::Problem points = build(m, three);
  EXPECT_EQ(points.held_points(), 3);
  EXPECT_EQ(points.point_id(0), 1000u);
  EXPECT_EQ(points.point_id(2), 1014u);
  three.constants.points = {0, 0, 0, 0, 1, 1};
  EXPECT_EQ(build(m, three).held_points(), 3);
}

// THREE_POINTS over variable points of a config: the three points COLMAP holds become constant
// points, so their observations in images outside the config with nothing refined leave the
// problem. Config image 20, every point variable: image 11 (camera 7, refined by image 20)
// keeps every observation, image 5 (camera 3, held) loses the three held points'.
TEST(ColmapProblem, ThreePointsHeldAsConstantPoints) {
  const colmap::Model m = plain_model();
  colmap::Options o;
  o.selection.images = {1, 0, 0, 0};
  o.selection.variable_points = {1, 1, 1, 1, 1, 1};
  EXPECT_EQ(build(m, o).points().pairs.size(), 18u);
  o.gauge = colmap::Gauge::ThreePoints;
  const colmap::Problem pr = build(m, o);
  EXPECT_EQ(pr.held_points(), 3);
  EXPECT_EQ(pr.npoints(), 6);
  EXPECT_EQ(pr.points().pairs.size(), 15u);
  EXPECT_EQ(pr.images(), (std::vector<int>{0, 1, 2}));
}

TEST(ColmapProblem, NonFiniteStartNamesTheObservation) {
  colmap::Model m = plain_model();
  m.cameras[1].params[3] = 1e200;
  const colmap::Problem pr = build(m);
  EXPECT_EQ(pr.nonfinite_error(m, "model").rfind("model: image 5 (image5.png), camera 3 (SIMPLE_RADIAL): point 1000 "
                                                 "projects to (",
                                                 0),
            0u)
      << pr.nonfinite_error(m, "model");
}

TEST(ColmapProblem, NoImagesOrNoPoints) {
  colmap::Model m = plain_model();
  m.points.clear();
  for (colmap::Image &im : m.images) im.points.clear();
  colmap::Problem pr;
  std::string error;
  EXPECT_FALSE(colmap::Problem::build(m, {}, "dir", &pr, &error));
  EXPECT_EQ(error, "dir: the model has no images or no points");
}

TEST(ColmapProblem, StopRule) {
  const double ulp4 = 4 * std::numeric_limits<double>::epsilon();
  double eps1 = 1e-12, eps4 = 0;
  EXPECT_TRUE(colmap::colmap_stop_rule(-1, -1, false, &eps1, &eps4));  // COLMAP 4's defaults, 0 and 1e-4
  EXPECT_EQ(eps4, ulp4);
  EXPECT_EQ(eps1, 1e-4);
  eps1 = 1e-12;
  eps4 = 1e-9;
  EXPECT_FALSE(colmap::colmap_stop_rule(-1, -1, false, &eps1, &eps4));  // an eps4 given keeps sba's tests
  EXPECT_EQ(eps4, 1e-9);
  EXPECT_EQ(eps1, 1e-12);
  eps4 = 0;
  EXPECT_FALSE(colmap::colmap_stop_rule(-1, -1, true, &eps1, &eps4));  // so does a strategy
  EXPECT_EQ(eps4, 0);
  EXPECT_EQ(eps1, 1e-12);
  EXPECT_TRUE(colmap::colmap_stop_rule(1e-6, -1, true, &eps1, &eps4));
  EXPECT_EQ(eps4, 1e-6);
  EXPECT_EQ(eps1, 1e-4);
  eps1 = 1e-7;  // an eps1 given is kept
  eps4 = 0;
  EXPECT_TRUE(colmap::colmap_stop_rule(-1, -1, false, &eps1, &eps4));
  EXPECT_EQ(eps1, 1e-7);
  // A gradient tolerance given is eps1, whether the rule applies or not.
  eps4 = 0;
  EXPECT_TRUE(colmap::colmap_stop_rule(-1, 0, false, &eps1, &eps4));
  EXPECT_EQ(eps1, 0);
  eps4 = 1e-9;
  EXPECT_FALSE(colmap::colmap_stop_rule(-1, 1e-3, false, &eps1, &eps4));
  EXPECT_EQ(eps1, 1e-3);
  EXPECT_EQ(std::string(colmap::kColmapStrategy), "trust-region");
  EXPECT_EQ(colmap::kDefaultItmax, 100);
}

// The problem's arrays and callbacks are a solve: from points moved off a model observed
// exactly, the solve returns to a reprojection error of rounding, and apply gives back the model
// it was observed at.
TEST(ColmapProblem, SolvesThroughItsArrays) {
  for (const bool rigs : {false, true}) {
    SCOPED_TRACE(rigs ? "rig" : "plain");
    colmap::Model m = rigs ? rig_model() : plain_model();
    observe(&m);
    colmap::Options o;
    o.intrinsics = {false, false, false};
    o.constants.poses = {1, 0, 0, 0};  // a gauge: image 20 (in a rig, frame 40) held
    o.constants.points = {1, 0, 0, 0, 0, 0};
    const colmap::Problem pr = build(m, o);
    std::vector<double> p = pr.initial_params();
    const int cnp = pr.cnp();
    // The points but the held one (which the solve keeps wherever p puts it).
    for (std::size_t k = static_cast<std::size_t>(3 * cnp + 3 * pr.held_points()); k < p.size(); ++k) p[k] += 0.01;
    const sbaformats::Visibility &v = pr.points().pairs;
    const sba_visibility vis{static_cast<long long>(v.size()), v.point.data(), v.camera.data()};
    sba_ext_options ext;
    sba_ext_options_init(&ext);
    ext.cam_fixed = pr.cam_fixed().data();
    ext.cam_fixed_per_camera = 1;
    ext.cam_param_group = pr.cam_param_group().data();
    ext.quiet = 1;
    std::vector<double> x = pr.points().x;
    double info[SBA_INFOSZ] = {};
    const double opts[SBA_OPTSSZ] = {1e-3, 1e-12, 1e-12, 1e-12, 0};
    const int ret = sba_motstr_levmar_x_vis(pr.npoints(), pr.held_points(), pr.ncameras(), 0, &vis, p.data(), cnp,
                                            3, x.data(), nullptr, 2, pr.func(), pr.fjac(), pr.adata(), 100, 0, opts,
                                            info, &ext);
    ASSERT_GE(ret, 0);
    EXPECT_GT(info[0], 1e-3);
    EXPECT_LT(info[1], 1e-16);
    colmap::Model out = m;
    pr.apply(p.data(), &out);
    for (std::size_t i = 0; i < m.points.size(); ++i)
      for (std::size_t c = 0; c < 3; ++c) EXPECT_NEAR(out.points[i].xyz[c], m.points[i].xyz[c], 1e-6) << i;
    EXPECT_EQ(out.points[0].xyz, m.points[0].xyz);  // held: its bits, and its ERROR as read
    EXPECT_EQ(out.points[0].error, 1);
    for (std::size_t i = 1; i < out.points.size(); ++i) EXPECT_LT(out.points[i].error, 1e-8) << i;
  }
}

TEST(RigidPose, ComposeAndInverse) {
  const sbacameras::RigidPose a{turn(0.3, 0, 0, 1), {1, 2, 3}}, b{turn(-0.2, 1, 0, 0), {0.5, -1, 0.25}};
  // a b maps X as a(b(X)).
  const sbacameras::RigidPose ab = sbacameras::compose(a, b);
  const double X[3] = {0.3, -0.7, 2};
  const auto apply = [](const sbacameras::RigidPose &p, const double *in, double *out) {
    const std::array<double, 4> &q = p.q;
    const double R[9] = {1 - 2 * (q[2] * q[2] + q[3] * q[3]), 2 * (q[1] * q[2] - q[0] * q[3]),
                         2 * (q[1] * q[3] + q[0] * q[2]),     2 * (q[1] * q[2] + q[0] * q[3]),
                         1 - 2 * (q[1] * q[1] + q[3] * q[3]), 2 * (q[2] * q[3] - q[0] * q[1]),
                         2 * (q[1] * q[3] - q[0] * q[2]),     2 * (q[2] * q[3] + q[0] * q[1]),
                         1 - 2 * (q[1] * q[1] + q[2] * q[2])};
    for (int r = 0; r < 3; ++r) out[r] = R[3 * r] * in[0] + R[3 * r + 1] * in[1] + R[3 * r + 2] * in[2] + p.t[r];
  };
  double bX[3], abX[3], want[3];
  apply(b, X, bX);
  apply(a, bX, want);
  apply(ab, X, abX);
  for (int r = 0; r < 3; ++r) EXPECT_NEAR(abX[r], want[r], 1e-14) << r;
  // p^-1 p is the identity; a quaternion of another norm is the same rotation.
  const sbacameras::RigidPose scaled{{2 * b.q[0], 2 * b.q[1], 2 * b.q[2], 2 * b.q[3]}, b.t};
  const sbacameras::RigidPose id = sbacameras::compose(sbacameras::inverse(scaled), b);
  EXPECT_NEAR(id.q[0], 1, 1e-15);
  for (int k = 1; k < 4; ++k) EXPECT_NEAR(id.q[static_cast<std::size_t>(k)], 0, 1e-15) << k;
  for (int k = 0; k < 3; ++k) EXPECT_NEAR(id.t[static_cast<std::size_t>(k)], 0, 1e-15) << k;
  // The identity's inverse is the identity, zeros positive.
  const sbacameras::RigidPose none = sbacameras::inverse({});
  EXPECT_FALSE(std::signbit(none.t[0]));
  EXPECT_EQ(none.q, (std::array<double, 4>{1, 0, 0, 0}));
}

}  // namespace

namespace {

// The pose of camera j at parameters a as COLMAP's tangent moves it from the pose at a_hat:
// (delta, t - t_hat).
std::array<double, 6> tangent_step(const cc::RigCameraModel &model, const std::vector<double> &a,
                                   const std::vector<double> &a_hat) {
  const cc::Camera c = model.camera(0, a.data()), c_hat = model.camera(0, a_hat.data());
  const std::array<double, 3> d = tangenttest::colmap_increment(c.q, c_hat.q);
  return {d[0], d[1], d[2], c.t[0] - c_hat.t[0], c.t[1] - c_hat.t[1], c.t[2] - c_hat.t[2]};
}

}  // namespace

// composed_pose_covariance is N C N^T with N = d(cam_from_world's tangent)/d(v_f t_f v_s t_s) by
// central differences of the rig camera model's composed pose, for a covariance C of the 12
// pose parameters with cross terms; with the sensor's pose held it is the frame's pose_covariance.
TEST(ColmapCovariance, ImageOfARigComposesFrameAndSensor) {
  cc::RigImage im;
  im.params = {500, 320, 240};
  im.q_frame = {0.9, 0.1, -0.3, 0.2};
  im.t_frame = {0.4, -1.0, 3.0};
  im.q_sensor = {0.8, -0.2, 0.1, 0.4};
  im.t_sensor = {0.3, 0.1, -0.2};
  const cc::RigCameraModel model({im}, {0, 0, 5});
  const int cnp = model.cnp();
  std::vector<double> a(model.initial_camera(0), model.initial_camera(0) + cnp);
  const double moved[12] = {0.05, -0.1, 0.02, 0.4, -1.0, 3.0, -0.03, 0.08, 0.1, 0.3, 0.1, -0.2};
  std::copy(moved, moved + 12, a.begin());
  std::vector<double> C(static_cast<std::size_t>(cnp) * cnp, 0.0);
  for (int r = 0; r < 12; ++r)
    for (int c = 0; c < 12; ++c) C[static_cast<std::size_t>(r * cnp + c)] = (r == c ? 2.0 : 0.0) + 0.1 * std::cos(r + c);
  double N[72];
  const double h = 1e-6;
  for (int k = 0; k < 12; ++k) {
    std::vector<double> ap = a, am = a;
    ap[static_cast<std::size_t>(k)] += h;
    am[static_cast<std::size_t>(k)] -= h;
    const std::array<double, 6> up = tangent_step(model, ap, a), down = tangent_step(model, am, a);
    for (int r = 0; r < 6; ++r) N[r * 12 + k] = (up[static_cast<std::size_t>(r)] - down[static_cast<std::size_t>(r)]) / (2 * h);
  }
  const cc::RigImage at = model.image(0, a.data());
  double R_s[9];
  sbacameras::euclidean::rotation_matrix(at.q_sensor, R_s);
  const colmap::CovarianceBlock b = colmap::composed_pose_covariance(a.data(), C.data(), nullptr, cnp, R_s,
                                                                     at.t_frame.data());
  ASSERT_EQ(b.coords, (std::vector<int>{0, 1, 2, 3, 4, 5}));
  for (int r = 0; r < 6; ++r)
    for (int c = 0; c < 6; ++c) {
      double want = 0;
      for (int k = 0; k < 12; ++k)
        for (int l = 0; l < 12; ++l) want += N[r * 12 + k] * C[static_cast<std::size_t>(k * cnp + l)] * N[c * 12 + l];
      EXPECT_NEAR(b.cov[static_cast<std::size_t>(r * 6 + c)], want, 1e-7 * (1 + std::fabs(want))) << r << " " << c;
    }
  // The sensor's pose held (its rows and columns of C zero, as the library gives them).
  std::vector<char> fixed;
  for (int c = 0; c < cnp; ++c) fixed.push_back(c >= 6 && c < 12);
  for (int r = 0; r < cnp; ++r)
    for (int c = 0; c < cnp; ++c)
      if (r >= 6 || c >= 6) C[static_cast<std::size_t>(r * cnp + c)] = 0.0;
  const colmap::CovarianceBlock held = colmap::composed_pose_covariance(a.data(), C.data(), fixed.data(), cnp, R_s,
                                                                        at.t_frame.data());
  const colmap::CovarianceBlock frame = colmap::pose_covariance(a.data(), C.data(), fixed.data(), cnp, 0);
  ASSERT_EQ(held.coords, frame.coords);
  ASSERT_EQ(held.coords.size(), 6u);
  // Then the image's pose is the frame's turned by R_s: diag(R_s, R_s) P_f diag(R_s, R_s)^T.
  for (int r = 0; r < 6; ++r)
    for (int c = 0; c < 6; ++c) {
      double want = 0;
      for (int k = 0; k < 3; ++k)
        for (int l = 0; l < 3; ++l)
          want += R_s[(r % 3) * 3 + k] * frame.cov[static_cast<std::size_t>((r / 3 * 3 + k) * 6 + c / 3 * 3 + l)] *
                  R_s[(c % 3) * 3 + l];
      EXPECT_NEAR(held.cov[static_cast<std::size_t>(r * 6 + c)], want, 1e-12 * (1 + std::fabs(want))) << r << " " << c;
    }
}
