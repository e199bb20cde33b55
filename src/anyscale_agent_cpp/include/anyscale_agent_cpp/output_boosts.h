// A node's raised CPU priority while its output is missing: from its start or resume until its
// first output, and while its output is late (no ROS).
#pragma once

#include <functional>
#include <map>
#include <optional>
#include <string>
#include <vector>

namespace anyscale_agent
{

// Two cases, one remedy: the node runs at `boost_nice` until this agent sees its next message
// on a watched topic, and for `boost_s` at most (a node whose output no one subscribes to here
// is never seen).
//
// At a start or resume: a node that starts on a loaded scale competes with the nodes already
// there while it loads its imports and fills its first output.
//
// When late: once its output has been seen here, a node with an output tolerance Δ (the
// model's connections) whose output has been silent for `late_fraction` x Δ is boosted until
// its next message: the node gets the CPU when its Δ is at stake, and the yielding order stays
// in place otherwise (docs/design/agent.md, "Start boost and migration stops").
//
// Times are seconds on a monotonic clock supplied by the caller.
class OutputBoosts
{
public:
  OutputBoosts() = default;
  OutputBoosts(int boost_nice, double boost_s, double late_fraction)
    : boost_nice_(boost_nice), boost_s_(boost_s), late_fraction_(late_fraction)
  {}

  // The nice a node declared at `declared_nice` runs at while boosted: boost_nice below 0, or
  // below its declared nice where that is lower: a node declared to yield does not yield while
  // its output is missing (docs/design/agent.md, "Paused at home").
  int boostedNice(int declared_nice) const;

  // A change of a process's nice for the caller to make.
  struct Change
  {
    std::string name;
    int pid;  // the process: the node may have been started again since
    int nice;
  };

  // `pid` now runs at boostedNice(declared_nice) (the caller set it); its boost ends when
  // `publisher` (the caller id its messages carry) is seen, or at now + boost_s. With
  // `tolerance_s` > 0 its output is watched for lateness afterwards. Replaces an earlier entry
  // of `name`. Nothing is recorded without a boost.
  void started(const std::string& name, const std::string& publisher, int pid, int declared_nice,
               double tolerance_s, double now);
  // A node that runs at its declared nice (adopted from a previous agent): watched for
  // lateness only, from its next output on.
  void watch(const std::string& name, const std::string& publisher, int pid, int declared_nice,
             double tolerance_s);

  // A message of `publisher` was seen: its boost, if it has one, ends (the nice to set back).
  std::optional<Change> published(const std::string& publisher, double now);

  // The boosts that ran out (nice back to declared) and the nodes whose output is late (nice
  // raised). `running(name, pid)` says whether that process still runs unpaused; entries of
  // one that does not are dropped.
  std::vector<Change> update(double now,
                             const std::function<bool(const std::string&, int)>& running);

  bool empty() const { return nodes_.empty(); }
  int lateBoosts() const { return late_boosts_; }  // counted since construction

private:
  struct Entry
  {
    std::string publisher;
    int pid;
    int declared_nice;
    double late_after_s;   // 0: never late
    double last_output;    // < 0: none seen since the start
    double boosted_until;  // 0: not boosted
  };
  bool boosts() const { return boost_nice_ != 0; }

  int boost_nice_ = 0;
  double boost_s_ = 3.0;
  double late_fraction_ = 0.0;
  int late_boosts_ = 0;
  std::map<std::string, Entry> nodes_;
};

}  // namespace anyscale_agent
