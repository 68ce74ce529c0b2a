// SPDX-License-Identifier: BSD-3-Clause
// pysba._core: the readers and the built-in camera models of the demo programs, and the
// expert drivers with Python callbacks (python_model.cpp). The Python-facing API, its
// defaults and its documentation are in pysba/__init__.py.
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <stdexcept>
#include <string>
#include <vector>

#include "arrays.h"
#include "cameras/bal_camera.h"
#include "cameras/euclidean.h"
#include "colmap.h"
#include "formats/bal_io.h"
#include "formats/eucsba_io.h"
#include "python_model.h"
#include "run.h"
#include "session.h"

namespace eucsba = sbaformats::eucsba;
namespace bal = sbaformats::bal;
namespace euclidean = sbacameras::euclidean;
namespace bal_camera = sbacameras::bal;

namespace pysba {
namespace {

// ---- eucsbademo's Euclidean cameras, as rows of the camera files ----

int row_width(euclidean::CameraKind kind) { return eucsba::camera_file_values(kind); }

euclidean::CameraKind kind_of_width(py::ssize_t width) {
  for (euclidean::CameraKind k : {euclidean::CameraKind::FixedIntrinsics, euclidean::CameraKind::VaryingIntrinsics,
                                  euclidean::CameraKind::VaryingIntrinsicsDistortion})
    if (row_width(k) == width) return k;
  throw py::value_error("eucsbademo cameras must have 7, 12 or 17 columns, got " + std::to_string(width));
}

void camera_to_row(euclidean::CameraKind kind, const euclidean::Camera &c, double *row) {
  if (kind != euclidean::CameraKind::FixedIntrinsics) {
    const double k[] = {c.k.fu, c.k.u0, c.k.v0, c.k.ar, c.k.s};
    row = std::copy(k, k + 5, row);
    if (kind == euclidean::CameraKind::VaryingIntrinsicsDistortion) row = std::copy(c.kc.begin(), c.kc.end(), row);
  }
  const double qt[] = {c.q.w, c.q.x, c.q.y, c.q.z, c.t[0], c.t[1], c.t[2]};
  std::copy(qt, qt + 7, row);
}

euclidean::Camera row_to_camera(euclidean::CameraKind kind, const double *row, const euclidean::Intrinsics &calib) {
  euclidean::Camera c;
  c.k = calib;
  if (kind != euclidean::CameraKind::FixedIntrinsics) {
    c.k = {row[0], row[1], row[2], row[3], row[4]};
    row += 5;
    if (kind == euclidean::CameraKind::VaryingIntrinsicsDistortion) {
      std::copy(row, row + 5, c.kc.begin());
      row += 5;
    }
  }
  c.q = {row[0], row[1], row[2], row[3]};
  c.t = {row[4], row[5], row[6]};
  return c;
}

py::array_t<double> calibration_matrix(const euclidean::Intrinsics &k) {
  std::vector<double> K = {k.fu, k.s, k.u0, 0.0, k.fu * k.ar, k.v0, 0.0, 0.0, 1.0};
  return adopt(std::move(K), {3, 3});
}

euclidean::Intrinsics intrinsics_of(const Doubles &K) {
  const double *k = K.data();
  if (k[3] != 0 || k[6] != 0 || k[7] != 0 || k[8] != 1)
    throw py::value_error("calibration must be [[fu, s, u0], [0, fv, v0], [0, 0, 1]]");
  if (k[0] == 0 || k[4] == 0) throw py::value_error("calibration: fu and fv must be nonzero");
  return {k[0], k[2], k[5], k[4] / k[0], k[1]};
}

// (camera, point) of each observation of a vmask, in sba's order.
void indices_of_vmask(const std::vector<char> &vmask, int n, int m, std::vector<long long> *cam,
                      std::vector<long long> *pt) {
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < m; ++j)
      if (vmask[size_t(i) * m + j]) {
        cam->push_back(j);
        pt->push_back(i);
      }
}

py::dict read_eucsbademo(const std::string &cams, const std::string &pts, const std::string &calib) {
  eucsba::Problem problem;
  std::string error;
  if (!without_gil([&] { return eucsba::load_problem(cams, pts, calib, &problem, &error); })) {
    // "<file>: why", with no line: the file could not be opened at all (OSError); otherwise,
    // "<file>:<line>: why", its content is wrong.
    bool unreachable = false;
    for (const std::string *file : {&cams, &pts, &calib})
      unreachable = unreachable || (!file->empty() && error.rfind(*file + ": ", 0) == 0);
    raise_file_error(unreachable ? PyExc_OSError : PyExc_ValueError, error);
  }
  eucsba::PointSet &ps = problem.points;
  const int m = ps.ncameras, n = ps.npoints(), nobs = ps.nprojections();
  const int w = row_width(problem.kind);
  std::vector<double> rows(size_t(m) * w);
  for (int j = 0; j < m; ++j) camera_to_row(problem.kind, problem.cameras[size_t(j)], rows.data() + size_t(j) * w);
  std::vector<long long> cam, pt;
  indices_of_vmask(ps.vmask, n, m, &cam, &pt);
  py::dict d;
  d["cameras"] = adopt(std::move(rows), {m, w});
  d["points"] = adopt(std::move(ps.xyz), {n, 3});
  d["camera_index"] = adopt(std::move(cam), {nobs});
  d["point_index"] = adopt(std::move(pt), {nobs});
  d["observations"] = adopt(std::move(ps.x), {nobs, 2});
  d["covariances"] = ps.has_covariances() ? py::object(adopt(std::move(ps.covx), {nobs, 2, 2})) : py::none();
  d["calibration"] = problem.kind == euclidean::CameraKind::FixedIntrinsics && m > 0
                         ? py::object(calibration_matrix(problem.cameras[0].k))
                         : py::none();
  return d;
}

py::dict read_bal(const std::string &path) {
  bal::Problem problem;
  bal::SbaLayout layout;
  std::string error;
  const bool ok = without_gil(
      [&] { return bal::read_problem(path, &problem, &error) && bal::to_sba(problem, path, &layout, &error); });
  if (!ok) {
    const bool unreadable =
        error.find(": cannot open") != std::string::npos || error.find(": read error") != std::string::npos;
    raise_file_error(unreadable ? PyExc_OSError : PyExc_ValueError, error);
  }
  const int nobs = layout.nobservations();
  std::vector<long long> cam(static_cast<size_t>(nobs)), pt(static_cast<size_t>(nobs));
  for (int k = 0; k < nobs; ++k) {
    const bal::Observation &o = problem.observations[size_t(layout.order[size_t(k)])];
    cam[size_t(k)] = o.camera;
    pt[size_t(k)] = o.point;
  }
  py::dict d;
  d["cameras"] = adopt(std::move(problem.cameras), {problem.ncameras, bal_camera::kCameraParams});
  d["points"] = adopt(std::move(problem.points), {problem.npoints, bal_camera::kPointParams});
  d["camera_index"] = adopt(std::move(cam), {nobs});
  d["point_index"] = adopt(std::move(pt), {nobs});
  d["observations"] = adopt(std::move(layout.x), {nobs, 2});
  return d;
}

// Motion and structure with eucsbademo's camera model, as eucsbademo runs it by default
// (expert driver, analytic Jacobian, callbacks shared by the threads). The array arguments
// are the caller's (borrowed); what is converted from them is copied and let go before the
// solve (gil.h).
py::dict solve_eucsbademo(py::handle camera_rows, py::handle point_rows, py::handle camera_index,
                          py::handle point_index, py::handle observations, py::handle covariances,
                          py::handle calibration, const py::kwargs &kw) {
  const SolveOptions o = solve_options(kw);
  euclidean::CameraKind kind;
  py::ssize_t width;
  std::vector<euclidean::Camera> cams;
  std::vector<double> xyz;
  {
    const Doubles cameras = parameter_rows(camera_rows, "cameras", -1);
    width = cameras.shape(1);
    kind = kind_of_width(width);
    const Doubles points = parameter_rows(point_rows, "points", 3);
    if (cameras.shape(0) == 0 || points.shape(0) == 0)
      throw py::value_error("a problem needs at least one camera and one point");
    euclidean::Intrinsics calib;
    if (kind == euclidean::CameraKind::FixedIntrinsics) {
      if (calibration.is_none()) throw py::value_error("cameras of 7 values need a calibration matrix");
      const Doubles K = float_array(calibration, "calibration");
      check_shape(K, "calibration", {3, 3});
      check_finite(K, "calibration");
      calib = intrinsics_of(K);
    } else if (!calibration.is_none()) {
      throw py::value_error("a calibration matrix goes only with cameras of 7 values (q, t)");
    }
    for (py::ssize_t j = 0; j < cameras.shape(0); ++j)
      cams.push_back(row_to_camera(kind, cameras.data() + size_t(j) * width, calib));
    xyz.assign(points.data(), points.data() + points.size());
  }
  const int m = static_cast<int>(cams.size()), n = static_cast<int>(xyz.size() / 3);

  Run run;
  run.obs = sorted_observations(n, m, camera_index, point_index, observations, covariances);
  if (run.obs.mnp != euclidean::kMeasurementParams) throw py::value_error("observations must have 2 columns");
  std::unique_ptr<euclidean::CameraModel> model;
  try {
    model = std::make_unique<euclidean::CameraModel>(kind, cams, xyz, o.nccalib, o.ncdist);
  } catch (const std::invalid_argument &e) {
    throw py::value_error(e.what());
  }
  const euclidean::ExpertCallbacks cb = euclidean::expert_callbacks(kind, euclidean::Refinement::MotionStructure);
  run.p = model->initial_camera_params();
  run.p.insert(run.p.end(), xyz.begin(), xyz.end());
  run.cnp = model->cnp();
  run.pnp = euclidean::kPointParams;
  run.func = cb.func;
  run.fjac = cb.fjac;
  run.adata = euclidean::as_adata(*model);
  run.parallel = true;  // the model's callbacks are re-entrant and walk the index by rows

  Session session(o);
  py::dict d = run_driver(run, session, o);
  std::vector<double> rows(size_t(m) * width);
  for (int j = 0; j < m; ++j)
    camera_to_row(kind, model->camera(j, run.p.data() + size_t(j) * run.cnp), rows.data() + size_t(j) * width);
  d["cameras"] = adopt(std::move(rows), {py::ssize_t(m), width});
  d["points"] = copy_of(run.p.data() + size_t(m) * run.cnp, {n, 3});
  d["nobs"] = run.obs.nobs();
  return d;
}

// Motion and structure with the BAL camera model and its analytic Jacobian, as balsba runs it.
py::dict solve_bal(py::handle camera_rows, py::handle point_rows, py::handle camera_index, py::handle point_index,
                   py::handle observations, py::handle covariances, const py::kwargs &kw) {
  const SolveOptions o = solve_options(kw);
  Run run;
  py::ssize_t m, n;
  {
    const Doubles cameras = parameter_rows(camera_rows, "cameras", bal_camera::kCameraParams);
    const Doubles points = parameter_rows(point_rows, "points", bal_camera::kPointParams);
    m = cameras.shape(0);
    n = points.shape(0);
    if (m == 0 || n == 0) throw py::value_error("a problem needs at least one camera and one point");
    run.p.assign(cameras.data(), cameras.data() + cameras.size());
    run.p.insert(run.p.end(), points.data(), points.data() + points.size());
  }
  run.obs = sorted_observations(static_cast<int>(n), static_cast<int>(m), camera_index, point_index, observations,
                                covariances);
  if (run.obs.mnp != bal_camera::kMeasurementParams) throw py::value_error("observations must have 2 columns");
  bal_camera::CallbackData data;
  data.ncameras = static_cast<int>(m);
  run.cnp = bal_camera::kCameraParams;
  run.pnp = bal_camera::kPointParams;
  run.func = bal_camera::motstr_func;
  run.fjac = bal_camera::motstr_fjac;
  run.adata = &data;
  run.parallel = true;
  Session session(o);
  py::dict d = run_driver(run, session, o);
  d["cameras"] = copy_of(run.p.data(), {m, bal_camera::kCameraParams});
  d["points"] = copy_of(run.p.data() + m * bal_camera::kCameraParams, {n, bal_camera::kPointParams});
  d["nobs"] = run.obs.nobs();
  return d;
}

}  // namespace
}  // namespace pysba

