// A started or resumed node's raised CPU priority until its first output, and when it ends (no ROS).
#include "anyscale_agent_cpp/start_boosts.h"

#include <algorithm>

namespace anyscale_agent
{

int StartBoosts::startNice(int declared_nice) const
{
  if (boost_nice_ == 0)
    return declared_nice;
  return std::clamp(std::min(declared_nice, 0) + boost_nice_, -20, 19);
}

void StartBoosts::started(const std::string& name, const std::string& publisher, int pid, int declared_nice,
                          double now)
{
  if (startNice(declared_nice) == declared_nice)
  {
    boosted_.erase(name);
    return;
  }
  boosted_[name] = { publisher, pid, now + boost_s_, declared_nice };
}

std::vector<StartBoosts::Due> StartBoosts::takeDue(double now)
{
  std::vector<Due> due;
  for (auto it = boosted_.begin(); it != boosted_.end();)
  {
    if (now < it->second.until)
    {
      ++it;
      continue;
    }
    due.push_back({ it->first, it->second.pid, it->second.nice });
    it = boosted_.erase(it);
  }
  return due;
}

std::optional<StartBoosts::Due> StartBoosts::published(const std::string& publisher)
{
  for (auto it = boosted_.begin(); it != boosted_.end(); ++it)
  {
    if (it->second.publisher != publisher)
      continue;
    Due due{ it->first, it->second.pid, it->second.nice };
    boosted_.erase(it);
    return due;
  }
  return std::nullopt;
}

}  // namespace anyscale_agent
