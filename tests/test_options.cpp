// SPDX-License-Identifier: BSD-3-Clause
// The options' one validity check (src/options.h) and the thread-count policy
// (src/thread_policy.h), linked from the library's objects. Through the C API, test_drivers
// checks the same messages as a caller sees them.
#include <gtest/gtest.h>

#include <climits>
#include <cmath>
#include <limits>
#include <string>

#include "options.h"
#include "thread_policy.h"

namespace {

std::string why_invalid(const sba::Options &o) {
  std::string error;
  return o.is_valid(&error) ? std::string("valid") : error;
}

TEST(Options, DefaultsAreValid) { EXPECT_EQ(why_invalid(sba::Options()), "valid"); }

TEST(Options, EachInvalidValueIsNamedAsTheCallerGaveIt) {
  sba::Options o;
  o.itmax = -1;
  EXPECT_EQ(why_invalid(o), "itmax must be >= 0 (got -1)");

  o = sba::Options();
  o.eps3 = std::numeric_limits<double>::quiet_NaN();
  EXPECT_EQ(why_invalid(o), "opts[3] is not finite");

  o = sba::Options();
  o.tau = std::numeric_limits<double>::infinity();
  EXPECT_EQ(why_invalid(o), "opts[0] is not finite");

  o = sba::Options();
  o.tau = 0.0;
  EXPECT_EQ(why_invalid(o),
            "opts[0] (tau: the initial damping is |tau| * max diag(J^T J)) must be nonzero");
}

TEST(Options, TheFirstProblemInTheCallersOrderIsReported) {
  sba::Options o;
  o.itmax = -5;
  o.tau = 0.0;
  o.eps1 = std::nan("");
  EXPECT_EQ(why_invalid(o), "itmax must be >= 0 (got -5)");
  o.itmax = 0;
  EXPECT_EQ(why_invalid(o), "opts[1] is not finite");
}

TEST(ThreadPolicy, ThreadCountText) {
  EXPECT_EQ(sba::parse_thread_count(nullptr), 0);
  EXPECT_EQ(sba::parse_thread_count(""), 0);
  EXPECT_EQ(sba::parse_thread_count("3"), 3);
  EXPECT_EQ(sba::parse_thread_count("99999999999999999999999"), INT_MAX);
  for (const char *bad : {"0", "-2", "3x", " ", "x3", "2.5"})
    EXPECT_EQ(sba::parse_thread_count(bad), -1) << bad;
}

TEST(ThreadPolicy, FittedToTheProblemAndTheHardware) {
  const int hw = sba::hardware_threads();
  EXPECT_GE(hw, 1);
  // Left to the library: one thread for a small problem, never more than the hardware's.
  EXPECT_EQ(sba::fit_threads(100, 1, true), 1);
  EXPECT_LE(sba::fit_threads(INT64_C(1) << 40, 1, true), hw);
  // Asked for: as asked within the caps, never fewer than one.
  EXPECT_EQ(sba::fit_threads(1 << 20, 2, false), std::min(2, 4 * hw));
  EXPECT_EQ(sba::fit_threads(1 << 20, 0, false), 1);
  EXPECT_LE(sba::fit_threads(INT64_C(1) << 40, INT_MAX, false), 4 * hw);
  EXPECT_EQ(sba::fit_threads(64, INT_MAX, false), 1);  // too few projections to share
}

}  // namespace
