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
  const bool ok = acceptable(fields, m, cnp);
  try {
    const sba_mex::CameraOptions o = sba_mex::options_struct(fields, m, cnp, 3).camera;
    require(ok, "an options struct taken against the rules");
    check_taken(o, fields, m, cnp);
  } catch (const ArgError &e) {
    require(!ok, "a good options struct refused: " + e.message);
    check_refusal(e);
    check_not_finite(e, fields);
  }
  return 0;
}
