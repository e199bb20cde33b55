// A started or resumed node's raised CPU priority until its first output, and when it ends (no ROS).
#pragma once

#include <map>
#include <optional>
#include <string>
#include <vector>

namespace anyscale_agent
{

// A node that starts (or is resumed) on a loaded scale competes with the nodes already there
// while it loads its imports and fills its first output: it runs at `boost_nice` until this
// agent sees its first message on a watched topic, and for `boost_s` at most (a node whose
// output no one subscribes to here is never seen). Times are seconds on a monotonic clock
// supplied by the caller.
class StartBoosts
{
public:
  StartBoosts() = default;
  StartBoosts(int boost_nice, double boost_s) : boost_nice_(boost_nice), boost_s_(boost_s) {}

  // The nice a node declared at `declared_nice` starts at: boost_nice below 0, or below its
  // declared nice where that is lower. A node declared to yield (nice > 0) does not yield
  // until its output is back: AR recognition (nice 5), resumed beside AMCL by a link loss,
  // ran at a quarter of AMCL's weight and took 0.7-1.25 s to its first output against its
  // Δ of 1 s (office floor, 8 double returns, 3 over). Its first output costs a few frames,
  // so the boost ends after a fraction of a second, not after boost_s (a boost of boost_s at
  // AMCL's priority once took half the robot's CPU, and AMCL's return took 2.43 s).
  int startNice(int declared_nice) const;

  // `pid` now runs at startNice(declared_nice); its boost ends when `publisher` (the caller id
  // its messages carry) is seen, or at now + boost_s. Replaces an earlier boost of `name`.
  // Nothing is recorded without a boost.
  void started(const std::string& name, const std::string& publisher, int pid, int declared_nice, double now);

  struct Due
  {
    std::string name;
    int pid;   // the process that was boosted: the node may have been started again since
    int nice;  // its declared nice, to set back
  };
  // The boosts that ran out at or before `now`; they are removed.
  std::vector<Due> takeDue(double now);
  // The boost of the node that publishes as `publisher`, if it has one; it is removed.
  std::optional<Due> published(const std::string& publisher);
  bool empty() const { return boosted_.empty(); }

private:
  struct Boost
  {
    std::string publisher;
    int pid;
    double until;
    int nice;
  };
  int boost_nice_ = 0;
  double boost_s_ = 3.0;
  std::map<std::string, Boost> boosted_;
};

}  // namespace anyscale_agent
