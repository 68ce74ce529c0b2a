// SPDX-License-Identifier: BSD-3-Clause
// The options struct of the MEX gateway (beyond 1.6; docs/mex.md, "Held and shared camera
// parameters" and "Priors"): which value beside reftype is one, and what its fields hold. The rules are
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
  bool text = false;               // a char row vector (or ''), its characters in chars
  std::string chars;
  bool handle = false;  // a function handle
  // A struct array: each element's fields (numel of them, column-major), each list in the
  // struct's field order.
  bool is_struct = false;
  std::vector<std::vector<OptionField>> elements;
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

// A prior's weight as sba_prior_weight's arrays, row-major; an empty one is not given.
struct PriorWeight {
  std::vector<double> sigma, covariance, sqrt_info;
};

// What the three kinds of prior share. The indices are the library's, from 0.
struct PriorBase {
  PriorWeight weight;
  bool has_loss = false;  // loss given ('' counts: the library takes it as unknown)
  std::string loss;
  double loss_scale = 0;
};

struct PointPrior : PriorBase {
  int point = 0;
  std::vector<double> mean;  // pnp values
};

struct LinearPrior : PriorBase {
  int camera = 0;
  std::vector<int> params;   // k parameter indices
  std::vector<double> mean;  // k values
};

// A function of a callback prior: a function's name, or a function handle (the gateway takes
// the handle itself from the struct).
struct PriorFunction {
  bool given = false, handle = false;
  std::string name;  // when given and not a handle
};

struct CallbackPrior : PriorBase {
  int camera = 0;
  int dim = 0;
  PriorFunction func, jac;  // jac not given: forward differences
};

// Every field of the options struct, read.
struct StructOptions {
  CameraOptions camera;
  std::vector<PointPrior> point_priors;
  std::vector<LinearPrior> linear_priors;
  std::vector<CallbackPrior> camera_priors;
};

// The fields of an options struct for m cameras of cnp parameters and points of pnp. Raises
// bad_arg (sba:invalidArgument, sba:wrongSize) naming the field, or the prior and its field
// ("point_priors(2).mean"), at the first bad one. As for the held and shared parameters, only
// the priors' types and sizes are checked here, the sizes the library will read: whether an
// index names a camera or point that a prior may constrain, and whether a mean, weight or loss
// can be used, is the library's check (its message names the prior).
StructOptions options_struct(const std::vector<OptionField> &fields, std::size_t m, std::size_t cnp, std::size_t pnp);

}  // namespace sba_mex

#endif
