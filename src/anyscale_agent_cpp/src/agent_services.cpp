// The agent's services: start, stop, renew leases, list nodes, set watched topics.
#include "anyscale_agent_cpp/agent_node.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdlib>

#include "anyscale_agent_cpp/param_loader.h"
#include "anyscale_agent_cpp/request_check.h"

namespace anyscale_agent
{
namespace
{
std::string join(const std::vector<std::string>& v)
{
  std::string out;
  for (const auto& s : v)
    out += (out.empty() ? "" : ", ") + s;
  return out;
}

// Names from a request, quoted, at most 10 of them: an answer or log line stays short.
std::string joinQuoted(const std::vector<std::string>& v)
{
  std::string out;
  for (std::size_t i = 0; i < v.size() && i < 10; ++i)
    out += (out.empty() ? "" : ", ") + quoted(v[i]);
  return v.size() > 10 ? out + " and " + std::to_string(v.size() - 10) + " more" : out;
}

bool isWaiting(const std::optional<ProcessInfo>& standby)
{
  return standby && standby->pid != 0 && standby->state == ProcState::Standby;
}
}  // namespace

void AgentNode::startNode(const anyscale_msgs::StartNode::Request& req,
                          anyscale_msgs::StartNode::Response& res)
{
  res.success = false;
  res.pid = 0;
  // Everything is checked, and every path resolved, before anything is written or forked.
  const NodeDecl* decl =
      isValidNodeName(req.node) || (req.node.size() > 1 && isValidNodeName(req.node.substr(1)))
          ? model_.find(req.node)
          : nullptr;
  if (!decl)
  {
    res.message = "refused: node " + quoted(req.node) + " is not declared in the model " +
                  model_path_ + " (declared: " + join(model_.names()) + ")";
    return;
  }
  if (const std::string why = checkSeconds("lease_s", req.lease_s, true, kMaxLeaseS); !why.empty())
  {
    res.message = "refused: " + why + " (0 = no lease)";
    return;
  }
  // The master scale's nodes are the robot's own: a lease there (a microsecond of one) would
  // have the agent end a driver, and nothing renews leases at home.
  if (is_master_ && req.lease_s > 0.0f)
  {
    res.message =
        "refused: lease_s " + std::to_string(req.lease_s) + ": no lease on the master scale";
    return;
  }
  for (const std::string& why :
       {checkAmount("cpu_percent", req.cpu_percent, kMaxExpectedCpuPercent, "%"),
        checkAmount("memory_mb", req.memory_mb, kMaxExpectedMemoryMb, "MB")})
    if (!why.empty())
    {
      res.message = "refused: " + why;
      return;
    }
  std::map<std::string, std::string> overrides;
  for (const auto& kv : req.param_overrides)
    if (!overrides.emplace(kv.key, kv.value).second)
    {
      res.message = "refused: param override " + quoted(kv.key) + " given twice";
      return;
    }
  if (const std::string why = checkOverrideKeys(*decl, overrides); !why.empty())
  {
    res.message = "refused: " + why;
    return;
  }
  const std::string name = qualifiedName(decl->name);
  const PackageLocator locate = [this](const std::string& p) { return locatePackage(p); };
  std::vector<std::string> argv;
  try
  {
    const std::string exe = resolveExecutable(
        decl->package, decl->type, catkinPrefixes(std::getenv("CMAKE_PREFIX_PATH")), locate);
    argv = buildArgv(*decl, exe, locate, instanceSuffix(scale_, is_master_));
    // A paused instance (a return to the master scale of a node declared launch.pause_at_home)
    // is resumed: running in milliseconds, with its connections and state, where a start
    // would spend a second or more of the starved robot's CPU before its first output. It
    // resumes its own state (the node's side of pause_at_home), so no overrides are set.
    if (const auto paused = supervisor_.info(name); paused && paused->state == ProcState::Paused)
    {
      std::string error;
      if (const int pid = supervisor_.resume(name, &error); pid > 0)
      {
        setStartPriority(*decl, name, pid);
        res.success = true;
        res.pid = pid;
        res.message =
            "resumed the paused instance of " + name + " (pid " + std::to_string(pid) + ")";
        ROS_INFO("%s", res.message.c_str());
        return;
      }
      ROS_WARN("%s; starting it", error.c_str());  // it ended while paused
    }
    // A node being stopped here cannot be taken over (a rospy node that got SIGINT is shutting
    // down): a link loss right after a planned move brings the node back to the scale whose
    // old instance is being stopped. The migration stop ends it within its SIGINT grace, so
    // the start waits for that and then goes ahead.
    if (const auto stopping = supervisor_.info(name);
        stopping && stopping->state == ProcState::Stopping)
    {
      const auto& o = supervisor_.options();
      if (!supervisor_.waitGone(name, o.sigint_timeout_s + o.sigterm_timeout_s + 5.0))
      {
        res.message = "refused: " + name + " is being stopped here and did not end (pid " +
                      std::to_string(stopping->pid) + ")";
        return;
      }
      ROS_INFO("start of %s waited for its previous instance (pid %d) to end", name.c_str(),
               stopping->pid);
    }
    if (const auto running = supervisor_.info(name); running && running->pid != 0)
    {
      // Starting is idempotent: the decision node asks for a node where it must run, and a
      // planned move that a link loss interrupts asks for the old instance it had not stopped.
      // Its lease, if it has one, is renewed; never shortened, removed or imposed.
      renewLease(name, req.lease_s);
      res.success = true;
      res.pid = running->pid;
      res.message = name + " is already running here (pid " + std::to_string(running->pid) + ")";
      return;
    }
    setNodeParams(rosName(name).substr(1), decl->params, overrides, locate, clear_params_,
                  decl->name);
  }
  catch (const ModelError& e)
  {
    res.message = "refused: " + name + ": " + e.what();
    return;
  }
  // On a shared scale the start holds its capacity from its admission on; no sync may free the
  // entry before the node is forked and its lease granted.
  std::unique_lock<std::mutex> ledger_lock(ledger_mutex_, std::defer_lock);
  if (ledger_)
    ledger_lock.lock();
  if (!admit(name, req, res))
    return;
  const std::string log_file = logFile(decl->name);
  std::string error;
  // A warm standby becomes the node; if it died meanwhile, the node starts cold as usual.
  int pid = isWaiting(supervisor_.standby(name)) ? supervisor_.activate(name, &error) : 0;
  const bool warm = pid > 0;
  if (!warm)
    pid = supervisor_.start(name, argv, log_file, &error);
  if (pid <= 0)
  {
    if (ledger_)
      syncLedgerLocked();  // frees what it was admitted with
    res.message = "failed: " + name + ": " + error;
    ROS_ERROR("start_node %s", res.message.c_str());
    return;
  }
  setStartPriority(*decl, name, pid);
  grantLease(name, req.lease_s);
  if (ledger_)
    syncLedgerLocked();  // its entry ends with the lease just granted
  res.success = true;
  res.pid = pid;
  res.message = std::string(warm ? "activated the warm standby of " : "started ") + name +
                " (pid " + std::to_string(pid) + ") from " + argv[0] + "; log " + log_file +
                (req.lease_s > 0.0f ? "; lease " + std::to_string(req.lease_s) + " s" : "");
  ROS_INFO("%s", res.message.c_str());
  return;
}

void AgentNode::stopNode(const anyscale_msgs::StopNode::Request& req,
                         anyscale_msgs::StopNode::Response& res)
{
  res.success = false;
  res.exit_code = -1;
  res.exit_signal = 0;
  if (const std::string why =
          checkSeconds("sigint_timeout_s", req.sigint_timeout_s, true, kMaxSigintTimeoutS);
      !why.empty())
  {
    res.message = "refused: " + why;
    return;
  }
  const std::string name = qualifiedName(req.node);
  if (req.pause)
  {
    pauseNode(name, res);
    return;
  }
  {
    std::lock_guard<std::mutex> lock(leases_mutex_);
    leases_.remove(name);
  }
  const auto before = supervisor_.info(name);
  if (!before || before->pid == 0)
  {
    res.message = quoted(name) + " is not running on scale " + scale_ +
                  (before ? " (it " + std::string(toString(before->state)) + ")" : "");
    if (before)
    {
      res.exit_code = before->exit_code;
      res.exit_signal = before->exit_signal;
    }
    return;
  }
  const auto stop_began = std::chrono::steady_clock::now();
  supervisor_.stop(name, ProcState::Exited, req.sigint_timeout_s);
  if (!req.wait)
  {
    res.success = true;
    res.message = "stopping " + name + " (pid " + std::to_string(before->pid) + ")";
    return;
  }
  const auto& o = supervisor_.options();
  const double limit = o.sigint_timeout_s + o.sigterm_timeout_s + 5.0;
  // A migration waits for the node to leave the master's system state, not for its threads:
  // a rospy node unregisters its topics and services early in its shutdown (after its
  // on_shutdown hooks), then spends half a second or more joining threads, all of it dead
  // time on its topics. Only a node seen registered counts: one still starting could
  // register after the check. Not asked over a link known to be down: roscpp's master call
  // has no timeout, and the SIGKILL after sigint_timeout_s ends the node anyway.
  bool left_master = false;
  if (req.sigint_timeout_s > 0.0f && before->state == ProcState::Running)
    while (!supervisor_.waitGone(name, 0.03) &&
           std::chrono::steady_clock::now() - stop_began < std::chrono::duration<double>(limit))
      if (link_->stats().up && !graph_.inSystemState(rosName(name)))
      {
        left_master = supervisor_.killNow(name);
        break;
      }
  const bool gone = supervisor_.waitGone(name, limit);
  const auto after = supervisor_.info(name);
  res.success = gone;
  if (after)
  {
    res.exit_code = after->exit_code;
    res.exit_signal = after->exit_signal;
  }
  syncLedger();  // frees its capacity on a shared scale
  res.message = gone ? "stopped " + name : "stop of " + name + " did not finish in time";
  if (gone)
    ROS_INFO("stopped %s (pid %d) in %.2f s%s", name.c_str(), before->pid,
             std::chrono::duration<double>(std::chrono::steady_clock::now() - stop_began).count(),
             left_master                  ? ": killed once it had left the master"
             : res.exit_signal == SIGKILL ? ": killed after the SIGINT grace"
                                          : "");
  return;
}

void AgentNode::pauseNode(const std::string& name, anyscale_msgs::StopNode::Response& res)
{
  // Elsewhere a node lives on its lease, and a paused instance behind a partition would hold
  // its memory, unseen, for as long as the partition lasts.
  if (!is_master_)
  {
    res.message = "refused: pause " + quoted(name) + ": only the master scale pauses nodes";
    return;
  }
  // A paused process is neither running nor ended: only a node the model declares able to
  // resume from a pause, and whose pause the decision node undoes, may be paused.
  const NodeDecl* decl = model_.find(name);
  if (!decl || !decl->pause_at_home)
  {
    res.message =
        "refused: pause " + quoted(name) + ": the model does not declare it launch.pause_at_home";
    return;
  }
  std::string error;
  if (!supervisor_.pause(name, &error))
  {
    res.message = "refused: pause: " + error;
    return;
  }
  res.success = true;
  res.message = "paused " + name + " (SIGSTOP): the next start here resumes it";
  ROS_INFO("%s", res.message.c_str());
}

void AgentNode::renewLeases(const anyscale_msgs::RenewLeases::Request& req,
                            anyscale_msgs::RenewLeases::Response& res)
{
  res.success = true;
  if (const std::string why = checkSeconds("lease_s", req.lease_s, false, kMaxLeaseS); !why.empty())
  {
    res.success = false;
    res.message = "refused: " + why;
    res.not_running = req.nodes;
    return;
  }
  std::vector<std::string> without_lease;
  std::map<std::string, double> renewed;
  const double now = steadyNow();
  std::unique_lock<std::mutex> lock(leases_mutex_);
  for (const auto& node : req.nodes)
  {
    const std::string name = qualifiedName(node);
    const auto info = supervisor_.info(name);
    if (!info || info->pid == 0 || info->state == ProcState::Stopping)
    {
      res.not_running.push_back(node);
      res.success = false;
    }
    else if (!leases_.renew(name, now, req.lease_s))
    {
      without_lease.push_back(node);  // runs without a lease; renewing must not impose one
    }
    else
    {
      renewed[name] = *leases_.expiry(name);
    }
  }
  // One write of the state file for the whole renewal, so that a successor enforces them.
  supervisor_.setLeaseEnds(renewed);
  lock.unlock();
  syncLedger();  // a shared scale's entries end with the leases
  res.message = res.success ? "renewed" : "not running here: " + joinQuoted(res.not_running);
  if (!without_lease.empty())
    res.message += "; running without a lease, unchanged: " + joinQuoted(without_lease);
  return;
}

std::string AgentNode::logFile(const std::string& node) const
{
  std::string file_name = node;
  std::replace(file_name.begin(), file_name.end(), '/', '.');
  return log_dir_ + "/" + file_name + ".log";
}

}  // namespace anyscale_agent
