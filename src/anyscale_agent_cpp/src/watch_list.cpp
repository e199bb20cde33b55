// The watched topics and their model subscribers on this scale.
#include "anyscale_agent_cpp/watch_list.h"

namespace anyscale_agent
{

bool WatchList::assign(const std::vector<std::string>& topics,
                       const std::vector<std::string>& subscribers, std::string* error)
{
  if (!subscribers.empty() && subscribers.size() != topics.size())
  {
    if (error)
      *error = std::to_string(subscribers.size()) + " subscribers for " +
               std::to_string(topics.size()) +
               " topics: give one per topic (\"\" for none), or none at all";
    return false;
  }
  std::map<std::string, std::set<std::string>> out;
  for (std::size_t i = 0; i < topics.size(); ++i)
  {
    auto& subs = out[topics[i]];
    if (!subscribers.empty() && !subscribers[i].empty())
      subs.insert(subscribers[i]);
  }
  subscribers_ = std::move(out);
  return true;
}

std::set<std::string> WatchList::toCount(const std::set<std::string>& graph_local,
                                         const std::set<std::string>& running, bool watch_all) const
{
  std::set<std::string> out;
  for (const auto& [topic, subs] : subscribers_)
  {
    bool counted = watch_all || graph_local.count(topic) > 0;
    for (auto it = subs.begin(); !counted && it != subs.end(); ++it)
      counted = running.count(*it) > 0;
    if (counted)
      out.insert(topic);
  }
  return out;
}

std::map<std::string, std::string> WatchList::runningSubscribers(
    const std::set<std::string>& running) const
{
  std::map<std::string, std::string> out;
  for (const auto& [topic, subs] : subscribers_)
    for (const auto& node : subs)
      if (running.count(node))
      {
        out[topic] = node;
        break;
      }
  return out;
}

std::vector<std::string> WatchList::topics() const
{
  std::vector<std::string> out;
  for (const auto& entry : subscribers_)
    out.push_back(entry.first);
  return out;
}

}  // namespace anyscale_agent
