// SPDX-License-Identifier: BSD-3-Clause
// The options' one validity check (src/options.h) and the thread-count policy
// (src/thread_policy.h), linked from the library's objects. Through the C API, test_drivers,
// test_robust and test_camera_params check the same messages as a caller sees them.
#include <gtest/gtest.h>

#include <climits>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include "options.h"
#include "thread_policy.h"

namespace {

// Three cameras of 2 parameters seeing two points, every parameter 1.0.
struct Problem {
  Problem() {
    const std::vector<char> vmask(2 * 3, 1);
    std::string msg;
    EXPECT_TRUE(sba::build_layout(lay, sba::Mode::MotStr, 2, 3, 0, 0, 2, 3, 2, vmask.data(), &msg)) << msg;
    p.assign(size_t(lay.nvars()), 1.0);
  }
  sba::Layout lay;
  std::vector<double> p;
};

std::string why_invalid(const sba::Options &o) {
  const Problem pb;
  std::string error;
  return o.is_valid(pb.lay, pb.p.data(), &error) ? std::string("valid") : error;
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
  o = sba::Options();
  o.loss = sba::Loss(sba::LossKind::Huber, -1.0);
  const int groups[] = {0, 0, 0};
  o.cams.group = groups;
  EXPECT_EQ(why_invalid(o).rfind("loss_scale must be positive", 0), 0u) << why_invalid(o);
}

// The loss's scale is checked only for a robust loss, as the solve uses it only then.
TEST(Options, ALossScaleOutsideWhatItsSquareCanHoldIsRefused) {
  sba::Options o;
  for (double scale : {0.0, -2.0, 0x1p-512, 0x1p512, std::nan(""), HUGE_VAL}) {
    o.loss = sba::Loss(sba::LossKind::Cauchy, scale);
    EXPECT_EQ(why_invalid(o).rfind("loss_scale must be positive and within [", 0), 0u) << scale;
    o.loss = sba::Loss(sba::LossKind::None, scale);
    EXPECT_EQ(why_invalid(o), "valid") << scale;
  }
  for (double scale : {0x1p-511, 1.0, 0x1p511}) {
    o.loss = sba::Loss(sba::LossKind::Tukey, scale);
    EXPECT_EQ(why_invalid(o), "valid") << scale;
  }
}

// The camera parameters' arrays are checked against the problem in the same call.
TEST(Options, HeldAndSharedCameraParametersAreCheckedWithTheRest) {
  sba::Options o;
  const int groups[] = {0, 0, 3};
  const char shared[] = {1, 0};
  o.cams.group = groups;
  EXPECT_EQ(why_invalid(o), "cam_group is given but cam_shared is NULL");
  o.cams.shared = shared;
  EXPECT_EQ(why_invalid(o), "cam_group[2] = 3 is neither -1 nor a group number in [0, m-1]");
  const int fine[] = {0, 0, -1};
  o.cams.group = fine;
  EXPECT_EQ(why_invalid(o), "valid");
  const char held[] = {1, 0, 0, 0, 0, 0};
  o.cams.fixed = held;
  o.cams.fixed_per_camera = true;
  EXPECT_EQ(why_invalid(o), "parameter 0 is shared by cameras 0 and 1 (group 0) but held (cam_fixed) in only one of them");
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
