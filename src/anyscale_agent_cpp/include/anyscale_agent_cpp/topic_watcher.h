// Type-agnostic rate counters for the topics the agent is told to watch on its scale.
#pragma once

#include <ros/callback_queue_interface.h>
#include <ros/ros.h>
#include <topic_tools/shape_shifter.h>

#include <anyscale_msgs/TopicStatistics.h>

#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <set>
#include <string>
#include <vector>

#include "anyscale_agent_cpp/bus_stats_poller.h"
#include "anyscale_agent_cpp/rate_window.h"
#include "anyscale_agent_cpp/watch_list.h"

namespace anyscale_agent
{

// Runs each counter callback at once, in the roscpp network thread that read the message.
// Through a normal queue every message costs a wake-up of a spinner thread, which profiling
// showed to be most of the agent's CPU at a few hundred messages per second; the counter's
// work (a mutex and a deque push) is far cheaper than that hand-off.
class InlineCallbackQueue : public ros::CallbackQueueInterface
{
public:
  void addCallback(const ros::CallbackInterfacePtr& callback, uint64_t owner_id) override;
  void removeByID(uint64_t owner_id) override;
};

class TopicWatcher
{
public:
  // Called with each message's publisher (its caller id), in the transport thread; keep it short.
  using PublisherSeen = std::function<void(const std::string& publisher)>;

  // A watched topic that a node this agent runs subscribes to (by the model) is counted from
  // that node's own getBusStats, polled every `bus_stats_period_s` (BusStatsPoller): a second
  // subscription would carry the topic across the link twice. Any other counted topic gets a
  // subscription of the agent's, with topic_tools::ShapeShifter, so nothing is deserialised:
  // the counter sees the serialized size, the receipt time and the publisher only.
  // `by_bus_stats` false: every counted topic by a subscription, none from a node's bus
  // statistics (see the agent's ~count_by_bus_stats).
  TopicWatcher(ros::NodeHandle nh, double window_s, int queue_size, bool watch_all,
               bool by_bus_stats, double bus_stats_period_s, double bus_stats_timeout_s,
               PublisherSeen on_publisher = {});

  // The topics to watch (resolved names), each with the node on this scale that subscribes
  // to it in the model (`subscribers`: empty, or one per topic; see WatchList). Names are
  // validated here; returns false with the offending one in *error and changes nothing.
  bool setWatched(const std::vector<std::string>& topics,
                  const std::vector<std::string>& subscribers, std::string* error);
  std::vector<std::string> watched() const;

  // Subscribes to the watched topics that a node on this scale subscribes to, and drops the
  // rest (WatchList::toCount): subscribing here to a topic no local node uses would pull its
  // data across the link only to count it. `update` gives what the master's graph shows (graph
  // thread); `setRunning` the nodes this agent runs (fully qualified), which needs no master
  // to know. It changes the subscriptions only if `may_call_master()` (see renewSilent); what is
  // counted from bus statistics changes at once (no master involved).
  struct RunningNode
  {
    std::string instance;  // the name it runs under here (the master's), fully qualified
    int pid = 0;           // its process group
    bool paused = false;   // SIGSTOPped: it receives nothing, its bus statistics say nothing
  };
  void update(const std::set<std::string>& local_topics);
  void setRunning(const std::map<std::string, RunningNode>& running,
                  const std::function<bool()>& may_call_master);

  std::vector<anyscale_msgs::TopicStatistics> stats(const ros::Time& now);

  // New subscriptions, keeping the counts, for the counted topics that received nothing for
  // `silent_s` (steady clock `now`) since they were last (re)subscribed. A connection across the
  // link can be dead while its publisher runs: TCP's backoff holds it silent for minutes after an
  // outage, and roscpp gives up on one whose retry failed at once (see LinkMonitor). A counter
  // that read 0 Hz there sent AMCL and AR home 9 s after every move out (office floor, seed 4).
  // `may_call_master` is asked once, and only when there is something to renew.
  void renewSilent(double now, double silent_s, const std::function<bool()>& may_call_master);

private:
  struct Counter
  {
    explicit Counter(double window_s) : window(window_s) {}
    std::mutex mutex;
    RateWindow window;
    std::string datatype;
    double last_seen = -1e300;      // steady s of the last message
    double subscribed_at = -1e300;  // steady s of the last (re)subscription
    ros::Subscriber sub;
  };
  void subscribe(const std::string& topic, const std::shared_ptr<Counter>& c);
  // What is counted how, from the watch list, the graph, the nodes run here and the nodes whose
  // bus statistics are refused (under mutex_).
  struct Plan
  {
    std::set<std::string> subscribed;
    std::map<std::string, BusStatsPoller::Node> polled;  // every topic a running node subscribes to
    std::set<std::string> by_bus;                        // those of them counted from bus stats
    std::map<std::string, std::string> refused;  // topic -> why its node's stats are refused
  };
  Plan plan() const;
  void applyBus();  // no master call
  std::mutex applying_bus_;
  std::string describeLocked() const;

  InlineCallbackQueue inline_queue_;
  ros::NodeHandle nh_;
  double window_s_;
  int queue_size_;
  bool watch_all_;
  bool by_bus_stats_;
  PublisherSeen on_publisher_;
  // Held across subscribing and unsubscribing (calls to the master, which may wait), so that
  // stats() never waits for them under mutex_.
  std::mutex subscribing_;
  mutable std::mutex mutex_;
  void apply();  // both: subscribes and unsubscribes to match the watch list

  WatchList watched_;
  std::set<std::string> local_topics_;
  std::set<std::string> running_;                     // declared names, for WatchList::toCount
  std::map<std::string, RunningNode> running_nodes_;  // declared name ->
  std::map<std::string, std::shared_ptr<Counter>> counters_;  // subscribed topics only
  std::map<std::string, std::string> by_bus_;  // topic -> node, counted from its bus stats
  std::unique_ptr<BusStatsPoller> poller_;
};

}  // namespace anyscale_agent
