// graph_state: which topics have a subscriber here, and a restarted master that does not know
// this agent yet (the fault soak's roscore restart: the agents dropped every rate counter).
#include <gtest/gtest.h>

#include "anyscale_agent_cpp/graph_state.h"

using anyscale_agent::knowsAgent;
using anyscale_agent::listsNode;
using anyscale_agent::localSubscribedTopics;
using anyscale_agent::SystemState;

namespace
{

const std::string kSelf = "/anyscale_agent_robot";

// The robot's graph: the EKF takes /amcl_pose from the laptop's AMCL, navigation /ar_markers;
// the agent counts both and publishes its status.
SystemState robotGraph()
{
  SystemState s;
  s.publishers = {{"/amcl_pose", {"/amcl__laptop"}}, {"/anyscale/status", {kSelf}}};
  s.subscribers = {{"/amcl_pose", {"/ekf", kSelf}},
                   {"/ar_markers", {"/navigation", kSelf}},
                   {"/camera/image_raw", {"/ar_recognition__laptop"}},
                   {"/rosout", {"/rosout"}}};
  s.services = {{"/anyscale/robot/start_node", {kSelf}}};
  return s;
}

bool onRobot(const std::string& node)
{
  return node.find("__laptop") == std::string::npos;
}

}  // namespace

TEST(GraphState, TopicsWithASubscriberHereOtherThanTheAgentItself)
{
  const auto topics = localSubscribedTopics(robotGraph(), kSelf, onRobot);
  ASSERT_TRUE(topics.has_value());
  EXPECT_EQ(*topics, (std::set<std::string>{"/amcl_pose", "/ar_markers", "/rosout"}));
}

TEST(GraphState, OnlyTheAgentsOwnCounterDoesNotMakeATopicLocal)
{
  SystemState s = robotGraph();
  s.subscribers = {{"/amcl_pose", {kSelf}}};
  EXPECT_EQ(localSubscribedTopics(s, kSelf, onRobot), std::set<std::string>{});
}

TEST(GraphState, AMasterThatDoesNotListTheAgentSaysNothingAboutWhoSubscribesHere)
{
  // roscore restarted: until the master keeper puts the registrations back, the new master
  // lists rosout's subscription alone. Taken for the graph, it dropped the counters of
  // /amcl_pose and /ar_markers, and the decision node, with no rate, brought AMCL and AR home.
  SystemState restarted;
  restarted.subscribers = {{"/rosout", {"/rosout"}}};
  restarted.publishers = {{"/rosout_agg", {"/rosout"}}};
  EXPECT_EQ(localSubscribedTopics(restarted, kSelf, onRobot), std::nullopt);
  EXPECT_EQ(localSubscribedTopics(SystemState{}, kSelf, onRobot), std::nullopt);
  // A counter the agent renewed meanwhile registers it as a subscriber, never a publisher.
  restarted.subscribers.push_back({"/ar_markers", {kSelf}});
  EXPECT_FALSE(knowsAgent(restarted, kSelf));
  EXPECT_EQ(localSubscribedTopics(restarted, kSelf, onRobot), std::nullopt);
  EXPECT_TRUE(knowsAgent(robotGraph(), kSelf));
}

TEST(GraphState, EachNodeIsAskedOnce)
{
  SystemState s = robotGraph();
  s.subscribers.push_back({"/scan", {"/amcl__laptop", "/navigation"}});
  s.subscribers.push_back({"/tf", {"/amcl__laptop"}});
  std::map<std::string, int> asked;
  localSubscribedTopics(s, kSelf, [&](const std::string& node) {
    ++asked[node];
    return onRobot(node);
  });
  for (const auto& [node, times] : asked)
    EXPECT_EQ(times, 1) << node;
}

TEST(GraphState, ANodeIsListedByAnyOfItsRegistrations)
{
  const SystemState s = robotGraph();
  EXPECT_TRUE(listsNode(s, "/amcl__laptop"));  // publisher
  EXPECT_TRUE(listsNode(s, "/ekf"));           // subscriber
  EXPECT_TRUE(listsNode(s, kSelf));            // also a service
  EXPECT_FALSE(listsNode(s, "/amcl"));
}
