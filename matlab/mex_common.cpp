// SPDX-License-Identifier: BSD-3-Clause
#include "mex_common.h"

#include <dlfcn.h>
#include <unistd.h>

#if !SBA_MEX_OCTAVE
// MATLAB: the undocumented but long-standing Ctrl-C query of libut. Weak, so that a MATLAB
// without it still loads the MEX file (Ctrl-C is then noticed only inside .m callbacks).
extern "C" bool utIsInterruptPending(void) __attribute__((weak));
#endif

namespace sba_mex {

const char *reftype_name(RefType r) {
  switch (r) {
    case RefType::MotStr:
      return "motstr";
    case RefType::Mot:
      return "mot";
    case RefType::Str:
      return "str";
  }
  return "";
}

bool interrupt_pending() {
#if SBA_MEX_OCTAVE
  return octave_interrupt_state > 0;
#else
  return utIsInterruptPending != nullptr && utIsInterruptPending();
#endif
}

std::string describe(const mxArray *a) {
  std::string dims;
  const mwSize nd = mxGetNumberOfDimensions(a);
  const mwSize *d = mxGetDimensions(a);
  for (mwSize k = 0; k < nd; ++k) dims += (k ? "x" : "") + std::to_string(d[k]);
  std::string what = mxIsSparse(a) ? "sparse " : "";
  if (mxIsComplex(a)) what += "complex ";
  return dims + " " + what + mxGetClassName(a);
}

bool is_real_double(const mxArray *a) { return mxIsDouble(a) && !mxIsComplex(a) && !mxIsSparse(a); }

std::string string_arg(const mxArray *a) {
  char *s = mxArrayToString(a);
  std::string out = s ? s : "";
  if (s) mxFree(s);
  return out;
}

Library::~Library() {
  if (handle_) dlclose(handle_);
}

void Library::open(const std::string &path, const char *role) {
  // A bare file name is looked up in the current directory first, as MATLAB users expect;
  // dlopen alone would search only the system's library path.
  std::string file = path;
  if (path.find('/') == std::string::npos && access(path.c_str(), F_OK) == 0) file = "./" + path;
  dlerror();
  handle_ = dlopen(file.c_str(), RTLD_NOW | RTLD_LOCAL);
  if (!handle_) {
    const char *why = dlerror();
    bad_arg("libraryNotFound", format("cannot load the library '%s' of %s: %s", path.c_str(),
                                      role, why ? why : "unknown dlopen error"));
  }
}

void *Library::symbol(const std::string &name, const std::string &path, const char *role) {
  dlerror();
  void *fn = dlsym(handle_, name.c_str());
  const char *why = dlerror();
  if (why || !fn)
    bad_arg("functionNotFound",
            format("the function '%s' of %s is not in the library '%s'%s%s", name.c_str(), role,
                   path.c_str(), why ? ": " : ".", why ? why : ""));
  return fn;
}

}  // namespace sba_mex
