// Link state to the master scale from probe round trips: up/down, RTT, loss, bandwidth (no ROS).
#pragma once

#include <cstddef>
#include <cstdint>
#include <deque>
#include <map>

namespace anyscale_agent
{

struct LinkSample
{
  bool up = false;
  double rtt_s;        // NaN until a probe was answered
  double rtt_mean_s;   // NaN until a probe was answered
  double loss_ratio = 0.0;
  double bandwidth_mbps;  // NaN until a bulk probe was answered
  double last_answer_t;   // NaN if never answered
  LinkSample();
};

// Small probes give RTT and loss; a bulk probe of B bytes, whose echo is small, takes about
// RTT + B / bandwidth, so bandwidth ~ 8 B / (RTT_bulk - RTT_floor), RTT_floor being the least
// RTT of the recent small probes. A link that is lost forgets its bandwidth: until the next
// bulk probe answers, it is unknown (NaN). This is a packet-train
// estimate on the same TCP connection the data uses, not a saturation test: it costs B bytes
// per bulk period, and it reads low while TCP's window is still opening (slow start after idle).
// A lower estimate replaces the current one at once; a higher one is blended in with
// `bandwidth_smoothing` (the weight of the new value).
class LinkEstimator
{
public:
  // A probe unanswered after `timeout_s` counts as lost; loss and mean RTT are over the last
  // `history` small probes; the link is down when nothing was answered for `timeout_s`.
  explicit LinkEstimator(double timeout_s = 1.0, std::size_t history = 20, double bandwidth_smoothing = 0.5);

  void sent(uint32_t seq, double t, uint32_t bytes, bool bulk);
  void answered(uint32_t seq, double t);  // unknown or already expired seqs are ignored
  LinkSample stats(double now);
  bool outstanding() const { return !pending_.empty(); }

private:
  void expire(double now);
  void record(double rtt);  // small-probe result; NaN = lost

  struct Pending
  {
    double t;
    uint32_t bytes;
    bool bulk;
  };
  double timeout_s_;
  std::size_t history_;
  double smoothing_;
  std::map<uint32_t, Pending> pending_;
  std::deque<double> results_;  // RTTs of small probes, NaN for lost ones
  double last_rtt_;
  double last_answer_t_;
  double bandwidth_mbps_;
};

}  // namespace anyscale_agent
