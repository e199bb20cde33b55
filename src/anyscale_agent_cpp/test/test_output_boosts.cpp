// OutputBoosts: the boosted nice (boost_nice, or below a lower declared nice; clamped); a start
// boost ends at the node's first output or after boost_s; a node whose output has been seen is
// boosted again when silent for late_fraction x its tolerance, until its next output.
#include <gtest/gtest.h>

#include "anyscale_agent_cpp/output_boosts.h"

using anyscale_agent::OutputBoosts;

namespace
{
const auto kAllRun = [](const std::string&, int) { return true; };
}

TEST(OutputBoosts, ABoostedNodeDoesNotYieldAndALowerDeclaredNiceStaysLower)
{
  const OutputBoosts boosts(-5, 3.0, 0.5);
  EXPECT_EQ(boosts.boostedNice(0), -5);
  EXPECT_EQ(boosts.boostedNice(5), -5);  // declared to yield: not while its output is missing
  EXPECT_EQ(boosts.boostedNice(-3), -8);
  EXPECT_EQ(boosts.boostedNice(-18), -20);
  EXPECT_EQ(OutputBoosts(0, 3.0, 0.5).boostedNice(7), 7);
}

TEST(OutputBoosts, AStartBoostRunsOutAfterBoostSecondsAndIsHandedBackOnce)
{
  OutputBoosts boosts(-5, 3.0, 0.5);
  boosts.started("amcl", "/amcl", 100, 0, 0.0, 10.0);
  boosts.started("ar", "/ar", 200, 5, 0.0, 11.0);
  EXPECT_TRUE(boosts.update(12.9, kAllRun).empty());
  const auto due = boosts.update(13.0, kAllRun);
  ASSERT_EQ(due.size(), 1u);
  EXPECT_EQ(due[0].name, "amcl");
  EXPECT_EQ(due[0].pid, 100);
  EXPECT_EQ(due[0].nice, 0);
  EXPECT_TRUE(boosts.update(13.5, kAllRun).empty());
  const auto later = boosts.update(20.0, kAllRun);
  ASSERT_EQ(later.size(), 1u);
  EXPECT_EQ(later[0].nice, 5);
  EXPECT_TRUE(boosts.empty());
}

TEST(OutputBoosts, TheFirstOutputEndsTheBoostOfItsPublisherOnly)
{
  OutputBoosts boosts(-5, 3.0, 0.5);
  boosts.started("amcl", "/amcl", 100, 0, 0.0, 10.0);
  boosts.started("ar_recognition", "/ar_recognition__laptop", 200, 5, 0.0, 10.0);
  EXPECT_FALSE(boosts.published("/ar_recognition", 10.5));  // another instance's output
  const auto ar = boosts.published("/ar_recognition__laptop", 10.5);
  ASSERT_TRUE(ar);
  EXPECT_EQ(ar->name, "ar_recognition");
  EXPECT_EQ(ar->pid, 200);
  EXPECT_EQ(ar->nice, 5);
  EXPECT_FALSE(boosts.published("/ar_recognition__laptop", 10.6));  // handed back once
  const auto due = boosts.update(13.0, kAllRun);
  ASSERT_EQ(due.size(), 1u);
  EXPECT_EQ(due[0].name, "amcl");
}

TEST(OutputBoosts, ANewStartReplacesTheBoostAndNoBoostRecordsNothing)
{
  OutputBoosts boosts(-5, 3.0, 0.5);
  boosts.started("amcl", "/amcl", 100, 0, 2.0, 10.0);
  boosts.started("amcl", "/amcl", 101, 0, 2.0,
                 12.0);  // started again: the new process, the new deadline
  EXPECT_TRUE(boosts.update(14.0, kAllRun).empty());
  const auto due = boosts.update(15.0, kAllRun);
  ASSERT_EQ(due.size(), 1u);
  EXPECT_EQ(due[0].pid, 101);
  OutputBoosts none(0, 3.0, 0.5);
  none.started("amcl", "/amcl", 100, 0, 2.0, 0.0);
  none.watch("ar", "/ar", 200, 5, 1.0);
  EXPECT_TRUE(none.empty());
  EXPECT_FALSE(none.published("/amcl", 1.0));
  EXPECT_TRUE(none.update(100.0, kAllRun).empty());
}

