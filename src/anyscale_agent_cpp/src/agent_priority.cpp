// Priorities: the agent's own (~control_nice), and each node's declared launch.nice with the start
// boost (~start_boost_nice until its first output, for ~start_boost_s at most).
#include "anyscale_agent_cpp/agent_node.h"

#include <unistd.h>

#include "anyscale_agent_cpp/process_priority.h"

namespace anyscale_agent
{

void AgentNode::raiseControlPriority(int control_nice)
{
  if (control_nice < -20 || control_nice > 0)
    throw std::runtime_error("parameter ~control_nice must be a nice value from -20 to 0 (0: the priority it was "
                             "started at), got " + std::to_string(control_nice));
  // On a robot held at its CPU quota, a stop, a resume or a status answered late is a node's
  // output silent for longer: the agent's own work is small, so a raised priority costs the
  // nodes little and answers its calls ahead of them. Its nodes start at the priority it had
  // before (SupervisorOptions::child_nice).
  std::string error;
  if (control_nice != 0 && !setProcessNice(::getpid(), control_nice, &error))
    ROS_WARN("cannot run the agent at nice %d (%s)%s; it runs at its nodes' priority", control_nice,
             error.c_str(), ": raising a priority needs CAP_SYS_NICE");
}

void AgentNode::setStartPriority(const std::string& name, int pid, int nice)
{
  const int start_nice = boosts_.startNice(nice);
  std::string error;
  if (start_nice != 0 && !setProcessNice(pid, start_nice, &error))
  {
    ROS_WARN_ONCE("%s: cannot run it at nice %d (%s)%s; nodes run at the agent's priority", name.c_str(),
                  start_nice, error.c_str(), start_nice < 0 ? ": raising a priority needs CAP_SYS_NICE" : "");
    return;
  }
  // Its messages carry the name it runs under here: the boost ends at the first one this agent
  // counts (a node whose output no one subscribes to here keeps it for ~start_boost_s).
  std::string publisher = rosName(name);
  if (publisher.empty() || publisher[0] != '/')
    publisher.insert(0, "/");
  std::lock_guard<std::mutex> lock(boost_mutex_);
  boosts_.started(name, publisher, pid, nice, steadyNow());
}

void AgentNode::endBoostAtOutput(const std::string& publisher)
{
  std::optional<StartBoosts::Due> due;
  {
    std::lock_guard<std::mutex> lock(boost_mutex_);
    if (boosts_.empty())
      return;
    due = boosts_.published(publisher);
  }
  if (due)
    endBoost(*due);
}

void AgentNode::endBoosts()
{
  std::vector<StartBoosts::Due> due;
  {
    std::lock_guard<std::mutex> lock(boost_mutex_);
    due = boosts_.takeDue(steadyNow());
  }
  for (const auto& boost : due)
    endBoost(boost);
}

void AgentNode::endBoost(const StartBoosts::Due& boost)
{
  const auto info = supervisor_.info(boost.name);
  std::string error;
  if (info && info->pid == boost.pid && !setProcessNice(boost.pid, boost.nice, &error))
    ROS_WARN("%s: could not end its start priority: %s", boost.name.c_str(), error.c_str());
}

}  // namespace anyscale_agent
