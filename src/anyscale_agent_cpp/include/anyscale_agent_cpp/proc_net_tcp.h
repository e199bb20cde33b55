// The lines of /proc/net/tcp and tcp6, and which of a process's descriptors are sockets (no ROS).
#pragma once

#include <cstdint>
#include <map>
#include <string>
#include <vector>

namespace anyscale_agent
{

struct TcpEntry
{
  std::string local;  // "a.b.c.d"; tcp6: "::", "::1" or an IPv4-mapped one as IPv4, else ""
  int local_port = 0;
  std::string remote;  // "a.b.c.d:port" (tcp only; "" in tcp6 entries)
  int state = 0;       // the kernel's TCP state: 0x01 ESTABLISHED, 0x02 SYN_SENT, 0x0A LISTEN, ...
  uint64_t tx_queue = 0;  // bytes sent and not yet acknowledged
  uint64_t inode = 0;
};
constexpr int kTcpEstablished = 0x01;
constexpr int kTcpSynSent = 0x02;
constexpr int kTcpListen = 0x0A;

// The entries of /proc/net/tcp's text (tcp6's with `ipv6`); lines that do not parse, the header
// among them, are skipped.
std::vector<TcpEntry> parseProcNetTcp(const std::string& text, bool ipv6 = false);

// "a.b.c.d:port" from /proc/net/tcp's "0100007F:2C2F" (little-endian hex address on x86 and ARM);
// "" if it does not parse.
std::string remoteFromHex(const std::string& hex);

// Socket inode -> descriptor, for the descriptors in `fd_dir` (/proc/PID/fd) that are sockets;
// empty if the directory cannot be read (the process is gone).
std::map<uint64_t, int> socketFds(const std::string& fd_dir);

}  // namespace anyscale_agent
