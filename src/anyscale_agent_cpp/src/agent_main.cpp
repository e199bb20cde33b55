// Entry point of the anyscale_agent node.
#include <atomic>
#include <csignal>
#include <cstdio>
#include <cstdlib>

#include "anyscale_agent_cpp/agent_config.h"
#include "anyscale_agent_cpp/agent_node.h"

namespace
{
std::atomic<bool> g_by_signal{false};

// SIGTERM too, not just SIGINT: the agent must stop its nodes whichever way it is asked to end.
void requestShutdown(int)
{
  g_by_signal = true;
  ros::requestShutdown();
}

// roslaunch's order: ROS_LOG_DIR, then ROS_HOME/log, then ~/.ros/log.
std::string logBase()
{
  if (const char* d = std::getenv("ROS_LOG_DIR"))
    return d;
  if (const char* h = std::getenv("ROS_HOME"))
    return std::string(h) + "/log";
  if (const char* home = std::getenv("HOME"))
    return std::string(home) + "/.ros/log";
  return "/tmp";
}
}  // namespace

int main(int argc, char** argv)
{
  // roscpp prints INFO to stdout, which roslaunch's output="screen" makes a pipe: block
  // buffered, the lines reached the log only at exit, and not at all when the agent was
  // killed (an evaluation run's laptop agent logged nothing after a long outage).
  std::setvbuf(stdout, nullptr, _IOLBF, 0);
  // Before ros::init, which moves the `name:=value` arguments out of argv.
  const auto private_args = anyscale_agent::privateArguments(argc, argv);
  ros::init(argc, argv, "anyscale_agent", ros::init_options::NoSigintHandler);
  std::signal(SIGINT, requestShutdown);
  std::signal(SIGTERM, requestShutdown);
  // Outlives the agent: when the last NodeHandle goes, roscpp shuts down and with it the
  // console, and the reason for a failed start would never be printed.
  ros::NodeHandle nh;
  try
  {
    const auto config =
        anyscale_agent::agentConfig(private_args, ros::this_node::getName(), logBase());
    // roscpp has put the command line's `_name:=` on the parameter server too; one there that the
    // command line did not give was set by a launch file's <param>, or by anyone on the graph.
    for (const char* key : anyscale_agent::kCommandLineSettings)
      if (!private_args.count(key) && ros::param::has(std::string("~") + key))
        ROS_WARN(
            "parameter ~%s is not read (anyone on the graph may set it): give _%s:= on the agent's "
            "command line (agent.launch's args)",
            key, key);
    anyscale_agent::AgentNode agent{nh, ros::NodeHandle("~"), config};
    agent.spin(g_by_signal);
  }
  catch (const std::exception& e)
  {
    ROS_FATAL("anyscale agent: %s", e.what());
    return 1;
  }
  return 0;
}
