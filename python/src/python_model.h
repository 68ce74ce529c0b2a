/* SPDX-License-Identifier: BSD-3-Clause */
// The expert drivers with a camera model written in Python: vectorized callbacks that get the
// cameras, the points and the (camera, point) index of every observation at once.
#ifndef PYSBA_PYTHON_MODEL_H
#define PYSBA_PYTHON_MODEL_H

#include <pybind11/pybind11.h>

#include "arrays.h"

namespace pysba {

// refine: "motstr", "mot" or "str". project(cameras, points, cam_idx, pt_idx) returns the
// predicted observations (nobs x mnp); jacobian (None: finite differences) returns
// (A, B) with A (nobs x mnp x cnp) and B (nobs x mnp x pnp), the one not refined may be None.
// Returns the report of run_driver with the refined "cameras" and "points".
py::dict solve_python(const std::string &refine, py::handle project, py::handle jacobian, py::handle cameras,
                      py::handle points, py::handle camera_index, py::handle point_index, py::handle observations,
                      py::handle covariances, const py::kwargs &kw);

}  // namespace pysba

#endif  // PYSBA_PYTHON_MODEL_H
