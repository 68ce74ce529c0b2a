// SPDX-License-Identifier: BSD-3-Clause
// The stop reasons (info[6], sba_ext.h's SBA_STOP_*) in words: the one table behind
// sba_stop_reason_text, which the programs' report and pysba read rather than keep their own.
#include "sba_export.h"

namespace sba {
namespace {

struct ReasonText {
  int reason;
  const char *text;
};
// eucsbademo and balsba print these words on their "Stop reason" line and in --json, so their
// goldens hold them: a change of wording is a change of the programs' output.
constexpr ReasonText kReasonTexts[] = {
    {SBA_STOP_NONE, "nothing ran"},
    {SBA_STOP_GRADIENT, "small gradient: ||J^T e||_inf <= eps1"},
    {SBA_STOP_STEP, "small step: ||dp|| <= eps2 ||p||"},
    {SBA_STOP_ITMAX, "the iteration limit (itmax) was reached"},
    {SBA_STOP_REDUCTION, "small relative reduction of the error (eps4)"},
    {SBA_STOP_ERROR, "small error: ||e|| <= eps3"},
    {SBA_STOP_DAMPING, "the damping could not grow any further (is the Jacobian right?)"},
    {SBA_STOP_NONFINITE, "NaN or Inf in the projections or the Jacobian"},
    {SBA_STOP_SINGULAR, "the augmented normal equations are almost singular"},
    {SBA_STOP_USER, "stopped on request"},
};

}  // namespace
}  // namespace sba

extern "C" const char *sba_stop_reason_text(int reason) {
  for (const sba::ReasonText &r : sba::kReasonTexts)
    if (r.reason == reason) return r.text;
  return "unknown";
}
