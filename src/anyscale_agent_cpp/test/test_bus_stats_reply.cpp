// gtest: getBusStats, getBusInfo and getPid replies of roscpp and rospy nodes, good and bad.
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "anyscale_agent_cpp/bus_stats_reply.h"

using namespace anyscale_agent;
using XmlRpc::XmlRpcValue;

namespace
{

XmlRpcValue connection(int id, int bytes, int messages)
{
  XmlRpcValue c;
  c[0] = id;
  c[1] = bytes;
  c[2] = messages;
  c[3] = 0;
  c[4] = true;
  return c;
}

XmlRpcValue topicStats(const std::string& topic, const std::vector<XmlRpcValue>& connections)
{
  XmlRpcValue t, list;
  list.setSize(0);
  for (std::size_t i = 0; i < connections.size(); ++i)
    list[int(i)] = connections[i];
  t[0] = topic;
  t[1] = list;
  return t;
}

XmlRpcValue emptyList()
{
  XmlRpcValue v;
  v.setSize(0);
  return v;
}

// roscpp's shape: [publishStats, subscribeStats] with no code.
XmlRpcValue roscppReply(const XmlRpcValue& subscribe)
{
  XmlRpcValue r;
  r[0] = emptyList();
  r[1] = subscribe;
  return r;
}

// rospy's: [1, "", [publishStats, subscribeStats, serviceStats]].
XmlRpcValue rospyReply(const XmlRpcValue& subscribe)
{
  XmlRpcValue stats, r;
  stats[0] = emptyList();
  stats[1] = subscribe;
  stats[2] = emptyList();
  r[0] = 1;
  r[1] = std::string("");
  r[2] = stats;
  return r;
}

}  // namespace

TEST(BusStatsReply, ParsesBothClientLibrariesShapes)
{
  XmlRpcValue subs;
  subs[0] = topicStats("/scan", {connection(3, 1200, 12), connection(7, 50, 1)});
  subs[1] = topicStats("/idle", {});
  for (const auto& reply : {roscppReply(subs), rospyReply(subs)})
  {
    SubscribedCounts out;
    std::string error;
    ASSERT_TRUE(parseBusStats(reply, &out, &error)) << error;
    ASSERT_EQ(out.size(), 2u);
    ASSERT_EQ(out["/scan"].size(), 2u);
    EXPECT_EQ(out["/scan"][0].id, 3);
    EXPECT_EQ(out["/scan"][0].bytes, 1200u);
    EXPECT_EQ(out["/scan"][0].messages, 12u);
    EXPECT_EQ(out["/scan"][1].id, 7);
    EXPECT_TRUE(out["/idle"].empty());
  }
}

TEST(BusStatsReply, RefusesBadAndPartialRepliesWithTheReason)
{
  SubscribedCounts out{{"/kept", {}}};
  std::string error;

  XmlRpcValue fault;
  fault[0] = -1;
  fault[1] = std::string("no such thing");
  fault[2] = 0;
  EXPECT_FALSE(parseBusStats(fault, &out, &error));
  EXPECT_NE(error.find("code -1 (no such thing)"), std::string::npos) << error;

  EXPECT_FALSE(parseBusStats(XmlRpcValue(std::string("hello")), &out, &error));
  EXPECT_NE(error.find("publishStats"), std::string::npos) << error;

  XmlRpcValue not_list;
  not_list[0] = emptyList();
  not_list[1] = 5;
  EXPECT_FALSE(parseBusStats(not_list, &out, &error));
  EXPECT_NE(error.find("subscribeStats is not a list"), std::string::npos) << error;

  // A connection with a count that is not an integer (or missing) spoils the whole reply.
  XmlRpcValue bad_count = connection(1, 10, 1);
  bad_count[2] = std::string("12");
  XmlRpcValue subs;
  subs[0] = topicStats("/good", {connection(0, 10, 1)});
  subs[1] = topicStats("/bad", {bad_count});
  EXPECT_FALSE(parseBusStats(roscppReply(subs), &out, &error));
  EXPECT_NE(error.find("connection 0 of /bad"), std::string::npos) << error;

  XmlRpcValue short_conn;
  short_conn[0] = 1;
  short_conn[1] = 10;
  XmlRpcValue subs2;
  subs2[0] = topicStats("/short", {short_conn});
  EXPECT_FALSE(parseBusStats(rospyReply(subs2), &out, &error));

  XmlRpcValue no_topic;
  no_topic[0] = 5;
  no_topic[1] = emptyList();
  XmlRpcValue subs3;
  subs3[0] = no_topic;
  EXPECT_FALSE(parseBusStats(roscppReply(subs3), &out, &error));
  EXPECT_NE(error.find("entry 0"), std::string::npos) << error;

  // Nothing of a refused reply is taken.
  ASSERT_EQ(out.size(), 1u);
  EXPECT_TRUE(out.count("/kept"));
}

TEST(BusStatsReply, NegativeIntegersAreTheLow32BitsOfALargeCount)
{
  XmlRpcValue subs;
  subs[0] = topicStats("/camera", {connection(0, -5, 3)});  // roscpp's byte count past 2^31
  SubscribedCounts out;
  ASSERT_TRUE(parseBusStats(roscppReply(subs), &out, nullptr));
  EXPECT_EQ(out["/camera"][0].bytes, uint32_t(-5));
}

TEST(BusStatsReply, BusInfoNamesTheInboundConnectionsPublishers)
{
  XmlRpcValue info, in, out_conn, reply;
  in[0] = 4;
  in[1] = std::string("http://robot:41234/");
  in[2] = std::string("i");
  in[3] = std::string("TCPROS");
  in[4] = std::string("/scan");
  in[5] = true;
  out_conn = in;
  out_conn[0] = 5;
  out_conn[1] = std::string("/rosout");
  out_conn[2] = std::string("o");
  out_conn[4] = std::string("/rosout");
  info[0] = in;
  info[1] = out_conn;
  reply[0] = 1;
  reply[1] = std::string("bus info");
  reply[2] = info;
  InboundPublishers publishers;
  std::string error;
  ASSERT_TRUE(parseBusInfo(reply, &publishers, &error)) << error;
  ASSERT_EQ(publishers.size(), 1u);
  EXPECT_EQ(publishers["/scan"][4], "http://robot:41234/");
  EXPECT_EQ(uriPort(publishers["/scan"][4]), 41234);
  EXPECT_EQ(uriPort("http://[::1]:80/"), 80);
  EXPECT_EQ(uriPort("http://robot/"), 0);
  EXPECT_EQ(uriPort("http://robot:99999/"), 0);
  EXPECT_EQ(uriPort(""), 0);

  reply[2] = 3;
  EXPECT_FALSE(parseBusInfo(reply, &publishers, &error));
  EXPECT_NE(error.find("getBusInfo"), std::string::npos);
}

TEST(BusStatsReply, PidReply)
{
  XmlRpcValue r;
  r[0] = 1;
  r[1] = std::string("");
  r[2] = 4242;
  EXPECT_EQ(parsePidReply(r), 4242);
  r[0] = 0;
  EXPECT_EQ(parsePidReply(r), 0);
  EXPECT_EQ(parsePidReply(XmlRpcValue(7)), 0);
}
