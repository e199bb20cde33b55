// /proc/PID/fd socket inodes matched against /proc/PID/net/tcp{,6}.
#include "anyscale_agent_cpp/listening_sockets.h"

#include <dirent.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <map>
#include <set>
#include <sstream>

#include "anyscale_agent_cpp/proc_reader.h"

namespace anyscale_agent
{
namespace
{

std::string ipv4(uint32_t host_order_word)
{
  // /proc prints the address as the in-memory 32-bit word, i.e. network order read as a
  // little-endian number: its lowest byte is the first octet.
  char buf[16];
  std::snprintf(buf, sizeof buf, "%u.%u.%u.%u", host_order_word & 0xff, (host_order_word >> 8) & 0xff,
                (host_order_word >> 16) & 0xff, (host_order_word >> 24) & 0xff);
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

std::set<uint64_t> socketInodes(int pid, const std::string& proc_root)
{
  std::set<uint64_t> out;
  const std::string dir = proc_root + "/" + std::to_string(pid) + "/fd";
  DIR* d = ::opendir(dir.c_str());
  if (!d)
    return out;
  while (const dirent* e = ::readdir(d))
  {
    char target[64];
    const ssize_t n = ::readlink((dir + "/" + e->d_name).c_str(), target, sizeof target - 1);
    if (n <= 0)
      continue;
    target[n] = '\0';
    unsigned long long inode = 0;
    if (std::sscanf(target, "socket:[%llu]", &inode) == 1)
      out.insert(inode);
  }
  ::closedir(d);
  return out;
}

}  // namespace

std::vector<LocalTcpEntry> parseLocalTcpEntries(const std::string& text, bool v6)
{
  std::vector<LocalTcpEntry> out;
  std::istringstream in(text);
  std::string line;
  while (std::getline(in, line))
  {
    // "  0: 0100007F:2B67 00000000:0000 0A 00000000:00000000 00:00000000 00000000  1000 0 12345 ..."
    std::istringstream fields(line);
    std::string slot, local, remote, state, queues, timer, retr, uid, timeout, inode;
    if (!(fields >> slot >> local >> remote >> state >> queues >> timer >> retr >> uid >> timeout >> inode))
      continue;
    const auto colon = local.find(':');
    if (slot.empty() || slot.back() != ':' || colon != (v6 ? 32u : 8u))
      continue;
    try
    {
      LocalTcpEntry e;
      e.address = v6 ? ipv6(local.substr(0, colon)) : ipv4(uint32_t(std::stoul(local.substr(0, colon), nullptr, 16)));
      e.port = int(std::stoul(local.substr(colon + 1), nullptr, 16));
      e.state = int(std::stoul(state, nullptr, 16));
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

std::vector<ListeningSocket> listeningSockets(const std::vector<int>& pids, const std::string& proc_root)
{
  std::vector<ListeningSocket> out;
  std::set<uint64_t> seen;
  for (const int pid : pids)
  {
    const std::set<uint64_t> inodes = socketInodes(pid, proc_root);
    if (inodes.empty())
      continue;
    std::vector<LocalTcpEntry> entries;
    for (const bool v6 : { false, true })
      if (const auto text = readFile(proc_root + "/" + std::to_string(pid) + (v6 ? "/net/tcp6" : "/net/tcp")))
        for (auto& e : parseLocalTcpEntries(*text, v6))
          if (inodes.count(e.inode))
            entries.push_back(e);
    std::set<int> established_ports;
    for (const auto& e : entries)
      if (e.state == 0x01)
        established_ports.insert(e.port);
    for (const auto& e : entries)
    {
      if (e.state != 0x0A || e.address.empty() || !seen.insert(e.inode).second)
        continue;
      ListeningSocket s;
      s.host = (e.address == "0.0.0.0" || e.address == "::") ? "127.0.0.1" : e.address;
      s.port = e.port;
      s.inode = e.inode;
      s.accepted = established_ports.count(e.port) > 0;
      out.push_back(s);
    }
  }
  std::sort(out.begin(), out.end(), [](const ListeningSocket& a, const ListeningSocket& b) {
    return a.accepted != b.accepted ? !a.accepted : a.inode < b.inode;
  });
  return out;
}

std::vector<int> processGroupMembers(int pgid, const std::string& proc_root)
{
  std::vector<int> out;
  for (const auto& p : readAllProcStats(proc_root))
    if (p.pgrp == pgid && p.state != 'Z')
      out.push_back(p.pid);
  return out;
}

}  // namespace anyscale_agent
