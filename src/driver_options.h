/* SPDX-License-Identifier: BSD-3-Clause */
// A driver call's options from its C arguments: itmax and opts[] (sba 1.6's), the extension
// options (sba_ext_options), and the environment, which is how an unmodified 1.6 program
// chooses the solver, the strategy and the threads. Translated and checked here, once.
#ifndef SBA_SRC_DRIVER_OPTIONS_H
#define SBA_SRC_DRIVER_OPTIONS_H

#include <string>

#include "driver_args.h"
#include "log.h"
#include "options.h"

namespace sba {

// The environment variables the library reads, as they were at the start of a call. Empty:
// unset or empty, which every one of them treats alike.
struct Environment {
  std::string linsolver;           // SBA_LINSOLVER
  std::string strategy;            // SBA_STRATEGY
  std::string num_threads;         // SBA_NUM_THREADS
  std::string avoid_shared_cores;  // SBA_AVOID_SHARED_CORES
};
Environment read_environment();

// The caller's extension options, read only as far as the caller's struct goes (older
// programs pass a shorter one), the rest at their defaults.
sba_ext_options read_ext(const sba_ext_options *ext);

// *o from a's itmax and opts, then from ext, with env where ext leaves a choice open; the
// values are checked afterwards, once the problem is laid out (Options::is_valid). A setting
// of env that cannot be used is a notice (shown verbose or not: for an unmodified 1.6 program
// nothing else would tell) and otherwise ignored, so that a typo does not stop the program.
// False, with the first name that is not known (a solver, a strategy, a loss) in *error; the
// notices before it have been logged.
bool options_from(const DriverArgs &a, const sba_ext_options &ext, const Environment &env,
                  const Logger &log, Options *o, std::string *error);

}  // namespace sba

#endif
