// A thread that breaks this agent's calls to the master stuck on a lost connection.
#include "anyscale_agent_cpp/master_call_watchdog.h"

#include <arpa/inet.h>
#include <netdb.h>
#include <ros/ros.h>

#include <chrono>
#include <fstream>
#include <memory>
#include <sstream>

#include "anyscale_agent_cpp/tcp_reachability.h"

namespace anyscale_agent
{

namespace
{

// "a.b.c.d:port" of the master as /proc/net/tcp shows it, or "" if the host does not resolve.
std::string ipv4Remote(const std::string& host, int port)
{
  addrinfo hints{};
  hints.ai_family = AF_INET;
  hints.ai_socktype = SOCK_STREAM;
  addrinfo* found = nullptr;
  if (getaddrinfo(host.c_str(), nullptr, &hints, &found) != 0 || !found)
    return "";
  const std::unique_ptr<addrinfo, decltype(&freeaddrinfo)> owned(found, &freeaddrinfo);
  char text[INET_ADDRSTRLEN] = {};
  const auto* a = reinterpret_cast<const sockaddr_in*>(found->ai_addr);
  if (!inet_ntop(AF_INET, &a->sin_addr, text, sizeof(text)))
    return "";
  return std::string(text) + ":" + std::to_string(port);
}

double steadyNow()
{
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

}  // namespace

MasterCallWatchdog::MasterCallWatchdog(const std::string& master_host, int master_port)
  : host_(master_host),
    port_(master_port),
    stuck_(ipv4Remote(master_host, master_port), kStuckAfterS)
{
  if (stuck_.remote().empty())
  {
    ROS_WARN(
        "master host %s has no IPv4 address: calls to it stuck on a lost connection are not broken",
        host_.c_str());
    return;
  }
  thread_ = std::thread(&MasterCallWatchdog::run, this);
}

MasterCallWatchdog::~MasterCallWatchdog()
{
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stopping_ = true;
  }
  wake_.notify_all();
  if (thread_.joinable())
    thread_.join();
}

void MasterCallWatchdog::run()
{
  std::unique_lock<std::mutex> lock(mutex_);
  while (!wake_.wait_for(lock, std::chrono::seconds(1), [this] { return stopping_; }))
  {
    std::ifstream file("/proc/self/net/tcp");
    std::stringstream text;
    text << file.rdbuf();
    const auto stuck = stuck_.update(parseProcNetTcp(text.str()), steadyNow());
    if (stuck.empty() || !tcpConnects(host_, port_, 1.0))
      continue;
    for (const uint64_t inode : stuck)
      if (breakConnection(socketFdOfInode(inode), inode))
        ROS_WARN(
            "a call to the master at %s waited %.0f s or more on a connection the link had lost: "
            "broken, "
            "so that roscpp makes the call again on a new one",
            stuck_.remote().c_str(), kStuckAfterS);
  }
}

}  // namespace anyscale_agent
