// Which of the watched topics the agent counts on its scale, and for which nodes (no ROS).
#pragma once

#include <map>
#include <set>
#include <string>
#include <vector>

namespace anyscale_agent
{

// The topics the decision node asks this agent to count, each with the nodes on this scale
// that subscribe to it in the model (fully qualified declared names; may be none).
//
// Why the subscribers: a counter across the link pulls the topic's data onto this scale, so a
// topic is counted only where a node uses it. The master's graph tells that once a poll of it
// has seen the node's subscription, and the poll runs in one thread with every other master
// query, each a call over the link to a master on the robot's quota. Four times in 18
// office-floor runs (evaluation seeds 13, 14 and 19) the laptop's counters for /scan and
// /camera/image_raw did not exist 9 s after AMCL and AR had moved there, on a 27 Mbit/s link,
// while the laptop's AMCL published at 5 Hz from its scans: the decision node read "no rate on
// laptop" and brought both home. A node this agent runs is known without the master.
class WatchList
{
public:
  // `subscribers` is empty or as long as `topics`: subscribers[i] subscribes to topics[i]
  // ("" for none). A topic may appear more than once, with different subscribers.
  // Returns false, with what was wrong in *error, if the lengths differ.
  bool assign(const std::vector<std::string>& topics, const std::vector<std::string>& subscribers,
              std::string* error);

  // The topics to count: every watched one with `watch_all`; else those that a node of this
  // scale subscribes to, by the master's graph (`graph_local`) or by the model, where the
  // subscriber is one of the nodes this agent runs (`running`, fully qualified).
  std::set<std::string> toCount(const std::set<std::string>& graph_local,
                                const std::set<std::string>& running, bool watch_all) const;

  // The watched topics that a node this agent runs subscribes to by the model, each with that
  // node (the first by name where several do): they are counted from the node's own bus
  // statistics, with no subscription of the agent's (see BusStatsRate).
  std::map<std::string, std::string> runningSubscribers(const std::set<std::string>& running) const;

  std::vector<std::string> topics() const;

private:
  std::map<std::string, std::set<std::string>> subscribers_;  // topic -> model subscribers here
};

}  // namespace anyscale_agent
