// Rate statistics of one topic from a subscriber node's cumulative per-connection counts (no ROS).
#pragma once

#include <cstdint>
#include <deque>
#include <map>
#include <vector>

#include "anyscale_agent_cpp/bus_stats_reply.h"
#include "anyscale_agent_cpp/rate_window.h"

namespace anyscale_agent
{

// The agent counts a topic that a node it runs subscribes to from that node's getBusStats,
// polled every `poll_period_s`, instead of subscribing a second time: a second subscription
// across a thin link carries the stream twice (the camera's 6.3 Mbit/s on a 3-12 Mbit/s WiFi
// link). A poll only tells how many messages arrived since the previous one, so arrival times
// are estimates at the poll's resolution:
// - k messages counted between replies at t0 and t1 are taken as k arrivals in (t0, t1], the
//   last of them at t1 - (t1 - t0) / (k + 1) (the expected latest of k uniform arrivals);
// - the rate is the messages between the estimated last arrivals of the first and the last
//   reply in the window that counted any, over the time between them (intervals / their sum, as
//   RateWindow), with the same decay after a silence; intervals are per-reply means;
// - time after the last reply is not silence until a reply is overdue (`overdue_s` after it):
//   a node that stops answering (frozen, gone) has received nothing that anyone knows of, and
//   its topic's age then grows from there.
// Times are seconds on a monotonic clock given by the caller.
class BusStatsRate
{
public:
  BusStatsRate(double window_s, double overdue_s);

  // A reply at `t` from the node process `pid` (its getPid: a restarted node is a new process
  // whose counts start again from 0) listing the topic's connections now (none if it has no
  // publisher connected, or does not subscribe). Connections that are new since the last reply
  // count in full (made after it); those gone take their unread tail with them. The first
  // reply, one from another process after a gap longer than the window, or one after such a
  // gap, is a baseline only. Returns the ids of the connections whose count grew.
  std::vector<int> add(double t, int pid, const std::vector<ConnectionCount>& connections);

  RateStats stats(double now);

  double windowSeconds() const { return window_s_; }

private:
  struct Reply  // a reply that counted messages
  {
    double t;
    double last_arrival;  // estimate
    uint64_t messages;
    uint64_t bytes;
  };
  double window_s_;
  double grace_s_;
  int pid_ = 0;
  bool have_baseline_ = false;
  double last_reply_t_ = 0.0;
  std::map<int, ConnectionCount> last_;  // connection id -> counts at the last reply
  std::deque<Reply> counted_;            // within the window
  bool ever_received_ = false;
  double last_arrival_ = 0.0;
};

}  // namespace anyscale_agent
