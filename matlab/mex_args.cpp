// SPDX-License-Identifier: BSD-3-Clause
#include "mex_args.h"

#include <cctype>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include "mex_options.h"

namespace sba_mex {
namespace {

bool is_real_numeric(const mxArray *a) {
  return (mxIsNumeric(a) || mxIsLogical(a)) && !mxIsComplex(a);
}

bool is_scalar_value(const mxArray *a) {
  return is_real_numeric(a) && mxGetNumberOfElements(a) == 1;
}

bool is_string(const mxArray *a) {
  return mxIsChar(a) && mxGetNumberOfDimensions(a) == 2 && (mxGetM(a) <= 1);
}

bool is_vector_shape(const mxArray *a) {
  return mxGetNumberOfDimensions(a) == 2 && (mxGetM(a) == 1 || mxGetN(a) == 1);
}

int int_arg(const mxArray *a, const char *name, int lo, int hi, const char *what) {
  if (!is_scalar_value(a))
    bad_arg("invalidArgument",
            format("%s must be %s scalar (got a %s).", name, what, describe(a).c_str()));
  const double v = mxGetScalar(a);
  if (!std::isfinite(v) || v != std::floor(v) || v < lo || v > hi) {
    if (hi == std::numeric_limits<int>::max())
      bad_arg("invalidArgument", format("%s must be %s scalar >= %d (got %g).", name, what, lo, v));
    bad_arg("invalidArgument",
            format("%s must be %s scalar in [%d, %d] (got %g).", name, what, lo, hi, v));
  }
  return static_cast<int>(v);
}

// A real double vector with exactly len values, all finite.
const double *vector_arg(const mxArray *a, const char *name, std::size_t len,
                         const char *len_text) {
  if (!is_real_double(a) || !(is_vector_shape(a) || mxGetNumberOfElements(a) == 0))
    bad_arg("invalidArgument",
            format("%s must be a real vector (got a %s).", name, describe(a).c_str()));
  const std::size_t got = mxGetNumberOfElements(a);
  if (got != len)
    bad_arg("wrongSize",
            format("%s must have %s = %zu values (got %zu).", name, len_text, len, got));
  const double *v = mxGetPr(a);
  for (std::size_t k = 0; k < len; ++k)
    if (!std::isfinite(v[k]))
      bad_arg("invalidArgument", format("%s(%zu) is not finite.", name, k + 1));
  return v;
}

template <typename T>
double load(const unsigned char *e) {
  T v;
  std::memcpy(&v, e, sizeof v);
  return static_cast<double>(v);
}

// Element k (column-major) of a dense real numeric or logical array, as a double: an integer
// beyond 2^53 rounds, which keeps it nonzero.
double element(const mxArray *a, std::size_t k) {
  const unsigned char *e = static_cast<const unsigned char *>(mxGetData(a)) + k * mxGetElementSize(a);
  switch (mxGetClassID(a)) {
    case mxDOUBLE_CLASS: return load<double>(e);
    case mxSINGLE_CLASS: return load<float>(e);
    case mxINT8_CLASS: return load<std::int8_t>(e);
    case mxUINT8_CLASS: return load<std::uint8_t>(e);
    case mxINT16_CLASS: return load<std::int16_t>(e);
    case mxUINT16_CLASS: return load<std::uint16_t>(e);
    case mxINT32_CLASS: return load<std::int32_t>(e);
    case mxUINT32_CLASS: return load<std::uint32_t>(e);
    case mxINT64_CLASS: return load<std::int64_t>(e);
    case mxUINT64_CLASS: return load<std::uint64_t>(e);
    default: return *e != 0 ? 1.0 : 0.0;  // logical
  }
}

// vmask as 1.6's n*m chars (vmask[i*m + j]: point i seen by camera j), dense or sparse.
std::vector<char> read_vmask(const mxArray *a, int n, int m, long long *nvis) {
  if (!is_real_numeric(a) || mxGetNumberOfDimensions(a) != 2)
    bad_arg("invalidArgument",
            format("vmask must be a real n x m matrix (got a %s).", describe(a).c_str()));
  if (mxGetM(a) != static_cast<std::size_t>(n) || mxGetN(a) != static_cast<std::size_t>(m))
    bad_arg("wrongSize",
            format("vmask must be n x m = %d x %d (got %zu x %zu).", n, m,
                   static_cast<std::size_t>(mxGetM(a)), static_cast<std::size_t>(mxGetN(a))));
  std::vector<char> mask(static_cast<std::size_t>(n) * m, 0);
  if (mxIsSparse(a)) {
    const mwIndex *ir = mxGetIr(a), *jc = mxGetJc(a);
    const bool logical = mxIsLogical(a);
    const mxLogical *lv = logical ? mxGetLogicals(a) : nullptr;
    const double *dv = logical ? nullptr : mxGetPr(a);
    for (int j = 0; j < m; ++j)
      for (mwIndex k = jc[j]; k < jc[j + 1]; ++k)
        if (logical ? lv[k] != 0 : dv[k] != 0.0) mask[ir[k] * m + j] = 1;
  } else {
    for (int j = 0; j < m; ++j)
      for (int i = 0; i < n; ++i)
        mask[static_cast<std::size_t>(i) * m + j] =
            element(a, static_cast<std::size_t>(j) * n + i) != 0.0 ? 1 : 0;
  }
  long long count = 0;
  for (char c : mask) count += c != 0;
  *nvis = count;
  return mask;
}

// The role of a value beside reftype (mex_options.h).
StructRole role(const mxArray *a) {
  std::vector<std::string> fields;
  if (mxIsStruct(a))
    for (int f = 0; f < mxGetNumberOfFields(a); ++f) fields.emplace_back(mxGetFieldNameByNumber(a, f));
  return struct_role(mxIsStruct(a), mxGetNumberOfElements(a), fields);
}

// A host value as the options struct's rules see it (mex_options.h), with the fields of every
// element of a struct array.
OptionField option_field(const std::string &name, const mxArray *v) {
  OptionField o;
  o.name = name;
  if (!v) return o;  // an element whose field was never set: []
  o.numel = mxGetNumberOfElements(v);
  o.description = describe(v);
  o.matrix = is_real_numeric(v) && !mxIsSparse(v) && mxGetNumberOfDimensions(v) == 2;
  if (o.matrix) {
    o.logical = mxIsLogical(v);
    o.rows = mxGetM(v);
    o.cols = mxGetN(v);
    for (std::size_t k = 0; k < o.numel; ++k) o.values.push_back(element(v, k));
  }
  o.text = is_string(v);
  if (o.text) o.chars = string_arg(v);
  o.handle = mxGetClassID(v) == mxFUNCTION_CLASS;
  o.is_struct = mxIsStruct(v);
  for (std::size_t q = 0; o.is_struct && q < o.numel; ++q) {
    std::vector<OptionField> fields;
    for (int f = 0; f < mxGetNumberOfFields(v); ++f)
      fields.push_back(option_field(mxGetFieldNameByNumber(v, f), mxGetFieldByNumber(v, q, f)));
    o.elements.push_back(std::move(fields));
  }
  return o;
}

// The options struct s: held and shared camera parameters in sba_ext_options' layout, and the
// priors, with the function handles of the callback priors taken from s itself (which outlives
// the call).
void read_options_struct(Gateway &g, const mxArray *s) {
  std::vector<OptionField> fields;
  for (int f = 0; f < mxGetNumberOfFields(s); ++f)
    fields.push_back(option_field(mxGetFieldNameByNumber(s, f), mxGetFieldByNumber(s, 0, f)));
  StructOptions o = options_struct(fields, static_cast<std::size_t>(g.m), static_cast<std::size_t>(g.cnp),
                                   static_cast<std::size_t>(g.pnp));
  g.cam_fixed = std::move(o.camera.fixed);
  g.cam_fixed_per_camera = o.camera.fixed_per_camera;
  g.cam_group = std::move(o.camera.group);
  g.cam_shared = std::move(o.camera.shared);
  g.cam_param_group = std::move(o.camera.param_group);
  g.point_priors = std::move(o.point_priors);
  g.linear_priors = std::move(o.linear_priors);
  g.camera_priors = std::move(o.camera_priors);
  const mxArray *priors = mxGetField(s, 0, "camera_priors");
  for (std::size_t q = 0; q < g.camera_priors.size(); ++q) {
    const CallbackPrior &p = g.camera_priors[q];
    PriorCallbacks cb;
    cb.where = format("camera_priors(%zu)", q + 1);
    cb.func = HostFunction{p.func.name, p.func.handle ? mxGetField(priors, q, "func") : nullptr};
    if (p.jac.given) cb.jac = HostFunction{p.jac.name, p.jac.handle ? mxGetField(priors, q, "jac") : nullptr};
    g.prior_callbacks.push_back(std::move(cb));
  }
}

void parse_callback(Callback &cb, const std::string &text, const char *role) {
  cb.text = text;
  const std::size_t at = text.find('@');
  if (at == std::string::npos) {
    cb.kind = Callback::kHost;
    cb.name = text;
    if (text.empty()) bad_arg("invalidArgument", format("%s must name a function.", role));
    return;
  }
  cb.kind = Callback::kNative;
  cb.name = text.substr(0, at);
  const std::string lib = text.substr(at + 1);
  if (cb.name.empty() || lib.empty())
    bad_arg("invalidArgument",
            format("%s '%s' must be NAME@LIBRARY with both parts given.", role, text.c_str()));
  cb.library.open(lib, role);
  cb.native = cb.library.symbol(cb.name, lib, role);
}

// Checks that a host function exists, so that a typo is reported as such; role names it.
void check_host_function(const std::string &fn, const std::string &role) {
  mxArray *name = mxCreateString(fn.c_str());
  mxArray *out = nullptr;
  bool found = true;
#if SBA_MEX_OCTAVE
  try {
    if (mexCallMATLAB(1, &out, 1, &name, "exist") == 0 && out) found = mxGetScalar(out) != 0;
  } catch (const octave::execution_exception &) {
    found = true;  // cannot tell: the trial call reports what goes wrong
  }
#else
  mxArray *ex = mexCallMATLABWithTrap(1, &out, 1, &name, "exist");
  if (ex)
    mxDestroyArray(ex);
  else if (out)
    found = mxGetScalar(out) != 0;
#endif
  if (out) mxDestroyArray(out);
  mxDestroyArray(name);
  if (!found) bad_arg("functionNotFound", format("%s: no function named '%s' was found.", role.c_str(), fn.c_str()));
}

void check_host_function(const Callback &cb, const char *role) {
  if (cb.kind == Callback::kHost) check_host_function(cb.name, role);
}

// opts: up to SBA_OPTSSZ finite values, the defaults for the rest (said in *warning).
void read_opts(Gateway &g, const mxArray *o, std::string *warning) {
  const std::size_t len = mxGetNumberOfElements(o);
  const double *v = mxGetPr(o);
  for (std::size_t q = 0; q < len; ++q) {
    if (!std::isfinite(v[q])) bad_arg("invalidArgument", format("opts(%zu) is not finite.", q + 1));
    g.opts[q] = v[q];
  }
  if (len > 0 && len < SBA_OPTSSZ)
    *warning = format(
        "opts has %zu of the %d values; the defaults are used for the rest "
        "(tau 1e-03, eps1 to eps3 1e-12, eps4 0).",
        len, SBA_OPTSSZ);
}

// 'strategy=NAME' and the options struct (beyond 1.6), which may come just before or just
// after reftype, each once; no reftype or problem data of a 1.6 call begins so.
struct TrailingOptions {
  Gateway &g;
  int nrhs;
  const mxArray **prhs;
  bool have_struct = false;

