// A started node's raised CPU priority for its first seconds, and when it ends (no ROS).
#pragma once

#include <map>
#include <string>
#include <vector>

namespace anyscale_agent
{

// A node that starts on a loaded scale competes with the nodes already there while it loads
// its imports and fills its first output: for its first `boost_s` it runs `boost_nice` below
// its declared nice. Times are seconds on a monotonic clock supplied by the caller.
class StartBoosts
{
public:
  StartBoosts() = default;
  StartBoosts(int boost_nice, double boost_s) : boost_nice_(boost_nice), boost_s_(boost_s) {}

  // The nice a node declared at `declared_nice` starts at. The boost is relative: a node
  // declared to yield (nice > 0) still yields to a boosted node of nice 0 started with it.
  int startNice(int declared_nice) const;

  // `pid` now runs at startNice(declared_nice); at now + boost_s it is due back at its
  // declared nice. Replaces an earlier boost of `name`. Nothing is recorded without a boost.
  void started(const std::string& name, int pid, int declared_nice, double now);

  struct Due
  {
    std::string name;
    int pid;   // the process that was boosted: the node may have been started again since
    int nice;  // its declared nice, to set back
  };
  // The boosts that ran out at or before `now`; they are removed.
  std::vector<Due> takeDue(double now);

private:
  struct Boost
  {
    int pid;
    double until;
    int nice;
  };
  int boost_nice_ = 0;
  double boost_s_ = 3.0;
  std::map<std::string, Boost> boosted_;
};

}  // namespace anyscale_agent
