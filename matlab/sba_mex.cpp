// SPDX-License-Identifier: BSD-3-Clause
// The MATLAB / GNU Octave gateway of sba (calling convention: docs/mex.md;
// help text: sba.m).
//
//   [ret, popt, info] = sba(n, ncon, m, mcon, vmask, p0, cnp, pnp, x, [covx,] mnp, proj,
//                           [projac,] itmax, [verbose,] [opts,] [reftype,] extra...)
//
// It keeps sba 1.6's calling convention and runs the simple drivers of the extension API
// (sba_ext.h) so that the library's messages go through the host's print function and a
// pending Ctrl-C stops the solve between callbacks.
//
// Error discipline. Raising a host error (mexErrMsgIdAndTxt) leaves the MEX file by a
// non-local exit: under MATLAB it may skip C++ destructors, and from inside a callback it would
// also cross the library's frames. So nothing here raises while a C++ object is alive or a
// solve is running. A failure is recorded in the Gateway state, the callbacks stop the solve
// (they answer NaN, which the library treats as fatal, and the progress callback asks it to
// stop), run_gateway() returns and destroys everything, and only then does mexFunction() raise
// the error, the warning or the host's own interrupt.
//
// The parts: mex_args.cpp parses the arguments, mex_callbacks.cpp bridges the callbacks and runs
// the solve, this file is the gateway; mex_common.h holds what they share.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <new>
#include <string>
#include <vector>

#include "mex_args.h"
#include "mex_callbacks.h"
#include "mex_common.h"

// Octave's mexErrMsgIdAndTxt and mexWarnMsgIdAndTxt put "sba: " (the MEX file's name) in front of
// the message themselves; MATLAB's do not.
#ifndef SBA_MEX_HOST_PREFIXES
#define SBA_MEX_HOST_PREFIXES SBA_MEX_OCTAVE
#endif

