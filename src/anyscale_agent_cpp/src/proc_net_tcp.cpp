// /proc/net/tcp{,6} parsing and a process's socket descriptors, shared by the master-call
// watchdog (stuck connections) and the bus-statistics poller (listening sockets).
#include "anyscale_agent_cpp/proc_net_tcp.h"

#include <dirent.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <memory>
#include <sstream>

namespace anyscale_agent
{
namespace
{

std::string ipv4(uint32_t host_order_word)
{
  // /proc prints the address as the in-memory 32-bit word, i.e. network order read as a
  // little-endian number: its lowest byte is the first octet.
  char buf[16];
  std::snprintf(buf, sizeof buf, "%u.%u.%u.%u", host_order_word & 0xff,
                (host_order_word >> 8) & 0xff, (host_order_word >> 16) & 0xff,
                (host_order_word >> 24) & 0xff);
  return buf;
}

std::string ipv6(const std::string& hex)
{
  uint32_t w[4];
  for (int i = 0; i < 4; ++i)
    w[i] = uint32_t(std::stoul(hex.substr(std::size_t(i) * 8, 8), nullptr, 16));
  if (w[0] == 0 && w[1] == 0 && w[2] == 0 && w[3] == 0)
    return "::";
  if (w[0] == 0 && w[1] == 0 && w[2] == 0 && w[3] == 0x01000000)
    return "::1";
  if (w[0] == 0 && w[1] == 0 && w[2] == 0xffff0000)
    return ipv4(w[3]);
  return "";
}

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
  return ipv4(addr) + ":" + std::to_string(port);
}

std::vector<TcpEntry> parseProcNetTcp(const std::string& text, bool v6)
{
  std::vector<TcpEntry> out;
  std::istringstream in(text);
  std::string line;
  while (std::getline(in, line))
  {
    // "  0: 0100007F:2B67 00000000:0000 0A 00000000:00000000 00:00000000 00000000  1000 0 ..."
    std::istringstream fields(line);
    std::string slot, local, remote, state, queues, timer, retr, uid, timeout, inode;
    if (!(fields >> slot >> local >> remote >> state >> queues >> timer >> retr >> uid >> timeout >>
          inode))
      continue;
    const auto colon = local.find(':');
    if (slot.empty() || slot.back() != ':' || colon != (v6 ? 32u : 8u))
      continue;
    try
    {
      TcpEntry e;
      e.local = v6 ? ipv6(local.substr(0, colon))
                   : ipv4(uint32_t(std::stoul(local.substr(0, colon), nullptr, 16)));
      e.local_port = int(std::stoul(local.substr(colon + 1), nullptr, 16));
      if (!v6)
        e.remote = remoteFromHex(remote);
      e.state = int(std::stoul(state, nullptr, 16));
      e.tx_queue = std::stoull(queues.substr(0, queues.find(':')), nullptr, 16);
      e.inode = std::stoull(inode);
      out.push_back(e);
    }
    catch (const std::exception&)
    {
      // A malformed line: skipped like the header.
    }
  }
  return out;
}

std::map<uint64_t, int> socketFds(const std::string& fd_dir)
{
  std::map<uint64_t, int> out;
  const std::unique_ptr<DIR, CloseDir> dir(opendir(fd_dir.c_str()));
  if (!dir)
    return out;
  while (const dirent* d = readdir(dir.get()))
  {
    char target[64];
    const ssize_t n = readlink((fd_dir + "/" + d->d_name).c_str(), target, sizeof target - 1);
    if (n <= 0)
      continue;
    target[n] = '\0';
    unsigned long long inode = 0;
    if (std::sscanf(target, "socket:[%llu]", &inode) == 1)
      out[inode] = std::atoi(d->d_name);
  }
  return out;
}

}  // namespace anyscale_agent
