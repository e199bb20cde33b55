// gtest: link RTT, loss, up/down and bandwidth estimation from synthetic probe times.
#include <gtest/gtest.h>

#include <cmath>

#include "anyscale_agent_cpp/link_estimator.h"

using anyscale_agent::LinkEstimator;
using anyscale_agent::ProbeKind;

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
  e.sent(1, 0.0, 20, ProbeKind::kSmall);
  e.answered(1, 0.010);
  e.sent(2, 0.5, 20, ProbeKind::kSmall);
  e.answered(2, 0.530);
  auto s = e.stats(0.6);
  EXPECT_TRUE(s.up);
  EXPECT_NEAR(s.rtt_s, 0.030, 1e-9);
  EXPECT_NEAR(s.rtt_mean_s, 0.020, 1e-9);
  EXPECT_DOUBLE_EQ(s.loss_ratio, 0.0);
  e.sent(3, 1.0, 20, ProbeKind::kSmall);
  e.sent(4, 1.5, 20, ProbeKind::kSmall);
  s = e.stats(2.6);  // both unanswered for > 1 s
  EXPECT_FALSE(s.up);
  EXPECT_DOUBLE_EQ(s.loss_ratio, 0.5);
  e.answered(3, 2.7);  // too late: already counted lost, ignored
  EXPECT_FALSE(e.stats(2.7).up);
}

TEST(LinkEstimator, BandwidthFromBulkMinusSmallRtt)
{
  LinkEstimator e(5.0, 10, 1.0);
  e.sent(1, 0.0, 20, ProbeKind::kSmall);
  e.answered(1, 0.002);  // 2 ms RTT
  e.sent(2, 1.0, 125000, ProbeKind::kBulk);
  e.answered(2, 1.102);  // 1 Mbit took 100 ms more than a small probe: 10 Mbit/s
  EXPECT_NEAR(e.stats(1.2).bandwidth_mbps, 10.0, 1e-6);
  // A bulk answer does not count as an RTT sample.
  EXPECT_NEAR(e.stats(1.2).rtt_mean_s, 0.002, 1e-12);
}

TEST(LinkEstimator, BandwidthFallsOnceConfirmedAndRisesSmoothly)
{
  LinkEstimator e(5.0, 10, 0.5);
  e.sent(1, 0.0, 20, ProbeKind::kSmall);
  e.answered(1, 0.0);  // RTT ~0
  e.sent(2, 1.0, 125000, ProbeKind::kBulk);
  e.answered(2, 1.1);  // 10 Mbit/s
  EXPECT_FALSE(e.confirmationWanted());
  e.sent(3, 2.0, 125000, ProbeKind::kBulk);
  e.answered(3, 3.0);  // 1 Mbit/s: not yet believed, a second probe is asked for
  EXPECT_NEAR(e.stats(3.0).bandwidth_mbps, 10.0, 1e-6);
  EXPECT_TRUE(e.confirmationWanted());
  e.sent(4, 3.0, 125000, ProbeKind::kBulk);
  e.answered(4, 3.5);  // 2 Mbit/s: the drop is real; the estimate takes the better reading
  EXPECT_NEAR(e.stats(3.5).bandwidth_mbps, 2.0, 1e-6);
  EXPECT_FALSE(e.confirmationWanted());
  e.sent(5, 4.0, 125000, ProbeKind::kBulk);
  e.answered(5, 4.1);  // 10 Mbit/s again: only half-way there
  EXPECT_NEAR(e.stats(4.1).bandwidth_mbps, 6.0, 1e-6);
}

TEST(LinkEstimator, ALoneDelayedBulkEchoDoesNotLowerTheEstimate)
{
  LinkEstimator e(5.0, 10, 1.0);
  e.sent(1, 0.0, 20, ProbeKind::kSmall);
  e.answered(1, 0.0);
  e.sent(2, 1.0, 125000, ProbeKind::kBulk);
  e.answered(2, 1.04);  // 25 Mbit/s
  e.sent(3, 6.0, 125000, ProbeKind::kBulk);
  e.answered(3, 6.2);  // the echo waited out a throttled CFS period: reads 5 Mbit/s
  e.sent(4, 6.5, 125000, ProbeKind::kBulk);
  e.answered(4, 6.54);  // the confirming probe: 25 Mbit/s
  EXPECT_NEAR(e.stats(6.6).bandwidth_mbps, 25.0, 1e-6);
  EXPECT_FALSE(e.confirmationWanted());
}

