// SPDX-License-Identifier: BSD-3-Clause
// libFuzzer target: sbarefine's prior files (colmap::parse_pose_priors_text, parse_point_priors,
// parse_intrinsic_priors; the first byte picks one, the rest is the file) against a fixed model,
// and what is accepted taken on as sbarefine takes it (place_on_priors: WGS84 to east-north-up,
// the usable priors, the model moved onto them by the robust similarity). An error is one line
// "<file>:<line>: ..." (or "<where>: ..." for a prior's values); what is accepted names only
// images, points and cameras of the model, with finite values, a positive deviation, a symmetric
// positive definite covariance; the model moved stays finite.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "formats/colmap_priors.h"
#include "fuzz_common.h"

namespace colmap = sbaformats::colmap;

namespace {

using sbafuzz::require;

// Three images that see four points, of two cameras (SIMPLE_RADIAL 1, OPENCV 2), and an image
// that sees nothing. Made once, copied for each input that moves it.
const colmap::Model &model() {
  static const colmap::Model m = [] {
    colmap::Model out;
    out.cameras = {{1, colmap::kSimpleRadial, 640, 480, {500, 320, 240, 0.01}},
                   {2, colmap::kOpenCV, 640, 480, {500, 505, 320, 240, 0.1, 0.01, 0, 0}}};
    const char *names[] = {"a.png", "b.png", "10", "unseen.png"};
    for (std::uint32_t k = 0; k < 4; ++k) {
      colmap::Image im;
      im.id = 10 + k;
      im.camera_id = 1 + k % 2;
      im.name = names[k];
      im.q = {std::cos(0.1 * k), 0, std::sin(0.1 * k), 0};
      im.t = {-0.5 * k, 0.1 * k, 0.2};
      out.images.push_back(im);
    }
    for (std::uint64_t i = 0; i < 4; ++i) {
      colmap::Point3D pt;
      pt.id = 100 + i;
      pt.xyz = {0.3 * static_cast<double>(i), 0.1 * static_cast<double>(i % 2), 5};
      for (std::size_t k = 0; k < 3; ++k) {
        colmap::Image &im = out.images[k];
        pt.track.push_back({im.id, static_cast<std::uint32_t>(im.points.size())});
        im.points.push_back({1, 2, pt.id});
      }
      out.points.push_back(pt);
    }
    return out;
  }();
  return m;
}

bool finite(const std::array<double, 3> &v) { return std::isfinite(v[0]) && std::isfinite(v[1]) && std::isfinite(v[2]); }

void check_model_finite(const colmap::Model &m) {
  for (const colmap::Point3D &p : m.points) require(finite(p.xyz), "a point moved to a value that is not finite");
  for (const colmap::Image &im : m.images)
    require(finite(im.t) && std::isfinite(im.q[0] + im.q[1] + im.q[2] + im.q[3]),
            "a pose moved to a value that is not finite");
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t *data, std::size_t size) {
  if (size == 0) return 0;
  const int kind = data[0] % 3;
  const std::string text(reinterpret_cast<const char *>(data + 1), size - 1);
  const std::string name = "priors.txt";
  std::string error;
  colmap::Model m = model();
  if (kind == 0) {
    std::vector<colmap::PosePrior> priors;
    int unknown = -1;
    if (!colmap::parse_pose_priors_text(text, name, m, &priors, &unknown, &error)) {
      sbafuzz::check_format_error(error, name);
      return 0;
    }
    require(unknown >= 0, "no count of unknown names");
    for (const colmap::PosePrior &p : priors) require(p.image_id >= 10 && p.image_id <= 13, "a prior of no image");
    std::vector<colmap::PosePrior> usable;
    std::string said;
    colmap::PosePriorOptions options;
    if (!colmap::place_on_priors(priors, unknown, name, {}, {}, options, true, &m, &usable, &said, &error)) {
      sbafuzz::check_error_line(error, name + ":");
      return 0;
    }
    require(usable.empty() || usable.size() >= 3, "fewer than 3 priors kept");
    for (const colmap::PosePrior &p : usable) {
      require(p.image_id != 13, "a prior of an image that sees no point kept");
      require(finite(p.position) && p.has_covariance, "a kept prior without a finite position or a covariance");
    }
    check_model_finite(m);
  } else if (kind == 1) {
    std::vector<colmap::PointPrior> priors;
    if (!colmap::parse_point_priors(text, name, m, &priors, &error)) {
      sbafuzz::check_format_error(error, name);
      return 0;
    }
    for (const colmap::PointPrior &p : priors) {
      require(p.point_id >= 100 && p.point_id <= 103, "a prior of no point");
      require(finite(p.position) && p.covariance[0] > 0 && p.covariance[4] > 0 && p.covariance[8] > 0,
              "a point prior without a finite position or a positive variance");
    }
    std::vector<colmap::PosePrior> usable;
    std::string said;
    if (!colmap::place_on_priors({}, 0, {}, priors, name, {}, true, &m, &usable, &said, &error)) {
      // Accepted control points are refused only when they are too far to move the model onto.
      require(error.rfind(name + ": the model cannot be moved onto these priors", 0) == 0,
              "placing on accepted point priors failed: " + error);
      sbafuzz::check_error_line(error, name + ":");
      return 0;
    }
    check_model_finite(m);
  } else {
    std::vector<colmap::IntrinsicPrior> priors;
    if (!colmap::parse_intrinsic_priors(text, name, m, &priors, &error)) {
      sbafuzz::check_format_error(error, name);
      return 0;
    }
    for (const colmap::IntrinsicPrior &p : priors)
      require((p.camera_id == 1 && p.param >= 0 && p.param < 4) || (p.camera_id == 2 && p.param >= 0 && p.param < 8),
              "an intrinsics prior of no parameter");
  }
  return 0;
}
