/* SPDX-License-Identifier: BSD-3-Clause */
// Camera parameters held by a mask and camera parameters shared by groups of cameras
// (sba_ext_options.cam_fixed, cam_group, cam_shared), for every linear solver.
//
// The unknowns are then the free parameters of each camera that are neither held nor shared
// (with the points: the system every solver knows, in which the other parameters are simply
// absent), plus one small set per group of cameras, the parameters its cameras share. A
// shared unknown moves every camera of its group and so couples, through the points, to all
// of them: its column is dense. It is eliminated by bordering instead of being put into the
// solvers' block structure: with H the system without it, C its columns and G its own
// block,
//   (G - C^T H^-1 C) ds = g_s - C^T H^-1 g,   dp = H^-1 g - H^-1 C ds,
// which costs one more solve of H per shared unknown and one small dense system, and works
// unchanged with the dense, sparse and iterative solvers, both strategies and the losses.
#ifndef SBA_SRC_CAMERA_PARAMS_H
#define SBA_SRC_CAMERA_PARAMS_H

#include <memory>
#include <string>
#include <vector>

#include "layout.h"
#include "options.h"
#include "parallel.h"
#include "step_solver.h"

namespace sba {

// What is wrong with o for this problem and the initial estimate p (empty: nothing). Only
// problems with cameras are checked; the structure-only drivers ignore the options.
std::string check_camera_params(const CameraParamOptions &o, const Layout &lay, const double *p);

// Which camera parameters are unknowns of their own, held, or shared, and the groups.
struct CameraUnknowns {
  struct Column {  // one shared unknown: parameter a of the cameras of one group
    int group, a;
  };
  CameraUnknowns(const Layout &lay, const CameraParamOptions &o);
  // Per free camera parameter (j >= mcon, (j - mcon) * cnp + a), the index of its unknown:
  // its own, or its group's shared one (after all the own ones); -1 when held. Returns how
  // many unknowns there are.
  int index(const Layout &lay, std::vector<int> *out) const;
  // How many camera unknowns there are: neither the cameras below mcon, held parameters nor
  // the copies of a shared one count.
  i64 count(const Layout &lay) const;

  // Per camera parameter (m * cnp): 0 an unknown of its own, 1 held, 2 shared.
  std::vector<char> kind;
  std::vector<std::vector<int>> groups;  // cameras of each group of two or more, ascending
  std::vector<Column> cols;              // the shared unknowns, by group then parameter
};

// The held and shared parameters of one solve, and the step solver that honours them around
// the solve's own.
class CameraParams final : public StepSolver {
 public:
  // o checked by check_camera_params.
  CameraParams(const Layout &lay, const CameraParamOptions &o, ThreadPool &pool,
               std::unique_ptr<StepSolver> inner);

  // Every group's shared (free) parameters in p set to its first camera's; returns the values
  // they replaced, for restore.
  std::vector<double> start(double *p) const;
  // p's shared parameters as they were before start returned given.
  void restore(double *p, const std::vector<double> &given) const;
  // max |gradient| and the largest diagonal entry of J^T J over the camera unknowns (a
  // shared one's are its cameras' sums), in the units of p (before the strategy changes
  // variables).
  void gradient_stats(const double *U, const double *ea, double *ginf, double *maxdiag) const;
  // After the strategy's change of variables, once per linearization: takes the held and
  // shared parameters out of the system the inner solver sees (their columns of jac and
  // their rows and columns of U are zeroed in place; e_a keeps them: the predicted
  // reduction needs the whole gradient) and forms the bordering. scale: the strategy's
  // dp = scale * dq per parameter, or null.
  void linearized(double *jac, double *U, const double *ea, const double *scale);

  StepStatus solve(const NormalEquations &ne, double mu, double *dp) override;

  // dp in the units of p: every copy of a shared unknown given its first camera's step. The
  // copies' steps are one number mapped back through each camera's own scale of the
  // strategy's change of variables, s (r / s), which rounds differently per camera; copies
  // that start equal and always take the same step stay equal to the bit.
  void tie(double *dp) const;

 private:
  using Column = CameraUnknowns::Column;

  const Layout &lay_;
  ThreadPool &pool_;
  std::unique_ptr<StepSolver> inner_;
  // Per camera parameter (m * cnp): 0 an unknown of its own, 1 held, 2 shared.
  std::vector<char> kind_;
  std::vector<std::vector<int>> groups_;  // cameras of each group of two or more, ascending
  std::vector<Column> cols_;              // the shared unknowns, by group then parameter
  // Per linearization: t (per column, per camera of its group: dq = t ds), the columns C
  // (camera part, point part), G with the damping weight of each column, the gradient g_s,
  // and e_a without the held and shared entries.
  std::vector<std::vector<double>> t_, ca_, cb_;
  std::vector<double> G_, wdiag_, gs_, ea_;
  // Per solve: H^-1 C, one nvars vector per column.
  std::vector<std::vector<double>> x_;
};

}  // namespace sba

#endif
