// /diagnostics of the agent (diagnostic_updater), from the last status sample.
#include "anyscale_agent_cpp/agent_node.h"

#include <cmath>

namespace anyscale_agent
{

void AgentNode::diagnoseNodes(diagnostic_updater::DiagnosticStatusWrapper& stat)
{
  std::lock_guard<std::mutex> lock(sample_mutex_);
  int running = 0, starting = 0, failed = 0;
  for (const auto& n : last_status_.nodes)
  {
    running += n.state == anyscale_msgs::NodeProcess::RUNNING;
    starting += n.state == anyscale_msgs::NodeProcess::STARTING;
    // A node that ended by itself with an error is worth a warning; stops and replacements are not.
    failed += n.state == anyscale_msgs::NodeProcess::EXITED && n.exit_code > 0;
    stat.add(n.name, std::to_string(n.pid) + " state " + std::to_string(n.state) + " cpu " +
                         std::to_string(n.cpu_percent) + " %");
  }
  stat.summaryf(
      failed ? diagnostic_msgs::DiagnosticStatus::WARN : diagnostic_msgs::DiagnosticStatus::OK,
      "%d running, %d starting, %d failed", running, starting, failed);
  std::lock_guard<std::mutex> boost_lock(boost_mutex_);
  stat.add("late output boosts", boosts_.lateBoosts());
}

void AgentNode::diagnoseScale(diagnostic_updater::DiagnosticStatusWrapper& stat)
{
  std::lock_guard<std::mutex> lock(sample_mutex_);
  const auto& s = last_status_;
  stat.summaryf(diagnostic_msgs::DiagnosticStatus::OK, "CPU %.0f %%, %.0f MB available",
                s.cpu_percent, double(s.memory_available_bytes) / 1e6);
  stat.add("cores", s.cores);
  stat.add("cpu_max_ghz", s.cpu_max_ghz);
  stat.add("cpu_quota_cores", s.cpu_quota_cores);
  stat.add("cpu_percent", s.cpu_percent);
  stat.add("memory_total_bytes", s.memory_total_bytes);
  stat.add("memory_available_bytes", s.memory_available_bytes);
  if (ledger_)
  {
    stat.add("capacity_ledger", ledger_->path());
    stat.add("cpu_held_percent_by_other_robots", s.cpu_held_percent);
    std::string error;
    {
      std::lock_guard<std::mutex> ledger_lock(ledger_mutex_);
      error = ledger_error_;
    }
    if (!error.empty())
      stat.mergeSummary(diagnostic_msgs::DiagnosticStatus::ERROR, error);
  }
}

void AgentNode::diagnoseLink(diagnostic_updater::DiagnosticStatusWrapper& stat)
{
  std::lock_guard<std::mutex> lock(sample_mutex_);
  const auto& l = last_status_.link;
  if (!l.carrier)
    stat.summaryf(diagnostic_msgs::DiagnosticStatus::ERROR, "uplink %s has no carrier",
                  l.uplink_interface.c_str());
  else if (is_master_)
    stat.summary(diagnostic_msgs::DiagnosticStatus::OK, l.uplink_interface.empty()
                                                            ? "master scale: no link to measure"
                                                            : "master scale: uplink has a carrier");
  else if (!l.up)
    stat.summary(diagnostic_msgs::DiagnosticStatus::ERROR, "link to the master scale is down");
  else
    stat.summaryf(diagnostic_msgs::DiagnosticStatus::OK, "up, RTT %.1f ms, %.1f Mbit/s",
                  1e3 * l.rtt_mean_s, l.bandwidth_mbps);
  stat.add("rtt_s", l.rtt_s);
  stat.add("rtt_mean_s", l.rtt_mean_s);
  stat.add("loss_ratio", l.loss_ratio);
  stat.add("bandwidth_mbps", l.bandwidth_mbps);
  if (!is_master_)
    stat.add("bandwidth measured by", link_->bandwidthMethod());
  stat.add("uplink_interface", l.uplink_interface);
  stat.add("carrier", bool(l.carrier));
}

void AgentNode::diagnoseTopics(diagnostic_updater::DiagnosticStatusWrapper& stat)
{
  std::lock_guard<std::mutex> lock(sample_mutex_);
  int stale = 0;
  for (const auto& t : last_status_.topics)
  {
    stale += t.window_messages == 0;
    stat.add(t.topic, std::to_string(t.rate_hz) + " Hz, last " +
                          std::to_string(t.last_message_age_s) + " s ago");
  }
  stat.summaryf(
      stale ? diagnostic_msgs::DiagnosticStatus::WARN : diagnostic_msgs::DiagnosticStatus::OK,
      "%zu topics counted, %d without messages in the window", last_status_.topics.size(), stale);
}

}  // namespace anyscale_agent
