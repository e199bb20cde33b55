// Connections to one address open too long: /proc/net/tcp parsing, tracking, breaking.
#include "anyscale_agent_cpp/stuck_connections.h"

#include <dirent.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cstdio>
#include <memory>
#include <set>
#include <sstream>

namespace anyscale_agent
{

namespace
{
constexpr int kEstablished = 1;
constexpr int kSynSent = 2;

struct CloseDir
{
  void operator()(DIR* d) const { closedir(d); }
};
}  // namespace

std::string remoteFromHex(const std::string& hex)
{
  unsigned int addr = 0, port = 0;
  if (hex.size() != 13 || hex[8] != ':' || std::sscanf(hex.c_str(), "%8X:%4X", &addr, &port) != 2)
    return "";
  // The kernel prints the address as the 32-bit word in host order: little-endian here.
  return std::to_string(addr & 0xff) + "." + std::to_string((addr >> 8) & 0xff) + "." +
         std::to_string((addr >> 16) & 0xff) + "." + std::to_string((addr >> 24) & 0xff) + ":" + std::to_string(port);
}

std::vector<TcpEntry> parseProcNetTcp(const std::string& text)
{
  std::vector<TcpEntry> out;
  std::istringstream lines(text);
  std::string line;
  while (std::getline(lines, line))
  {
    // sl local rem st tx:rx tr:when retrnsmt uid timeout inode ...
    std::istringstream f(line);
    std::string sl, local, rem, st, queues, timer, retr, uid, timeout, inode;
    if (!(f >> sl >> local >> rem >> st >> queues >> timer >> retr >> uid >> timeout >> inode) || sl.back() != ':')
      continue;
    TcpEntry e;
    e.remote = remoteFromHex(rem);
    try
    {
      e.state = std::stoi(st, nullptr, 16);
      e.inode = std::stoull(inode);
      e.tx_queue = std::stoull(queues.substr(0, queues.find(':')), nullptr, 16);
    }
    catch (const std::exception&)
    {
      continue;
    }
    if (!e.remote.empty())
      out.push_back(e);
  }
  return out;
}

std::vector<uint64_t> StuckConnections::update(const std::vector<TcpEntry>& entries, double now)
{
  std::map<uint64_t, double> seen;
  std::vector<uint64_t> stuck;
  for (const auto& e : entries)
  {
    const bool waiting = e.state == kSynSent || (e.state == kEstablished && e.tx_queue > 0);
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
  const std::unique_ptr<DIR, CloseDir> dir(opendir(fd_dir.c_str()));
  if (!dir)
    return -1;
  const std::string wanted = "socket:[" + std::to_string(inode) + "]";
  while (const dirent* d = readdir(dir.get()))
  {
    char target[64];
    const std::string path = fd_dir + "/" + d->d_name;
    const ssize_t n = readlink(path.c_str(), target, sizeof(target) - 1);
    if (n > 0 && std::string(target, std::size_t(n)) == wanted)
      return std::atoi(d->d_name);
  }
  return -1;
}

bool breakConnection(int fd, uint64_t inode)
{
  struct stat st{};
  if (fd < 0 || fstat(fd, &st) != 0 || !S_ISSOCK(st.st_mode) || uint64_t(st.st_ino) != inode)
    return false;
  // connect() with AF_UNSPEC dissolves a TCP association in any state, a SYN still unanswered
  // included (shutdown() does not end a connect in progress); the owner's next poll sees the error.
  sockaddr unspec{};
  unspec.sa_family = AF_UNSPEC;
  return ::connect(fd, &unspec, sizeof(unspec)) == 0;
}

}  // namespace anyscale_agent
