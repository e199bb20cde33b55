// Counting the inputs of the nodes this agent runs from their own XML-RPC getBusStats (a thread of
// its own).
#pragma once

#include <condition_variable>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "anyscale_agent_cpp/bus_stats_rate.h"

namespace anyscale_agent
{

class TimedXmlRpcClient;

// Polls each counted node's getBusStats every `period_s` and keeps a BusStatsRate per topic.
// The node's XML-RPC server is found without the master (on the laptop the master is across
// the link, and master calls there have taken up to 116 s after a link loss): the TCP ports its
// process group listens on (/proc), asked `getPid` until one answers with a pid of the group.
// Ports that hold accepted connections (TCPROS servers, which rosout connects to) are asked
// last: a TCPROS server takes the request for a header length (roscpp logs an error, rospy
// stops accepting subscribers until the request is closed). Each call is bounded by
// `call_timeout_s`, so a node that does not answer (SIGSTOP, busy) only leaves its topics
// without data; it never holds this thread for long.
class BusStatsPoller
{
public:
  using PublisherSeen = std::function<void(const std::string& publisher)>;
  struct Node
  {
    std::string name;  // as it runs here (the master's name), fully qualified
    int pgid = 0;      // its process group (the pid the agent started)
    bool operator==(const Node& o) const { return name == o.name && pgid == o.pgid; }
    bool operator!=(const Node& o) const { return !(*this == o); }
  };
  struct TopicRate
  {
    std::string topic;
    std::string node;
    RateStats stats;
  };

  // `seen` gets the name of a node this agent runs when a counted topic received a message
  // from it (the start boost ends at a node's first output); called from the poll thread.
  BusStatsPoller(double window_s, double period_s, double call_timeout_s, std::string caller_id,
                 PublisherSeen seen);
  ~BusStatsPoller();
  BusStatsPoller(const BusStatsPoller&) = delete;
  BusStatsPoller& operator=(const BusStatsPoller&) = delete;

  // topic -> the node whose bus statistics count it; `running`: every node this agent runs,
  // to name a counted message's publisher (by the port of its XML-RPC URI). A topic whose
  // node changed starts again from no data.
  void setTargets(const std::map<std::string, Node>& topics, const std::vector<Node>& running);

  std::vector<TopicRate> stats(double now);

  // The topics whose node has refused getBusStats (a fault, or a reply that is not bus
  // statistics) at its last `kRefusalsToGiveUp` polls, with the reason: they are better counted
  // by a subscription. A rospy node faults once a connection passed 2 GiB (its byte count no
  // longer fits an XML-RPC integer).
  std::map<std::string, std::string> refused() const;
  static constexpr int kRefusalsToGiveUp = 3;

private:
  struct NodeState;
  void run();
  void poll(NodeState& node, double now);
  bool discover(NodeState& node, double now);
  std::string publisherName(int port);

  double window_s_, period_s_, call_timeout_s_;
  std::string caller_id_;
  PublisherSeen seen_;

  mutable std::mutex mutex_;  // the targets and the rates; never held across a call
  std::map<std::string, Node> topics_;
  std::vector<Node> running_;
  std::map<std::string, std::unique_ptr<BusStatsRate>> rates_;  // topic ->
  std::map<std::string, std::string> refused_;                  // node name -> why

  // Poll thread only.
  std::map<std::string, std::unique_ptr<NodeState>> nodes_;  // node name ->
  std::map<int, std::string> publisher_names_;               // XML-RPC port -> running node
  std::vector<Node> named_running_;                          // running_ when that was filled

  std::condition_variable wake_;
  bool stopping_ = false;
  std::thread thread_;
};

}  // namespace anyscale_agent
