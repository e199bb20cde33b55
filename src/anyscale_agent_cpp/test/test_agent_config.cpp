// gtest: the agent's configuration from its command line, its defaults and its refusals.
#include <gtest/gtest.h>

#include <stdexcept>

#include "anyscale_agent_cpp/agent_config.h"

using namespace anyscale_agent;

namespace
{
std::map<std::string, std::string> args(std::initializer_list<const char*> argv)
{
  std::vector<const char*> v{"/opt/ws/lib/anyscale_agent_cpp/anyscale_agent"};
  v.insert(v.end(), argv);
  return privateArguments(int(v.size()), v.data());
}

std::string refusal(const std::map<std::string, std::string>& a,
                    const std::string& node = "/anyscale_agent_robot")
{
  try
  {
    agentConfig(a, node, "/home/r/.ros/log");
  }
  catch (const std::runtime_error& e)
  {
    return e.what();
  }
  return "";
}
}  // namespace

TEST(AgentConfig, PrivateArgumentsAreTheSingleUnderscoreOnes)
{
  const auto a = args({"__name:=anyscale_agent_laptop", "_model:=/m.yaml", "chatter:=/x",
                       "_rate:=2", "--flag", "__log:=/tmp/l", "_state_file:=/s/a:=b"});
  EXPECT_EQ(a, (std::map<std::string, std::string>{
                   {"model", "/m.yaml"}, {"rate", "2"}, {"state_file", "/s/a:=b"}}));
}

TEST(AgentConfig, DefaultsFollowTheScaleAndTheMasterFlag)
{
  const AgentConfig robot = agentConfig(args({"_model:=/m.yaml", "_is_master:=true"}),
                                        "/anyscale_agent_robot", "/home/r/.ros/log");
  EXPECT_EQ(robot.scale, "robot");
  EXPECT_TRUE(robot.is_master);
  EXPECT_EQ(robot.model_path, "/m.yaml");
  EXPECT_EQ(robot.log_dir, "/home/r/.ros/log/anyscale/robot");
  EXPECT_EQ(robot.state_file, "/home/r/.ros/log/anyscale/robot/running_nodes.yaml");
  EXPECT_TRUE(robot.nodes_outlive_agent);
  const AgentConfig laptop = agentConfig(args({"_model:=/m.yaml", "_scale:=laptop",
                                               "_log_dir:=/var/log/as", "_nodes_outlive_agent:=1"}),
                                         "/agent", "/home/r/.ros/log");
  EXPECT_EQ(laptop.scale, "laptop");
  EXPECT_FALSE(laptop.is_master);
  EXPECT_EQ(laptop.state_file, "/var/log/as/running_nodes.yaml");
  EXPECT_TRUE(laptop.nodes_outlive_agent);
}

TEST(AgentConfig, MissingOrWrongSettingsAreNamed)
{
  EXPECT_NE(refusal(args({})).find("_model:=PATH"), std::string::npos);
  EXPECT_NE(refusal(args({"_model:="})).find("_model:=PATH"), std::string::npos);
  EXPECT_NE(refusal(args({"_model:=/m.yaml"}), "/agent").find("_scale:="), std::string::npos);
  EXPECT_NE(refusal(args({"_model:=/m.yaml", "_scale:=../x"})).find("'../x'"), std::string::npos);
  EXPECT_NE(refusal(args({"_model:=/m.yaml", "_is_master:=maybe"}))
                .find("_is_master:= must be true or false"),
            std::string::npos);
  EXPECT_NE(
      refusal(args({"_model:=/m.yaml", "_state_file:="})).find("_state_file:= must not be empty"),
      std::string::npos);
  EXPECT_EQ(refusal(args({"_model:=/m.yaml"})), "");
}

TEST(AgentConfig, ASharedScaleNeedsARobotIdAndKeepsEachRobotsFilesApart)
{
  const AgentConfig alone = agentConfig(args({"_model:=/m.yaml", "_ledger_file:=", "_robot:="}),
                                        "/anyscale_agent_laptop", "/home/r/.ros/log");
  EXPECT_EQ(alone.ledger_file, "");  // agent.launch passes both empty when not shared
  EXPECT_EQ(alone.log_dir, "/home/r/.ros/log/anyscale/laptop");
  const AgentConfig shared =
      agentConfig(args({"_model:=/m.yaml", "_ledger_file:=/var/lib/as/laptop.yaml", "_robot:=r2"}),
                  "/anyscale_agent_laptop", "/home/r/.ros/log");
  EXPECT_EQ(shared.ledger_file, "/var/lib/as/laptop.yaml");
  EXPECT_EQ(shared.robot, "r2");
  // Two agents of one scale on one machine: their logs and state files must not be one.
  EXPECT_EQ(shared.log_dir, "/home/r/.ros/log/anyscale/laptop/r2");
  EXPECT_EQ(shared.state_file, "/home/r/.ros/log/anyscale/laptop/r2/running_nodes.yaml");
  EXPECT_NE(refusal(args({"_model:=/m.yaml", "_ledger_file:=/l.yaml"}), "/anyscale_agent_laptop")
                .find("_ledger_file:= needs _robot:=ID"),
            std::string::npos);
  EXPECT_NE(refusal(args({"_model:=/m.yaml", "_ledger_file:=/l.yaml", "_robot:=../r"}),
                    "/anyscale_agent_laptop")
                .find("_robot:= must be a robot id"),
            std::string::npos);
  EXPECT_NE(
      refusal(args({"_model:=/m.yaml", "_ledger_file:=/l.yaml", "_robot:=r", "_is_master:=true"}))
          .find("a master scale is its robot's own"),
      std::string::npos);
}
