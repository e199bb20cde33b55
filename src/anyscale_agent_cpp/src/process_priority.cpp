// Nice values of a process's threads, through /proc/<pid>/task and setpriority(2).
#include "anyscale_agent_cpp/process_priority.h"

#include <sys/resource.h>

#include <cerrno>
#include <cstring>
#include <filesystem>

namespace anyscale_agent
{
namespace
{
std::vector<int> threadIds(int pid)
{
  std::vector<int> tids;
  std::error_code ec;
  for (const auto& entry : std::filesystem::directory_iterator("/proc/" + std::to_string(pid) + "/task", ec))
  {
    try
    {
      tids.push_back(std::stoi(entry.path().filename().string()));
    }
    catch (const std::exception&)
    {
    }
  }
  return tids;
}
}  // namespace

bool setProcessNice(int pid, int nice, std::string* error)
{
  const auto tids = threadIds(pid);
  if (tids.empty())
  {
    *error = "process " + std::to_string(pid) + " is gone";
    return false;
  }
  for (const int tid : tids)
    // ESRCH: the thread ended meanwhile, nothing to set.
    if (::setpriority(PRIO_PROCESS, id_t(tid), nice) != 0 && errno != ESRCH)
    {
      *error = "setpriority(" + std::to_string(tid) + ", " + std::to_string(nice) + "): " + std::strerror(errno);
      return false;
    }
  return true;
}

std::vector<int> threadNices(int pid)
{
  std::vector<int> nices;
  for (const int tid : threadIds(pid))
  {
    errno = 0;
    const int nice = ::getpriority(PRIO_PROCESS, id_t(tid));
    if (errno == 0)
      nices.push_back(nice);
  }
  return nices;
}

}  // namespace anyscale_agent
