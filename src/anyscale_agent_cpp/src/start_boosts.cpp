// A started node's raised CPU priority for its first seconds, and when it ends (no ROS).
#include "anyscale_agent_cpp/start_boosts.h"

#include <algorithm>

namespace anyscale_agent
{

int StartBoosts::startNice(int declared_nice) const
{
  return std::clamp(declared_nice + boost_nice_, -20, 19);
}

void StartBoosts::started(const std::string& name, int pid, int declared_nice, double now)
{
  if (startNice(declared_nice) == declared_nice)
  {
    boosted_.erase(name);
    return;
  }
  boosted_[name] = { pid, now + boost_s_, declared_nice };
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

}  // namespace anyscale_agent
