// /proc/PID/fd socket inodes matched against /proc/PID/net/tcp{,6}.
#include "anyscale_agent_cpp/listening_sockets.h"

#include <algorithm>
#include <map>
#include <set>

#include "anyscale_agent_cpp/proc_net_tcp.h"
#include "anyscale_agent_cpp/proc_reader.h"

namespace anyscale_agent
{

std::vector<ListeningSocket> listeningSockets(const std::vector<int>& pids,
                                              const std::string& proc_root)
{
  std::vector<ListeningSocket> out;
  std::set<uint64_t> seen;
  for (const int pid : pids)
  {
    const std::map<uint64_t, int> sockets =
        socketFds(proc_root + "/" + std::to_string(pid) + "/fd");
    if (sockets.empty())
      continue;
    std::vector<TcpEntry> entries;
    for (const bool v6 : {false, true})
      if (const auto text =
              readFile(proc_root + "/" + std::to_string(pid) + (v6 ? "/net/tcp6" : "/net/tcp")))
        for (auto& e : parseProcNetTcp(*text, v6))
          if (sockets.count(e.inode))
            entries.push_back(e);
    std::set<int> established_ports;
    for (const auto& e : entries)
      if (e.state == kTcpEstablished)
        established_ports.insert(e.local_port);
    for (const auto& e : entries)
    {
      if (e.state != kTcpListen || e.local.empty() || !seen.insert(e.inode).second)
        continue;
      ListeningSocket s;
      s.host = (e.local == "0.0.0.0" || e.local == "::") ? "127.0.0.1" : e.local;
      s.port = e.local_port;
      s.inode = e.inode;
      s.accepted = established_ports.count(e.local_port) > 0;
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
