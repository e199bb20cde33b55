// The agent's warm standbys: one per warm_start node, kept ready also while the node runs here,
// and hurried out of SCHED_IDLE once it is the one the node's next start here will use.
#include "anyscale_agent_cpp/agent_node.h"

#include <chrono>
#include <cstdlib>
#include <fstream>
#include <limits>

#include "anyscale_agent_cpp/process_priority.h"

namespace anyscale_agent
{
namespace
{
constexpr double kStandbyRetryS = 30.0;

bool isPythonScript(const std::string& path)
{
  std::ifstream f(path);
  std::string first_line;
  std::getline(f, first_line);
  return first_line.rfind("#!", 0) == 0 && first_line.find("python") != std::string::npos;
}

// The node has an instance here that is not on its way out.
bool runsHere(const std::optional<ProcessInfo>& node)
{
  return node && node->pid != 0 &&
         (node->state == ProcState::Starting || node->state == ProcState::Running);
}
}  // namespace

std::vector<std::string> AgentNode::standbyArgv(const NodeDecl& decl)
{
  const PackageLocator locate = [this](const std::string& p) { return locatePackage(p); };
  const auto prefixes = catkinPrefixes(std::getenv("CMAKE_PREFIX_PATH"));
  const std::string exe = resolveExecutable(decl.package, decl.type, prefixes, locate);
  if (!isPythonScript(exe))
    throw ModelError(exe + " is not a Python script (a warm standby pre-imports a rospy node)");
  std::vector<std::string> argv{
      resolveExecutable("anyscale_agent_cpp", "python_standby", prefixes, locate)};
  for (auto& a : buildArgv(decl, exe, locate, instanceSuffix(scale_, is_master_)))
    argv.push_back(std::move(a));
  return argv;
}

void AgentNode::keepStandbysReady()
{
  if (!warm_start_)
    return;
  const double now = steadyNow();
  const auto steady = std::chrono::steady_clock::now();
  for (const auto& node : model_.names())
  {
    const NodeDecl* decl = model_.find(node);
    if (!decl->warm_start)
      continue;
    const std::string name = qualifiedName(node);
    const auto running = supervisor_.info(name);
    if (const auto waiting = supervisor_.standby(name); waiting && waiting->pid != 0)
    {
      if (!runsHere(running))
        hurryStandby(name, waiting->pid, "the node does not run here");
      else if (ended_unasked_.count(name))
        hurryStandby(name, waiting->pid, "the node ended unasked here before");
      continue;
    }
    // Also while the node runs here: it is ready the moment the node leaves or ends.
    double& due = standby_due_.emplace(name, now).first->second;
    if (running && running->pid != 0 && running->pid == last_standby_pid_[name])
    {
      // The last standby became the node: the next one once the node's own start is over.
      if (std::chrono::duration<double>(steady - running->started).count() < standby_delay_s_)
        continue;
    }
    else if (now < due)
    {
      continue;  // the last one ended by itself: not again at once
    }
    due = now + kStandbyRetryS;
    std::string error;
    try
    {
      const int pid = supervisor_.startStandby(name, standbyArgv(*decl), logFile(node), &error);
      last_standby_pid_[name] = pid;
      if (pid > 0)
        ROS_INFO("warm standby of %s started (pid %d)", name.c_str(), pid);
      else
        ROS_WARN("warm standby of %s: %s; retrying in %.0f s", name.c_str(), error.c_str(),
                 kStandbyRetryS);
    }
    catch (const ModelError& e)
    {
      due = std::numeric_limits<double>::infinity();
      ROS_ERROR("no warm standby of %s: %s; it starts cold", name.c_str(), e.what());
    }
  }
}

// Moves a standby out of SCHED_IDLE (scripts/python_standby), where a robot whose nodes use up its
// quota gives it no CPU, once the node's next start here will use it: the node left, or ended
// unasked here before (docs/design/agent.md, "Warm standby").
void AgentNode::hurryStandby(const std::string& name, int pid, const char* why)
{
  if (!inIdleScheduling(pid))
    return;
  std::string error;
  if (leaveIdleScheduling(pid, &error))
    ROS_INFO("warm standby of %s (pid %d): imports at normal priority now, %s", name.c_str(), pid,
             why);
  else
    ROS_WARN_THROTTLE(30.0, "warm standby of %s: %s", name.c_str(), error.c_str());
}

}  // namespace anyscale_agent
