// This process's TCP connections to one address that have stayed open too long, and breaking
// them (no ROS): the way out of a call to the master that waits on a connection the link lost.
#pragma once

#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "anyscale_agent_cpp/proc_net_tcp.h"

namespace anyscale_agent
{

// Why: roscpp calls the master with no timeout (XmlRpcClient waits for as long as TCP does).
// Started in a flicker of the link, such a call waited up to 220 s (TCP's backoff) after the
// link was back, holding the laptop agent's graph view or subscriptions. A connection whose SYN
// or request has gone unacknowledged for seconds is such a call (idle keep-alive connections to
// the master, which roscpp keeps, have nothing unacknowledged). Breaking it makes roscpp fail or
// retry the call on a fresh connection, which goes through at once on a link that is up.

// Tracks the connections to one remote address across calls of update(), once a second or so.
class StuckConnections
{
public:
  StuckConnections(std::string remote, double stuck_after_s)
    : remote_(std::move(remote)), after_s_(stuck_after_s)
  {}
  // The connections to the remote among `entries` that wait for an acknowledgement (SYN_SENT,
  // or ESTABLISHED with bytes unacknowledged) at time `now` (s); returns the inodes of those that
  // have waited since at least stuck_after_s.
  std::vector<uint64_t> update(const std::vector<TcpEntry>& entries, double now);
  const std::string& remote() const { return remote_; }

private:
  std::string remote_;
  double after_s_;
  std::map<uint64_t, double> first_seen_;
};

// fd of this process's socket with the given inode (from /proc/self/fd), or -1.
int socketFdOfInode(uint64_t inode, const std::string& fd_dir = "/proc/self/fd");

// Ends a connection, whether established or still connecting (connect with AF_UNSPEC), if `fd`
// is still the socket `inode`. Returns whether it did.
bool breakConnection(int fd, uint64_t inode);

}  // namespace anyscale_agent
