// gtest: the wire check of the agent's requests against what roscpp serialises for them, and the
// claims it refuses before roscpp would allocate for them.
#include <gtest/gtest.h>
#include <ros/serialization.h>

#include <anyscale_msgs/LinkProbe.h>
#include <anyscale_msgs/ListNodes.h>
#include <anyscale_msgs/RenewLeases.h>
#include <anyscale_msgs/SetWatchedTopics.h>
#include <anyscale_msgs/StartNode.h>
#include <anyscale_msgs/StopNode.h>

#include <cstring>

#include "anyscale_agent_cpp/request_wire.h"

using namespace anyscale_agent;

namespace
{
template <class M>
std::vector<uint8_t> bytesOf(const M& m)
{
  std::vector<uint8_t> out(ros::serialization::serializationLength(m));
  ros::serialization::OStream stream(out.data(), uint32_t(out.size()));
  ros::serialization::serialize(stream, m);
  return out;
}

// A message's bytes pass; every shorter prefix and one byte more do not.
template <class M>
void expectExactlyOneMessage(const M& m, const WireLayout& layout)
{
  const auto bytes = bytesOf(m);
  EXPECT_EQ(checkWire(bytes.data(), bytes.size(), layout), "");
  for (std::size_t n = 0; n < bytes.size(); ++n)
    EXPECT_NE(checkWire(bytes.data(), n, layout), "") << "a prefix of " << n << " bytes";
  auto longer = bytes;
  longer.push_back(0);
  EXPECT_NE(checkWire(longer.data(), longer.size(), layout), "");
}

std::vector<uint8_t> u32s(std::initializer_list<uint32_t> values)
{
  std::vector<uint8_t> out(values.size() * 4);
  std::memcpy(out.data(), values.begin(), out.size());
  return out;
}
}  // namespace

TEST(RequestWire, TheLayoutsAreWhatRoscppSerialises)
{
  anyscale_msgs::StartNode::Request start;
  start.node = "amcl";
  start.lease_s = 3.0f;
  start.cpu_percent = 36.0f;
  start.memory_mb = 150.0f;
  diagnostic_msgs::KeyValue kv;
  kv.key = "initial_pose_x";
  kv.value = "1.5";
  start.param_overrides = {kv, kv};
  expectExactlyOneMessage(start, kStartNodeWire);
  start.param_overrides.clear();
  expectExactlyOneMessage(start, kStartNodeWire);
  anyscale_msgs::StopNode::Request stop;
  stop.node = "robot/camera";
  stop.wait = stop.pause = true;
  expectExactlyOneMessage(stop, kStopNodeWire);
  anyscale_msgs::RenewLeases::Request renew;
  renew.nodes = {"amcl", "", "ar_recognition"};
  expectExactlyOneMessage(renew, kRenewLeasesWire);
  expectExactlyOneMessage(anyscale_msgs::ListNodes::Request(), kListNodesWire);
  anyscale_msgs::SetWatchedTopics::Request watch;
  watch.topics = {"/scan", "/camera/image_raw"};
  watch.subscribers = {"/amcl", ""};
  expectExactlyOneMessage(watch, kSetWatchedTopicsWire);
  anyscale_msgs::LinkProbe probe;
  probe.scale = "laptop";
  probe.payload.resize(100);
  expectExactlyOneMessage(probe, kLinkProbeWire);
}

TEST(RequestWire, AClaimBeyondTheBytesIsRefusedNamingTheField)
{
  // 12 bytes claiming 60 million names: roscpp built 2 GB of empty strings from them.
  auto renew = u32s({60000000, 0});
  EXPECT_EQ(checkWire(renew.data(), renew.size(), kRenewLeasesWire),
            "nodes claims 60000000 entries of at least 4 bytes each in 4 bytes");
  auto start = u32s({4});
  for (const char c : std::string("amcl"))
    start.push_back(uint8_t(c));
  for (const uint8_t b : u32s({60000000, 0}))
    start.push_back(b);
  EXPECT_EQ(checkWire(start.data(), start.size(), kStartNodeWire)
                .rfind("param_overrides claims 60000000", 0),
            0u);
  auto probe = u32s({0, 1});
  probe.push_back(1);
  for (const uint8_t b : u32s({4000000000u}))
    probe.push_back(b);
  EXPECT_EQ(
      checkWire(probe.data(), probe.size(), kLinkProbeWire).rfind("payload claims 4000000000", 0),
      0u);
  auto name = u32s({4000000000u});
  EXPECT_EQ(checkWire(name.data(), name.size(), kStopNodeWire), "node is cut short (0 bytes left)");
  EXPECT_EQ(checkWire(nullptr, 0, kListNodesWire), "");
  // A start of the layout before the expected CPU and memory: those fields are missing.
  auto before = u32s({4});
  for (const char c : std::string("amcl"))
    before.push_back(uint8_t(c));
  for (const uint8_t b : u32s({0, 0}))
    before.push_back(b);
  EXPECT_EQ(checkWire(before.data(), before.size(), kStartNodeWire),
            "cpu_percent is cut short (0 bytes left)");
}
