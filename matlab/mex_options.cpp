// SPDX-License-Identifier: BSD-3-Clause
#include "mex_options.h"

#include <climits>
#include <cmath>

namespace sba_mex {
namespace {

constexpr const char *kOptionFields[] = {"fixed_params", "camera_groups",        "shared_params", "param_groups",
                                         "point_priors", "camera_linear_priors", "camera_priors"};

bool is_option_field(const std::string &name) {
  for (const char *f : kOptionFields)
    if (name == f) return true;
  return false;
}

bool is_vector_shape(const OptionField &f) { return f.rows == 1 || f.cols == 1; }

// Element k (column-major) of f as the messages name it: (row,col) in a matrix, (k) in a
// vector.
std::string element_name(const OptionField &f, std::size_t k, bool as_matrix) {
  if (!as_matrix) return format("%s(%zu)", f.name.c_str(), k + 1);
  return format("%s(%zu,%zu)", f.name.c_str(), k % f.rows + 1, k / f.rows + 1);
}

// f's values, all finite; as_matrix says how a message names an element.
const std::vector<double> &finite_values(const OptionField &f, bool as_matrix) {
  for (std::size_t k = 0; k < f.values.size(); ++k)
    if (!std::isfinite(f.values[k]))
      bad_arg("invalidArgument", format("%s is not finite.", element_name(f, k, as_matrix).c_str()));
  return f.values;
}

// The values of a field of flags: a dense real or logical matrix, nonzero meaning set.
const std::vector<double> &flag_values(const OptionField &f) {
  if (!f.matrix)
    bad_arg("invalidArgument", format("%s must be a dense real or logical matrix (got a %s).", f.name.c_str(),
                                      f.description.c_str()));
  return finite_values(f, !is_vector_shape(f));
}

// The values of a field of group numbers: a dense real numeric matrix. A logical one is
// refused rather than read as numbers: false would be group 0, and every parameter left
// unmarked would be shared.
const std::vector<double> &group_values(const OptionField &f, bool as_matrix) {
  if (!f.matrix || f.logical)
    bad_arg("invalidArgument", format("%s must be a dense real numeric matrix of group numbers (got a %s).",
                                      f.name.c_str(), f.description.c_str()));
  return finite_values(f, as_matrix);
}

// The group number g at `where` ("camera_groups(3)") as the library's int: a whole number an
// int holds. Which numbers are groups (-1 for none, a camera group in [0, m-1]) is the
// library's rule, checked with the rest of the options.
int group_number(double g, const std::string &where) {
  if (g != std::floor(g) || g < INT_MIN || g > INT_MAX)
    bad_arg("invalidArgument", format("%s must be a whole number within [%d, %d] (got %.15g).", where.c_str(),
                                      INT_MIN, INT_MAX, g));
  return static_cast<int>(g);
}

// ---- priors: struct arrays, one element per prior ----

enum class PriorKind { kPoint, kLinear, kCallback };

const char *prior_field_name(PriorKind kind) {
  return kind == PriorKind::kPoint    ? "point_priors"
         : kind == PriorKind::kLinear ? "camera_linear_priors"
                                      : "camera_priors";
}

// One element of a prior field, and how messages name it and its fields.
struct PriorElement {
  const std::vector<OptionField> &fields;
  std::string name;  // "point_priors(2)"

