// Sliding-window rate, interval and throughput maths of one topic.
#include "anyscale_agent_cpp/rate_window.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace anyscale_agent
{

void IntervalStats::add(double span, uint64_t messages)
{
  if (messages == 0)
    return;
  const double mean = span / double(messages);
  sum_ += span;
  sum_sq_ += mean * mean * double(messages);
  n_ += messages;
  min_ = std::min(min_, mean);
  max_ = std::max(max_, mean);
}

void IntervalStats::fill(RateStats& s, double silence_s) const
{
  if (n_ == 0)
    return;
  const double mean = sum_ / double(n_);
  s.interval_min_s = min_;
  s.interval_max_s = max_;
  s.interval_std_s = std::sqrt(std::max(0.0, sum_sq_ / double(n_) - mean * mean));
  const double excess = std::max(0.0, silence_s - max_);
  s.rate_hz = sum_ + excess > 0.0 ? double(n_) / (sum_ + excess) : 0.0;
}

RateWindow::RateWindow(double window_s, std::size_t max_messages)
  : window_s_(window_s > 0.0 ? window_s : 2.0),
    max_messages_(std::max<std::size_t>(max_messages, 2))
{}

void RateWindow::add(double t, uint32_t bytes)
{
  arrivals_.push_back({t, bytes});
  if (arrivals_.size() > max_messages_)
    arrivals_.pop_front();
  ever_received_ = true;
  last_t_ = t;
}

void RateWindow::prune(double now)
{
  while (!arrivals_.empty() && arrivals_.front().t < now - window_s_)
    arrivals_.pop_front();
}

RateStats RateWindow::stats(double now)
{
  prune(now);
  RateStats s;
  s.window_s = window_s_;
  s.window_messages = arrivals_.size();
  s.last_message_age_s =
      ever_received_ ? std::max(0.0, now - last_t_) : std::numeric_limits<double>::infinity();
  if (arrivals_.empty())
    return s;

  uint64_t bytes = 0;
  for (const auto& a : arrivals_)
    bytes += a.bytes;
  // Throughput over the whole window, not just the span of the messages: a single large message
  // in a 2 s window is 1/2 of its size per second.
  s.bytes_per_second = double(bytes) / window_s_;

  const std::size_t n = arrivals_.size() - 1;  // closed intervals
  if (n == 0)
  {
    // One message: no interval yet, the only honest rate is "one in the window".
    s.rate_hz = 1.0 / window_s_;
    return s;
  }
  IntervalStats intervals;
  for (std::size_t i = 1; i < arrivals_.size(); ++i)
    intervals.add(arrivals_[i].t - arrivals_[i - 1].t, 1);
  intervals.fill(s, now - arrivals_.back().t);
  return s;
}

}  // namespace anyscale_agent
