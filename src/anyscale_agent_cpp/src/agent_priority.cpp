// Priorities: the agent's own (~control_nice), and each node's declared launch.nice with its output
// boosts (~start_boost_nice until its first output and while its output is late; OutputBoosts).
#include "anyscale_agent_cpp/agent_node.h"

#include <unistd.h>

#include "anyscale_agent_cpp/process_priority.h"

namespace anyscale_agent
{

void AgentNode::raiseControlPriority(int control_nice)
{
  if (control_nice < -20 || control_nice > 0)
    throw std::runtime_error(
        "parameter ~control_nice must be a nice value from -20 to 0 (0: the priority it was "
        "started at), got " +
        std::to_string(control_nice));
  // On a robot held at its CPU quota, a stop, a resume or a status answered late is a node's
  // output silent for longer: the agent's own work is small, so a raised priority costs the
  // nodes little and answers its calls ahead of them. Its nodes start at the priority it had
  // before (SupervisorOptions::child_nice).
  std::string error;
  if (control_nice != 0 && !setProcessNice(::getpid(), control_nice, &error))
    ROS_WARN("cannot run the agent at nice %d (%s)%s; it runs at its nodes' priority", control_nice,
             error.c_str(), ": raising a priority needs CAP_SYS_NICE");
}

void AgentNode::setStartPriority(const NodeDecl& decl, const std::string& name, int pid)
{
  const int start_nice = boosts_.boostedNice(decl.nice);
  std::string error;
  if (start_nice != 0 && !setProcessNice(pid, start_nice, &error))
  {
    ROS_WARN_ONCE("%s: cannot run it at nice %d (%s)%s; nodes run at the agent's priority",
                  name.c_str(), start_nice, error.c_str(),
                  start_nice < 0 ? ": raising a priority needs CAP_SYS_NICE" : "");
    return;
  }
  // Its messages carry the name it runs under here: the boost ends at the first one this agent
  // counts (a node whose output no one subscribes to here keeps it for ~start_boost_s).
  std::lock_guard<std::mutex> lock(boost_mutex_);
  boosts_.started(name, publisherName(name), pid, decl.nice, decl.output_tolerance_s, steadyNow());
}

void AgentNode::watchOutput(const NodeDecl& decl, const std::string& name, int pid)
{
  std::lock_guard<std::mutex> lock(boost_mutex_);
  boosts_.watch(name, publisherName(name), pid, decl.nice, decl.output_tolerance_s);
}

std::string AgentNode::publisherName(const std::string& name) const
{
  std::string publisher = rosName(name);
  if (publisher.empty() || publisher[0] != '/')
    publisher.insert(0, "/");
  return publisher;
}

void AgentNode::outputSeen(const std::string& publisher)
{
  std::optional<OutputBoosts::Change> back;
  {
    std::lock_guard<std::mutex> lock(boost_mutex_);
    if (boosts_.empty())
      return;
    back = boosts_.published(publisher, steadyNow());
  }
  if (back)
    applyBoost(*back);
}

void AgentNode::updateBoosts()
{
  std::vector<OutputBoosts::Change> changes;
  {
    std::lock_guard<std::mutex> lock(boost_mutex_);
    if (boosts_.empty())
      return;
    changes = boosts_.update(steadyNow(), [this](const std::string& name, int pid) {
      const auto info = supervisor_.info(name);
      // A paused node is silent by design; one that starts is not yet registered (Starting).
      return info && info->pid == pid &&
             (info->state == ProcState::Running || info->state == ProcState::Starting);
    });
  }
  for (const auto& change : changes)
    applyBoost(change);
}

void AgentNode::applyBoost(const OutputBoosts::Change& change)
{
  const auto info = supervisor_.info(change.name);
  if (!info || info->pid != change.pid)
    return;  // ended or started again meanwhile: its new process has its own priority
  std::string error;
  if (!setProcessNice(change.pid, change.nice, &error))
    ROS_WARN("%s: could not set its nice to %d: %s", change.name.c_str(), change.nice,
             error.c_str());
  else
    ROS_DEBUG("%s (pid %d) now at nice %d", change.name.c_str(), change.pid, change.nice);
}

}  // namespace anyscale_agent
