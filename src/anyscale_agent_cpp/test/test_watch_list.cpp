// WatchList: which watched topics are counted, by the master's graph or by the nodes run here.
#include <gtest/gtest.h>

#include "anyscale_agent_cpp/watch_list.h"

using anyscale_agent::WatchList;
using Set = std::set<std::string>;

TEST(WatchList, CountsTheInputsOfARunningNodeWithoutTheGraph)
{
  WatchList w;
  ASSERT_TRUE(w.assign({"/scan", "/camera/image_raw"}, {"/amcl", "/ar_recognition"}, nullptr));
  // The master's graph has not (yet) seen either subscription; AMCL runs here.
  EXPECT_EQ(w.toCount({}, {"/amcl"}, false), Set({"/scan"}));
  EXPECT_EQ(w.toCount({}, {"/amcl", "/ar_recognition"}, false),
            Set({"/scan", "/camera/image_raw"}));
}

TEST(WatchList, ATopicNoNodeHereUsesIsNotCounted)
{
  WatchList w;
  ASSERT_TRUE(w.assign({"/scan", "/camera/image_raw"}, {"/amcl", "/ar_recognition"}, nullptr));
  EXPECT_TRUE(w.toCount({}, {}, false).empty());
  EXPECT_TRUE(w.toCount({"/odom"}, {"/navigation"}, false).empty());
  EXPECT_EQ(w.toCount({}, {}, true), Set({"/scan", "/camera/image_raw"}));
}

TEST(WatchList, TheGraphStillCountsWhatNoModelSubscriberNames)
{
  WatchList w;
  ASSERT_TRUE(w.assign({"/scan", "/odom"}, {}, nullptr));
  EXPECT_EQ(w.toCount({"/odom", "/tf"}, {"/amcl"}, false), Set({"/odom"}));
}

TEST(WatchList, ATopicWithSeveralSubscribersIsCountedForAnyOfThem)
{
  WatchList w;
  ASSERT_TRUE(w.assign({"/scan", "/scan", "/odom"}, {"/amcl", "/navigation", ""}, nullptr));
  EXPECT_EQ(w.topics(), std::vector<std::string>({"/odom", "/scan"}));
  EXPECT_EQ(w.toCount({}, {"/navigation"}, false), Set({"/scan"}));
  EXPECT_TRUE(w.toCount({}, {"/map_server"}, false).empty());
}

TEST(WatchList, MismatchedListsAreRefusedAndChangeNothing)
{
  WatchList w;
  ASSERT_TRUE(w.assign({"/scan"}, {"/amcl"}, nullptr));
  std::string error;
  EXPECT_FALSE(w.assign({"/scan", "/odom"}, {"/amcl"}, &error));
  EXPECT_NE(error.find("1 subscribers for 2 topics"), std::string::npos) << error;
  EXPECT_EQ(w.toCount({}, {"/amcl"}, false), Set({"/scan"}));
}
