// Master and node XML-RPC queries: getSystemState, lookupNode, getPid.
#include "anyscale_agent_cpp/graph_monitor.h"

#include <XmlRpcClient.h>
#include <ros/master.h>
#include <ros/network.h>
#include <ros/this_node.h>

#include <map>

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

GraphMonitor::GraphMonitor() : host_(ros::network::getHost())
{
}

std::optional<GraphMonitor::Registration> GraphMonitor::lookup(const std::string& node) const
{
  XmlRpc::XmlRpcValue args, result, payload;
  args[0] = ros::this_node::getName();
  args[1] = node;
  if (!ros::master::execute("lookupNode", args, result, payload, false) || payload.getType() != XmlRpc::XmlRpcValue::TypeString)
    return std::nullopt;
  Registration r;
  int port = 0;
  if (!splitUri(std::string(payload), &r.host, &port))
    return std::nullopt;
  // roscpp's master::execute is the only XML-RPC helper it exposes; a node is asked directly.
  XmlRpc::XmlRpcClient client(r.host.c_str(), port, "/");
  XmlRpc::XmlRpcValue pid_args, pid_result;
  pid_args[0] = ros::this_node::getName();
  if (client.execute("getPid", pid_args, pid_result) && pid_result.getType() == XmlRpc::XmlRpcValue::TypeArray &&
      pid_result.size() == 3 && int(pid_result[0]) == 1 && pid_result[2].getType() == XmlRpc::XmlRpcValue::TypeInt)
    r.pid = int(pid_result[2]);
  client.close();
  return r;
}

bool GraphMonitor::inSystemState(const std::string& node) const
{
  XmlRpc::XmlRpcValue args, result, payload;
  args[0] = ros::this_node::getName();
  if (!ros::master::execute("getSystemState", args, result, payload, false) ||
      payload.getType() != XmlRpc::XmlRpcValue::TypeArray || payload.size() < 3)
    return true;
  // payload: [publishers, subscribers, services], each a list of [name, [node, ...]].
  for (int kind = 0; kind < 3; ++kind)
    for (int i = 0; i < payload[kind].size(); ++i)
      for (int j = 0; j < payload[kind][i][1].size(); ++j)
        if (std::string(payload[kind][i][1][j]) == node)
          return true;
  return false;
}

std::optional<std::set<std::string>> GraphMonitor::localSubscribedTopics(const std::set<std::string>& own_nodes) const
{
  XmlRpc::XmlRpcValue args, result, payload;
  args[0] = ros::this_node::getName();
  if (!ros::master::execute("getSystemState", args, result, payload, false) ||
      payload.getType() != XmlRpc::XmlRpcValue::TypeArray || payload.size() < 2)
    return std::nullopt;
  std::set<std::string> topics;
  std::map<std::string, bool> is_local;  // per node, asked once per call
  const std::string self = ros::this_node::getName();
  XmlRpc::XmlRpcValue& subscribers = payload[1];
  for (int i = 0; i < subscribers.size(); ++i)
  {
    const std::string topic = subscribers[i][0];
    XmlRpc::XmlRpcValue& nodes = subscribers[i][1];
    for (int j = 0; j < nodes.size(); ++j)
    {
      const std::string node = nodes[j];
      if (node == self)
        continue;  // our own counter does not make a topic local
      auto it = is_local.find(node);
      if (it == is_local.end())
      {
        bool local = own_nodes.count(node) > 0;
        if (!local)
        {
          XmlRpc::XmlRpcValue a, r, p;
          a[0] = self;
          a[1] = node;
          std::string host;
          int port = 0;
          local = ros::master::execute("lookupNode", a, r, p, false) && p.getType() == XmlRpc::XmlRpcValue::TypeString &&
                  splitUri(std::string(p), &host, &port) && host == host_;
        }
        it = is_local.emplace(node, local).first;
      }
      if (it->second)
      {
        topics.insert(topic);
        break;
      }
    }
  }
  return topics;
}

}  // namespace anyscale_agent
