// SPDX-License-Identifier: BSD-3-Clause
// libFuzzer target: pysba's rules for the entries of fixed_params, shared_params (flags) and
// camera_groups and param_groups (group numbers), python/src/option_values.h, over entries of
// every kind the extension reads from Python: bools, integers in and beyond long long's range,
// floats of any bits, and other objects by their repr. Each entry is judged against the rules
// as docs/python.md states them: a flag is a bool or an integer 0 or 1; a group number is an
// integer (or a float holding one) that is -1 or in [0, INT_MAX]; whatever is refused is
// refused with one line naming the entry and the value as Python shows it, as a TypeError for
// a wrong kind and a ValueError for a wrong value. The entry names must name the entry. A
// whole array is taken when each of its entries is, in C order (for param_groups of shape
// (m, cnp), the entry named [j, c] at j*cnp + c, the library's layout), and refused at its
// first bad entry otherwise; param_groups' shape must be (m, cnp), else a ValueError that
// says both shapes as Python shows tuples.
#include <fuzzer/FuzzedDataProvider.h>

#include <climits>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

#include "fuzz_common.h"
#include "option_values.h"

namespace {

using pysba::OptionError;
using pysba::Value;
using sbafuzz::require;

double double_from_bits(std::uint64_t bits) {
  double x;
  std::memcpy(&x, &bits, sizeof x);
  return x;
}

Value next_value(FuzzedDataProvider &in) {
  switch (in.ConsumeIntegralInRange<int>(0, 8)) {
    case 0:
      return Value::boolean(in.ConsumeBool());
    case 1:
      return Value::signed_integer(in.ConsumeIntegralInRange<long long>(-3, 3));
    case 2:
      return Value::signed_integer(in.ConsumeIntegral<long long>());
    case 3:
      return Value::unsigned_integer(in.ConsumeIntegral<unsigned long long>());
    case 4: {
      static const double kFloats[] = {0.0, -0.0, 1.0, -1.0, 0.5, 1.2, 2.0, 2147483647.0, 2147483648.0,
                                       -2.0, 1e16, 1e-5, 1e300, NAN, INFINITY, -INFINITY};
      return Value::floating(
          kFloats[in.ConsumeIntegralInRange<size_t>(0, sizeof kFloats / sizeof *kFloats - 1)]);
    }
    case 5:
      return Value::floating(double_from_bits(in.ConsumeIntegral<std::uint64_t>()));
    case 6:
      return Value::floating(in.ConsumeIntegralInRange<int>(-3, 100));
    case 7:
      // beyond long long's range, as Python's ints may be
      return Value::big_integer((in.ConsumeBool() ? "-1" : "1") + std::string(19, '0') +
                                std::to_string(in.ConsumeIntegral<std::uint64_t>()));
    default:
      return Value::other(in.ConsumeRandomLengthString(16));
  }
}

bool one_line(const std::string &s) {
  return s.find('\n') == std::string::npos && s.find('\r') == std::string::npos;
}

// What Python shows: integers exactly, floats so that they read back as the same double and
// as floats (with a point, an exponent, or nan/inf), bools as True and False.
void check_text(const Value &v) {
  const std::string t = pysba::python_text(v);
  switch (v.kind) {
    case Value::kBool:
      require(t == (v.integer ? "True" : "False"), "a bool shown as " + t);
      break;
    case Value::kInt:
      require(!v.fits || t == std::to_string(v.integer), "an integer shown as " + t);
      break;
    case Value::kFloat:
      if (std::isnan(v.real)) {
        require(t == "nan", "NaN shown as " + t);
      } else {
        require(std::strtod(t.c_str(), nullptr) == v.real &&
                    std::signbit(std::strtod(t.c_str(), nullptr)) == std::signbit(v.real),
                "the float shown as " + t + " reads back as another value");
        require(t.find_first_of(".ein") != std::string::npos, "the float shown as " + t + " reads as an int");
      }
      break;
    case Value::kOther:
      require(t == v.text, "another object's repr changed");
      break;
  }
}

// Whether v is an integer in [lo, hi], and which.
bool integer_in(const Value &v, long long lo, long long hi, long long *out) {
  if (v.kind == Value::kInt && v.fits && v.integer >= lo && v.integer <= hi) {
    *out = v.integer;
    return true;
  }
  if (v.kind == Value::kFloat && std::isfinite(v.real) && std::trunc(v.real) == v.real &&
      v.real >= double(lo) && v.real <= double(hi)) {
    *out = static_cast<long long>(v.real);
    return true;
  }
  return false;
}

void check_refusal(const OptionError &e, const std::string &where, const Value &v, bool wrong_type) {
  // An object's repr is its own business, and may hold a line break.
  require(one_line(e.message) || !one_line(pysba::python_text(v)),
          "a refusal of more than one line: " + e.message);
  require(e.message.compare(0, where.size() + 1, where + " ") == 0,
          "a refusal that does not name the entry: " + e.message);
  const std::string got = " got " + pysba::python_text(v);
  require(e.message.size() >= got.size() &&
              e.message.compare(e.message.size() - got.size(), got.size(), got) == 0,
          "a refusal that does not end with the value as given: " + e.message);
  require(e.wrong_type == wrong_type, std::string("a ") + (e.wrong_type ? "TypeError" : "ValueError") +
                                          " where the other is due: " + e.message);
}

void check_flag(const Value &v, const std::string &where) {
  const bool is_flag =
      v.kind == Value::kBool || (v.kind == Value::kInt && v.fits && (v.integer == 0 || v.integer == 1));
  try {
    const char f = pysba::flag_value(v, where);
    require(is_flag, "a flag taken from " + pysba::python_text(v));
    require(f == v.integer, "the flag " + pysba::python_text(v) + " taken as " + std::to_string(int(f)));
  } catch (const OptionError &e) {
    require(!is_flag, "the flag " + pysba::python_text(v) + " refused: " + e.message);
    check_refusal(e, where, v, v.kind == Value::kFloat || v.kind == Value::kOther);
  }
}

void check_group(const Value &v, const std::string &where) {
  long long expected = 0;
  const bool is_group = integer_in(v, INT_MIN, INT_MAX, &expected);
  try {
    const int g = pysba::group_number(v, where);
    require(is_group, "a group number taken from " + pysba::python_text(v));
    require(g == expected, "the group number " + pysba::python_text(v) + " taken as " + std::to_string(g));
  } catch (const OptionError &e) {
    require(!is_group, "the group number " + pysba::python_text(v) + " refused: " + e.message);
    check_refusal(e, where, v, v.kind == Value::kBool || v.kind == Value::kOther);
  }
}

// "what[i, j]" names entry k: each index within its dimension, k in C order.
void check_entry_name(const std::string &name, const std::vector<long long> &shape, long long k) {
  require(name.compare(0, 4, "opt[") == 0 && name.back() == ']', "an entry named " + name);
  const char *s = name.c_str() + 4;
  long long flat = 0;
  for (size_t d = 0; d < shape.size(); ++d) {
    char *end = nullptr;
    const long long i = std::strtoll(s, &end, 10);
    require(end != s && i >= 0 && i < shape[d], "entry " + std::to_string(k) + " named " + name);
    flat = flat * shape[d] + i;
    s = end + (d + 1 < shape.size() ? 2 : 0);
  }
  require(flat == k && std::string(s) == "]", "entry " + std::to_string(k) + " named " + name);
}

// The rule over a whole array: rule_of_array takes every entry or throws the refusal of the
// first it refuses, which must be what rule says of that entry.
template <class T, class ArrayRule, class Rule>
void check_array(const std::vector<Value> &values, const char *what, const std::vector<long long> &shape,
                 ArrayRule rule_of_array, Rule rule) {
  std::vector<T> each;
  std::string first_refusal;
  for (size_t k = 0; k < values.size() && first_refusal.empty(); ++k) {
    try {
      each.push_back(rule(values[k], pysba::entry_name(what, shape, static_cast<long long>(k))));
    } catch (const OptionError &e) {
      first_refusal = e.message;
    }
  }
  try {
    const std::vector<T> all = rule_of_array(values, what, shape);
    require(first_refusal.empty(), "an array taken with a bad entry: " + first_refusal);
    require(all == each, "an array's entries taken as others or in another order");
  } catch (const OptionError &e) {
    require(e.message == first_refusal, "an array refused with " + e.message + ", not " + first_refusal);
  }
}

// A tuple as Python shows it: (), (7,), (4, 7).
std::string tuple(const std::vector<long long> &t) {
  if (t.empty()) return "()";
  if (t.size() == 1) return "(" + std::to_string(t[0]) + ",)";
  std::string s;
  for (long long d : t) s += (s.empty() ? "(" : ", ") + std::to_string(d);
  return s + ")";
}

// param_groups must have shape (m, cnp); m and cnp are often the array's own.
void check_shape(FuzzedDataProvider &in, const std::vector<long long> &shape) {
  const bool fits = shape.size() == 2 && in.ConsumeBool();
  const long long m = fits ? shape[0] : in.ConsumeIntegralInRange<long long>(1, 6);
  const long long cnp = fits ? shape[1] : in.ConsumeIntegralInRange<long long>(0, 6);
  const bool due = shape.size() == 2 && shape[0] == m && shape[1] == cnp;
  try {
    pysba::require_shape("param_groups", shape, {m, cnp});
    require(due, "param_groups of shape " + tuple(shape) + " taken for " + tuple({m, cnp}));
  } catch (const OptionError &e) {
    require(!due, "param_groups of shape " + tuple(shape) + " refused: " + e.message);
    require(!e.wrong_type && e.message == "param_groups must have shape " + tuple({m, cnp}) + ", got " + tuple(shape),
            "a shape refused with " + e.message);
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t *data, std::size_t size) {
  FuzzedDataProvider in(data, size);
  std::vector<long long> shape(in.ConsumeIntegralInRange<size_t>(1, 3));
  long long count = 1;
  for (long long &d : shape) count *= (d = in.ConsumeIntegralInRange<long long>(1, 6));
  std::vector<Value> values;
  for (long long k = 0; k < count && in.remaining_bytes() > 0; ++k) {
    const std::string where = pysba::entry_name("opt", shape, k);
    check_entry_name(where, shape, k);
    values.push_back(next_value(in));
    check_text(values.back());
    check_flag(values.back(), where);
    check_group(values.back(), where);
  }
  if (values.size() == size_t(count)) {
    check_array<char>(values, "fixed_params", shape, pysba::flag_values, pysba::flag_value);
    check_array<int>(values, "param_groups", shape, pysba::group_numbers, pysba::group_number);
  }
  // Shapes of any number of dimensions, empty ones too, against param_groups' (m, cnp).
  if (in.ConsumeBool()) {
    shape.resize(in.ConsumeIntegralInRange<size_t>(0, 3));
    for (long long &d : shape) d = in.ConsumeIntegralInRange<long long>(0, 6);
  }
  check_shape(in, shape);
  return 0;
}
