// Master and node XML-RPC queries: getSystemState, lookupNode, getPid.
#include "anyscale_agent_cpp/graph_monitor.h"

#include <XmlRpcClient.h>
#include <ros/master.h>
#include <ros/network.h>
#include <ros/this_node.h>

namespace anyscale_agent
{

bool splitUri(const std::string& uri, std::string* host, int* port)
{
  const std::string scheme = "http://";
  if (uri.rfind(scheme, 0) != 0)
    return false;
  const auto start = scheme.size();
  const auto colon = uri.find(':', start);
  if (colon == std::string::npos)
    return false;
  *host = uri.substr(start, colon - start);
  try
  {
    *port = std::stoi(uri.substr(colon + 1));
  }
  catch (const std::exception&)
  {
    return false;
  }
  return !host->empty() && *port > 0;
}

GraphMonitor::GraphMonitor() : host_(ros::network::getHost()) {}

std::optional<GraphMonitor::Registration> GraphMonitor::lookup(const std::string& node) const
{
  XmlRpc::XmlRpcValue args, result, payload;
  args[0] = ros::this_node::getName();
  args[1] = node;
  if (!ros::master::execute("lookupNode", args, result, payload, false) ||
      payload.getType() != XmlRpc::XmlRpcValue::TypeString)
    return std::nullopt;
  Registration r;
  int port = 0;
  if (!splitUri(std::string(payload), &r.host, &port))
    return std::nullopt;
  // roscpp's master::execute is the only XML-RPC helper it exposes; a node is asked directly.
  XmlRpc::XmlRpcClient client(r.host.c_str(), port, "/");
  XmlRpc::XmlRpcValue pid_args, pid_result;
  pid_args[0] = ros::this_node::getName();
  if (client.execute("getPid", pid_args, pid_result) &&
      pid_result.getType() == XmlRpc::XmlRpcValue::TypeArray && pid_result.size() == 3 &&
      int(pid_result[0]) == 1 && pid_result[2].getType() == XmlRpc::XmlRpcValue::TypeInt)
    r.pid = int(pid_result[2]);
  client.close();
  return r;
}

std::optional<SystemState> GraphMonitor::systemState() const
{
  XmlRpc::XmlRpcValue args, result, payload;
  args[0] = ros::this_node::getName();
  if (!ros::master::execute("getSystemState", args, result, payload, false) ||
      payload.getType() != XmlRpc::XmlRpcValue::TypeArray || payload.size() < 3)
    return std::nullopt;
  // payload: [publishers, subscribers, services], each a list of [name, [node, ...]].
  SystemState state;
  SystemState::Table* tables[] = {&state.publishers, &state.subscribers, &state.services};
  for (int kind = 0; kind < 3; ++kind)
    for (int i = 0; i < payload[kind].size(); ++i)
    {
      std::vector<std::string> nodes;
      for (int j = 0; j < payload[kind][i][1].size(); ++j)
        nodes.push_back(std::string(payload[kind][i][1][j]));
      tables[kind]->emplace_back(std::string(payload[kind][i][0]), std::move(nodes));
    }
  return state;
}

bool GraphMonitor::inSystemState(const std::string& node) const
{
  const auto state = systemState();
  // A master that does not list this agent either (restarted, not yet restored) cannot tell.
  return !state || listsNode(*state, node) || !knowsAgent(*state, ros::this_node::getName());
}

std::optional<std::set<std::string>> GraphMonitor::localSubscribedTopics(
    const std::set<std::string>& own_nodes) const
{
  const auto state = systemState();
  if (!state)
    return std::nullopt;
  return anyscale_agent::localSubscribedTopics(
      *state, ros::this_node::getName(), [&](const std::string& node) {
        if (own_nodes.count(node))
          return true;
        XmlRpc::XmlRpcValue a, r, p;
        a[0] = ros::this_node::getName();
        a[1] = node;
        std::string host;
        int port = 0;
        return ros::master::execute("lookupNode", a, r, p, false) &&
               p.getType() == XmlRpc::XmlRpcValue::TypeString &&
               splitUri(std::string(p), &host, &port) && host == host_;
      });
}

}  // namespace anyscale_agent
