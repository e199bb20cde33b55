// A node's raised CPU priority while its output is missing: from its start or resume until its
// first output, and while its output is late (no ROS).
#include "anyscale_agent_cpp/output_boosts.h"

#include <algorithm>

namespace anyscale_agent
{

int OutputBoosts::boostedNice(int declared_nice) const
{
  if (!boosts())
    return declared_nice;
  return std::clamp(std::min(declared_nice, 0) + boost_nice_, -20, 19);
}

void OutputBoosts::started(const std::string& name, const std::string& publisher, int pid,
                           int declared_nice, double tolerance_s, double now)
{
  if (!boosts())
  {
    nodes_.erase(name);
    return;
  }
  nodes_[name] = {publisher,     pid,
                  declared_nice, late_fraction_ * std::max(tolerance_s, 0.0),
                  -1.0,          now + boost_s_};
}

void OutputBoosts::watch(const std::string& name, const std::string& publisher, int pid,
                         int declared_nice, double tolerance_s)
{
  const double late_after_s = late_fraction_ * std::max(tolerance_s, 0.0);
  if (!boosts() || late_after_s <= 0.0)
  {
    nodes_.erase(name);
    return;
  }
  nodes_[name] = {publisher, pid, declared_nice, late_after_s, -1.0, 0.0};
}

std::optional<OutputBoosts::Change> OutputBoosts::published(const std::string& publisher,
                                                            double now)
{
  for (auto it = nodes_.begin(); it != nodes_.end(); ++it)
  {
    Entry& e = it->second;
    if (e.publisher != publisher)
      continue;
    e.last_output = now;
    std::optional<Change> back;
    if (e.boosted_until > 0.0)
      back = Change{it->first, e.pid, e.declared_nice};
    e.boosted_until = 0.0;
    if (e.late_after_s <= 0.0)
      nodes_.erase(it);
    return back;
  }
  return std::nullopt;
}

std::vector<OutputBoosts::Change> OutputBoosts::update(
    double now, const std::function<bool(const std::string&, int)>& running)
{
  std::vector<Change> changes;
  for (auto it = nodes_.begin(); it != nodes_.end();)
  {
    Entry& e = it->second;
    if (!running(it->first, e.pid))
    {
      it = nodes_.erase(it);
      continue;
    }
    if (e.boosted_until > 0.0)
    {
      if (now < e.boosted_until)
      {
        ++it;
        continue;
      }
      // Still silent after boost_s: a node without input or stuck gains nothing from more CPU.
      // It is watched again from its next output.
      changes.push_back({it->first, e.pid, e.declared_nice});
      e.boosted_until = 0.0;
      e.last_output = -1.0;
      if (e.late_after_s <= 0.0)
      {
        it = nodes_.erase(it);
        continue;
      }
    }
    else if (e.late_after_s > 0.0 && e.last_output >= 0.0 && now - e.last_output >= e.late_after_s)
    {
      changes.push_back({it->first, e.pid, boostedNice(e.declared_nice)});
      e.boosted_until = now + boost_s_;
      ++late_boosts_;
    }
    ++it;
  }
  return changes;
}

}  // namespace anyscale_agent
