// SPDX-License-Identifier: BSD-3-Clause
#include "mex_options.h"

#include <climits>
#include <cmath>

namespace sba_mex {
namespace {

constexpr const char *kOptionFields[] = {"fixed_params", "camera_groups", "shared_params", "param_groups"};

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

CameraOptions camera_options(const std::vector<OptionField> &fields, std::size_t m, std::size_t cnp) {
  const OptionField *fixed = nullptr, *groups = nullptr, *shared = nullptr, *per_param = nullptr;
  for (const OptionField &f : fields) {
    if (!is_option_field(f.name))
      bad_arg("invalidArgument",
              format("the options struct has an unknown field '%s' (expected fixed_params, "
                     "camera_groups, shared_params or param_groups).",
                     f.name.c_str()));
    if (f.numel == 0) continue;  // [] is not given
    (f.name == "fixed_params"    ? fixed
     : f.name == "camera_groups" ? groups
     : f.name == "shared_params" ? shared
                                 : per_param) = &f;
  }
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

}  // namespace sba_mex
