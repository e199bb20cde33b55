// The TCP ports a process group listens on, from /proc: where a node's XML-RPC server may be
// (no ROS).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace anyscale_agent
{

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
std::vector<ListeningSocket> listeningSockets(const std::vector<int>& pids,
                                              const std::string& proc_root = "/proc");

// The pids of the processes in process group `pgid` (a node started through a wrapper script
// registers from a child).
std::vector<int> processGroupMembers(int pgid, const std::string& proc_root = "/proc");

}  // namespace anyscale_agent
