// RTT, loss and bandwidth estimation from probe send/answer times.
#include "anyscale_agent_cpp/link_estimator.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace anyscale_agent
{
namespace
{
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
}

double silentSince(double heard, double subscribed_at)
{
  return std::isnan(heard) ? subscribed_at : std::max(heard, subscribed_at);
}

LinkSample::LinkSample() : rtt_s(kNaN), rtt_mean_s(kNaN), bandwidth_mbps(kNaN), last_answer_t(kNaN)
{}

LinkEstimator::LinkEstimator(double timeout_s, std::size_t history, double bandwidth_smoothing)
  : timeout_s_(timeout_s),
    history_(std::max<std::size_t>(history, 1)),
    smoothing_(std::clamp(bandwidth_smoothing, 0.0, 1.0)),
    last_rtt_(kNaN),
    last_answer_t_(kNaN),
    bandwidth_mbps_(kNaN),
    unconfirmed_drop_(kNaN)
{}

void LinkEstimator::sent(uint32_t seq, double t, uint32_t bytes, ProbeKind kind)
{
  pending_[seq] = Pending{t, bytes, kind};
}

void LinkEstimator::record(double rtt)
{
  results_.push_back(rtt);
  while (results_.size() > history_)
    results_.pop_front();
}

ProbeKind LinkEstimator::answered(uint32_t seq, double t)
{
  const auto it = pending_.find(seq);
  if (it == pending_.end())
    return ProbeKind::kSmall;
  const Pending p = it->second;
  pending_.erase(it);
  const double rtt = std::max(0.0, t - p.t);
  last_answer_t_ = t;
  if (p.kind == ProbeKind::kSmall)
  {
    last_rtt_ = rtt;
    record(rtt);
    return p.kind;
  }
  if (p.kind == ProbeKind::kWarmUp)
    return p.kind;
  // The link's floor (the least recent RTT), not the mean: the echo runs on a busy robot, and
  // a mean that holds its scheduling delays can exceed the delay this probe met, which read a
  // 27 Mbit/s link as 36. With the floor, such delays count as transfer time: the estimate
  // errs low, the safe side for deciding whether a stream fits.
  double small = std::numeric_limits<double>::infinity();
  for (double r : results_)
    if (!std::isnan(r))
      small = std::min(small, r);
  if (std::isinf(small))
    small = 0.0;
  // 50 us floor: on loopback the difference is within timer noise and would divide by ~0.
  const double transfer = std::max(rtt - small, 50e-6);
  addBandwidthReading(8.0 * double(p.bytes) / transfer / 1e6);
  return p.kind;
}

void LinkEstimator::addBandwidthReading(double mbps)
{
  if (std::isnan(mbps))
    return;
  if (std::isnan(bandwidth_mbps_))
  {
    bandwidth_mbps_ = mbps;
  }
  else if (mbps >= bandwidth_mbps_)
  {
    bandwidth_mbps_ = smoothing_ * mbps + (1.0 - smoothing_) * bandwidth_mbps_;
    unconfirmed_drop_ = kNaN;
  }
  else if (std::isnan(unconfirmed_drop_))
  {
    // A drop waits for one confirming probe, sent at once (confirmationWanted). Delays at the
    // echo only ever lower a reading, and an echo on a robot held at its CPU quota waits out
    // the throttled part of a CFS period now and then. Two such delays in a row are rarer, and a
    // real drop shows in both readings: it is believed one probe period (0.5 s) later.
    unconfirmed_drop_ = mbps;
  }
  else
  {
    bandwidth_mbps_ = std::max(mbps, unconfirmed_drop_);
    unconfirmed_drop_ = kNaN;
  }
}

void LinkEstimator::expire(double now)
{
  for (auto it = pending_.begin(); it != pending_.end();)
  {
    if (now - it->second.t > timeout_s_)
    {
      if (it->second.kind == ProbeKind::kSmall)
        record(kNaN);
      else if (!std::isnan(unconfirmed_drop_))
      {
        // The confirming probe was lost: the link is worse than the drop said, not better.
        bandwidth_mbps_ = unconfirmed_drop_;
        unconfirmed_drop_ = kNaN;
      }
      it = pending_.erase(it);
    }
    else
    {
      ++it;
    }
  }
}

LinkSample LinkEstimator::stats(double now)
{
  expire(now);
  LinkSample s;
  s.rtt_s = last_rtt_;
  s.last_answer_t = last_answer_t_;
  s.up = !std::isnan(last_answer_t_) && now - last_answer_t_ <= timeout_s_;
  // A link that was lost has shown nothing since: the estimate from before the loss (another
  // place, another access point) must not stand for it until the next bulk probe answers.
  if (!s.up)
    bandwidth_mbps_ = unconfirmed_drop_ = kNaN;
  s.bandwidth_mbps = bandwidth_mbps_;
  double sum = 0.0;
  std::size_t answered = 0;
  for (double r : results_)
    if (!std::isnan(r))
    {
      sum += r;
      ++answered;
    }
  if (answered)
    s.rtt_mean_s = sum / double(answered);
  if (!results_.empty())
    s.loss_ratio = double(results_.size() - answered) / double(results_.size());
  return s;
}

}  // namespace anyscale_agent
