// The master's system state as the agent reads it, ROS-free: who subscribes to what here, and
// whether the master is one that knows this agent at all.
#pragma once

#include <functional>
#include <optional>
#include <set>
#include <string>
#include <utility>
#include <vector>

namespace anyscale_agent
{

// getSystemState's answer: per kind, (topic or service, the nodes that hold it).
struct SystemState
{
  using Table = std::vector<std::pair<std::string, std::vector<std::string>>>;
  Table publishers, subscribers, services;
};

// Whether `node` publishes, subscribes to or serves anything in `state`.
bool listsNode(const SystemState& state, const std::string& node);

// Whether the master whose state this is knows the agent `self`: it lists a publication of it.
// The agent advertises its topics once, at its start, so a master that lists none restarted
// and has not been given back the old one's registrations (the master keeper) yet; a
// subscription the agent made since (a renewed rate counter) registers it with that master,
// but no publication.
bool knowsAgent(const SystemState& state, const std::string& self);

// Topics with a subscriber other than `self` for which `is_local(node)` holds (asked once per
// node). nullopt if the master does not know the agent `self`: then its graph, empty or
// nearly, says nothing about who subscribes here.
std::optional<std::set<std::string>> localSubscribedTopics(
    const SystemState& state, const std::string& self,
    const std::function<bool(const std::string&)>& is_local);

}  // namespace anyscale_agent