  std::string where(const char *field) const { return name + "." + field; }
  // The field, or null when absent or empty ([] and '' are not given).
  const OptionField *get(const char *field) const {
    for (const OptionField &f : fields)
      if (f.name == field) return f.numel > 0 ? &f : nullptr;
    return nullptr;
  }
  const OptionField &required(const char *field) const {
    if (const OptionField *f = get(field)) return *f;
    bad_arg("invalidArgument", format("%s must be given (it is missing or empty).", where(field).c_str()));
  }
};

// The values of a numeric field: a dense real numeric matrix. A logical one is refused: no
// index, mean or weight is a flag.
const std::vector<double> &numbers(const OptionField &f, const std::string &where) {
  if (!f.matrix || f.logical)
    bad_arg("invalidArgument",
            format("%s must be a dense real numeric array (got a %s).", where.c_str(), f.description.c_str()));
  return f.values;
}

double scalar(const OptionField &f, const std::string &where) {
  const std::vector<double> &v = numbers(f, where);
  if (v.size() != 1)
    bad_arg("invalidArgument",
            format("%s must be a real numeric scalar (got a %s).", where.c_str(), f.description.c_str()));
  return v[0];
}

// A 1-based index as the library's 0-based one. Whether it names a camera, point or parameter
// the prior may constrain is the library's check.
int index_from_one(double v, const std::string &where) {
  if (!(v == std::floor(v) && v >= 1 && v <= INT_MAX))
    bad_arg("invalidArgument", format("%s must be a whole number within [1, %d], a 1-based index (got %.15g).",
                                      where.c_str(), INT_MAX, v));
  return static_cast<int>(v) - 1;
}

// A vector of k values (k_text says what k is: "pnp").
std::vector<double> vector_of(const OptionField &f, const std::string &where, std::size_t k, const char *k_text) {
  const std::vector<double> &v = numbers(f, where);
  if (!is_vector_shape(f))
    bad_arg("wrongSize",
            format("%s must have %s = %zu values (got a %zu x %zu matrix).", where.c_str(), k_text, k, f.rows, f.cols));
  if (v.size() != k)
    bad_arg("wrongSize", format("%s must have %s = %zu values (got %zu).", where.c_str(), k_text, k, v.size()));
  return v;
}

// A k x k matrix, to the library's row-major layout.
std::vector<double> square_of(const OptionField &f, const std::string &where, std::size_t k, const char *k_text) {
  const std::vector<double> &v = numbers(f, where);
  if (f.rows != k || f.cols != k)
    bad_arg("wrongSize", format("%s must be %s x %s = %zu x %zu (got %zu x %zu).", where.c_str(), k_text, k_text, k, k,
                                f.rows, f.cols));
  std::vector<double> out(k * k);
  for (std::size_t r = 0; r < k; ++r)
    for (std::size_t c = 0; c < k; ++c) out[r * k + c] = v[c * k + r];
  return out;
}

// The weight, the loss and its scale, for a residual of k entries (k_text). k < 1 is the
// library's to refuse, and it then reads no weight: their sizes are not checked.
void read_base(const PriorElement &e, long long k, const char *k_text, PriorBase *out) {
  const std::size_t uk = k > 0 ? static_cast<std::size_t>(k) : 0;
  if (const OptionField *f = e.get("sigma"))
    out->weight.sigma = k > 0 ? vector_of(*f, e.where("sigma"), uk, k_text) : numbers(*f, e.where("sigma"));
  if (const OptionField *f = e.get("covariance"))
    out->weight.covariance =
        k > 0 ? square_of(*f, e.where("covariance"), uk, k_text) : numbers(*f, e.where("covariance"));
  if (const OptionField *f = e.get("sqrt_info"))
    out->weight.sqrt_info = k > 0 ? square_of(*f, e.where("sqrt_info"), uk, k_text) : numbers(*f, e.where("sqrt_info"));
  if (const OptionField *f = e.get("loss")) {
    if (!f->text)
      bad_arg("invalidArgument",
              format("%s must be a string (got a %s).", e.where("loss").c_str(), f->description.c_str()));
    out->has_loss = true;
    out->loss = f->chars;
  }
  if (const OptionField *f = e.get("loss_scale")) out->loss_scale = scalar(*f, e.where("loss_scale"));
}

PriorFunction prior_function(const OptionField *f, const std::string &where) {
  PriorFunction fn;
  if (!f) return fn;
  if (!f->handle && !f->text)
    bad_arg("invalidArgument", format("%s must be a function name or a function handle (got a %s).", where.c_str(),
                                      f->description.c_str()));
  fn.given = true;
  fn.handle = f->handle;
  if (f->text) fn.name = f->chars;
  return fn;
}

void check_prior_fields(const PriorElement &e, PriorKind kind) {
  static const char *const kKnown[3][10] = {
      {"point", "mean", "sigma", "covariance", "sqrt_info", "loss", "loss_scale"},
      {"camera", "params", "mean", "sigma", "covariance", "sqrt_info", "loss", "loss_scale"},
      {"camera", "dim", "func", "jac", "sigma", "covariance", "sqrt_info", "loss", "loss_scale"}};
  const char *const *known = kKnown[static_cast<int>(kind)];
  for (const OptionField &f : e.fields) {
    bool ok = false;
    std::string list;
    for (int q = 0; known[q]; ++q) {
      ok = ok || f.name == known[q];
      list += std::string(q == 0 ? "" : known[q + 1] ? ", " : " or ") + known[q];
    }
    // A misspelt "sigmas" would otherwise leave the prior without its weight.
    if (!ok)
      bad_arg("invalidArgument", format("%s has an unknown field '%s' (expected %s).", prior_field_name(kind),
                                        f.name.c_str(), list.c_str()));
  }
}

// The elements of prior field f, each read by read(element).
template <class Prior, class Read>
std::vector<Prior> read_priors(const OptionField &f, PriorKind kind, Read read) {
  if (!f.is_struct)
    bad_arg("invalidArgument", format("%s must be a struct array, one element per prior (got a %s).", f.name.c_str(),
                                      f.description.c_str()));
  std::vector<Prior> out;
  for (std::size_t q = 0; q < f.elements.size(); ++q) {
    const PriorElement e{f.elements[q], format("%s(%zu)", f.name.c_str(), q + 1)};
    check_prior_fields(e, kind);
    out.push_back(read(e));
  }
  return out;
}

// param_groups: m x cnp, row j camera j's, to the library's camera-major layout.
std::vector<int> param_groups(const OptionField &f, std::size_t m, std::size_t cnp) {
  const std::vector<double> &v = group_values(f, true);
  if (f.rows != m || f.cols != cnp)
    bad_arg("wrongSize",
            format("param_groups must be m x cnp = %zu x %zu (got %zu x %zu).", m, cnp, f.rows, f.cols));
  std::vector<int> out(m * cnp);
  for (std::size_t j = 0; j < m; ++j)
    for (std::size_t c = 0; c < cnp; ++c)
      out[j * cnp + c] = group_number(v[c * m + j], format("param_groups(%zu,%zu)", j + 1, c + 1));
  return out;
}

}  // namespace

StructRole struct_role(bool is_struct, std::size_t numel, const std::vector<std::string> &fields) {
  if (!is_struct) return StructRole::kData;
  for (const std::string &f : fields)
    if (is_option_field(f)) return numel == 1 ? StructRole::kOptions : StructRole::kRefused;
  return StructRole::kData;
}

void refuse_options_struct(const std::string &description) {
  // Taken as problem data, its options would reach the callbacks unread and the solve would
  // move what the caller meant to hold.
  bad_arg("invalidArgument",
          format("the options struct must be a 1x1 struct (got a %s array).", description.c_str()));
}

namespace {

CameraOptions camera_options(const OptionField *fixed, const OptionField *groups, const OptionField *shared,
                             const OptionField *per_param, std::size_t m, std::size_t cnp) {
  CameraOptions o;
  if (fixed) {
    const std::vector<double> &v = flag_values(*fixed);
    if (is_vector_shape(*fixed) && v.size() == cnp) {
      for (double x : v) o.fixed.push_back(x != 0.0);
    } else if (fixed->rows == m && fixed->cols == cnp) {
      o.fixed_per_camera = true;  // row j is camera j's: to camera-major
      o.fixed.resize(m * cnp);
      for (std::size_t j = 0; j < m; ++j)
        for (std::size_t c = 0; c < cnp; ++c) o.fixed[j * cnp + c] = v[c * m + j] != 0.0;
    } else {
      bad_arg("wrongSize", format("fixed_params must have cnp = %zu flags (for every camera) or be m x cnp = "
                                  "%zu x %zu (got %zu x %zu).",
                                  cnp, m, cnp, fixed->rows, fixed->cols));
    }
  }
  // Whatever combination is given goes to the library, which refuses one without the other
  // (camera_groups, shared_params) or both forms at once: one check.
  if (per_param) o.param_group = param_groups(*per_param, m, cnp);
  if (groups) {
    const std::vector<double> &gv = group_values(*groups, !is_vector_shape(*groups));
    if (!is_vector_shape(*groups) || gv.size() != m)
      bad_arg("wrongSize", format("camera_groups must have m = %zu values (got %zu).", m, gv.size()));
    for (std::size_t j = 0; j < m; ++j) o.group.push_back(group_number(gv[j], format("camera_groups(%zu)", j + 1)));
  }
  if (shared) {
    const std::vector<double> &sv = flag_values(*shared);
    if (!is_vector_shape(*shared) || sv.size() != cnp)
      bad_arg("wrongSize", format("shared_params must have cnp = %zu flags (got %zu).", cnp, sv.size()));
    for (double x : sv) o.shared.push_back(x != 0.0);
  }
  return o;
}

}  // namespace

StructOptions options_struct(const std::vector<OptionField> &fields, std::size_t m, std::size_t cnp, std::size_t pnp) {
  const OptionField *given[sizeof kOptionFields / sizeof *kOptionFields] = {};
  for (const OptionField &f : fields) {
    std::size_t k = 0;
    while (k < sizeof kOptionFields / sizeof *kOptionFields && f.name != kOptionFields[k]) ++k;
    if (k == sizeof kOptionFields / sizeof *kOptionFields)
      bad_arg("invalidArgument",
              format("the options struct has an unknown field '%s' (expected fixed_params, camera_groups, "
                     "shared_params, param_groups, point_priors, camera_linear_priors or camera_priors).",
                     f.name.c_str()));
    if (f.numel > 0) given[k] = &f;  // [] (or an empty struct array) is not given
  }
  StructOptions o;
  o.camera = camera_options(given[0], given[1], given[2], given[3], m, cnp);
  if (given[4])
    o.point_priors = read_priors<PointPrior>(*given[4], PriorKind::kPoint, [&](const PriorElement &e) {
      PointPrior p;
      p.point = index_from_one(scalar(e.required("point"), e.where("point")), e.where("point"));
      const OptionField &mean = e.required("mean");
      p.mean = pnp > 0 ? vector_of(mean, e.where("mean"), pnp, "pnp") : numbers(mean, e.where("mean"));
      read_base(e, static_cast<long long>(pnp), "pnp", &p);
      return p;
    });
  if (given[5])
    o.linear_priors = read_priors<LinearPrior>(*given[5], PriorKind::kLinear, [&](const PriorElement &e) {
      LinearPrior p;
      p.camera = index_from_one(scalar(e.required("camera"), e.where("camera")), e.where("camera"));
      const OptionField &params = e.required("params");
      const std::vector<double> &pv = numbers(params, e.where("params"));
      if (!is_vector_shape(params))
        bad_arg("invalidArgument", format("%s must be a vector of parameter indices (got a %s).",
                                          e.where("params").c_str(), params.description.c_str()));
      for (std::size_t q = 0; q < pv.size(); ++q)
        p.params.push_back(index_from_one(pv[q], format("%s(%zu)", e.where("params").c_str(), q + 1)));
      p.mean = vector_of(e.required("mean"), e.where("mean"), p.params.size(), "numel(params)");
      read_base(e, static_cast<long long>(p.params.size()), "numel(params)", &p);
      return p;
    });
  if (given[6])
    o.camera_priors = read_priors<CallbackPrior>(*given[6], PriorKind::kCallback, [&](const PriorElement &e) {
      CallbackPrior p;
      p.camera = index_from_one(scalar(e.required("camera"), e.where("camera")), e.where("camera"));
      p.dim = group_number(scalar(e.required("dim"), e.where("dim")), e.where("dim"));
      p.func = prior_function(&e.required("func"), e.where("func"));
      p.jac = prior_function(e.get("jac"), e.where("jac"));
      read_base(e, p.dim, "dim", &p);
      return p;
    });
  return o;
}

}  // namespace sba_mex
