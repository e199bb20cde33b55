// gtest: rate window maths on synthetic arrival times.
#include <gtest/gtest.h>

#include <cmath>

#include "anyscale_agent_cpp/rate_window.h"

using anyscale_agent::RateWindow;

TEST(RateWindow, EmptyHasInfiniteAgeAndZeroRate)
{
  RateWindow w(2.0);
  const auto s = w.stats(10.0);
  EXPECT_EQ(s.rate_hz, 0.0);
  EXPECT_TRUE(std::isinf(s.last_message_age_s));
  EXPECT_EQ(s.window_messages, 0u);
}

TEST(RateWindow, SteadyRateIsExactAtAnySamplingPhase)
{
  RateWindow w(2.0);
  for (int i = 0; i <= 100; ++i)
    w.add(i * 0.025, 1000);  // 40 Hz for 2.5 s
  const auto first = w.stats(2.51);
  EXPECT_EQ(first.window_messages, 80u);  // messages in [0.51, 2.51]
  EXPECT_NEAR(first.bytes_per_second, 80 * 1000 / 2.0, 1e-6);
  EXPECT_NEAR(first.last_message_age_s, 0.01, 1e-9);
  // Sampled up to one period after the last message: still exactly 40 Hz.
  for (double phase : {0.01, 0.02, 0.025})
  {
    const auto s = w.stats(2.5 + phase);
    EXPECT_NEAR(s.rate_hz, 40.0, 1e-6) << "phase " << phase;
    EXPECT_NEAR(s.interval_min_s, 0.025, 1e-9);
    EXPECT_NEAR(s.interval_max_s, 0.025, 1e-9);
    EXPECT_NEAR(s.interval_std_s, 0.0, 1e-6);
  }
}

TEST(RateWindow, IntervalStatistics)
{
  RateWindow w(10.0);
  double t = 0.0;
  w.add(t, 10);
  for (double d : {0.1, 0.3, 0.1, 0.3})
    w.add(t += d, 10);
  const auto s = w.stats(t);
  EXPECT_NEAR(s.rate_hz, 4 / 0.8, 1e-9);
  EXPECT_NEAR(s.interval_min_s, 0.1, 1e-9);
  EXPECT_NEAR(s.interval_max_s, 0.3, 1e-9);
  EXPECT_NEAR(s.interval_std_s, 0.1, 1e-9);
}

TEST(RateWindow, StoppedTopicDecaysThenReachesZero)
{
  RateWindow w(2.0);
  for (int i = 0; i <= 30; ++i)
    w.add(i * 0.1, 100);  // 10 Hz until t = 3
  const double r0 = w.stats(3.05).rate_hz;
  const double r1 = w.stats(3.5).rate_hz;
  const double r2 = w.stats(4.5).rate_hz;
  EXPECT_NEAR(r0, 10.0, 1e-6);
  EXPECT_LT(r1, 9.0);
  EXPECT_LT(r2, r1);
  EXPECT_GT(r2, 0.0);
  const auto gone = w.stats(5.5);
  EXPECT_EQ(gone.rate_hz, 0.0);
  EXPECT_EQ(gone.window_messages, 0u);
  EXPECT_NEAR(gone.last_message_age_s, 2.5, 1e-9);
}

TEST(RateWindow, MessageCapBoundsMemory)
{
  RateWindow w(100.0, 50);
  for (int i = 0; i < 1000; ++i)
    w.add(i * 0.001, 1);
  const auto s = w.stats(0.999);
  EXPECT_EQ(s.window_messages, 50u);
  EXPECT_NEAR(s.rate_hz, 1000.0, 1e-3);
}
