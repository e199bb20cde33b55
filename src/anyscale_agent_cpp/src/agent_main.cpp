// Entry point of the anyscale_agent node.
#include <csignal>
#include <cstdio>

#include "anyscale_agent_cpp/agent_node.h"

namespace
{
// SIGTERM too, not just SIGINT: the agent must stop its nodes whichever way it is asked to end.
void requestShutdown(int)
{
  ros::requestShutdown();
}
}  // namespace

int main(int argc, char** argv)
{
  // roscpp prints INFO to stdout, which roslaunch's output="screen" makes a pipe: block
  // buffered, the lines reached the log only at exit, and not at all when the agent was
  // killed (an evaluation run's laptop agent logged nothing after a long outage).
  std::setvbuf(stdout, nullptr, _IOLBF, 0);
  ros::init(argc, argv, "anyscale_agent", ros::init_options::NoSigintHandler);
  std::signal(SIGINT, requestShutdown);
  std::signal(SIGTERM, requestShutdown);
  // Outlives the agent: when the last NodeHandle goes, roscpp shuts down and with it the
  // console, and the reason for a failed start would never be printed.
  ros::NodeHandle nh;
  try
  {
    anyscale_agent::AgentNode agent{ nh, ros::NodeHandle("~") };
    agent.spin();
  }
  catch (const std::exception& e)
  {
    ROS_FATAL("anyscale agent: %s", e.what());
    return 1;
  }
  return 0;
}
