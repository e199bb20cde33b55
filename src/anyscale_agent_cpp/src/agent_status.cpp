// The agent's /anyscale/status: a sample of /proc, topic rates and link at ~sample_rate_hz, and one
// more at once when the uplink's carrier changes.
#include "anyscale_agent_cpp/agent_node.h"

#include <algorithm>
#include <chrono>

#include "anyscale_agent_cpp/uplink_carrier.h"

namespace anyscale_agent
{
namespace
{
uint8_t toMsgState(ProcState s)
{
  switch (s)
  {
    case ProcState::Starting: return anyscale_msgs::NodeProcess::STARTING;
    case ProcState::Running: return anyscale_msgs::NodeProcess::RUNNING;
    case ProcState::Stopping: return anyscale_msgs::NodeProcess::STOPPING;
    case ProcState::Exited: return anyscale_msgs::NodeProcess::EXITED;
    case ProcState::Replaced: return anyscale_msgs::NodeProcess::REPLACED;
    case ProcState::LeaseExpired: return anyscale_msgs::NodeProcess::LEASE_EXPIRED;
    case ProcState::Standby: return anyscale_msgs::NodeProcess::STANDBY;
    case ProcState::Paused: return anyscale_msgs::NodeProcess::PAUSED;
  }
  return anyscale_msgs::NodeProcess::EXITED;
}
}  // namespace

void AgentNode::onUplink(const ros::SteadyTimerEvent&)
{
  const Carrier carrier = readCarrier(uplink_interface_);
  const bool up = carrier == Carrier::Up;
  if (up == uplink_up_.exchange(up))
    return;
  if (up)
    ROS_INFO("uplink %s has a carrier again", uplink_interface_.c_str());
  else
    ROS_WARN("uplink %s lost its carrier (%s): the other scales are out of reach",
             uplink_interface_.c_str(), toString(carrier));
  // At once, not at the next sample: the decision node brings remote nodes home on this.
  publishStatusNow();
}

void AgentNode::publishStatusNow()
{
  anyscale_msgs::ScaleStatus s;
  {
    std::lock_guard<std::mutex> lock(sample_mutex_);
    if (last_status_.scale.empty())
      return;  // nothing sampled yet; the first sample carries the state
    applyUplink(last_status_.link);
    s = last_status_;
    // The processes as they are now, not as last sampled: a start since then (a node brought
    // home by this very link loss) replaced the record of the instance before it, and the
    // old record, ended by the stop of a move, read as a crash of the new one to the decision
    // node: it "restarted" a node that was starting (seen after link-loss returns, 'signal 9').
    s.nodes = nodeProcesses();
  }
  status_pub_.publish(s);
}

void AgentNode::applyUplink(anyscale_msgs::LinkStatistics& link) const
{
  link.uplink_interface = uplink_interface_;
  link.carrier = uplink_up_;
  link.up = link.up && link.carrier;
}

std::vector<anyscale_msgs::NodeProcess> AgentNode::nodeProcesses()
{
  const ros::Time now = ros::Time::now();
  const auto steady = std::chrono::steady_clock::now();
  const double steady_s = steadyNow();
  std::vector<anyscale_msgs::NodeProcess> out;
  std::lock_guard<std::mutex> lock(leases_mutex_);
  for (const auto& p : supervisor_.snapshot())
  {
    anyscale_msgs::NodeProcess m;
    m.name = p.name;
    m.instance = rosName(p.name);
    m.pid = p.pid;
    m.state = toMsgState(p.state);
    m.exit_code = p.exit_code;
    m.exit_signal = p.exit_signal;
    if (p.pid != 0)
      if (const auto g = sampler_.group(p.pid))
      {
        m.cpu_percent = float(g->cpu_percent);
        m.rss_bytes = g->rss_bytes;
      }
    const double age = std::chrono::duration<double>(steady - p.started).count();
    m.started = now - ros::Duration(std::min(age, now.toSec()));
    if (const auto expiry = p.state != ProcState::Standby ? leases_.expiry(p.name) : std::nullopt)
      m.lease_expiry = now + ros::Duration(std::max(0.0, *expiry - steady_s));
    m.log_file = p.log_file;
    out.push_back(m);
  }
  return out;
}

void AgentNode::onSample(const ros::SteadyTimerEvent&)
{
  std::vector<int> pgids;
  for (const auto& p : supervisor_.snapshot())
    if (p.pid != 0)
      pgids.push_back(p.pid);
  anyscale_msgs::ScaleStatus s;
  s.cpu_held_percent = cpuHeldByOthers();  // a file read under its lock: not under ours
  {
    std::lock_guard<std::mutex> lock(sample_mutex_);
    sampler_.sample(steadyNow(), pgids);
    const ScaleUsage& u = sampler_.scale();
    s.header.stamp = ros::Time::now();
    s.scale = scale_;
    s.is_master = is_master_;
    s.cores = u.cores;
    s.cpu_max_ghz = float(u.cpu_max_ghz);
    s.cpu_quota_cores = float(u.quota_cores);
    s.cpu_percent = float(u.cpu_percent);
    s.memory_total_bytes = u.memory_total_bytes;
    s.memory_available_bytes = u.memory_available_bytes;
    s.sample_period_s = float(sampler_.periodSeconds());
    s.topics = topics_->stats(s.header.stamp);
    s.link = link_->stats();
    applyUplink(s.link);
    s.nodes = nodeProcesses();  // last, just before publishing: see onUplink
    last_status_ = s;
  }
  status_pub_.publish(s);
  diagnostics_.update();
}

}  // namespace anyscale_agent
