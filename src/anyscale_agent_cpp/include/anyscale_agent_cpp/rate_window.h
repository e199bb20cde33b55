// Sliding-window message rate statistics of one topic, rostopic-hz style (no ROS).
#pragma once

#include <cstddef>
#include <cstdint>
#include <deque>
#include <limits>

namespace anyscale_agent
{

struct RateStats
{
  double rate_hz = 0.0;
  double interval_min_s = 0.0;
  double interval_max_s = 0.0;
  double interval_std_s = 0.0;
  double bytes_per_second = 0.0;
  double last_message_age_s = 0.0;  // +inf before the first message
  std::size_t window_messages = 0;
  double window_s = 0.0;
};

// The interval statistics and the rate of a RateStats from the intervals between arrivals, each
// given as `messages` intervals of equal length spread over `span` (one by one from RateWindow,
// a poll's worth at a time from BusStatsRate).
class IntervalStats
{
public:
  void add(double span, uint64_t messages);
  // Fills s's interval fields and rate_hz, `silence_s` after the last arrival: only the part of
  // the silence beyond the longest interval counts, so a sample just before a message that is on
  // time changes nothing, while a stopped topic decays continuously.
  void fill(RateStats& s, double silence_s) const;

private:
  double sum_ = 0.0, sum_sq_ = 0.0;
  uint64_t n_ = 0;
  double min_ = std::numeric_limits<double>::infinity(), max_ = 0.0;
};

// Arrival times in seconds on any monotonic clock; `now` passed in so tests need no clock.
class RateWindow
{
public:
  // `window_s`: how far back messages count; `max_messages` bounds memory at high rates.
  explicit RateWindow(double window_s = 2.0, std::size_t max_messages = 10000);

  void add(double t, uint32_t bytes);

  // Statistics over the messages within [now - window_s, now]. The rate is the one rostopic hz
  // gives (intervals / their sum, i.e. 1 / mean interval), which has no +-1 message
  // quantisation error. A rate computed only from past intervals would stay at its old value
  // after the publisher stops, so the part of the silence since the last message that exceeds
  // the longest interval in the window is added to the intervals' sum: the rate then decays at
  // once and reaches 0 when the window holds no message.
  RateStats stats(double now);

  double windowSeconds() const { return window_s_; }

private:
  void prune(double now);

  struct Arrival
  {
    double t;
    uint32_t bytes;
  };
  double window_s_;
  std::size_t max_messages_;
  std::deque<Arrival> arrivals_;
  bool ever_received_ = false;
  double last_t_ = 0.0;
};

}  // namespace anyscale_agent
