// ICMP echo to one IPv4 host with the kernel's receive timestamps.
#include "anyscale_agent_cpp/icmp_echo.h"

#include <arpa/inet.h>
#include <netdb.h>
#include <netinet/ip.h>
#include <netinet/ip_icmp.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <ctime>
#include <limits>
#include <stdexcept>

namespace anyscale_agent
{
namespace
{
double realtimeNow()
{
  timespec ts{};
  clock_gettime(CLOCK_REALTIME, &ts);
  return double(ts.tv_sec) + 1e-9 * double(ts.tv_nsec);
}

uint16_t checksum(const uint8_t* data, std::size_t n)
{
  uint32_t sum = 0;
  for (std::size_t i = 0; i + 1 < n; i += 2)
    sum += uint32_t(data[i]) << 8 | data[i + 1];
  if (n % 2)
    sum += uint32_t(data[n - 1]) << 8;
  while (sum >> 16)
    sum = (sum & 0xffff) + (sum >> 16);
  return htons(uint16_t(~sum));
}

uint32_t resolve(const std::string& host, std::string* address)
{
  addrinfo hints{};
  hints.ai_family = AF_INET;
  addrinfo* found = nullptr;
  const int err = getaddrinfo(host.c_str(), nullptr, &hints, &found);
  if (err != 0 || found == nullptr)
    throw std::runtime_error("cannot resolve '" + host +
                             "' to an IPv4 address: " + gai_strerror(err));
  const uint32_t peer = reinterpret_cast<sockaddr_in*>(found->ai_addr)->sin_addr.s_addr;
  freeaddrinfo(found);
  char text[INET_ADDRSTRLEN] = {};
  inet_ntop(AF_INET, &peer, text, sizeof(text));
  *address = text;
  return peer;
}
}  // namespace

IcmpEcho::IcmpEcho(const std::string& host) : buffer_(70000)
{
  peer_ = resolve(host, &address_);
  fd_ = UniqueFd(::socket(AF_INET, SOCK_DGRAM | SOCK_NONBLOCK | SOCK_CLOEXEC, IPPROTO_ICMP));
  if (fd_.get() < 0)
  {
    const int dgram_errno = errno;
    fd_ = UniqueFd(::socket(AF_INET, SOCK_RAW | SOCK_NONBLOCK | SOCK_CLOEXEC, IPPROTO_ICMP));
    if (fd_.get() < 0)
      throw std::runtime_error(std::string("no ICMP socket: a ping socket is refused (") +
                               std::strerror(dgram_errno) +
                               "; see net.ipv4.ping_group_range) and a raw one too (" +
                               std::strerror(errno) + "; needs root or CAP_NET_RAW)");
    raw_ = true;
  }
  // A raw socket sees every echo reply to this host: our id tells ours apart. A ping socket's
  // kernel sets the id to the socket's own and delivers only its replies.
  id_ = uint16_t(::getpid() & 0xffff);
  const int on = 1;
  if (setsockopt(fd_.get(), SOL_SOCKET, SO_TIMESTAMPNS, &on, sizeof(on)) != 0)
    throw std::runtime_error(std::string("SO_TIMESTAMPNS: ") + std::strerror(errno));
}

double IcmpEcho::send(uint16_t seq, std::size_t payload_bytes)
{
  std::vector<uint8_t> packet(sizeof(icmphdr) + std::min(payload_bytes, kMaxPayload), 0);
  icmphdr header{};
  header.type = ICMP_ECHO;
  header.un.echo.id = htons(id_);
  header.un.echo.sequence = htons(seq);
  std::memcpy(packet.data(), &header, sizeof(header));
  header.checksum = checksum(packet.data(), packet.size());
  std::memcpy(packet.data(), &header, sizeof(header));
  sockaddr_in to{};
  to.sin_family = AF_INET;
  to.sin_addr.s_addr = peer_;
  const double t = realtimeNow();
  if (::sendto(fd_.get(), packet.data(), packet.size(), 0, reinterpret_cast<sockaddr*>(&to),
               sizeof(to)) < 0)
    throw std::runtime_error("ICMP echo to " + address_ + ": " + std::strerror(errno));
  return t;
}

std::vector<std::pair<uint16_t, double>> IcmpEcho::receive()
{
  std::vector<std::pair<uint16_t, double>> replies;
  for (;;)
  {
    char control[CMSG_SPACE(sizeof(timespec))] = {};
    iovec iov{buffer_.data(), buffer_.size()};
    sockaddr_in from{};
    msghdr msg{};
    msg.msg_name = &from;
    msg.msg_namelen = sizeof(from);
    msg.msg_iov = &iov;
    msg.msg_iovlen = 1;
    msg.msg_control = control;
    msg.msg_controllen = sizeof(control);
    const ssize_t n = ::recvmsg(fd_.get(), &msg, 0);
    if (n < 0)
      break;  // EAGAIN: nothing more; any other error: nothing usable now
    std::size_t offset = 0;
    if (raw_)  // a raw socket hands over the IP header too
      offset = n > 0 ? std::size_t(buffer_[0] & 0x0f) * 4 : 0;
    if (from.sin_addr.s_addr != peer_ || std::size_t(n) < offset + sizeof(icmphdr))
      continue;
    icmphdr header{};
    std::memcpy(&header, buffer_.data() + offset, sizeof(header));
    if (header.type != ICMP_ECHOREPLY || (raw_ && ntohs(header.un.echo.id) != id_))
      continue;
    double t = realtimeNow();
    for (cmsghdr* c = CMSG_FIRSTHDR(&msg); c != nullptr; c = CMSG_NXTHDR(&msg, c))
      if (c->cmsg_level == SOL_SOCKET && c->cmsg_type == SCM_TIMESTAMPNS)
      {
        timespec ts{};
        std::memcpy(&ts, CMSG_DATA(c), sizeof(ts));
        t = double(ts.tv_sec) + 1e-9 * double(ts.tv_nsec);
      }
    replies.emplace_back(ntohs(header.un.echo.sequence), t);
  }
  return replies;
}

}  // namespace anyscale_agent

