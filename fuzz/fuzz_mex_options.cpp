// SPDX-License-Identifier: BSD-3-Clause
// libFuzzer target: the MEX gateway's options struct (matlab/mex_options.h): which value beside
// reftype is one (struct_role), and what its fields may hold (camera_options), with fields of
// any name, size and values (NaN, fractions, huge and negative numbers, non-matrices).
// Each call is judged against docs/mex.md's rules, written out here afresh: a struct with an
// option field is the options struct when 1x1 and refused otherwise; fixed_params holds cnp
// flags or an m x cnp matrix, camera_groups m numbers in -1..m-1 with shared_params' cnp
// flags, nonzero meaning set, param_groups an m x cnp matrix of whole numbers in
// -1..2147483647 (with camera_groups too: the library refuses the pair, not the gateway);
// flags may be logical, group numbers may not (false would be group 0); anything else is
// refused with one line, ending in a full stop, under the identifier sba:invalidArgument or
// sba:wrongSize, and a value that is not finite is named where it is: the first one in
// column-major order, by (row,col) in a matrix (param_groups always) and by (k) in a vector.
// What is taken must be exactly what was given, in sba_ext_options' layout (param_groups:
// row j's numbers at j*cnp).
// The priors (point_priors, camera_linear_priors, camera_priors) are struct arrays whose
// elements have fields of any kind: each element may have only its kind's fields; the index
// fields (point, camera, params) are 1-based whole numbers in [1, 2147483647], dim any whole
// number an int holds, never logical; mean has pnp values (point) or numel(params) (linear),
// sigma k values and covariance and sqrt_info are k x k, k being pnp, numel(params) or dim,
// unchecked when k < 1; loss is a string, loss_scale a scalar, func a name or a handle, jac
// one too when given; [] is not given, and point, mean, camera, params, dim and func must be.
// NaN and Inf are the library's to refuse: taken as given. What is taken: the indices less
// one, the values as given, the matrices row-major.
#include <fuzzer/FuzzedDataProvider.h>

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

#include "fuzz_common.h"
#include "mex_options.h"