namespace {

using namespace sba_mex;

// What mexFunction() does after run_gateway() has returned and freed everything. Plain data:
// it outlives the C++ objects and survives a non-local exit.
struct Outcome {
  enum Kind { kOk, kError, kInterrupt } kind = kOk;
  char id[64] = {0};
  char message[kMaxMessage] = {0};
  char warning_id[64] = {0};
  char warning[kMaxMessage] = {0};
  char solver_warning[kMaxMessage] = {0};  // id sba:solverFailed
};

void copy_text(char *dst, std::size_t size, const std::string &src) {
  std::snprintf(dst, size, "%s", src.c_str());
}

// The first line of a block of text.
std::string first_line(const std::string &s) { return s.substr(0, s.find('\n')); }

// The parameters the driver refines: all of p0, its cameras or its points.
std::vector<double> refined_params(const Gateway &g) {
  const std::size_t acount = static_cast<std::size_t>(g.m) * g.cnp;
  if (g.reftype == RefType::Mot) return std::vector<double>(g.p0.begin(), g.p0.begin() + acount);
  if (g.reftype == RefType::Str) return std::vector<double>(g.p0.begin() + acount, g.p0.end());
  return g.p0;
}

// sba 1.6's demo's lines, with verbose.
void print_result(const Gateway &g, int ret, const double info[SBA_INFOSZ], double seconds) {
  long long nvars = 0;
  if (g.reftype != RefType::Str) nvars += static_cast<long long>(g.m) * g.cnp;
  if (g.reftype != RefType::Mot) nvars += static_cast<long long>(g.n) * g.pnp;
  mexPrintf("SBA using %d 3D pts, %d frames and %lld image projections, %lld variables\n", g.n, g.m, g.nvis,
            nvars);
  mexPrintf(
      "\nSBA returned %d in %g iter, reason %g, error %g [initial %g], %d/%d func/fjac "
      "evals, %d lin. systems\n",
      ret, info[5], info[6], info[1] / double(g.nvis), info[0] / double(g.nvis), static_cast<int>(info[7]),
      static_cast<int>(info[8]), static_cast<int>(info[9]));
  mexPrintf("Elapsed time: %.2f seconds, %.2f msecs\n", seconds, seconds * 1000.0);
}

// [ret, popt, info]: popt is p0 with the refined part p replaced, in p0's orientation.
void set_outputs(const Gateway &g, const std::vector<double> &p, int ret, const double info[SBA_INFOSZ], int nlhs,
                 mxArray *plhs[]) {
  plhs[0] = mxCreateDoubleScalar(ret);
  if (nlhs > 1) {
    std::vector<double> popt = g.p0;
    const std::size_t off = g.reftype == RefType::Str ? static_cast<std::size_t>(g.m) * g.cnp : 0;
    std::copy(p.begin(), p.end(), popt.begin() + off);
    mxArray *po = mxCreateDoubleMatrix(mxGetM(g.p0_arg), mxGetN(g.p0_arg), mxREAL);
    std::memcpy(mxGetPr(po), popt.data(), sizeof(double) * popt.size());
    plhs[1] = po;
  }
  if (nlhs > 2) {
    mxArray *io = mxCreateDoubleMatrix(1, SBA_INFOSZ, mxREAL);
    std::memcpy(mxGetPr(io), info, sizeof(double) * SBA_INFOSZ);
    plhs[2] = io;
  }
}

// Does the whole call. Every C++ object lives in here; what is left to raise goes to *out, and
// an exception of the host to *rethrow.
void run_gateway(int nlhs, mxArray *plhs[], int nrhs, const mxArray *prhs[], Outcome *out,
                 std::exception_ptr *rethrow) {
  auto error = [&](const std::string &id, const std::string &message) {
    out->kind = Outcome::kError;
    copy_text(out->id, sizeof out->id, id);
    copy_text(out->message, sizeof out->message, message);
  };
  try {
    if (nlhs > 3) return error("sba:tooManyOutputs", "at most 3 outputs: [ret, popt, info].");
    Gateway g;
    std::string warning;
    parse(g, nrhs, prhs, &warning);
    if (!warning.empty()) {
      copy_text(out->warning_id, sizeof out->warning_id, "sba:shortOpts");
      copy_text(out->warning, sizeof out->warning, warning);
    }

    trial_call(g);

    std::vector<double> p = refined_params(g);
    double info[SBA_INFOSZ] = {0};
    int ret = SBA_ERROR;
    double seconds = 0;
    if (g.state == Gateway::State::kRunning) {
      const auto t0 = std::chrono::steady_clock::now();
      ret = solve(g, p, info);
      seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    }

    switch (g.state) {
      case Gateway::State::kRunning:
        break;
      case Gateway::State::kFailed:
        return error(g.error_id, g.error_message);
      case Gateway::State::kInterrupted:
      case Gateway::State::kHostException:
        if (g.state == Gateway::State::kInterrupted || g.host_exception_is_interrupt)
          mexPrintf("sba: interrupted after %d iterations; no result is returned.\n",
                    g.last_iteration);
        if (g.state == Gateway::State::kHostException) {
          *rethrow = g.host_exception;
        } else {
          out->kind = Outcome::kInterrupt;
        }
        return;
    }
    if (ret == SBA_ERROR && info[6] == SBA_STOP_NONE)  // nothing ran: the solver refused the input
      return error("sba:invalidProblem",
                   "the solver refused the problem: " + (g.solver_errors.empty()
                                                             ? std::string("unknown reason")
                                                             : first_line(g.solver_errors)));
    if (!g.solver_errors.empty()) {
      std::string text = g.solver_errors;
      if (text.back() == '\n') text.pop_back();
      copy_text(out->solver_warning, sizeof out->solver_warning, text);
    }

    if (g.verbose) print_result(g, ret, info, seconds);

    set_outputs(g, p, ret, info, nlhs, plhs);
  } catch (const ArgError &e) {
    error(e.id, e.message);
  } catch (const std::bad_alloc &) {
    error("sba:outOfMemory", "out of memory.");
  } catch (const std::exception &e) {
    error("sba:internal", std::string("internal error: ") + e.what());
  } catch (...) {
    // Something of the host's outside a callback (e.g. an interrupt during a host call made
    // while parsing): let the host handle it once everything here is gone.
    *rethrow = std::current_exception();
  }
}

[[noreturn]] void raise_interrupt() {
#if SBA_MEX_OCTAVE
  // Octave's own interrupt, as if a builtin had been interrupted: back to the prompt.
  octave_quit();
  octave_handle_signal();
#endif
  mexErrMsgIdAndTxt("sba:interrupted", "%sinterrupted by the user.",
                    SBA_MEX_HOST_PREFIXES ? "" : "sba: ");
  std::abort();  // not reached: mexErrMsgIdAndTxt does not return
}

}  // namespace

void mexFunction(int nlhs, mxArray *plhs[], int nrhs, const mxArray *prhs[]) {
  Outcome out;
  {
    std::exception_ptr rethrow;
    run_gateway(nlhs, plhs, nrhs, prhs, &out, &rethrow);
    if (rethrow) std::rethrow_exception(rethrow);
  }
  // Nothing with a destructor is alive from here on.
  const char *prefix = SBA_MEX_HOST_PREFIXES ? "" : "sba: ";
  if (out.warning[0]) mexWarnMsgIdAndTxt(out.warning_id, "%s%s", prefix, out.warning);
  if (out.solver_warning[0])
    mexWarnMsgIdAndTxt("sba:solverFailed", "%s%s", prefix, out.solver_warning);
  if (out.kind == Outcome::kInterrupt) raise_interrupt();
  if (out.kind == Outcome::kError) mexErrMsgIdAndTxt(out.id, "%s%s", prefix, out.message);
}
