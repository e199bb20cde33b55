// The TCP ports a process group listens on, from /proc: where a node's XML-RPC server may be (no ROS).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace anyscale_agent
{

// The local side of one line of /proc/net/tcp or tcp6 (stuck_connections.h reads the remote side).
struct LocalTcpEntry
{
  std::string address;  // dotted IPv4 ("0.0.0.0"); IPv6 as "::", "::1" or an IPv4-mapped one as IPv4
  int port = 0;
  int state = 0;        // 0x0A: listening, 0x01: established
  uint64_t inode = 0;
};
// Lines it cannot read are skipped (the header among them). IPv6 addresses other than the
// unspecified, loopback and IPv4-mapped ones are given as "" (not reachable as written here).
std::vector<LocalTcpEntry> parseLocalTcpEntries(const std::string& text, bool ipv6);

struct ListeningSocket
{
  std::string host;  // where to connect: 127.0.0.1 for a socket bound to every address
  int port = 0;
  uint64_t inode = 0;
  // The process holds an established connection on this port: a subscriber's (rosout's,
  // at least) on a TCPROS server. A node's XML-RPC server has none between calls.
  bool accepted = false;
};

// The listening TCP sockets held by the processes `pids` (their /proc/PID/fd), those without
// accepted connections first, then by inode (creation order). Processes that vanish are skipped.
std::vector<ListeningSocket> listeningSockets(const std::vector<int>& pids, const std::string& proc_root = "/proc");

// The pids of the processes in process group `pgid` (a node started through a wrapper script
// registers from a child).
std::vector<int> processGroupMembers(int pgid, const std::string& proc_root = "/proc");

}  // namespace anyscale_agent