TEST(LinkEstimator, ALostConfirmingProbeConfirmsTheDrop)
{
  LinkEstimator e(1.0, 10, 1.0);
  e.sent(1, 0.0, 20, ProbeKind::kSmall);
  e.answered(1, 0.0);
  e.sent(2, 1.0, 125000, ProbeKind::kBulk);
  e.answered(2, 1.1);  // 10 Mbit/s
  e.sent(3, 2.0, 125000, ProbeKind::kBulk);
  e.answered(3, 2.5);  // 2 Mbit/s
  e.sent(4, 2.5, 125000, ProbeKind::kBulk);
  e.sent(5, 3.0, 20, ProbeKind::kSmall);
  e.answered(5, 3.0);  // still up, but the confirming bulk probe never comes back
  EXPECT_NEAR(e.stats(3.6).bandwidth_mbps, 2.0, 1e-6);
  EXPECT_FALSE(e.confirmationWanted());
}

TEST(LinkEstimator, ALostLinkForgetsItsBandwidthUntilTheNextBulkAnswer)
{
  LinkEstimator e(1.0, 10, 1.0);
  e.sent(1, 0.0, 20, ProbeKind::kSmall);
  e.answered(1, 0.0);
  e.sent(2, 1.0, 125000, ProbeKind::kBulk);
  e.answered(2, 1.1);  // 10 Mbit/s where the robot was
  EXPECT_NEAR(e.stats(1.2).bandwidth_mbps, 10.0, 1e-6);
  e.sent(3, 2.0, 20, ProbeKind::kSmall);  // the link goes: unanswered
  EXPECT_FALSE(e.stats(3.5).up);
  EXPECT_TRUE(std::isnan(e.stats(3.5).bandwidth_mbps));
  e.sent(4, 4.0, 20, ProbeKind::kSmall);
  e.answered(4, 4.0);  // back, elsewhere: up, nothing measured yet
  EXPECT_TRUE(e.stats(4.1).up);
  EXPECT_TRUE(std::isnan(e.stats(4.1).bandwidth_mbps));
  e.sent(5, 5.0, 125000, ProbeKind::kBulk);
  e.answered(5, 5.5);  // 2 Mbit/s here
  EXPECT_NEAR(e.stats(5.6).bandwidth_mbps, 2.0, 1e-6);
}

TEST(LinkEstimator, ADelayedEchoDoesNotInflateTheBandwidth)
{
  LinkEstimator e(5.0, 10, 1.0);
  e.sent(1, 0.0, 20, ProbeKind::kSmall);
  e.answered(1, 0.002);  // the link's floor: 2 ms
  e.sent(2, 0.5, 20, ProbeKind::kSmall);
  e.answered(2, 0.540);  // an echo the busy robot scheduled 38 ms late
  e.sent(3, 1.0, 125000, ProbeKind::kBulk);
  e.answered(3, 1.102);  // 1 Mbit, 100 ms over the floor: 10 Mbit/s, not 12.3 (the mean's)
  EXPECT_NEAR(e.stats(1.2).bandwidth_mbps, 10.0, 1e-6);
}

TEST(LinkEstimator, AWarmUpProbeIsAnsweredButNotMeasured)
{
  LinkEstimator e(5.0, 10, 1.0);
  e.sent(1, 0.0, 20, ProbeKind::kSmall);
  e.answered(1, 0.0);
  e.sent(2, 1.0, 125000, ProbeKind::kWarmUp);
  // Slow start after idle: the warm-up crosses in 0.5 s; it neither sets the bandwidth nor
  // counts as an RTT sample, but it shows the link is up.
  EXPECT_EQ(e.answered(2, 1.5), ProbeKind::kWarmUp);
  EXPECT_TRUE(std::isnan(e.stats(1.5).bandwidth_mbps));
  EXPECT_NEAR(e.stats(1.5).rtt_mean_s, 0.0, 1e-12);
  e.sent(3, 1.5, 125000, ProbeKind::kBulk);
  EXPECT_EQ(e.answered(3, 1.6), ProbeKind::kBulk);  // the window open: 10 Mbit/s
  EXPECT_NEAR(e.stats(1.6).bandwidth_mbps, 10.0, 1e-6);
  EXPECT_EQ(e.answered(99, 1.7), ProbeKind::kSmall);  // unknown seq: ignored
}

TEST(SilentSince, ASubscriptionThatNeverHeardAnythingIsSilentSinceItWasMade)
{
  // The laptop agent whose echo subscription never connected: renewed like a dead one.
  EXPECT_DOUBLE_EQ(anyscale_agent::silentSince(std::nan(""), 100.0), 100.0);
}

TEST(SilentSince, FromTheLastMessageOrTheLastRenewalWhicheverIsLater)
{
  EXPECT_DOUBLE_EQ(anyscale_agent::silentSince(120.0, 100.0), 120.0);
  // Renewed since the last message: the new subscription gets its own time to connect.
  EXPECT_DOUBLE_EQ(anyscale_agent::silentSince(120.0, 130.0), 130.0);
}
