// getBusStats polling of the nodes this agent runs: bounded XML-RPC calls, servers found
// through /proc.
#include "anyscale_agent_cpp/bus_stats_poller.h"

#include <ros/console.h>
#include <xmlrpcpp/XmlRpcClient.h>

#include <algorithm>
#include <chrono>

#include "anyscale_agent_cpp/listening_sockets.h"
#include "anyscale_agent_cpp/proc_reader.h"

namespace anyscale_agent
{
namespace
{
// A node that did not answer is asked again this often, not at every poll: the poll thread
// would otherwise spend a call timeout on it each time, and the other nodes' replies would be
// overdue.
constexpr double kUnansweredRetryS = 1.0;
// How often a node whose XML-RPC server was not found (still starting) is looked for again.
constexpr double kDiscoveryRetryS = 0.5;

double steadyNow()
{
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

std::string faultText(const XmlRpc::XmlRpcValue& fault)
{
  if (fault.getType() == XmlRpc::XmlRpcValue::TypeStruct && fault.hasMember("faultString"))
  {
    XmlRpc::XmlRpcValue copy = fault;  // xmlrpcpp's struct access is not const
    if (copy["faultString"].getType() == XmlRpc::XmlRpcValue::TypeString)
      return copy["faultString"];
  }
  return "(no fault string)";
}

}  // namespace

// xmlrpcpp's execute() waits for as long as the server takes; its dispatcher can be run for a
// bounded time instead.
class TimedXmlRpcClient : public XmlRpc::XmlRpcClient
{
public:
  enum class Result
  {
    Ok,
    Fault,
    NoReply
  };
  TimedXmlRpcClient(const std::string& host, int port) : XmlRpcClient(host.c_str(), port, "/") {}

