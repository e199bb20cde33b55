// Nice values and scheduling policies of a process's threads, through /proc/<pid>/task,
// setpriority(2) and sched_setscheduler(2).
#include "anyscale_agent_cpp/process_priority.h"

#include <sched.h>
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
  for (const auto& entry :
       std::filesystem::directory_iterator("/proc/" + std::to_string(pid) + "/task", ec))
  {
    try
    {
      tids.push_back(std::stoi(entry.path().filename().string()));
    }
    catch (const std::exception&)
    {}
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
      *error = "setpriority(" + std::to_string(tid) + ", " + std::to_string(nice) +
               "): " + std::strerror(errno);
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

bool leaveIdleScheduling(int pid, std::string* error)
{
  const auto tids = threadIds(pid);
  if (tids.empty())
  {
    *error = "process " + std::to_string(pid) + " is gone";
    return false;
  }
  const sched_param normal{0};
  for (const int tid : tids)
  {
    if (::sched_getscheduler(tid) != SCHED_IDLE)
      continue;  // also -1 (ESRCH): the thread ended meanwhile
    if (::sched_setscheduler(tid, SCHED_OTHER, &normal) != 0 && errno != ESRCH)
    {
      *error =
          "sched_setscheduler(" + std::to_string(tid) + ", SCHED_OTHER): " + std::strerror(errno);
      return false;
    }
  }
  return true;
}

bool inIdleScheduling(int pid)
{
  for (const int tid : threadIds(pid))
    if (::sched_getscheduler(tid) == SCHED_IDLE)
      return true;
  return false;
}

}  // namespace anyscale_agent
