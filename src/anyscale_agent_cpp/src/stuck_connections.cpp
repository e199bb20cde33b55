// Connections to one address open too long: tracking and breaking them.
#include "anyscale_agent_cpp/stuck_connections.h"

#include <sys/socket.h>
#include <sys/stat.h>

namespace anyscale_agent
{

std::vector<uint64_t> StuckConnections::update(const std::vector<TcpEntry>& entries, double now)
{
  std::map<uint64_t, double> seen;
  std::vector<uint64_t> stuck;
  for (const auto& e : entries)
  {
    const bool waiting = e.state == kTcpSynSent || (e.state == kTcpEstablished && e.tx_queue > 0);
    if (e.remote != remote_ || !waiting || e.inode == 0)
      continue;
    const auto it = first_seen_.find(e.inode);
    const double since = it == first_seen_.end() ? now : it->second;
    seen[e.inode] = since;
    if (now - since >= after_s_)
      stuck.push_back(e.inode);
  }
  first_seen_ = std::move(seen);
  return stuck;
}

int socketFdOfInode(uint64_t inode, const std::string& fd_dir)
{
  const auto fds = socketFds(fd_dir);
  const auto it = fds.find(inode);
  return it == fds.end() ? -1 : it->second;
}

bool breakConnection(int fd, uint64_t inode)
{
  struct stat st
  {};
  if (fd < 0 || fstat(fd, &st) != 0 || !S_ISSOCK(st.st_mode) || uint64_t(st.st_ino) != inode)
    return false;
  // connect() with AF_UNSPEC dissolves a TCP association in any state, a SYN still unanswered
  // included (shutdown() does not end a connect in progress); the owner's next poll sees the error.
  sockaddr unspec{};
  unspec.sa_family = AF_UNSPEC;
  return ::connect(fd, &unspec, sizeof(unspec)) == 0;
}

}  // namespace anyscale_agent
