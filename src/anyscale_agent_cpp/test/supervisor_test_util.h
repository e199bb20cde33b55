// Helpers of the supervisor gtests: log files in a temporary directory, checks that processes
// and groups are gone, and a wait that keeps polling the supervisor.
#pragma once

#include <signal.h>

#include <cerrno>
#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "anyscale_agent_cpp/supervisor.h"

namespace supervisor_test
{
using Clock = std::chrono::steady_clock;

// The logs of one test run, in a directory removed when the run ends.
class TempDir
{
public:
  TempDir()
  {
    char path[] = "/tmp/anyscale_supervisor_test_XXXXXX";
    if (::mkdtemp(path))
      path_ = path;
  }
  ~TempDir()
  {
    std::error_code ignored;
    if (!path_.empty())
      std::filesystem::remove_all(path_, ignored);
  }
  const std::string& path() const { return path_; }

private:
  std::string path_;
};

inline std::string tempLog(const std::string& tag)
{
  static TempDir dir;
  return dir.path() + "/" + tag + ".log";
}

inline std::string readFile(const std::string& path)
{
  std::ifstream f(path);
  std::stringstream ss;
  ss << f.rdbuf();
  return ss.str();
}

// A process that is gone and reaped: kill() finds nothing (a zombie would still be found).
inline bool processGone(int pid)
{
  return ::kill(pid, 0) != 0 && errno == ESRCH;
}

inline bool groupGone(int pgid)
{
  return ::kill(-pgid, 0) != 0 && errno == ESRCH;
}

inline std::vector<std::string> sh(const std::string& script)
{
  return {"/bin/sh", "-c", script};
}

inline bool waitUntil(const std::function<bool()>& cond, double timeout_s, anyscale_agent::Supervisor& s)
{
  const auto end = Clock::now() + std::chrono::duration<double>(timeout_s);
  while (Clock::now() < end)
  {
    s.poll();
    if (cond())
      return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  return cond();
}
}  // namespace supervisor_test
