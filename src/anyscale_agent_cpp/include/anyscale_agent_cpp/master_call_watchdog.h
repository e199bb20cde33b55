// Breaks this agent's calls to the master that wait on a connection the link lost.
#pragma once

#include <condition_variable>
#include <mutex>
#include <string>
#include <thread>

#include "anyscale_agent_cpp/stuck_connections.h"

namespace anyscale_agent
{

// Once a second, this process's connections to the master that have waited kStuckAfterS for an
// acknowledgement are broken, provided a fresh connection to the master opens now (the link is
// back, so roscpp's retry goes through). For an agent away from the master's machine: see
// stuck_connections.h for why.
class MasterCallWatchdog
{
public:
  MasterCallWatchdog(const std::string& master_host, int master_port);
  ~MasterCallWatchdog();

private:
  void run();

  static constexpr double kStuckAfterS = 3.0;
  std::string host_;
  int port_;
  StuckConnections stuck_;
  std::mutex mutex_;
  std::condition_variable wake_;
  bool stopping_ = false;
  std::thread thread_;
};

}  // namespace anyscale_agent