namespace anyscale_agent
{
namespace
{
// The kernel receive time of reply `seq`, or NaN when none came within `timeout_s`.
double awaitReply(IcmpEcho& echo, uint16_t seq, double sent, double timeout_s)
{
  for (;;)
  {
    const double left = sent + timeout_s - realtimeNow();
    if (left <= 0.0)
      return std::numeric_limits<double>::quiet_NaN();
    pollfd p{echo.fd(), POLLIN, 0};
    ::poll(&p, 1, std::max(1, int(left * 1000.0)));
    for (const auto& [s, t] : echo.receive())
      if (s == seq)
        return t;
  }
}
}  // namespace

std::size_t echoBulkBytes(double estimate_mbps, std::size_t max_bytes)
{
  constexpr std::size_t kMin = 4096;
  const std::size_t most = std::max(kMin, std::min(max_bytes, IcmpEcho::kMaxPayload));
  if (!std::isfinite(estimate_mbps) || estimate_mbps <= 0.0)
    return kMin;
  const double bytes = estimate_mbps * 1e6 / 8.0 * 0.020;
  return std::clamp(std::size_t(bytes), kMin, most);
}

void RttFloor::add(double rtt_s)
{
  if (std::isnan(rtt_s))
    return;
  rtts_.push_back(rtt_s);
  while (rtts_.size() > window_)
    rtts_.pop_front();
}

double RttFloor::least() const
{
  if (rtts_.empty())
    return std::numeric_limits<double>::quiet_NaN();
  return *std::min_element(rtts_.begin(), rtts_.end());
}

double echoBandwidthMbps(std::size_t bytes, double bulk_rtt_s, double floor_rtt_s)
{
  return 2.0 * 8.0 * double(bytes) / std::max(bulk_rtt_s - floor_rtt_s, 50e-6) / 1e6;
}

double measureEchoBandwidth(IcmpEcho& echo, std::size_t bulk_bytes, double timeout_s,
                            double bulk_timeout_s, uint16_t* seq, RttFloor& floor)
{
  const uint16_t small_seq = ++*seq;
  const double small_sent = echo.send(small_seq, 56);
  const double small_rtt = awaitReply(echo, small_seq, small_sent, timeout_s) - small_sent;
  if (std::isnan(small_rtt))
    return small_rtt;
  floor.add(small_rtt);
  const std::size_t bytes = std::min(bulk_bytes, IcmpEcho::kMaxPayload);
  const uint16_t bulk_seq = ++*seq;
  const double bulk_sent = echo.send(bulk_seq, bytes);
  double bulk_rtt = awaitReply(echo, bulk_seq, bulk_sent, bulk_timeout_s) - bulk_sent;
  // Unanswered while the small one was: the link did not carry it within the timeout, or dropped
  // one of its fragments from a full queue. Either way it carries less than this bound, which is
  // what the reading says (a 3 Mbit/s link full of camera images answered no bulk echo at all,
  // and the estimate had stayed at the 26 Mbit/s of before).
  if (std::isnan(bulk_rtt))
    bulk_rtt = bulk_timeout_s;
  return echoBandwidthMbps(bytes, bulk_rtt, floor.least());
}

}  // namespace anyscale_agent