namespace {

using sba_mex::ArgError;
using sba_mex::OptionField;
using sbafuzz::require;

const char *const kNames[] = {"fixed_params", "camera_groups", "shared_params", "param_groups",
                              "camera_group", "foo", ""};
const std::size_t kOptionNames = 4;  // the first four of kNames

double next_number(FuzzedDataProvider &in, std::size_t m) {
  switch (in.ConsumeIntegralInRange<int>(0, 5)) {
    case 0:
      return 0;
    case 1:
      return 1;
    case 2:
      return in.ConsumeIntegralInRange<int>(-2, int(m) + 1);
    case 3: {
      static const double kOdd[] = {-0.0, 0.5, -1.5, NAN, INFINITY, -INFINITY, 1e300, 1e-300,
                                    2147483647.0, 2147483648.0, -2.0};
      return kOdd[in.ConsumeIntegralInRange<size_t>(0, sizeof kOdd / sizeof *kOdd - 1)];
    }
    case 4: {
      double x;
      const std::uint64_t bits = in.ConsumeIntegral<std::uint64_t>();
      std::memcpy(&x, &bits, sizeof x);
      return x;
    }
    default:
      return in.ConsumeIntegralInRange<int>(0, 1);
  }
}

OptionField next_field(FuzzedDataProvider &in, std::size_t m, std::size_t cnp) {
  OptionField f;
  f.name = in.ConsumeBool()
               ? kNames[in.ConsumeIntegralInRange<size_t>(0, kOptionNames - 1)]
               : kNames[in.ConsumeIntegralInRange<size_t>(0, sizeof kNames / sizeof *kNames - 1)];
  f.matrix = in.ConsumeIntegralInRange<int>(0, 7) != 0;
  f.logical = f.matrix && in.ConsumeIntegralInRange<int>(0, 3) == 0;
  // Mostly the sizes that fit, m x cnp, 1 x cnp and 1 x m, or their transposes.
  const std::size_t sizes[] = {m, cnp, 1, 0, in.ConsumeIntegralInRange<size_t>(0, 8)};
  f.rows = sizes[in.ConsumeIntegralInRange<size_t>(0, 4)];
  f.cols = sizes[in.ConsumeIntegralInRange<size_t>(0, 4)];
  f.numel = f.rows * f.cols;
  f.description = std::to_string(f.rows) + "x" + std::to_string(f.cols) +
                  (f.logical ? " logical" : f.matrix ? " double" : " cell");
  if (f.matrix)
    for (std::size_t k = 0; k < f.numel; ++k) f.values.push_back(f.logical ? in.ConsumeBool() : next_number(in, m));
  return f;
}

// ---- priors ----

const char *const kPriorNames[] = {"point_priors", "camera_linear_priors", "camera_priors"};
// Each kind's fields, then one it does not have ("params" is the linear kind's alone).
const char *const kPriorFields[3][10] = {
    {"point", "mean", "sigma", "covariance", "sqrt_info", "loss", "loss_scale", "params"},
    {"camera", "params", "mean", "sigma", "covariance", "sqrt_info", "loss", "loss_scale", "sigmas"},
    {"camera", "dim", "func", "jac", "sigma", "covariance", "sqrt_info", "loss", "loss_scale", "params"}};
const std::size_t kPriorFieldCount[3] = {7, 8, 9};

// A value of an element's field: empty, a matrix of a size near k (or k x k), a string, a
// function handle or a cell.
OptionField next_prior_value(FuzzedDataProvider &in, const char *name, std::size_t k, std::size_t m) {
  OptionField f;
  f.name = name;
  const int kind = in.ConsumeIntegralInRange<int>(0, 9);
  if (kind == 0) {
    f.matrix = true;  // []
    f.description = "0x0 double";
    return f;
  }
  if (kind == 1 || kind == 2) {
    static const char *const kTexts[] = {"huber", "fn", "", "cauchy"};
    f.text = true;
    f.chars = kTexts[in.ConsumeIntegralInRange<size_t>(0, 3)];
    f.numel = f.chars.size();
    f.rows = f.numel ? 1 : 0;
    f.cols = f.numel;
    f.description = "1x" + std::to_string(f.numel) + " char";
    return f;
  }
  if (kind == 3) {
    f.handle = true;
    f.numel = 1;
    f.description = "1x1 function_handle";
    return f;
  }
  if (kind == 4) {
    f.numel = in.ConsumeIntegralInRange<size_t>(0, 2);
    f.description = "1x" + std::to_string(f.numel) + " cell";
    return f;
  }
  f.matrix = true;
  f.logical = in.ConsumeIntegralInRange<int>(0, 7) == 0;
  const std::size_t sizes[] = {1, k, k + 1, k > 0 ? k - 1 : 0, in.ConsumeIntegralInRange<size_t>(0, 4)};
  f.rows = sizes[in.ConsumeIntegralInRange<size_t>(0, 4)];
  f.cols = sizes[in.ConsumeIntegralInRange<size_t>(0, 4)];
  f.numel = f.rows * f.cols;
  f.description = std::to_string(f.rows) + "x" + std::to_string(f.cols) + (f.logical ? " logical" : " double");
  for (std::size_t q = 0; q < f.numel; ++q) f.values.push_back(f.logical ? in.ConsumeBool() : next_number(in, m));
  return f;
}

// A prior field: mostly a struct array of up to 3 elements with the same fields.
OptionField next_prior_field(FuzzedDataProvider &in, int kind, std::size_t m, std::size_t cnp, std::size_t pnp) {
  if (in.ConsumeIntegralInRange<int>(0, 7) == 0) return next_prior_value(in, kPriorNames[kind], 3, m);
  OptionField f;
  f.name = kPriorNames[kind];
  f.is_struct = true;
  f.numel = in.ConsumeIntegralInRange<size_t>(0, 3);
  f.rows = f.numel ? 1 : 0;
  f.cols = f.numel;
  f.description = "1x" + std::to_string(f.numel) + " struct";
  // The first three fields (the required ones, and jac) mostly, the others now and then, the
  // foreign one seldom.
  std::vector<const char *> names;
  for (std::size_t q = 0; q <= kPriorFieldCount[kind]; ++q) {
    const int odds = q < 3 ? 8 : q < kPriorFieldCount[kind] ? 3 : 16;
    const bool present =
        q < 3 ? in.ConsumeIntegralInRange<int>(1, odds) != 1 : in.ConsumeIntegralInRange<int>(1, odds) == 1;
    if (present) names.push_back(kPriorFields[kind][q]);
  }
  const std::size_t k = kind == 0   ? pnp
                        : kind == 1 ? in.ConsumeIntegralInRange<size_t>(1, 3)
                                    : in.ConsumeIntegralInRange<size_t>(0, 3);
  for (std::size_t e = 0; e < f.numel; ++e) {
    std::vector<OptionField> fields;
    for (const char *name : names)
      fields.push_back(next_prior_value(in, name, std::string(name) == "jac" ? cnp : k, m));
    f.elements.push_back(std::move(fields));
  }
  return f;
}

const OptionField *element_field(const std::vector<OptionField> &fields, const char *name) {
  for (const OptionField &f : fields)
    if (f.name == name && f.numel > 0) return &f;
  return nullptr;
}

bool numeric(const OptionField *f) { return f && f->matrix && !f->logical; }
bool vector_shape(const OptionField *f) { return f->rows == 1 || f->cols == 1; }
bool scalar(const OptionField *f) { return numeric(f) && f->numel == 1; }
bool one_based(double v) { return v == std::floor(v) && v >= 1 && v <= 2147483647.0; }

// k values (k < 1: any numbers), or k x k.
bool sized(const OptionField *f, long long k, bool square) {
  if (!f) return true;
  if (!numeric(f)) return false;
  if (k < 1) return true;
  const std::size_t uk = static_cast<std::size_t>(k);
  return square ? f->rows == uk && f->cols == uk : vector_shape(f) && f->numel == uk;
}

bool function_value(const OptionField *f) { return f->handle || (f->text && !f->chars.empty()); }

// docs/mex.md's rules for one element of a prior field of kind 0 (point), 1 (linear) or 2
// (callback).
bool prior_acceptable(const std::vector<OptionField> &e, int kind, std::size_t pnp) {
  for (const OptionField &f : e) {
    bool known = false;
    for (std::size_t q = 0; q < kPriorFieldCount[kind]; ++q) known = known || f.name == kPriorFields[kind][q];
    if (!known) return false;
  }
  const OptionField *target = element_field(e, kind == 0 ? "point" : "camera");
  if (!scalar(target) || !one_based(target->values[0])) return false;
  long long k = static_cast<long long>(pnp);
  if (kind == 1) {
    const OptionField *params = element_field(e, "params");
    if (!numeric(params) || !vector_shape(params)) return false;
    for (double v : params->values)
      if (!one_based(v)) return false;
    k = static_cast<long long>(params->numel);
  }
  if (kind == 2) {
    const OptionField *dim = element_field(e, "dim"), *func = element_field(e, "func"), *jac = element_field(e, "jac");
    if (!scalar(dim)) return false;
    const double d = dim->values[0];
    if (d != std::trunc(d) || d < -2147483648.0 || d > 2147483647.0) return false;
    k = static_cast<long long>(d);
    if (!func || !function_value(func) || (jac && !function_value(jac))) return false;
  } else {
    const OptionField *mean = element_field(e, "mean");
    if (!mean || !sized(mean, k, false)) return false;
  }
  const OptionField *loss = element_field(e, "loss"), *scale = element_field(e, "loss_scale");
  return sized(element_field(e, "sigma"), k, false) && sized(element_field(e, "covariance"), k, true) &&
         sized(element_field(e, "sqrt_info"), k, true) && (!loss || loss->text) && (!scale || scalar(scale));
}

bool priors_acceptable(const OptionField &f, int kind, std::size_t pnp) {
  if (f.numel == 0) return true;
  if (!f.is_struct) return false;
  for (const std::vector<OptionField> &e : f.elements)
    if (!prior_acceptable(e, kind, pnp)) return false;
  return true;
}

bool same(double a, double b) { return a == b || (std::isnan(a) && std::isnan(b)); }

// The values of f (absent: none) as taken, row-major when square.
void check_values(const std::vector<double> &taken, const OptionField *f, bool square, const std::string &what) {
  if (!f) {
    require(taken.empty(), what + " taken from nothing");
    return;
  }
  require(taken.size() == f->values.size(), what + " taken with another size");
  const std::size_t k = square ? f->rows : 1;
  for (std::size_t q = 0; q < taken.size(); ++q) {
    const std::size_t from = square ? (q % k) * k + q / k : q;  // taken[r*k + c] is (r, c)
    require(same(taken[q], f->values[from]), what + " taken as other values");
  }
}

void check_base(const sba_mex::PriorBase &p, const std::vector<OptionField> &e, long long k, const std::string &what) {
  // With k < 1 the matrices are taken as they are, unread by the library.
  check_values(p.weight.sigma, element_field(e, "sigma"), false, what + ".sigma");
  check_values(p.weight.covariance, element_field(e, "covariance"), k > 0, what + ".covariance");
  check_values(p.weight.sqrt_info, element_field(e, "sqrt_info"), k > 0, what + ".sqrt_info");
  const OptionField *loss = element_field(e, "loss"), *scale = element_field(e, "loss_scale");
  require(p.has_loss == (loss != nullptr) && (!loss || p.loss == loss->chars), what + ".loss taken as another");
  require(same(p.loss_scale, scale ? scale->values[0] : 0.0), what + ".loss_scale taken as another");
}

void check_function(const sba_mex::PriorFunction &fn, const OptionField *f, const std::string &what) {
  require(fn.given == (f != nullptr), what + " given or not given as the other");
  if (f) require(fn.handle == f->handle && fn.name == (f->text ? f->chars : ""), what + " taken as another");
}

void check_priors_taken(const sba_mex::StructOptions &o, const OptionField *const given[3], std::size_t pnp) {
  require(o.point_priors.size() == (given[0] ? given[0]->numel : 0) &&
              o.linear_priors.size() == (given[1] ? given[1]->numel : 0) &&
              o.camera_priors.size() == (given[2] ? given[2]->numel : 0),
          "another number of priors taken");
  for (std::size_t q = 0; q < o.point_priors.size(); ++q) {
    const sba_mex::PointPrior &p = o.point_priors[q];
    const std::vector<OptionField> &e = given[0]->elements[q];
    require(p.point == element_field(e, "point")->values[0] - 1, "point_priors: point taken as another");
    check_values(p.mean, element_field(e, "mean"), false, "point_priors mean");
    check_base(p, e, static_cast<long long>(pnp), "point_priors");
  }
  for (std::size_t q = 0; q < o.linear_priors.size(); ++q) {
    const sba_mex::LinearPrior &p = o.linear_priors[q];
    const std::vector<OptionField> &e = given[1]->elements[q];
    const OptionField *params = element_field(e, "params");
    require(p.camera == element_field(e, "camera")->values[0] - 1 && p.params.size() == params->numel,
            "camera_linear_priors: camera or params taken as others");
    for (std::size_t c = 0; c < p.params.size(); ++c)
      require(p.params[c] == params->values[c] - 1, "camera_linear_priors: a parameter taken as another");
    check_values(p.mean, element_field(e, "mean"), false, "camera_linear_priors mean");
    check_base(p, e, static_cast<long long>(p.params.size()), "camera_linear_priors");
  }
  for (std::size_t q = 0; q < o.camera_priors.size(); ++q) {
    const sba_mex::CallbackPrior &p = o.camera_priors[q];
    const std::vector<OptionField> &e = given[2]->elements[q];
    require(p.camera == element_field(e, "camera")->values[0] - 1 && p.dim == element_field(e, "dim")->values[0],
            "camera_priors: camera or dim taken as another");
    check_function(p.func, element_field(e, "func"), "camera_priors func");
    check_function(p.jac, element_field(e, "jac"), "camera_priors jac");
    check_base(p, e, p.dim, "camera_priors");
  }
}

bool finite_matrix(const OptionField &f) {
  if (!f.matrix) return false;
  for (double x : f.values)
    if (!std::isfinite(x)) return false;
  return true;
}

bool is_vector(const OptionField &f) { return f.rows == 1 || f.cols == 1; }

// docs/mex.md's rules, whether the fields are an options struct the gateway takes.
bool acceptable(const std::vector<OptionField> &fields, std::size_t m, std::size_t cnp) {
  const OptionField *given[kOptionNames] = {nullptr, nullptr, nullptr, nullptr};
  for (const OptionField &f : fields) {
    std::size_t k = 0;
    while (k < kOptionNames && f.name != kNames[k]) ++k;
    if (k == kOptionNames) return false;  // an unknown field
    if (f.numel > 0) given[k] = &f;
  }
  const OptionField *fixed = given[0], *groups = given[1], *shared = given[2], *per_param = given[3];
  if (fixed && !(finite_matrix(*fixed) &&
                 ((is_vector(*fixed) && fixed->numel == cnp) || (fixed->rows == m && fixed->cols == cnp))))
    return false;
  // Group numbers need only be whole numbers an int holds: which are groups is the library's
  // rule, not the gateway's.
  auto whole_ints = [](const OptionField &f) {
    for (double g : f.values)
      if (g != std::trunc(g) || g < -2147483648.0 || g > 2147483647.0) return false;
    return true;
  };
  if (per_param && !(finite_matrix(*per_param) && !per_param->logical && per_param->rows == m &&
                     per_param->cols == cnp && whole_ints(*per_param)))
    return false;
  if (groups && !(finite_matrix(*groups) && !groups->logical && is_vector(*groups) && groups->numel == m &&
                  whole_ints(*groups)))
    return false;
  return !shared || (finite_matrix(*shared) && is_vector(*shared) && shared->numel == cnp);
}

const OptionField *field(const std::vector<OptionField> &fields, const char *name) {
  for (const OptionField &f : fields)
    if (f.name == name && f.numel > 0) return &f;
  return nullptr;
}

// What camera_options took is what the fields hold.
void check_taken(const sba_mex::CameraOptions &o, const std::vector<OptionField> &fields, std::size_t m,
                 std::size_t cnp) {
  if (const OptionField *f = field(fields, "fixed_params")) {
    require(o.fixed.size() == (o.fixed_per_camera ? m * cnp : cnp), "fixed_params taken with another size");
    for (std::size_t j = 0; j < (o.fixed_per_camera ? m : 1); ++j)
      for (std::size_t c = 0; c < cnp; ++c) {
        const double x = o.fixed_per_camera ? f->values[c * m + j] : f->values[c];
        require(o.fixed[j * cnp + c] == (x != 0 ? 1 : 0), "a fixed_params flag taken as another");
      }
  } else {
    require(o.fixed.empty(), "fixed_params taken from nothing");
  }
  const OptionField *groups = field(fields, "camera_groups"), *shared = field(fields, "shared_params");
  require(o.group.size() == (groups ? m : 0) && o.shared.size() == (shared ? cnp : 0),
          "camera_groups or shared_params taken with another size");
  for (std::size_t j = 0; j < o.group.size(); ++j)
    require(o.group[j] == groups->values[j], "a group number taken as another");
  for (std::size_t c = 0; c < o.shared.size(); ++c)
    require(o.shared[c] == (shared->values[c] != 0 ? 1 : 0), "a shared_params flag taken as another");
  const OptionField *per_param = field(fields, "param_groups");
  require(o.param_group.size() == (per_param ? m * cnp : 0), "param_groups taken with another size");
  for (std::size_t j = 0; per_param && j < m; ++j)
    for (std::size_t c = 0; c < cnp; ++c)
      require(o.param_group[j * cnp + c] == per_param->values[c * m + j],
              "param_groups(" + std::to_string(j + 1) + "," + std::to_string(c + 1) + ") taken as another");
}

// A refusal of a value that is not finite ("param_groups(2,3) is not finite."): the element
// it names is the first such of its field, by (row,col) in a matrix and by (k) in a vector.
void check_not_finite(const ArgError &e, const std::vector<OptionField> &fields) {
  const std::string tail = " is not finite.";
  const std::string &msg = e.message;
  if (msg.size() < tail.size() || msg.compare(msg.size() - tail.size(), tail.size(), tail) != 0) return;
  const std::string where = msg.substr(0, msg.size() - tail.size());
  const OptionField *f = nullptr;
  for (const OptionField &g : fields)
    if (where.compare(0, g.name.size() + 1, g.name + "(") == 0) f = &g;
  require(f && f->matrix, "a value that is not finite named in no matrix field: " + msg);
  std::size_t k = 0;
  while (k < f->values.size() && std::isfinite(f->values[k])) ++k;
  require(k < f->values.size(), "a field of finite values refused as not finite: " + msg);
  const bool as_matrix = f->name == "param_groups" || !is_vector(*f);
  const std::string due = f->name + (as_matrix ? "(" + std::to_string(k % f->rows + 1) + "," +
                                                     std::to_string(k / f->rows + 1) + ")"
                                               : "(" + std::to_string(k + 1) + ")");
  require(where == due, "the value that is not finite named " + where + ", not " + due);
}

void check_refusal(const ArgError &e) {
  require(e.id == "sba:invalidArgument" || e.id == "sba:wrongSize", "a refusal under the identifier " + e.id);
  require(!e.message.empty() && e.message.back() == '.', "a refusal that is not a sentence: " + e.message);
  require(e.message.find('\n') == std::string::npos, "a refusal of more than one line: " + e.message);
  bool named = e.message.find("options struct") != std::string::npos;
  for (std::size_t k = 0; k < kOptionNames; ++k)
    named = named || e.message.find(kNames[k]) != std::string::npos;
  for (const char *name : kPriorNames) named = named || e.message.find(name) != std::string::npos;
  require(named, "a refusal that names no field: " + e.message);
}

void check_role(FuzzedDataProvider &in) {
  const bool is_struct = in.ConsumeBool();
  const std::size_t numel = in.ConsumeIntegralInRange<size_t>(0, 3);
  std::vector<std::string> names;
  bool has_option = false;
  for (int k = in.ConsumeIntegralInRange<int>(0, 3); k > 0; --k) {
    const std::size_t q = in.ConsumeIntegralInRange<size_t>(0, sizeof kNames / sizeof *kNames - 1);
    names.emplace_back(kNames[q]);
    has_option = has_option || q < kOptionNames;
  }
  const sba_mex::StructRole role = sba_mex::struct_role(is_struct, numel, names);
  const sba_mex::StructRole due = !is_struct || !has_option ? sba_mex::StructRole::kData
                                  : numel == 1              ? sba_mex::StructRole::kOptions
                                                            : sba_mex::StructRole::kRefused;
  require(role == due, "a value beside reftype taken for what it is not");
  if (role != sba_mex::StructRole::kRefused) return;
  const std::string what = std::to_string(numel) + "x1 struct";
  try {
    sba_mex::refuse_options_struct(what);
  } catch (const ArgError &e) {
    check_refusal(e);
    require(e.message.find(what) != std::string::npos,
            "the refusal does not say what was given: " + e.message);
    return;
  }
  sbafuzz::broken("refuse_options_struct returned");
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t *data, std::size_t size) {
  FuzzedDataProvider in(data, size);
  check_role(in);
  const std::size_t m = in.ConsumeIntegralInRange<size_t>(1, 6),
                    cnp = in.ConsumeIntegralInRange<size_t>(0, 6);
  std::vector<OptionField> fields;
  for (int k = in.ConsumeIntegralInRange<int>(0, 4); k > 0; --k) {
    OptionField f = next_field(in, m, cnp);
    bool repeated = false;  // a struct's field names are distinct
    for (const OptionField &g : fields) repeated = repeated || g.name == f.name;
    if (!repeated) fields.push_back(std::move(f));
  }
  // The priors after the camera fields, from what is left of the input.
  const std::size_t pnp = in.ConsumeIntegralInRange<size_t>(0, 4);
  const OptionField *given[3] = {nullptr, nullptr, nullptr};
  bool priors_ok = true;
  for (int kind = 0; kind < 3; ++kind)
    if (in.ConsumeBool()) fields.push_back(next_prior_field(in, kind, m, cnp, pnp));
  for (const OptionField &f : fields)
    for (int kind = 0; kind < 3; ++kind)
      if (f.name == kPriorNames[kind]) {
        priors_ok = priors_ok && priors_acceptable(f, kind, pnp);
        if (f.numel > 0) given[kind] = &f;
      }
  // A struct with a prior field alone is the options struct.
  for (int kind = 0; kind < 3; ++kind)
    if (given[kind])
      require(sba_mex::struct_role(true, 1, {kPriorNames[kind]}) == sba_mex::StructRole::kOptions &&
                  sba_mex::struct_role(true, 2, {"foo", kPriorNames[kind]}) == sba_mex::StructRole::kRefused,
              "a struct with a prior field taken for problem data");
  std::vector<OptionField> camera_fields;
  for (const OptionField &f : fields)
    if (f.name != kPriorNames[0] && f.name != kPriorNames[1] && f.name != kPriorNames[2]) camera_fields.push_back(f);
  const bool ok = acceptable(camera_fields, m, cnp) && priors_ok;
  try {
    const sba_mex::StructOptions o = sba_mex::options_struct(fields, m, cnp, pnp);
    require(ok, "an options struct taken against the rules");
    check_taken(o.camera, fields, m, cnp);
    check_priors_taken(o, given, pnp);
  } catch (const ArgError &e) {
    require(!ok, "a good options struct refused: " + e.message);
    check_refusal(e);
    check_not_finite(e, fields);
  }
  return 0;
}
