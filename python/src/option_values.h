/* SPDX-License-Identifier: BSD-3-Clause */
// What pysba takes as camera parameter flags (fixed_params, shared_params) and as group
// numbers (camera_groups, param_groups), without Python: session.cpp reads the caller's
// objects into Values, and fuzz/ calls the same rules directly.
//
// A flag is a bool, or an integer that is 0 or 1. A group number is an integer, -1 (no
// group) or in [0, INT_MAX], given as an integer or as a float that holds one. Nothing is
// rounded, wrapped or read by its truth value: anything else is refused with an OptionError
// that names the entry and the value as the caller gave it.
#ifndef PYSBA_OPTION_VALUES_H
#define PYSBA_OPTION_VALUES_H

#include <string>
#include <vector>

namespace pysba {

// One entry of an option array, as the caller gave it.
struct Value {
  enum Kind { kBool, kInt, kFloat, kOther };
  Kind kind = kOther;
  long long integer = 0;  // kBool (0 or 1), and kInt when it fits
  bool fits = true;       // kInt: false for an integer beyond long long's range
  double real = 0;        // kFloat
  std::string text;       // kOther, and a kInt that does not fit: how Python shows it (repr)

  static Value boolean(bool b);
  static Value signed_integer(long long i);
  static Value unsigned_integer(unsigned long long u);
  static Value big_integer(std::string text);  // an int beyond long long's range
  static Value floating(double x);
  static Value other(std::string repr);
};

// A refused entry: a TypeError (wrong_type) or a ValueError for the caller.
struct OptionError {
  bool wrong_type;
  std::string message;
};

// v as Python shows it: True, -1, 0.5, 1e+16, nan, or the text given.
std::string python_text(const Value &v);

// The flag at `where` (such as "fixed_params[2]"): 0 or 1. Throws OptionError.
char flag_value(const Value &v, const std::string &where);

// The group number at `where` (such as "camera_groups[3]") as the library's int: an integer an
// int holds (which numbers are groups is the library's rule). Throws OptionError.
int group_number(const Value &v, const std::string &where);

// "what[i, j]": the entry at flat index k (C order) of an array of the given shape.
std::string entry_name(const std::string &what, const std::vector<long long> &shape, long long k);

// The entries of the array `what` (values in C order, of the given shape), each read by
// flag_value or group_number under its entry_name. Throws OptionError at the first bad one.
std::vector<char> flag_values(const std::vector<Value> &values, const std::string &what,
                              const std::vector<long long> &shape);
std::vector<int> group_numbers(const std::vector<Value> &values, const std::string &what,
                               const std::vector<long long> &shape);

// A shape as Python shows the tuple: (), (7,), (4, 7).
std::string shape_text(const std::vector<long long> &shape);

// Throws OptionError (a ValueError) unless shape is want: "what must have shape (4, 7), got
// (4, 6)".
void require_shape(const std::string &what, const std::vector<long long> &shape,
                   const std::vector<long long> &want);

}  // namespace pysba

#endif  // PYSBA_OPTION_VALUES_H
