// SPDX-License-Identifier: BSD-3-Clause
#include "prior_callbacks.h"

#include <algorithm>
#include <limits>
#include <string>

#include "arrays.h"

namespace pysba {
namespace {

void fill_nan(double *out, size_t len) { std::fill_n(out, len, std::numeric_limits<double>::quiet_NaN()); }

// fn(j, a_j), an array of the given shape, copied to out. NaN there instead once the solve has
// failed or when fn raises (the exception is kept): the library then ends the solve, and the
// exception is raised again once it has returned.
void call_prior(const PriorStructs::Call &c, py::handle fn, const char *what, int j, const double *aj, double *out,
                std::vector<py::ssize_t> shape) {
  size_t len = 1;
  for (const py::ssize_t d : shape) len *= size_t(d);
  Session &s = *c.session;
  if (s.failed()) return fill_nan(out, len);
  with_gil(s.released_thread(), [&] {
    try {
      const PyRef a(copy_of(aj, {c.cnp})), index(PyLong_FromLong(j));
      if (!index) throw py::error_already_set();
      const PyRef r = call_python(fn, {index.handle(), a.handle()});
      const Doubles arr = result_array(r.handle(), (c.spec->where + what).c_str(), std::move(shape));
      std::copy_n(arr.data(), len, out);
    }
    PYSBA_FORCED_UNWIND_PASSES_THROUGH
    catch (...) {
      s.keep_current_exception();
      fill_nan(out, len);
    }
  });
}

void prior_func(int j, const double *aj, double *r, void *data) {
  const auto &c = *static_cast<const PriorStructs::Call *>(data);
  call_prior(c, c.spec->func->handle(), "['func']'s result", j, aj, r, {c.spec->dim});
}

void prior_jac(int j, const double *aj, double *jac, void *data) {
  const auto &c = *static_cast<const PriorStructs::Call *>(data);
  call_prior(c, c.spec->jac->handle(), "['jac']'s result", j, aj, jac, {c.spec->dim, c.cnp});
}

const double *given(const PriorArray &a) { return a.given ? a.values.data() : nullptr; }

// A library struct with the weight and the loss of s (pointing into s).
template <class T>
T with_weight(const PriorSpec &s) {
  T t{};
  t.weight.sigma = given(s.sigma);
  t.weight.covariance = given(s.covariance);
  t.weight.sqrt_info = given(s.sqrt_info);
  t.loss = s.loss.empty() ? nullptr : s.loss.c_str();
  t.loss_scale = s.loss_scale;
  return t;
}

}  // namespace

void PriorStructs::attach(const Priors &p, Session &session, int cnp, sba_ext_options *ext) {
  calls_.clear();
  camera_.clear();
  linear_.clear();
  point_.clear();
  // Filled before the structs point into it: it is not resized afterwards.
  for (const PriorSpec &s : p.camera) calls_.push_back({&session, &s, cnp});
  for (size_t q = 0; q < p.camera.size(); ++q) {
    sba_camera_prior c = with_weight<sba_camera_prior>(p.camera[q]);
    c.camera = p.camera[q].target;
    c.dim = p.camera[q].dim;
    c.func = prior_func;
    c.jacf = p.camera[q].jac ? prior_jac : nullptr;
    c.data = &calls_[q];
    camera_.push_back(c);
  }
  for (const PriorSpec &s : p.linear) {
    sba_camera_linear_prior c = with_weight<sba_camera_linear_prior>(s);
    c.camera = s.target;
    c.k = static_cast<int>(s.params.size());
    c.params = s.params.data();
    c.mean = given(s.mean);
    linear_.push_back(c);
  }
  for (const PriorSpec &s : p.point) {
    sba_point_prior c = with_weight<sba_point_prior>(s);
    c.point = s.target;
    c.mean = given(s.mean);
    point_.push_back(c);
  }
  ext->ncamera_priors = static_cast<int>(camera_.size());
  ext->camera_priors = camera_.empty() ? nullptr : camera_.data();
  ext->ncamera_linear_priors = static_cast<int>(linear_.size());
  ext->camera_linear_priors = linear_.empty() ? nullptr : linear_.data();
  ext->npoint_priors = static_cast<int>(point_.size());
  ext->point_priors = point_.empty() ? nullptr : point_.data();
}

}  // namespace pysba
