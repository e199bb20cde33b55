// A shared scale's capacity ledger in the agent (_ledger_file:=): each start admitted against what
// every robot's agent on this machine holds, its entries following the nodes' leases and ends.
#include "anyscale_agent_cpp/agent_node.h"

#include <algorithm>

#include "anyscale_agent_cpp/request_check.h"

namespace anyscale_agent
{
namespace
{
// A node holds its capacity from its fork until it is gone, also while it shuts down.
bool holdsCapacity(ProcState s)
{
  return s == ProcState::Starting || s == ProcState::Running || s == ProcState::Stopping ||
         s == ProcState::Paused;
}
}  // namespace

void AgentNode::openLedger(const AgentConfig& config)
{
  if (config.ledger_file.empty())
    return;
  const auto memory_mb = model_.scaleMemoryMb(scale_);
  if (!memory_mb)
    throw std::runtime_error("_ledger_file:= needs the memory_mb of scale '" + scale_ + "' in " +
                             model_path_ + " (its scales list): the ledger's memory capacity");
  prepareLedgerDirectory(config.ledger_file);
  robot_ = config.robot;
  ledger_ = std::make_unique<CapacityLedger>(config.ledger_file, robot_, scale_,
                                             LedgerCapacity{100.0, *memory_mb});
  // Its entries of a predecessor: kept for the nodes it adopted, freed for the others.
  syncLedger();
  const Holdings h = ledger_->held(steadyNow());
  ROS_INFO(
      "shared scale '%s' for robot '%s': capacity ledger %s (100 %% CPU, %.0f MB), now "
      "holding %.0f %% CPU and %.0f MB for %zu robots",
      scale_.c_str(), robot_.c_str(), ledger_->path().c_str(), *memory_mb, h.cpu_percent,
      h.memory_mb, h.robots);
}

bool AgentNode::admit(const std::string& name, const anyscale_msgs::StartNode::Request& req,
                      anyscale_msgs::StartNode::Response& res)
{
  if (!ledger_)
    return true;
  // An entry without a lease would hold its capacity for good once its robot is gone.
  if (!(req.lease_s > 0.0f))
  {
    res.message = "refused: " + name +
                  ": a shared scale admits only starts under a lease "
                  "(lease_s > 0)";
    return false;
  }
  LedgerEntry entry;
  entry.robot = robot_;
  entry.master_uri = ros::master::getURI();
  entry.node = name;
  entry.instance = rosName(name);
  entry.cpu_percent = req.cpu_percent;
  entry.memory_mb = req.memory_mb;
  entry.lease_end_s = steadyNow() + req.lease_s;
  try
  {
    const Admission a = ledger_->admit(entry, steadyNow());
    if (a.admitted)
    {
      ROS_INFO("%s for robot '%s' %s", name.c_str(), robot_.c_str(), a.message.c_str());
      return true;
    }
    res.scale_full = true;
    res.cpu_free_percent = float(a.cpu_free_percent);
    res.memory_free_mb = float(a.memory_free_mb);
    res.message = "refused: " + name + ": " + a.message;
  }
  catch (const LedgerError& e)
  {
    // Without the ledger nothing says there is room: nothing is admitted.
    res.message = "refused: " + name + ": " + e.what();
  }
  return false;
}

void AgentNode::syncLedger()
{
  if (!ledger_)
    return;
  std::lock_guard<std::mutex> ledger_lock(ledger_mutex_);
  syncLedgerLocked();
}

void AgentNode::syncLedgerLocked()
{
  std::map<std::string, double> live;
  {
    std::lock_guard<std::mutex> lock(leases_mutex_);
    for (const auto& p : supervisor_.snapshot())
      if (p.pid != 0 && holdsCapacity(p.state))
        live[p.name] = leases_.expiry(p.name).value_or(0.0);
  }
  try
  {
    ledger_->sync(live, steadyNow());
    if (!ledger_error_.empty())
      ROS_INFO("capacity ledger %s is kept again", ledger_->path().c_str());
    ledger_error_.clear();
    ledger_live_.clear();
    for (const auto& l : live)
      ledger_live_.insert(l.first);
  }
  catch (const LedgerError& e)
  {
    if (ledger_error_ != e.what())
      ROS_ERROR("%s: this robot's entries are not renewed or freed; starts here are refused",
                e.what());
    ledger_error_ = e.what();
  }
}

void AgentNode::syncLedgerOnChange()
{
  if (!ledger_)
    return;
  std::set<std::string> live;
  for (const auto& p : supervisor_.snapshot())
    if (p.pid != 0 && holdsCapacity(p.state))
      live.insert(p.name);
  std::lock_guard<std::mutex> ledger_lock(ledger_mutex_);
  if (live != ledger_live_ || !ledger_error_.empty())
    syncLedgerLocked();
}

float AgentNode::cpuHeldByOthers()
{
  if (!ledger_)
    return 0.0f;
  try
  {
    // More than the whole scale (entries written by hand) is full all the same.
    return float(std::min(100.0, ledger_->held(steadyNow(), true).cpu_percent));
  }
  catch (const LedgerError&)
  {
    // Nothing is admitted here while it cannot be read: full, as far as anyone knows.
    return 100.0f;
  }
}

}  // namespace anyscale_agent
