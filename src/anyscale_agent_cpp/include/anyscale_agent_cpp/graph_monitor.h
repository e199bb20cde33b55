// Questions the agent asks the ROS master: who subscribes to what, who holds a node name.
#pragma once

#include <optional>
#include <set>
#include <string>

#include "anyscale_agent_cpp/graph_state.h"

namespace anyscale_agent
{

// Every call goes to the master (and possibly a node) over XML-RPC and can block while the
// link to the master is down, so the agent calls these from a thread of their own, never from
// the one that expires leases.
class GraphMonitor
{
public:
  GraphMonitor();

  // Topics with at least one subscriber on this scale: a node this agent supervises
  // (`own_nodes`, fully qualified), or any node whose XML-RPC URI is on this host.
  // nullopt if the master cannot be asked or does not know this agent (graph_state.h).
  std::optional<std::set<std::string>> localSubscribedTopics(
      const std::set<std::string>& own_nodes) const;

  struct Registration
  {
    std::string host;
    int pid = 0;  // 0 if the node did not answer getPid
  };
  // The process the master lists under `node` (fully qualified); nullopt if not registered.
  std::optional<Registration> lookup(const std::string& node) const;
  // Whether `node` publishes, subscribes to or serves anything in the master's system state.
  // (lookupNode is no test of that: the master keeps a node with a parameter subscription,
  // and rospy's rosout subscribes to one that is never dropped.) True if the master cannot
  // be asked or does not know this agent.
  bool inSystemState(const std::string& node) const;

  const std::string& host() const { return host_; }

private:
  std::optional<SystemState> systemState() const;

  std::string host_;
};

// "http://host:11311/" -> host and port; false if it is not such a URI.
bool splitUri(const std::string& uri, std::string* host, int* port);

}  // namespace anyscale_agent