PYBIND11_MODULE(_core, mod) {
  namespace py = pybind11;
  using namespace pysba;
  mod.doc() = "The compiled part of pysba; use the functions of the pysba package instead.";

  py::class_<sba_progress>(mod, "Progress", "The state after an iteration, passed to progress callbacks.")
      .def_readonly("iteration", &sba_progress::iteration, "Iterations done so far (1, 2, ...).")
      .def_readonly("error", &sba_progress::error, "Sum of squared errors (or the robust cost) now.")
      .def_readonly("mu", &sba_progress::mu, "The damping the next iteration starts from.")
      .def_readonly("dp_norm", &sba_progress::dp_norm, "Norm of the last step tried.")
      .def_readonly("elapsed", &sba_progress::elapsed, "Seconds since the solve started.")
      .def("__repr__", [](const sba_progress &s) {
        return "Progress(iteration=" + std::to_string(s.iteration) + ", error=" + std::to_string(s.error) + ")";
      });

  mod.def("read_eucsbademo", &read_eucsbademo, py::arg("cams"), py::arg("pts"), py::arg("calib"));
  mod.def("read_bal", &read_bal, py::arg("path"));
  mod.def("solve_eucsbademo", &solve_eucsbademo, py::arg("cameras"), py::arg("points"), py::arg("camera_index"),
          py::arg("point_index"), py::arg("observations"), py::arg("covariances"), py::arg("calibration"));
  mod.def("solve_bal", &solve_bal, py::arg("cameras"), py::arg("points"), py::arg("camera_index"),
          py::arg("point_index"), py::arg("observations"), py::arg("covariances"));
  mod.def("solve_python", &solve_python, py::arg("refine"), py::arg("project"), py::arg("jacobian"),
          py::arg("cameras"), py::arg("points"), py::arg("camera_index"), py::arg("point_index"),
          py::arg("observations"), py::arg("covariances"));
  mod.def(
      "float_array", [](py::handle obj, const std::string &what) { return float_array(obj, what.c_str()); },
      py::arg("obj"), py::arg("what"));
  mod.def(
      "index_array",
      [](py::handle obj, const std::string &what, long long bound) {
        std::vector<long long> v = index_array(obj, what.c_str(), bound);
        const py::ssize_t len = py::ssize_t(v.size());
        return adopt(std::move(v), {len});
      },
      py::arg("obj"), py::arg("what"), py::arg("bound"));
  add_colmap(mod);
  mod.def("solver_names", [] { return std::string(sba_linsolver_names()); });
  mod.def("strategy_names", [] { return std::string(sba_strategy_names()); });
  mod.def("stop_reason_text", &sba_stop_reason_text, py::arg("reason"));
  mod.attr("SBA_VERSION") = SBA_VERSION;
}
