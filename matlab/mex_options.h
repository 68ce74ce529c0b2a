// SPDX-License-Identifier: BSD-3-Clause
// The options struct of the MEX gateway (beyond 1.6; docs/mex.md, "Held and shared camera
// parameters"): which value beside reftype is one, and what its fields hold. The rules are
// written over plain values, not the host's arrays: mex_args.cpp describes the host's value
// to them, and fuzz/ calls them directly.
#ifndef SBA_MATLAB_MEX_OPTIONS_H
#define SBA_MATLAB_MEX_OPTIONS_H

#include <cstddef>
#include <string>
#include <vector>

#include "mex_error.h"

namespace sba_mex __attribute__((visibility("hidden"))) {

// What a value beside reftype is.
enum class StructRole {
  kData,     // problem data, as in 1.6: not a struct, or a struct without any option field
  kOptions,  // the options struct: a 1x1 struct with at least one option field
  kRefused,  // a struct array (or an empty struct) with an option field
};

// The role of a value: is_struct, its number of elements and its field names.
StructRole struct_role(bool is_struct, std::size_t numel, const std::vector<std::string> &fields);

// Raises bad_arg for a value whose role is kRefused; description says what it is ("1x2 struct").
[[noreturn]] void refuse_options_struct(const std::string &description);

// One field of the options struct, as the host gave it.
struct OptionField {
  std::string name;
  std::size_t numel = 0;           // 0: not given ([])
  bool matrix = false;             // a dense real numeric or logical 2-D array
  bool logical = false;            // a logical one, when matrix
  std::size_t rows = 0, cols = 0;  // its size, when matrix
  std::vector<double> values;      // its values column-major, when matrix
  std::string description;         // what it is, for messages ("1x3 cell")
};

// The held and shared camera parameters in sba_ext_options' layout: fixed has cnp flags
// (every camera; fixed_per_camera false) or m*cnp (camera j's at j*cnp); group m numbers or
// empty; shared cnp flags or empty; param_group m*cnp numbers (camera j's parameter c at
// j*cnp + c) or empty. Only the fields' types and sizes are checked here: which combinations
// and group numbers are valid is the library's to check (Options::is_valid), and its message
// is what the caller sees.
struct CameraOptions {
  std::vector<char> fixed;
  bool fixed_per_camera = false;
  std::vector<int> group;
  std::vector<char> shared;
  std::vector<int> param_group;
};

// The fields of an options struct for m cameras of cnp parameters. Raises bad_arg
// (sba:invalidArgument, sba:wrongSize) naming the field at the first bad one.
CameraOptions camera_options(const std::vector<OptionField> &fields, std::size_t m, std::size_t cnp);

}  // namespace sba_mex

#endif
