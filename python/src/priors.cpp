// SPDX-License-Identifier: BSD-3-Clause
#include "priors.h"

#include <climits>
#include <initializer_list>

#include "arrays.h"
#include "keywords.h"
#include "option_values.h"

namespace pysba {
namespace {

enum class Kind { Camera, Linear, Point };

// TypeError for a key of d that is not one of known (a misspelt "sigmas" would otherwise be a
// prior without its weight), as Python refuses an unexpected keyword argument.
void check_keys(const py::dict &d, const std::string &where, std::initializer_list<const char *> known) {
  for (const auto item : d) {
    bool ok = false;
    if (PyUnicode_Check(item.first.ptr())) {
      const std::string key = item.first.cast<std::string>();
      for (const char *name : known) ok = ok || key == name;
    }
    if (ok) continue;
    std::string names;
    for (const char *name : known) names += (names.empty() ? "" : ", ") + std::string(name);
    throw py::type_error(where + " has an unknown key " + std::string(py::repr(item.first)) + " (known: " + names +
                         ")");
  }
}

py::handle required(const Keywords &k, const char *name, const std::string &where) {
  const py::handle v = k.get(name);
  if (v.is_none()) throw py::type_error(where + " needs '" + name + "'");
  return v;
}

PriorArray float_entry(const Keywords &k, const char *name) {
  PriorArray a;
  const py::handle v = k.get(name);
  if (v.is_none()) return a;
  const Doubles d = float_array(v, k.named(name).c_str());
  a.given = true;
  a.values.assign(d.data(), d.data() + d.size());
  a.shape.assign(d.shape(), d.shape() + d.ndim());
  return a;
}

std::shared_ptr<PyRef> callable_entry(const Keywords &k, const char *name) {
  const py::handle v = k.get(name);
  if (v.is_none()) return nullptr;
  if (!PyCallable_Check(v.ptr())) throw Keywords::wrong_type(k.named(name), "callable", v);
  return std::make_shared<PyRef>(py::reinterpret_borrow<py::object>(v));
}

// The entries of one kind of prior that the others do not have.
void read_own(const Keywords &k, const std::string &where, Kind kind, PriorSpec *s) {
  if (kind != Kind::Camera) {
    required(k, "mean", where);
    s->mean = float_entry(k, "mean");
  }
  if (kind == Kind::Linear) s->params = int_array(required(k, "params", where), k.named("params"));
  if (kind == Kind::Camera) {
    required(k, "dim", where);
    s->dim = int(k.integer("dim", 0, INT_MIN, INT_MAX));
    s->func = callable_entry(k, "func");
    if (!s->func) throw py::type_error(where + " needs 'func'");
    s->jac = callable_entry(k, "jac");
  }
}

PriorSpec read_one(py::handle item, const std::string &where, Kind kind) {
  if (!PyDict_Check(item.ptr())) throw Keywords::wrong_type(where, "a dict", item);
  const py::dict d = py::reinterpret_borrow<py::dict>(item);
  const char *target = kind == Kind::Point ? "point" : "camera";
  const char *weight[] = {"sigma", "covariance", "sqrt_info", "loss", "loss_scale"};
  if (kind == Kind::Point) check_keys(d, where, {"point", "mean", weight[0], weight[1], weight[2], weight[3], weight[4]});
  if (kind == Kind::Linear)
    check_keys(d, where, {"camera", "params", "mean", weight[0], weight[1], weight[2], weight[3], weight[4]});
  if (kind == Kind::Camera)
    check_keys(d, where, {"camera", "dim", "func", "jac", weight[0], weight[1], weight[2], weight[3], weight[4]});
  const Keywords k(d, where);
  PriorSpec s;
  s.where = where;
  required(k, target, where);
  s.target = int(k.integer(target, 0, INT_MIN, INT_MAX));
  read_own(k, where, kind, &s);
  s.sigma = float_entry(k, "sigma");
  s.covariance = float_entry(k, "covariance");
  s.sqrt_info = float_entry(k, "sqrt_info");
  s.loss = k.text("loss");
  s.loss_scale = k.number("loss_scale", 0.0);
  return s;
}

std::vector<PriorSpec> read_kind(const Keywords &kw, const char *name, Kind kind) {
  std::vector<PriorSpec> out;
  const py::handle v = kw.get(name);
  if (v.is_none()) return out;
  if (PyDict_Check(v.ptr()) || PyUnicode_Check(v.ptr()) || !PySequence_Check(v.ptr()))
    throw Keywords::wrong_type(name, "a sequence of dicts", v);
  const py::sequence seq = py::reinterpret_borrow<py::sequence>(v);
  for (size_t q = 0; q < seq.size(); ++q)
    out.push_back(read_one(seq[q], std::string(name) + "[" + std::to_string(q) + "]", kind));
  return out;
}

// The weight's and the mean's shapes for k entries. k < 1 is refused by the library, which
// then reads neither.
void check_sizes(const PriorSpec &s, long long k, bool has_mean) {
  if (k < 1) return;
  python_errors([&] {
    if (has_mean) require_shape(s.where + "['mean']", s.mean.shape, {k});
    if (s.sigma.given) require_shape(s.where + "['sigma']", s.sigma.shape, {k});
    if (s.covariance.given) require_shape(s.where + "['covariance']", s.covariance.shape, {k, k});
    if (s.sqrt_info.given) require_shape(s.where + "['sqrt_info']", s.sqrt_info.shape, {k, k});
  });
}

}  // namespace

Priors read_priors(const py::dict &kw) {
  const Keywords k(kw);
  Priors p;
  p.camera = read_kind(k, "camera_priors", Kind::Camera);
  p.linear = read_kind(k, "camera_linear_priors", Kind::Linear);
  p.point = read_kind(k, "point_priors", Kind::Point);
  return p;
}

void check_prior_shapes(const Priors &p, int pnp) {
  for (const PriorSpec &s : p.camera) check_sizes(s, s.dim, false);
  for (const PriorSpec &s : p.linear) check_sizes(s, static_cast<long long>(s.params.size()), true);
  for (const PriorSpec &s : p.point) check_sizes(s, pnp, true);
}

}  // namespace pysba
