// SPDX-License-Identifier: BSD-3-Clause
#include "option_values.h"

#include <climits>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <utility>

namespace pysba {

Value Value::boolean(bool b) {
  Value v;
  v.kind = kBool;
  v.integer = b ? 1 : 0;
  return v;
}

Value Value::signed_integer(long long i) {
  Value v;
  v.kind = kInt;
  v.integer = i;
  return v;
}

Value Value::unsigned_integer(unsigned long long u) {
  if (u <= static_cast<unsigned long long>(LLONG_MAX)) return signed_integer(static_cast<long long>(u));
  return big_integer(std::to_string(u));
}

Value Value::big_integer(std::string text) {
  Value v;
  v.kind = kInt;
  v.fits = false;
  v.text = std::move(text);
  return v;
}

Value Value::floating(double x) {
  Value v;
  v.kind = kFloat;
  v.real = x;
  return v;
}

Value Value::other(std::string repr) {
  Value v;
  v.text = std::move(repr);
  return v;
}

namespace {

// x as Python's repr writes a float: the fewest digits that read back as x, in positional
// notation from 1e-4 up to 1e16 and in exponent notation outside.
std::string float_text(double x) {
  if (std::isnan(x)) return "nan";
  if (std::isinf(x)) return x < 0 ? "-inf" : "inf";
  char buf[40];
  for (int digits = 1; digits <= 17; ++digits) {
    std::snprintf(buf, sizeof buf, "%.*e", digits - 1, x);
    if (std::strtod(buf, nullptr) == x) break;
  }
  const std::string s = buf;  // [-]d[.ddd]e[+-]XX
  const std::size_t e = s.find('e');
  const int exponent = std::atoi(s.c_str() + e + 1);
  const bool negative = s[0] == '-';
  std::string mantissa;
  for (std::size_t q = negative ? 1 : 0; q < e; ++q)
    if (s[q] != '.') mantissa += s[q];
  const std::string sign = negative ? "-" : "";
  if (exponent < -4 || exponent >= 16) {
    std::snprintf(buf, sizeof buf, "e%c%02d", exponent < 0 ? '-' : '+', std::abs(exponent));
    return sign + mantissa.substr(0, 1) + (mantissa.size() > 1 ? "." + mantissa.substr(1) : "") + buf;
  }
  if (exponent < 0) return sign + "0." + std::string(size_t(-exponent - 1), '0') + mantissa;
  const std::size_t whole = size_t(exponent) + 1;
  if (mantissa.size() <= whole) return sign + mantissa + std::string(whole - mantissa.size(), '0') + ".0";
  return sign + mantissa.substr(0, whole) + "." + mantissa.substr(whole);
}

}  // namespace

std::string python_text(const Value &v) {
  switch (v.kind) {
    case Value::kBool:
      return v.integer ? "True" : "False";
    case Value::kInt:
      return v.fits ? std::to_string(v.integer) : v.text;
    case Value::kFloat:
      return float_text(v.real);
    case Value::kOther:
      break;
  }
  return v.text;
}

char flag_value(const Value &v, const std::string &where) {
  if (v.kind == Value::kBool) return static_cast<char>(v.integer);
  const bool integer = v.kind == Value::kInt;
  if (integer && v.fits && (v.integer == 0 || v.integer == 1)) return static_cast<char>(v.integer);
  // A float, even 1.0, is of the wrong type: flags are not rounded or read by their truth.
  throw OptionError{!integer, where + " must be 0 or 1 (or a bool), got " + python_text(v)};
}

int group_number(const Value &v, const std::string &where) {
  const OptionError out_of_range{false, where + " must be an integer within [" + std::to_string(INT_MIN) + ", " +
                                            std::to_string(INT_MAX) + "], got " + python_text(v)};
  switch (v.kind) {
    case Value::kInt:
      if (!v.fits || v.integer < INT_MIN || v.integer > INT_MAX) throw out_of_range;
      return static_cast<int>(v.integer);
    case Value::kFloat:
      if (!std::isfinite(v.real) || v.real != std::floor(v.real))
        throw OptionError{false, where + " must be an integer, got " + python_text(v)};
      if (v.real < INT_MIN || v.real > INT_MAX) throw out_of_range;
      return static_cast<int>(v.real);
    case Value::kBool:  // a bool is not a group number
    case Value::kOther:
      break;
  }
  throw OptionError{true, where + " must be an integer, got " + python_text(v)};
}

std::string entry_name(const std::string &what, const std::vector<long long> &shape, long long k) {
  std::vector<long long> at(shape.size());
  for (size_t d = shape.size(); d-- > 0;) {
    at[d] = shape[d] > 0 ? k % shape[d] : 0;
    k = shape[d] > 0 ? k / shape[d] : 0;
  }
  std::string s = what + "[";
  for (size_t d = 0; d < at.size(); ++d) s += (d ? ", " : "") + std::to_string(at[d]);
  return s + "]";
}

namespace {

template <class T, class Rule>
std::vector<T> entries(const std::vector<Value> &values, const std::string &what,
                       const std::vector<long long> &shape, Rule rule) {
  std::vector<T> out;
  out.reserve(values.size());
  for (size_t k = 0; k < values.size(); ++k)
    out.push_back(rule(values[k], entry_name(what, shape, static_cast<long long>(k))));
  return out;
}

}  // namespace

std::vector<char> flag_values(const std::vector<Value> &values, const std::string &what,
                              const std::vector<long long> &shape) {
  return entries<char>(values, what, shape, flag_value);
}

std::vector<int> group_numbers(const std::vector<Value> &values, const std::string &what,
                               const std::vector<long long> &shape) {
  return entries<int>(values, what, shape, group_number);
}

std::string shape_text(const std::vector<long long> &shape) {
  std::string t = "(";
  for (size_t d = 0; d < shape.size(); ++d) t += (d ? ", " : "") + std::to_string(shape[d]);
  return t + (shape.size() == 1 ? ",)" : ")");
}

void require_shape(const std::string &what, const std::vector<long long> &shape,
                   const std::vector<long long> &want) {
  if (shape != want)
    throw OptionError{false, what + " must have shape " + shape_text(want) + ", got " + shape_text(shape)};
}

}  // namespace pysba