  bool strategy(int at) {
    if (!mxIsChar(prhs[at])) return false;
    const std::string v = string_arg(prhs[at]);
    if (v.compare(0, 9, "strategy=") != 0) return false;
    g.strategy = v.substr(9);
    if (!sba_strategy_valid(g.strategy.c_str()))
      bad_arg("unknownStrategy", format("unknown strategy '%s' (expected one of: %s).", g.strategy.c_str(),
                                        sba_strategy_names()));
    return true;
  }
  // Whether argument `at` is one of them (read), else it is left.
  bool take(int at) {
    if (at >= nrhs) return false;
    if (g.strategy.empty() && strategy(at)) return true;
    if (have_struct) return false;
    switch (role(prhs[at])) {
      case StructRole::kData:
        return false;
      case StructRole::kRefused:
        refuse_options_struct(describe(prhs[at]));
      case StructRole::kOptions:
        break;
    }
    read_options_struct(g, prhs[at]);
    have_struct = true;
    return true;
  }
};

RefType reftype_arg(const mxArray *a) {
  std::string r = string_arg(a);
  for (char &c : r) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  if (r == "motstr") return RefType::MotStr;
  if (r == "mot") return RefType::Mot;
  if (r == "str") return RefType::Str;
  bad_arg("unknownReftype", format("unknown reftype '%s' (expected 'motstr', 'mot' or 'str').", r.c_str()));
}

// What depends on the reftype and the sizes: the camera options, cnp and pnp, vmask, and p0,
// x and covx of their lengths.
void check_problem(Gateway &g, const mxArray *p0, const mxArray *x, const mxArray *covx) {
  const bool camera_options =
      !g.cam_fixed.empty() || !g.cam_group.empty() || !g.cam_shared.empty() || !g.cam_param_group.empty();
  if (g.reftype == RefType::Str && camera_options)
    bad_arg("invalidArgument",
            "fixed_params, camera_groups, shared_params and param_groups apply to cameras, which reftype "
            "'str' does not refine.");
  if (g.reftype != RefType::Str && g.cnp == 0)
    bad_arg("invalidArgument", format("cnp must be positive for reftype '%s'.", reftype_name(g.reftype)));
  if (g.reftype != RefType::Mot && g.pnp == 0)
    bad_arg("invalidArgument", format("pnp must be positive for reftype '%s'.", reftype_name(g.reftype)));
  if (g.nvis == 0) bad_arg("invalidArgument", "vmask has no nonzero entry: there is nothing to fit.");
  const std::size_t nvars = static_cast<std::size_t>(g.m) * g.cnp + static_cast<std::size_t>(g.n) * g.pnp;
  const double *pv = vector_arg(p0, "p0", nvars, "m*cnp + n*pnp");
  g.p0.assign(pv, pv + nvars);
  g.p0_arg = p0;
  const std::size_t nobs = static_cast<std::size_t>(g.nvis) * g.mnp;
  g.x = vector_arg(x, "x", nobs, "nvis*mnp (nvis: the nonzeros of vmask)");
  if (covx && mxGetNumberOfElements(covx) > 0) g.covx = vector_arg(covx, "covx", nobs * g.mnp, "nvis*mnp*mnp");
}

// proj and projac, the extra arguments a native one is handed, and that a host one exists.
void read_callbacks(Gateway &g, const std::string &proj, const std::string &projac) {
  parse_callback(g.proj, proj, "proj");
  if (!projac.empty()) parse_callback(g.projac, projac, "projac");
  if (g.proj.kind == Callback::kNative || g.projac.kind == Callback::kNative) {
    for (std::size_t q = 0; q < g.extra.size(); ++q) {
      const mxArray *e = g.extra[q];
      if (!mxIsDouble(e) || mxIsComplex(e) || mxIsSparse(e))
        bad_arg("invalidArgument",
                format("extra argument %zu must be a real dense double array for NAME@LIBRARY "
                       "callbacks (got a %s).",
                       q + 1, describe(e).c_str()));
      g.extra_ptrs.push_back(mxGetPr(e));
    }
  }
  g.extra_ptrs.push_back(nullptr);  // never empty: data() is valid even without extra data
  check_host_function(g.proj, "proj");
  check_host_function(g.projac, "projac");
  for (const PriorCallbacks &p : g.prior_callbacks) {
    if (!p.func.handle) check_host_function(p.func.name, p.where + ".func");
    if (!p.jac.handle && !p.jac.name.empty()) check_host_function(p.jac.name, p.where + ".jac");
  }
}

}  // namespace

// The argument list of 1.6 (docs/mex.md, "The call").
void parse(Gateway &g, int nrhs, const mxArray *prhs[], std::string *warning) {
  if (nrhs < 12)
    bad_arg("notEnoughInputs",
            format("at least 12 input arguments are needed (n, ncon, m, mcon, vmask, p0, cnp, pnp, "
                   "x, mnp, proj, itmax); got %d.",
                   nrhs));
  const int kIntMax = std::numeric_limits<int>::max();
  g.n = int_arg(prhs[0], "n", 1, kIntMax, "a positive integer");
  g.ncon = int_arg(prhs[1], "ncon", 0, g.n, "an integer");
  g.m = int_arg(prhs[2], "m", 1, kIntMax, "a positive integer");
  g.mcon = int_arg(prhs[3], "mcon", 0, g.m, "an integer");
  g.vmask = read_vmask(prhs[4], g.n, g.m, &g.nvis);
  const mxArray *p0 = prhs[5];
  g.cnp = int_arg(prhs[6], "cnp", 0, 1 << 20, "a non-negative integer");
  g.pnp = int_arg(prhs[7], "pnp", 0, 1 << 20, "a non-negative integer");
  const mxArray *x = prhs[8];

  int k = 9;
  const mxArray *covx = nullptr;
  if (!is_scalar_value(prhs[k])) covx = prhs[k++];  // a scalar right after x is mnp
  if (k >= nrhs) bad_arg("notEnoughInputs", "mnp, proj and itmax are missing.");
  g.mnp = int_arg(prhs[k++], "mnp", 1, 1 << 20, "a positive integer");

  if (k >= nrhs || !is_string(prhs[k]))
    bad_arg("invalidArgument", format("proj must be a function name or 'NAME@LIBRARY' (got %s).",
                                      k < nrhs ? ("a " + describe(prhs[k])).c_str() : "nothing"));
  const std::string proj = string_arg(prhs[k++]);
  std::string projac;
  if (k < nrhs && is_string(prhs[k])) projac = string_arg(prhs[k++]);
  if (k >= nrhs) bad_arg("notEnoughInputs", "itmax is missing.");
  g.itmax = int_arg(prhs[k++], "itmax", 0, kIntMax, "a non-negative integer");
  if (k < nrhs && is_scalar_value(prhs[k])) {
    const double v = mxGetScalar(prhs[k++]);
    if (!std::isfinite(v)) bad_arg("invalidArgument", "verbose must be a finite scalar.");
    g.verbose = v > 100 ? 100 : (v < 0 ? 0 : static_cast<int>(v));
  }
  if (k < nrhs && is_real_double(prhs[k]) && mxGetNumberOfElements(prhs[k]) <= SBA_OPTSSZ &&
      (is_vector_shape(prhs[k]) || mxGetNumberOfElements(prhs[k]) == 0))
    read_opts(g, prhs[k++], warning);
  TrailingOptions options{g, nrhs, prhs};
  while (options.take(k)) ++k;
  if (k < nrhs && mxIsChar(prhs[k])) g.reftype = reftype_arg(prhs[k++]);
  while (options.take(k)) ++k;
  for (; k < nrhs; ++k) g.extra.push_back(prhs[k]);
  check_problem(g, p0, x, covx);
  read_callbacks(g, proj, projac);
}

}  // namespace sba_mex