  Result call(const char* method, const XmlRpc::XmlRpcValue& params, XmlRpc::XmlRpcValue& result,
              double timeout_s)
  {
    if (!executeNonBlock(method, params))
    {
      close();
      return Result::NoReply;
    }
    _disp.work(timeout_s);
    if (!executeCheckDone(result) || !result.valid())
    {
      close();  // the next call starts on a new connection, not behind this one's late answer
      return Result::NoReply;
    }
    return isFault() ? Result::Fault : Result::Ok;
  }
};

struct BusStatsPoller::NodeState
{
  Node node;
  std::unique_ptr<TimedXmlRpcClient> client;
  int port = 0;
  int server_pid = 0;
  double next_try = 0.0;  // steady s
  int refusals = 0;
  std::map<std::string, std::map<int, int>>
      publishers;  // topic -> connection -> publisher's XML-RPC port
};

BusStatsPoller::BusStatsPoller(double window_s, double period_s, double call_timeout_s,
                               std::string caller_id, PublisherSeen seen)
  : window_s_(window_s),
    period_s_(period_s),
    call_timeout_s_(call_timeout_s),
    caller_id_(std::move(caller_id)),
    seen_(std::move(seen)),
    thread_(&BusStatsPoller::run, this)
{}

BusStatsPoller::~BusStatsPoller()
{
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stopping_ = true;
  }
  wake_.notify_all();
  thread_.join();
}

void BusStatsPoller::setTargets(const std::map<std::string, Node>& topics,
                                const std::vector<Node>& running)
{
  std::lock_guard<std::mutex> lock(mutex_);
  for (auto it = rates_.begin(); it != rates_.end();)
    it = topics.count(it->first) ? std::next(it) : rates_.erase(it);
  for (const auto& [topic, node] : topics)
  {
    const auto before = topics_.find(topic);
    if (before == topics_.end() || before->second != node || !rates_.count(topic))
      // A reply is overdue once the poll period, a call's timeout and another period have passed.
      rates_[topic] = std::make_unique<BusStatsRate>(window_s_, 2.0 * period_s_ + call_timeout_s_);
  }
  topics_ = topics;
  running_ = running;
}

std::vector<BusStatsPoller::TopicRate> BusStatsPoller::stats(double now)
{
  std::lock_guard<std::mutex> lock(mutex_);
  std::vector<TopicRate> out;
  for (const auto& [topic, node] : topics_)
    out.push_back({topic, node.name, rates_.at(topic)->stats(now)});
  return out;
}

std::map<std::string, std::string> BusStatsPoller::refused() const
{
  std::lock_guard<std::mutex> lock(mutex_);
  std::map<std::string, std::string> out;
  for (const auto& [topic, node] : topics_)
  {
    const auto why = refused_.find(node.name);
    if (why != refused_.end())
      out[topic] = why->second;
  }
  return out;
}

void BusStatsPoller::run()
{
  std::unique_lock<std::mutex> lock(mutex_);
  while (!stopping_)
  {
    const auto began = std::chrono::steady_clock::now();
    std::map<std::string, Node> wanted;
    for (const auto& entry : topics_)
      wanted[entry.second.name] = entry.second;
    if (running_ != named_running_)
    {
      named_running_ = running_;
      publisher_names_.clear();
    }
    for (auto it = refused_.begin(); it != refused_.end();)
      it = wanted.count(it->first) ? std::next(it) : refused_.erase(it);
    lock.unlock();

    for (auto it = nodes_.begin(); it != nodes_.end();)
    {
      const auto w = wanted.find(it->first);
      it = (w == wanted.end() || w->second != it->second->node) ? nodes_.erase(it) : std::next(it);
    }
    for (const auto& [name, node] : wanted)
    {
      auto& state = nodes_[name];
      if (!state)
      {
        state = std::make_unique<NodeState>();
        state->node = node;
      }
      if (steadyNow() >= state->next_try)
        poll(*state, steadyNow());
    }

    lock.lock();
    wake_.wait_until(lock, began + std::chrono::duration<double>(period_s_),
                     [this] { return stopping_; });
  }
}

bool BusStatsPoller::discover(NodeState& node, double now)
{
  node.next_try = now + kDiscoveryRetryS;
  const std::vector<int> members = processGroupMembers(node.node.pgid);
  XmlRpc::XmlRpcValue params;
  params[0] = caller_id_;
  for (const auto& socket : listeningSockets(members))
  {
    auto client = std::make_unique<TimedXmlRpcClient>(socket.host, socket.port);
    XmlRpc::XmlRpcValue reply;
    if (client->call("getPid", params, reply, call_timeout_s_) != TimedXmlRpcClient::Result::Ok)
      continue;
    const int pid = parsePidReply(reply);
    if (std::find(members.begin(), members.end(), pid) == members.end())
      continue;
    ROS_INFO(
        "topic counter: %s answers XML-RPC at %s:%d (pid %d): its inputs are counted from its "
        "getBusStats",
        node.node.name.c_str(), socket.host.c_str(), socket.port, pid);
    node.client = std::move(client);
    node.port = socket.port;
    node.server_pid = pid;
    node.publishers.clear();  // connection ids are the process's own
    return true;
  }
  return false;
}

void BusStatsPoller::poll(NodeState& node, double now)
{
  if (!node.client && !discover(node, now))
    return;
  XmlRpc::XmlRpcValue params, reply;
  params[0] = caller_id_;
  const auto result = node.client->call("getBusStats", params, reply, call_timeout_s_);
  const double t = steadyNow();
  if (result == TimedXmlRpcClient::Result::NoReply)
  {
    node.next_try = t + kUnansweredRetryS;
    // A server that is gone (the process ended or exec'd) is looked for again; one that is
    // there but silent (SIGSTOP, busy) is asked again later.
    bool listening = false;
    for (const auto& socket : listeningSockets(processGroupMembers(node.node.pgid)))
      listening = listening || socket.port == node.port;
    if (!listening)
      node.client.reset();
    return;
  }
  std::string why;
  SubscribedCounts counts;
  if (result == TimedXmlRpcClient::Result::Fault)
    why = "getBusStats answered a fault: " + faultText(reply);
  else
    parseBusStats(reply, &counts, &why);
  std::vector<std::pair<std::string, std::vector<int>>> grown;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (!why.empty())
    {
      if (++node.refusals >= kRefusalsToGiveUp)
        refused_[node.node.name] = why;
      return;
    }
    node.refusals = 0;
    refused_.erase(node.node.name);
    for (const auto& [topic, source] : topics_)
    {
      if (source.name != node.node.name)
        continue;
      const auto c = counts.find(topic);
      auto grew = rates_.at(topic)->add(
          t, node.server_pid, c == counts.end() ? std::vector<ConnectionCount>{} : c->second);
      if (!grew.empty())
        grown.emplace_back(topic, std::move(grew));
    }
  }
  if (!seen_ || grown.empty())
    return;
  // Who sent what was counted: the start boost of a node this agent runs ends at its first
  // output. getBusInfo names each connection's publisher by its XML-RPC URI; asked only when a
  // connection is new.
  bool unknown = false;
  for (const auto& [topic, ids] : grown)
    for (const int id : ids)
      unknown = unknown || !node.publishers[topic].count(id);
  if (unknown)
  {
    XmlRpc::XmlRpcValue info;
    InboundPublishers inbound;
    if (node.client->call("getBusInfo", params, info, call_timeout_s_) ==
            TimedXmlRpcClient::Result::Ok &&
        parseBusInfo(info, &inbound, nullptr))
      for (const auto& [topic, connections] : inbound)
        for (const auto& [id, uri] : connections)
          if (!node.publishers[topic].count(id))
            node.publishers[topic][id] = uriPort(uri);
  }
  for (const auto& [topic, ids] : grown)
    for (const int id : ids)
    {
      // Named now, not when the connection was new: a node started a moment ago may not be
      // among the running nodes yet.
      const auto port = node.publishers[topic].find(id);
      const std::string name =
          port == node.publishers[topic].end() ? "" : publisherName(port->second);
      if (!name.empty())
        seen_(name);
    }
}

std::string BusStatsPoller::publisherName(int port)
{
  if (port <= 0)
    return "";
  const auto known = publisher_names_.find(port);
  if (known != publisher_names_.end())
    return known->second;
  std::map<int, std::vector<int>> groups;
  for (const auto& p : readAllProcStats())
    groups[p.pgrp].push_back(p.pid);
  for (const auto& n : named_running_)
    for (const auto& socket : listeningSockets(groups[n.pgid]))
      publisher_names_.emplace(socket.port, n.name);
  // A publisher on another host (or not run by this agent) stays unnamed until the nodes
  // run here change.
  return publisher_names_.emplace(port, "").first->second;
}

}  // namespace anyscale_agent
