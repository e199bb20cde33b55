// Cumulative per-connection message counts turned into rate, throughput and age.
#include "anyscale_agent_cpp/bus_stats_rate.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace anyscale_agent
{

BusStatsRate::BusStatsRate(double window_s, double overdue_s)
  : window_s_(window_s > 0.0 ? window_s : 2.0), grace_s_(overdue_s > 0.0 ? overdue_s : 0.5)
{}

std::vector<int> BusStatsRate::add(double t, int pid,
                                   const std::vector<ConnectionCount>& connections)
{
  std::map<int, ConnectionCount> now;
  for (const auto& c : connections)
    now[c.id] = c;
  const bool gap = have_baseline_ && t - last_reply_t_ > window_s_;
  const bool baseline = !have_baseline_ || gap;
  std::vector<int> grew;
  uint64_t messages = 0, bytes = 0;
  if (!baseline)
  {
    // Another process: its counts began at its start, after our last reply from the old one.
    const bool restarted = pid != pid_;
    for (const auto& [id, c] : now)
    {
      const auto before = last_.find(id);
      const bool known = !restarted && before != last_.end();
      // Unsigned 32-bit differences: right across the wrap of roscpp's byte count.
      const uint32_t dm = known ? uint32_t(c.messages - before->second.messages) : c.messages;
      const uint32_t db = known ? uint32_t(c.bytes - before->second.bytes) : c.bytes;
      if (dm > 0)
        grew.push_back(id);
      messages += dm;
      bytes += db;
    }
  }
  if (messages > 0)
  {
    const double last_arrival = t - (t - last_reply_t_) / double(messages + 1);
    counted_.push_back({t, last_arrival, messages, bytes});
    ever_received_ = true;
    last_arrival_ = last_arrival;
  }
  last_ = std::move(now);
  pid_ = pid;
  have_baseline_ = true;
  last_reply_t_ = std::max(last_reply_t_, t);
  return grew;
}

RateStats BusStatsRate::stats(double now)
{
  while (!counted_.empty() && counted_.front().t < now - window_s_)
    counted_.pop_front();
  RateStats s;
  s.window_s = window_s_;
  // Known (or, once a reply is overdue, assumed) to have received nothing up to here.
  const double silent_until = have_baseline_ ? std::max(last_reply_t_, now - grace_s_) : now;
  s.last_message_age_s = ever_received_ ? std::max(0.0, silent_until - last_arrival_)
                                        : std::numeric_limits<double>::infinity();
  if (counted_.empty())
    return s;
  uint64_t messages = 0, bytes = 0;
  for (const auto& r : counted_)
  {
    messages += r.messages;
    bytes += r.bytes;
  }
  s.window_messages = std::size_t(messages);
  s.bytes_per_second = double(bytes) / window_s_;
  if (counted_.size() == 1)
  {
    // No interval between two estimated arrivals yet: what the window holds.
    s.rate_hz = double(messages) / window_s_;
    return s;
  }
  IntervalStats intervals;
  for (std::size_t i = 1; i < counted_.size(); ++i)
    intervals.add(counted_[i].last_arrival - counted_[i - 1].last_arrival, counted_[i].messages);
  intervals.fill(s, silent_until - counted_.back().last_arrival);
  return s;
}

}  // namespace anyscale_agent
