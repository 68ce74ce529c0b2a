// SPDX-License-Identifier: BSD-3-Clause
// The LM core (src/lm_core.cpp), linked from the library's objects: the stop-4 test. The loop
// driven by fakes: test_lm_loop.cpp; the strategies' retries: test_strategy.cpp.
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "lm.h"

namespace {

using sba::reduction_stalled;

// With eps4 > 0 the expression is the relative RMS reduction test: sqrt(e) - sqrt(en) <
// eps4 sqrt(e). Values chosen so that every operation is exact.
TEST(ReductionStalled, IsTheRelativeRmsTestForPositiveEps4) {
  // sqrt(100) - sqrt(81) = 1 against eps4 * 10.
  EXPECT_TRUE(reduction_stalled(100.0, 81.0, 0.125));
  EXPECT_FALSE(reduction_stalled(100.0, 81.0, 0.0625));
  // The boundary itself: 8 - 7 = 0.125 * 8 is not below it.
  EXPECT_FALSE(reduction_stalled(64.0, 49.0, 0.125));
  EXPECT_FALSE(reduction_stalled(64.0, 49.0, 0.0));
}

// At eps4 = 0 the exact test never fires on a decrease; the expression as sba 1.6 writes it
// does, through the rounding of 2 sqrt(e en), once the relative decrease is tiny.
TEST(ReductionStalled, FiresThroughCancellationAtEps4Zero) {
  const double e = 1294.059147798527;
  EXPECT_TRUE(reduction_stalled(e, 1294.0591476985269, 0.0));   // relative decrease 7.7e-11
  EXPECT_FALSE(reduction_stalled(e, 1294.059147598527, 0.0));   // 1.5e-10
  EXPECT_TRUE(reduction_stalled(3.0, 3.0 * 0.999999999, 0.0));
  EXPECT_FALSE(reduction_stalled(1.0, 0.999999999, 0.0));
  // No decrease at all is not a stall.
  EXPECT_FALSE(reduction_stalled(e, e, 0.0));
}

// Where the cancellation begins: never at a relative decrease of 1e-7 or more, about one step
// in four far below 1e-8. The share is what makes 1.6 end most runs with reason 4.
TEST(ReductionStalled, CancellationLevelIsNearThreeTimesTenToTheMinusEight) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> mag(0.0, 8.0);
  const int kDraws = 4000;
  int fired_big = 0, fired_tiny = 0;
  for (int k = 0; k < kDraws; ++k) {
    const double e = std::pow(10.0, mag(rng));
    fired_big += reduction_stalled(e, e * (1.0 - 1e-7), 0.0);
    fired_big += reduction_stalled(e, e * (1.0 - 1e-3), 0.0);
    fired_tiny += reduction_stalled(e, e * (1.0 - 1e-11), 0.0);
  }
  EXPECT_EQ(fired_big, 0);
  EXPECT_GT(fired_tiny, kDraws / 6);
  EXPECT_LT(fired_tiny, kDraws / 3);
}

}  // namespace
