/* SPDX-License-Identifier: BSD-3-Clause */
// The priors of pysba's solves (point_priors, camera_linear_priors, camera_priors: sequences
// of dicts, see pysba/__init__.py), read into copies that live as long as the solve (the
// library's structs over them: prior_callbacks.h). pysba checks the types, and the shapes it
// must know to hand the library arrays of the right size; which values are valid (indices,
// means, weights, losses) is the library's check, whose message, naming the prior, is the
// caller's ValueError.
#ifndef PYSBA_PRIORS_H
#define PYSBA_PRIORS_H

#include <pybind11/pybind11.h>

#include <memory>
#include <string>
#include <vector>

#include "gil.h"

namespace pysba {

namespace py = pybind11;

// A float array of a prior as given (absent: !given), and its shape for the checks.
struct PriorArray {
  bool given = false;
  std::vector<double> values;
  std::vector<long long> shape;
};

// One prior as given. where names it in pysba's messages ("point_priors[2]").
struct PriorSpec {
  std::string where;
  int target = 0;  // the camera or the point
  PriorArray mean, sigma, covariance, sqrt_info;
  std::vector<int> params;           // camera linear priors
  int dim = 0;                       // camera priors
  std::shared_ptr<PyRef> func, jac;  // camera priors; jac may be null (forward differences)
  std::string loss;                  // empty: none
  double loss_scale = 0;
};

struct Priors {
  std::vector<PriorSpec> camera, linear, point;
};

// The keyword arguments point_priors, camera_linear_priors and camera_priors of kw (absent or
// None: none). TypeError or ValueError naming the entry for what pysba cannot hand over.
Priors read_priors(const py::dict &kw);

// ValueError unless the arrays of every prior have the sizes the library will read: pnp
// entries for a point prior, len(params) for a linear one, dim for a callback one.
void check_prior_shapes(const Priors &p, int pnp);

}  // namespace pysba

#endif  // PYSBA_PRIORS_H
