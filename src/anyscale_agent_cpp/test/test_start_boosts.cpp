// StartBoosts: the start nice (boost_nice, or below a lower declared nice; clamped); boosts end at
// the node's first output or after boost_s, and are handed back once, with the pid that was boosted.
#include <gtest/gtest.h>

#include "anyscale_agent_cpp/start_boosts.h"

using anyscale_agent::StartBoosts;

TEST(StartBoosts, ABoostedNodeDoesNotYieldAndALowerDeclaredNiceStaysLower)
{
  const StartBoosts boosts(-5, 3.0);
  EXPECT_EQ(boosts.startNice(0), -5);
  EXPECT_EQ(boosts.startNice(5), -5);  // declared to yield: not while its output is restored
  EXPECT_EQ(boosts.startNice(-3), -8);
  EXPECT_EQ(boosts.startNice(-18), -20);
  EXPECT_EQ(StartBoosts(0, 3.0).startNice(7), 7);
}

TEST(StartBoosts, ABoostRunsOutAfterBoostSecondsAndIsHandedBackOnce)
{
  StartBoosts boosts(-5, 3.0);
  boosts.started("amcl", "/amcl", 100, 0, 10.0);
  boosts.started("ar", "/ar", 200, 5, 11.0);
  EXPECT_TRUE(boosts.takeDue(12.9).empty());
  const auto due = boosts.takeDue(13.0);
  ASSERT_EQ(due.size(), 1u);
  EXPECT_EQ(due[0].name, "amcl");
  EXPECT_EQ(due[0].pid, 100);
  EXPECT_EQ(due[0].nice, 0);
  EXPECT_TRUE(boosts.takeDue(13.5).empty());
  const auto later = boosts.takeDue(20.0);
  ASSERT_EQ(later.size(), 1u);
  EXPECT_EQ(later[0].nice, 5);
  EXPECT_TRUE(boosts.empty());
}

TEST(StartBoosts, TheFirstOutputEndsTheBoostOfItsPublisherOnly)
{
  StartBoosts boosts(-5, 3.0);
  boosts.started("amcl", "/amcl", 100, 0, 10.0);
  boosts.started("ar_recognition", "/ar_recognition__laptop", 200, 5, 10.0);
  EXPECT_FALSE(boosts.published("/ar_recognition"));  // another instance's output
  const auto ar = boosts.published("/ar_recognition__laptop");
  ASSERT_TRUE(ar);
  EXPECT_EQ(ar->name, "ar_recognition");
  EXPECT_EQ(ar->pid, 200);
  EXPECT_EQ(ar->nice, 5);
  EXPECT_FALSE(boosts.published("/ar_recognition__laptop"));  // handed back once
  const auto due = boosts.takeDue(13.0);
  ASSERT_EQ(due.size(), 1u);
  EXPECT_EQ(due[0].name, "amcl");
}

TEST(StartBoosts, ANewStartReplacesTheBoostAndNoBoostRecordsNothing)
{
  StartBoosts boosts(-5, 3.0);
  boosts.started("amcl", "/amcl", 100, 0, 10.0);
  boosts.started("amcl", "/amcl", 101, 0, 12.0);  // started again: the new process, the new deadline
  EXPECT_TRUE(boosts.takeDue(14.0).empty());
  const auto due = boosts.takeDue(15.0);
  ASSERT_EQ(due.size(), 1u);
  EXPECT_EQ(due[0].pid, 101);
  StartBoosts none(0, 3.0);
  none.started("amcl", "/amcl", 100, 0, 0.0);
  EXPECT_TRUE(none.takeDue(100.0).empty());
  EXPECT_FALSE(none.published("/amcl"));
}
