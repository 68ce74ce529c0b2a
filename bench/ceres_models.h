/* SPDX-License-Identifier: BSD-3-Clause */
// Ceres cost functions that evaluate exactly the models sba is given in the benchmark: the
// residual is predicted minus observed (Ceres minimises 1/2 sum r^2, sba sum r^2 with the
// opposite sign, so the costs differ by the factor 1/2 only), and the Jacobian blocks come
// from the same analytic code as sba's fjac callbacks (eucsba: its one-projection form,
// project_jacobian_at_point, equal up to rounding).
#ifndef SBA_BENCH_CERES_MODELS_H
#define SBA_BENCH_CERES_MODELS_H

#include <ceres/ceres.h>

#include "cameras/bal_camera.h"
#include "cameras/euclidean.h"

namespace sbabench {

// eucsbademo's quaternion camera model (q = qs(v) * q0_j, cnp 6, 11 or 16) with the point's
// 3 coordinates: the same parameter blocks as sba's a_j and b_i.
template <int CNP>
class EucsbaCost final : public ceres::SizedCostFunction<2, CNP, 3> {
 public:
  EucsbaCost(const sbacameras::euclidean::CameraModel &model, int camera, double x, double y)
      : model_(model), camera_(camera), obs_{x, y} {}

  bool Evaluate(double const *const *parameters, double *residuals, double **jacobians) const override {
    double *A = jacobians ? jacobians[0] : nullptr;
    double *B = jacobians ? jacobians[1] : nullptr;
    model_.project_jacobian_at_point(camera_, parameters[0], parameters[1], residuals, A, B);
    residuals[0] -= obs_[0];
    residuals[1] -= obs_[1];
    return true;
  }

 private:
  const sbacameras::euclidean::CameraModel &model_;
  int camera_;
  double obs_[2];
};

// The BAL camera (Rodrigues w, t, f, k1, k2) and point.
class BalCost final : public ceres::SizedCostFunction<2, sbacameras::bal::kCameraParams, sbacameras::bal::kPointParams> {
 public:
  BalCost(double x, double y) : obs_{x, y} {}

  bool Evaluate(double const *const *parameters, double *residuals, double **jacobians) const override {
    double *A = jacobians ? jacobians[0] : nullptr;
    double *B = jacobians ? jacobians[1] : nullptr;
    sbacameras::bal::project_jacobian(parameters[0], parameters[1], residuals, A, B);
    residuals[0] -= obs_[0];
    residuals[1] -= obs_[1];
    return true;
  }

 private:
  double obs_[2];
};

}  // namespace sbabench

#endif  // SBA_BENCH_CERES_MODELS_H
