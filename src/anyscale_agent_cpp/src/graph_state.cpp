// The master's system state as the agent reads it, ROS-free.
#include "anyscale_agent_cpp/graph_state.h"

#include <map>

namespace anyscale_agent
{

namespace
{

bool inTable(const SystemState::Table& table, const std::string& node)
{
  for (const auto& [name, nodes] : table)
    for (const auto& n : nodes)
      if (n == node)
        return true;
  return false;
}

}  // namespace

bool listsNode(const SystemState& state, const std::string& node)
{
  return inTable(state.publishers, node) || inTable(state.subscribers, node) ||
         inTable(state.services, node);
}

bool knowsAgent(const SystemState& state, const std::string& self)
{
  return inTable(state.publishers, self);
}

std::optional<std::set<std::string>> localSubscribedTopics(
    const SystemState& state, const std::string& self,
    const std::function<bool(const std::string&)>& is_local)
{
  if (!knowsAgent(state, self))
    return std::nullopt;
  std::set<std::string> topics;
  std::map<std::string, bool> local;
  for (const auto& [topic, nodes] : state.subscribers)
    for (const auto& node : nodes)
    {
      if (node == self)
        continue;  // our own counter does not make a topic local
      auto it = local.find(node);
      if (it == local.end())
        it = local.emplace(node, is_local(node)).first;
      if (it->second)
      {
        topics.insert(topic);
        break;
      }
    }
  return topics;
}

}  // namespace anyscale_agent
