// Agent restarts: the nodes a killed predecessor left running (~state_file) adopted with their
// leases, and every lease end kept in that state file for a successor to enforce.
#include "anyscale_agent_cpp/agent_node.h"

#include "anyscale_agent_cpp/process_priority.h"

namespace anyscale_agent
{

void AgentNode::adoptNodes(const std::string& state_file)
{
  const AdoptionReport report = supervisor_.adopt(state_file);
  if (!report.warning.empty())
    ROS_WARN("%s", report.warning.c_str());
  for (const auto& line : report.dropped)
    ROS_WARN("not adopted from %s: %s", state_file.c_str(), line.c_str());
  const double now = steadyNow();
  for (const auto& a : report.adopted)
  {
    const ProcessInfo& p = a.info;
    const NodeDecl* decl = model_.find(p.name);
    if (!decl)
    {
      // The model is what may run here; this agent would never have started it.
      ROS_WARN("adopted %s (pid %d) is not declared in %s: stopping it", p.name.c_str(), p.pid,
               model_path_.c_str());
      supervisor_.stop(p.name);
      continue;
    }
    ROS_INFO("adopted %s (pid %d, %s), left running by the agent before this one; log %s",
             p.name.c_str(), p.pid, toString(p.state), p.log_file.c_str());
    // Its start boost may have been under way when the predecessor died, and nobody would end it.
    std::string error;
    if (p.state != ProcState::Stopping && !setProcessNice(p.pid, decl->nice, &error))
      ROS_WARN("adopted %s: cannot set its nice to %d: %s", p.name.c_str(), decl->nice,
               error.c_str());
    else if (p.state != ProcState::Stopping)
      watchOutput(*decl, p.name, p.pid);
    if (a.lease_end_s <= 0.0 || p.state == ProcState::Stopping)
      continue;
    if (a.lease_end_s <= now)
    {
      // It ran on past its lease while no agent watched it: what the lease exists to prevent.
      ROS_WARN("adopted %s: its lease ended %.1f s ago, while no agent ran: stopping it",
               p.name.c_str(), now - a.lease_end_s);
      supervisor_.stop(p.name, ProcState::LeaseExpired);
      continue;
    }
    grantLease(p.name, a.lease_end_s - now);
  }
}

void AgentNode::grantLease(const std::string& name, double lease_s)
{
  std::lock_guard<std::mutex> lock(leases_mutex_);
  leases_.grant(name, steadyNow(), lease_s);
  // In the state file too, so that a successor enforces it (the steady clock is the system's
  // CLOCK_MONOTONIC, the same in every process of a boot).
  supervisor_.setLeaseEnds({{name, leases_.expiry(name).value_or(0.0)}});
}

void AgentNode::renewLease(const std::string& name, double lease_s)
{
  std::lock_guard<std::mutex> lock(leases_mutex_);
  if (lease_s > 0.0 && leases_.renew(name, steadyNow(), lease_s))
    supervisor_.setLeaseEnds({{name, *leases_.expiry(name)}});
}

}  // namespace anyscale_agent
