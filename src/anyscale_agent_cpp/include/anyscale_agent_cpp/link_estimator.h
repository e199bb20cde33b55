// Link state to the master scale from probe round trips: up/down, RTT, loss, bandwidth (no ROS).
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <deque>
#include <map>

namespace anyscale_agent
{

struct LinkSample
{
  bool up = false;
  double rtt_s;       // NaN until a probe was answered
  double rtt_mean_s;  // NaN until a probe was answered
  double loss_ratio = 0.0;
  double bandwidth_mbps;  // NaN until a bulk probe was answered
  double last_answer_t;   // NaN if never answered
  LinkSample();
};

// Small probes give RTT and loss; a bulk probe of B bytes, whose echo is small, takes about
// RTT + B / bandwidth, so bandwidth ~ 8 B / (RTT_bulk - RTT_floor), RTT_floor being the least
// RTT of the recent small probes. A link that is lost forgets its bandwidth: until the next
// bulk probe answers, it is unknown (NaN). This is a packet-train estimate on the same TCP
// connection the data uses, not a saturation test.
//
// Each measured bulk probe follows a warm-up probe of the same size, sent when the warm-up's echo
// comes back. Linux restarts TCP's slow start on a connection idle for longer than its RTO
// (tcp_slow_start_after_idle, RFC 2861), and small probes every 0.5 s leave it idle that long:
// a lone 64 KB probe then crossed a 27 Mbit/s link in three round trips and read 6-7 Mbit/s for
// a whole run, which kept AR on the robot. The warm-up opens the window; its reading is not used.
// It costs 2 B per bulk period.
//
// A higher reading is blended in with `bandwidth_smoothing` (the weight of the new value); a
// lower one is confirmed first: the next bulk probe goes out at once (confirmationWanted) and the
// estimate falls to the higher of the two readings (or to the first, if the second is lost).
// Since when a link subscription has carried nothing: its last message (`heard`), or its making
// (`subscribed_at`) if that is later or nothing came yet (`heard` NaN). A subscription that never
// connected is as dead as one whose connection died: roscpp does not retry a publisher it could
// not reach (a robot agent that came up with the link down left the laptop agent's echo
// subscription empty for a whole run, and the laptop out of reach on a good link).
double silentSince(double heard, double subscribed_at);

enum class ProbeKind
{
  kSmall,   // RTT and loss
  kWarmUp,  // bulk, opens TCP's window; not measured
  kBulk,    // bulk, measured
};

class LinkEstimator
{
public:
  // A probe unanswered after `timeout_s` counts as lost; loss and mean RTT are over the last
  // `history` small probes; the link is down when nothing was answered for `timeout_s`.
  explicit LinkEstimator(double timeout_s = 1.0, std::size_t history = 20,
                         double bandwidth_smoothing = 0.5);

  void sent(uint32_t seq, double t, uint32_t bytes, ProbeKind kind);
  // What was answered: unknown or already expired seqs are ignored (kSmall is returned).
  ProbeKind answered(uint32_t seq, double t);
  // A bandwidth reading from elsewhere (an ICMP echo); NaN is ignored.
  void addBandwidthReading(double mbps);
  double bandwidthMbps() const { return bandwidth_mbps_; }  // NaN until measured
  LinkSample stats(double now);
  bool outstanding() const { return !pending_.empty(); }
  // A lower bandwidth reading awaits a second bulk probe before the estimate follows it.
  bool confirmationWanted() const { return !std::isnan(unconfirmed_drop_); }

private:
  void expire(double now);
  void record(double rtt);  // small-probe result; NaN = lost

  struct Pending
  {
    double t;
    uint32_t bytes;
    ProbeKind kind;
  };
  double timeout_s_;
  std::size_t history_;
  double smoothing_;
  std::map<uint32_t, Pending> pending_;
  std::deque<double> results_;  // RTTs of small probes, NaN for lost ones
  double last_rtt_;
  double last_answer_t_;
  double bandwidth_mbps_;
  double unconfirmed_drop_;  // a lower reading not yet confirmed; NaN if none
};

}  // namespace anyscale_agent