TEST(OutputBoosts, ALateOutputIsBoostedUntilItsNextMessage)
{
  OutputBoosts boosts(-5, 3.0, 0.5);
  boosts.started("ar", "/ar", 200, 5, 1.0, 10.0);
  ASSERT_TRUE(boosts.published("/ar", 10.4));         // the start boost ends
  EXPECT_TRUE(boosts.update(10.8, kAllRun).empty());  // silent 0.4 s of the 0.5 allowed
  const auto late = boosts.update(10.9, kAllRun);
  ASSERT_EQ(late.size(), 1u);
  EXPECT_EQ(late[0].name, "ar");
  EXPECT_EQ(late[0].pid, 200);
  EXPECT_EQ(late[0].nice, -5);
  EXPECT_TRUE(boosts.update(11.0, kAllRun).empty());  // raised once
  const auto back = boosts.published("/ar", 11.1);
  ASSERT_TRUE(back);
  EXPECT_EQ(back->nice, 5);
  EXPECT_FALSE(boosts.published("/ar", 11.3));  // not boosted: nothing to set back
  EXPECT_TRUE(boosts.update(11.7, kAllRun).empty());
  EXPECT_EQ(boosts.update(11.8, kAllRun).size(), 1u);  // late again, 0.5 s after 11.3
  EXPECT_EQ(boosts.lateBoosts(), 2);
}

TEST(OutputBoosts, ANodeStillSilentAfterItsBoostIsWatchedAgainOnlyFromItsNextOutput)
{
  OutputBoosts boosts(-5, 3.0, 0.5);
  boosts.watch("amcl", "/amcl", 100, 0, 2.0);  // adopted: no boost, no lateness before an output
  EXPECT_TRUE(boosts.update(50.0, kAllRun).empty());
  EXPECT_FALSE(boosts.published("/amcl", 50.0));
  ASSERT_EQ(boosts.update(51.0, kAllRun).size(), 1u);  // Δ 2 s: late after 1 s
  const auto back = boosts.update(54.0, kAllRun);      // its input is gone: boost_s, then back
  ASSERT_EQ(back.size(), 1u);
  EXPECT_EQ(back[0].nice, 0);
  EXPECT_TRUE(boosts.update(100.0, kAllRun).empty());
  EXPECT_FALSE(boosts.published("/amcl", 100.0));
  EXPECT_EQ(boosts.update(101.0, kAllRun).size(), 1u);
}

TEST(OutputBoosts, AnEntryWhoseProcessNoLongerRunsIsDropped)
{
  OutputBoosts boosts(-5, 3.0, 0.5);
  boosts.started("ar", "/ar", 200, 5, 1.0, 10.0);
  boosts.published("/ar", 10.2);
  const auto paused = [](const std::string& name, int pid) {
    return !(name == "ar" && pid == 200);
  };
  EXPECT_TRUE(boosts.update(20.0, paused).empty());  // paused at home: silent, and not late
  EXPECT_TRUE(boosts.empty());
  boosts.started("ar", "/ar", 201, 5, 1.0, 30.0);  // resumed or started again
  EXPECT_FALSE(boosts.empty());
}

TEST(OutputBoosts, WithoutALateFractionOnlyStartsAreBoosted)
{
  OutputBoosts boosts(-5, 3.0, 0.0);
  boosts.started("ar", "/ar", 200, 5, 1.0, 10.0);
  ASSERT_TRUE(boosts.published("/ar", 10.4));
  EXPECT_TRUE(boosts.empty());
  EXPECT_TRUE(boosts.update(60.0, kAllRun).empty());
}
