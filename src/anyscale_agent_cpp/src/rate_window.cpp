// Sliding-window rate, interval and throughput maths of one topic.
#include "anyscale_agent_cpp/rate_window.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace anyscale_agent
{

RateWindow::RateWindow(double window_s, std::size_t max_messages)
  : window_s_(window_s > 0.0 ? window_s : 2.0), max_messages_(std::max<std::size_t>(max_messages, 2))
{
}

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
  s.last_message_age_s = ever_received_ ? std::max(0.0, now - last_t_) : std::numeric_limits<double>::infinity();
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
  double sum = 0.0, sum_sq = 0.0;
  s.interval_min_s = std::numeric_limits<double>::infinity();
  s.interval_max_s = 0.0;
  for (std::size_t i = 1; i < arrivals_.size(); ++i)
  {
    const double d = arrivals_[i].t - arrivals_[i - 1].t;
    sum += d;
    sum_sq += d * d;
    s.interval_min_s = std::min(s.interval_min_s, d);
    s.interval_max_s = std::max(s.interval_max_s, d);
  }
  const double mean = sum / double(n);
  s.interval_std_s = std::sqrt(std::max(0.0, sum_sq / double(n) - mean * mean));
  // Only the part of the silence beyond the longest interval counts, so sampling just before a
  // message that is on time changes nothing, while a stopped topic decays continuously.
  const double excess = std::max(0.0, now - arrivals_.back().t - s.interval_max_s);
  s.rate_hz = sum + excess > 0.0 ? double(n) / (sum + excess) : 0.0;
  return s;
}

}  // namespace anyscale_agent
