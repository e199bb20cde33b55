// ICMP echo to one IPv4 host with the kernel's receive timestamps (no ROS).
#pragma once

#include <cstddef>
#include <cstdint>
#include <deque>
#include <string>
#include <utility>
#include <vector>

#include "anyscale_agent_cpp/unique_fd.h"

namespace anyscale_agent
{

// Why ICMP for the bandwidth: the peer's kernel answers an echo request in softirq context, where
// neither the peer's CPU quota nor its busy processes can delay the answer, and SO_TIMESTAMPNS
// dates the reply when it arrived, not when this process got to read it. A probe echoed by the
// master's agent over ROS waited for that agent to be scheduled: on a robot held at its quota by
// its own nodes (throttled in 272 of 281 CFS periods, measured), 64 KB read 5 Mbit/s on a
// 27 Mbit/s link for whole runs. Nothing in ROS or Debian's libraries offers a timestamped echo
// (liboping and fping time in user space), hence this small class.
class IcmpEcho
{
public:
  // Resolves `host` (IPv4) and opens a ping socket: SOCK_DGRAM where net.ipv4.ping_group_range
  // admits this process's group, else SOCK_RAW (root or CAP_NET_RAW). Throws std::runtime_error
  // saying which and why when neither opens.
  explicit IcmpEcho(const std::string& host);

  // Sends echo request `seq` with `payload_bytes` of payload (at most kMaxPayload); returns the
  // send time [s, CLOCK_REALTIME, the clock of the receive timestamps]. Throws on a send error.
  double send(uint16_t seq, std::size_t payload_bytes);

  // Echo replies to this object's requests that have arrived, without blocking:
  // (seq, kernel receive time [s, CLOCK_REALTIME]).
  std::vector<std::pair<uint16_t, double>> receive();

  int fd() const { return fd_.get(); }
  const std::string& address() const { return address_; }
  bool raw() const { return raw_; }

  static constexpr std::size_t kMaxPayload = 65000;  // an IPv4 datagram holds 65507

private:
  UniqueFd fd_;
  std::string address_;
  uint32_t peer_ = 0;  // network byte order
  uint16_t id_ = 0;
  bool raw_ = false;
  std::vector<uint8_t> buffer_;
};

}  // namespace anyscale_agent

namespace anyscale_agent
{

// The size of the next bulk echo: about 20 ms of the link at `estimate_mbps`, between 4 KiB and
// `max_bytes` (4 KiB while nothing is measured). A shaper's queue holds some tens of ms (tc tbf
// `latency 50ms` on the test bed): a 32 KiB burst of fragments overflowed it below ~4.7 Mbit/s,
// one fragment lost the whole echo, and the tail drops hit the nodes' own traffic on that link.
std::size_t echoBulkBytes(double estimate_mbps, std::size_t max_bytes);

// The path's floor: the least small-echo RTT of the last `window` readings. A bulk echo's
// bandwidth is measured against it, not against the small echo sent just before: a link that the
// nodes' own streams fill has a queue that TCP fills and drains, and a small echo that met it
// full followed by a bulk one that met it drained read 9-12 Mbit/s on a 6 Mbit/s link carrying
// AR's camera stream (test bed, count_by_bus_stats), so AR stayed on a link it overfilled.
// Against the floor the bulk echo's queueing counts: the reading is what the streams leave.
class RttFloor
{
public:
  explicit RttFloor(std::size_t window = 10) : window_(window) {}
  void add(double rtt_s);  // NaN is ignored
  double least() const;    // NaN until a reading came
private:
  std::size_t window_;
  std::deque<double> rtts_;
};

// 2 * 8 B / (RTT_bulk - floor) [Mbit/s]: the reply is as large as the request, so the reading is
// the harmonic mean of the two directions (50 us least difference: on loopback it is timer noise).
double echoBandwidthMbps(std::size_t bytes, double bulk_rtt_s, double floor_rtt_s);

// One bandwidth reading [Mbit/s] from a small echo (awaited for at most `timeout_s`, its RTT
// added to `floor`) and then one of `bulk_bytes` (at most `bulk_timeout_s`), measured against the
// floor; NaN if the small one went unanswered. A bulk echo unanswered in time reads as if it had
// taken `bulk_timeout_s`. Blocks for up to timeout_s + bulk_timeout_s.
double measureEchoBandwidth(IcmpEcho& echo, std::size_t bulk_bytes, double timeout_s,
                            double bulk_timeout_s, uint16_t* seq, RttFloor& floor);

}  // namespace anyscale_agent
