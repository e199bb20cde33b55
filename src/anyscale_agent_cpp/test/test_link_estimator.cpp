// gtest: link RTT, loss, up/down and bandwidth estimation from synthetic probe times.
#include <gtest/gtest.h>

#include <cmath>

#include "anyscale_agent_cpp/link_estimator.h"

using anyscale_agent::LinkEstimator;

TEST(LinkEstimator, UnknownUntilAnswered)
{
  LinkEstimator e(1.0, 10);
  const auto s = e.stats(0.0);
  EXPECT_FALSE(s.up);
  EXPECT_TRUE(std::isnan(s.rtt_s));
  EXPECT_TRUE(std::isnan(s.bandwidth_mbps));
}

TEST(LinkEstimator, RttLossAndDown)
{
  LinkEstimator e(1.0, 4);
  e.sent(1, 0.0, 20, false);
  e.answered(1, 0.010);
  e.sent(2, 0.5, 20, false);
  e.answered(2, 0.530);
  auto s = e.stats(0.6);
  EXPECT_TRUE(s.up);
  EXPECT_NEAR(s.rtt_s, 0.030, 1e-9);
  EXPECT_NEAR(s.rtt_mean_s, 0.020, 1e-9);
  EXPECT_DOUBLE_EQ(s.loss_ratio, 0.0);
  e.sent(3, 1.0, 20, false);
  e.sent(4, 1.5, 20, false);
  s = e.stats(2.6);  // both unanswered for > 1 s
  EXPECT_FALSE(s.up);
  EXPECT_DOUBLE_EQ(s.loss_ratio, 0.5);
  e.answered(3, 2.7);  // too late: already counted lost, ignored
  EXPECT_FALSE(e.stats(2.7).up);
}

TEST(LinkEstimator, BandwidthFromBulkMinusSmallRtt)
{
  LinkEstimator e(5.0, 10, 1.0);
  e.sent(1, 0.0, 20, false);
  e.answered(1, 0.002);  // 2 ms RTT
  e.sent(2, 1.0, 125000, true);
  e.answered(2, 1.102);  // 1 Mbit took 100 ms more than a small probe: 10 Mbit/s
  EXPECT_NEAR(e.stats(1.2).bandwidth_mbps, 10.0, 1e-6);
  // A bulk answer does not count as an RTT sample.
  EXPECT_NEAR(e.stats(1.2).rtt_mean_s, 0.002, 1e-12);
}

TEST(LinkEstimator, BandwidthFallsAtOnceAndRisesSmoothly)
{
  LinkEstimator e(5.0, 10, 0.5);
  e.sent(1, 0.0, 20, false);
  e.answered(1, 0.0);  // RTT ~0
  e.sent(2, 1.0, 125000, true);
  e.answered(2, 1.1);  // 10 Mbit/s
  e.sent(3, 2.0, 125000, true);
  e.answered(3, 3.0);  // 1 Mbit/s: taken at once
  EXPECT_NEAR(e.stats(3.0).bandwidth_mbps, 1.0, 1e-6);
  e.sent(4, 4.0, 125000, true);
  e.answered(4, 4.1);  // 10 Mbit/s again: only half-way there
  EXPECT_NEAR(e.stats(4.1).bandwidth_mbps, 5.5, 1e-6);
}

TEST(LinkEstimator, ALostLinkForgetsItsBandwidthUntilTheNextBulkAnswer)
{
  LinkEstimator e(1.0, 10, 1.0);
  e.sent(1, 0.0, 20, false);
  e.answered(1, 0.0);
  e.sent(2, 1.0, 125000, true);
  e.answered(2, 1.1);  // 10 Mbit/s where the robot was
  EXPECT_NEAR(e.stats(1.2).bandwidth_mbps, 10.0, 1e-6);
  e.sent(3, 2.0, 20, false);                      // the link goes: unanswered
  EXPECT_FALSE(e.stats(3.5).up);
  EXPECT_TRUE(std::isnan(e.stats(3.5).bandwidth_mbps));
  e.sent(4, 4.0, 20, false);
  e.answered(4, 4.0);                             // back, elsewhere: up, nothing measured yet
  EXPECT_TRUE(e.stats(4.1).up);
  EXPECT_TRUE(std::isnan(e.stats(4.1).bandwidth_mbps));
  e.sent(5, 5.0, 125000, true);
  e.answered(5, 5.5);                             // 2 Mbit/s here
  EXPECT_NEAR(e.stats(5.6).bandwidth_mbps, 2.0, 1e-6);
}

TEST(LinkEstimator, ADelayedEchoDoesNotInflateTheBandwidth)
{
  LinkEstimator e(5.0, 10, 1.0);
  e.sent(1, 0.0, 20, false);
  e.answered(1, 0.002);  // the link's floor: 2 ms
  e.sent(2, 0.5, 20, false);
  e.answered(2, 0.540);  // an echo the busy robot scheduled 38 ms late
  e.sent(3, 1.0, 125000, true);
  e.answered(3, 1.102);  // 1 Mbit, 100 ms over the floor: 10 Mbit/s, not 12.3 (the mean's)
  EXPECT_NEAR(e.stats(1.2).bandwidth_mbps, 10.0, 1e-6);
}
