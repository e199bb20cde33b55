// Supervisor, the supervising side: the node states, the staged SIGINT -> SIGTERM -> SIGKILL
// stop of whole process groups, reaping, and the queries. Starts are in supervisor_spawn.cpp.
#include "anyscale_agent_cpp/supervisor.h"

#include <signal.h>
#include <sys/prctl.h>
#include <sys/wait.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <thread>

namespace anyscale_agent
{
namespace
{
using Clock = std::chrono::steady_clock;

Clock::duration seconds(double s)
{
  return std::chrono::duration_cast<Clock::duration>(
      std::chrono::duration<double>(std::max(0.0, s)));
}

bool groupExists(int pgid)
{
  return ::kill(-pgid, 0) == 0 || errno == EPERM;
}
}  // namespace

const char* toString(ProcState s)
{
  switch (s)
  {
    case ProcState::Starting: return "starting";
    case ProcState::Running: return "running";
    case ProcState::Stopping: return "stopping";
    case ProcState::Exited: return "exited";
    case ProcState::Replaced: return "replaced";
    case ProcState::LeaseExpired: return "lease expired";
    case ProcState::Standby: return "standby";
    case ProcState::Paused: return "paused";
  }
  return "?";
}

Supervisor::Supervisor(SupervisorOptions options) : options_(options)
{
  if (options_.subreaper)
    ::prctl(PR_SET_CHILD_SUBREAPER, 1);
  spawner_ = std::thread([this] { spawnerLoop(); });
}

Supervisor::~Supervisor()
{
  stopAll();
  {
    std::lock_guard<std::mutex> lock(spawn_mutex_);
    spawner_quit_ = true;
  }
  spawn_cv_.notify_all();
  spawner_.join();
}

bool Supervisor::isAlive(const Record& r)
{
  return r.info.pid != 0;
}

std::optional<ProcessInfo> Supervisor::standby(const std::string& name) const
{
  std::lock_guard<std::mutex> lock(mutex_);
  const auto it = standbys_.find(name);
  if (it == standbys_.end())
    return std::nullopt;
  return it->second.info;
}

bool Supervisor::stopStandby(const std::string& name)
{
  std::lock_guard<std::mutex> lock(mutex_);
  auto it = standbys_.find(name);
  if (it == standbys_.end() || !isAlive(it->second))
    return false;
  Record& r = it->second;
  r.info.stop_requested = true;
  r.activation.reset();
  r.group.stage = 2;  // the next escalation is SIGKILL
  escalate(r.group, Clock::now());
  return true;
}

bool Supervisor::stop(const std::string& name, ProcState final_state, double kill_after_s)
{
  StateLock lock(*this);
  const bool stopping = stopLocked(name, final_state, kill_after_s);
  if (stopping)
    saveStateLocked();
  return stopping;
}

bool Supervisor::stopLocked(const std::string& name, ProcState final_state, double kill_after_s)
{
  auto it = records_.find(name);
  if (it == records_.end() || !isAlive(it->second))
    return false;
  Record& r = it->second;
  r.info.stop_requested = true;
  r.final_state = final_state;
  r.info.state = ProcState::Stopping;
  if (r.group.stage == 0)
  {
    // A lease runs out only on a scale cut off from the decision node. A clean shutdown would
    // try to unregister from a master it cannot reach and hang there, while the name already
    // belongs to the new instance on the other side: straight to SIGKILL.
    if (final_state == ProcState::LeaseExpired)
      r.group.stage = 2;
    const auto now = Clock::now();
    escalate(r.group, now);
    if (kill_after_s > 0.0 && r.group.stage == 1)
    {
      r.group.stage = 2;  // the next escalation is SIGKILL
      r.group.deadline = now + seconds(kill_after_s);
    }
  }
  return true;
}

bool Supervisor::pause(const std::string& name, std::string* error)
{
  StateLock lock(*this);
  auto it = records_.find(name);
  if (it == records_.end() || !isAlive(it->second) || it->second.info.state != ProcState::Running)
  {
    *error = "'" + name + "' is not running here" +
             (it != records_.end() ? std::string(" (it is ") + toString(it->second.info.state) + ")"
                                   : "");
    return false;
  }
  if (::kill(-it->second.group.pgid, SIGSTOP) != 0)
  {
    *error = "cannot pause '" + name + "': " + std::strerror(errno);
    return false;
  }
  it->second.info.state = ProcState::Paused;
  saveStateLocked();
  return true;
}

int Supervisor::resume(const std::string& name, std::string* error)
{
  StateLock lock(*this);
  reapLocked();  // a paused node that was killed meanwhile must not count as resumed
  auto it = records_.find(name);
  if (it == records_.end() || !isAlive(it->second) || it->second.info.state != ProcState::Paused)
  {
    *error = "'" + name + "' is not paused here";
    return 0;
  }
  if (::kill(-it->second.group.pgid, SIGCONT) != 0)
  {
    *error = "cannot resume '" + name + "': " + std::strerror(errno);
    return 0;
  }
  it->second.info.state = ProcState::Running;
  saveStateLocked();
  return it->second.info.pid;
}

bool Supervisor::killNow(const std::string& name)
{
  std::lock_guard<std::mutex> lock(mutex_);
  auto it = records_.find(name);
  if (it == records_.end() || !isAlive(it->second) || !it->second.info.stop_requested)
    return false;
  it->second.group.stage = 2;  // the next escalation is SIGKILL
  escalate(it->second.group, Clock::now());
  return true;
}

void Supervisor::escalate(Group& g, Clock::time_point now)
{
  // SIGCONT after SIGINT and SIGTERM: a paused group (pause()) handles them only once it runs.
  // SIGKILL needs none.
  if (g.stage == 0)
  {
    ::kill(-g.pgid, SIGINT);
    ::kill(-g.pgid, SIGCONT);
    g.stage = 1;
    g.deadline = now + seconds(options_.sigint_timeout_s);
  }
  else if (g.stage == 1)
  {
    ::kill(-g.pgid, SIGTERM);
    ::kill(-g.pgid, SIGCONT);
    g.stage = 2;
    g.deadline = now + seconds(options_.sigterm_timeout_s);
  }
  else
  {
    ::kill(-g.pgid, SIGKILL);
    g.stage = 3;
    g.deadline = now + seconds(1.0);  // re-sent until the group is empty
  }
}

void Supervisor::reapLocked()
{
  bool node_exited = false;
  for (;;)
  {
    int status = 0;
    // -1: with the subreaper flag, orphaned members of node groups become our children too
    // (an adopted node among them, if its agent died while it was our ancestor).
    const pid_t pid = ::waitpid(-1, &status, WNOHANG);
    if (pid <= 0)
      break;
    for (auto* slots : {&records_, &standbys_})
      for (auto& [name, r] : *slots)
        if (r.info.pid == pid)
        {
          recordExitLocked(name, r, WIFEXITED(status) ? WEXITSTATUS(status) : -1,
                           WIFSIGNALED(status) ? WTERMSIG(status) : 0);
          node_exited |= slots == &records_;
        }
  }
  // Adopted nodes are not our children, unless their agent died while it was our ancestor (the
  // subreaper flag): then one that exited after the loop above is reaped here, with its status.
  for (auto& [name, r] : records_)
    if (isAlive(r) && r.info.adopted && adoptedExited(r))
    {
      int status = 0;
      if (::waitpid(r.info.pid, &status, WNOHANG) == r.info.pid)
        recordExitLocked(name, r, WIFEXITED(status) ? WEXITSTATUS(status) : -1,
                         WIFSIGNALED(status) ? WTERMSIG(status) : 0);
      else
        recordExitLocked(name, r, -1, 0);
      node_exited = true;
    }
  if (node_exited)
    saveStateLocked();
}

void Supervisor::recordExitLocked(const std::string& name, Record& r, int exit_code,
                                  int exit_signal)
{
  // A standby that ended was never a node, and a paused one is not the node's instance
  // in use (it runs on another scale): nothing for the node-exit handling to do.
  const bool not_in_use = r.info.state == ProcState::Standby || r.info.state == ProcState::Paused;
  r.info.pid = 0;
  r.info.exit_code = exit_code;
  r.info.exit_signal = exit_signal;
  r.info.state = r.info.stop_requested ? r.final_state : ProcState::Exited;
  r.activation.reset();
  r.pidfd.reset();
  if (!r.info.stop_requested && !not_in_use)
  {
    unrequested_exits_.push_back(name);
    ++unrequested_exit_count_;
  }
  // Members that outlive the leader are cleared the same way, continuing its sequence.
  if (groupExists(r.group.pgid))
    orphan_groups_.push_back(r.group);
  changed_.notify_all();
}

void Supervisor::poll()
{
  StateLock lock(*this);
  reapLocked();
  const auto now = Clock::now();
  for (auto* slots : {&records_, &standbys_})
    for (auto& [name, r] : *slots)
      if (isAlive(r) && r.group.stage > 0 && now >= r.group.deadline)
        escalate(r.group, now);
  for (auto& g : orphan_groups_)
    if (g.stage == 0 || now >= g.deadline)
      escalate(g, now);
  orphan_groups_.erase(std::remove_if(orphan_groups_.begin(), orphan_groups_.end(),
                                      [](const Group& g) { return !groupExists(g.pgid); }),
                       orphan_groups_.end());
}

bool Supervisor::waitGone(const std::string& name, double timeout_s)
{
  const auto deadline = Clock::now() + seconds(timeout_s);
  for (;;)
  {
    poll();
    {
      std::unique_lock<std::mutex> lock(mutex_);
      const auto it = records_.find(name);
      if (it == records_.end() || !isAlive(it->second))
        return true;
      if (Clock::now() >= deadline)
        return false;
      // Woken by another thread's poll(), or after 20 ms to poll ourselves: SIGCHLD is not
      // used because a handler cannot safely take this mutex.
      changed_.wait_for(lock, std::chrono::milliseconds(20));
    }
  }
}

void Supervisor::markRunning(const std::string& name)
{
  StateLock lock(*this);
  auto it = records_.find(name);
  if (it != records_.end() && it->second.info.state == ProcState::Starting)
  {
    it->second.info.state = ProcState::Running;
    saveStateLocked();
  }
}

bool Supervisor::setFinalState(const std::string& name, ProcState state)
{
  std::lock_guard<std::mutex> lock(mutex_);
  auto it = records_.find(name);
  if (it == records_.end() || isAlive(it->second))
    return false;
  it->second.info.state = state;
  return true;
}

std::optional<ProcessInfo> Supervisor::info(const std::string& name) const
{
  std::lock_guard<std::mutex> lock(mutex_);
  const auto it = records_.find(name);
  if (it == records_.end())
    return std::nullopt;
  return it->second.info;
}

std::vector<ProcessInfo> Supervisor::snapshot() const
{
  std::lock_guard<std::mutex> lock(mutex_);
  std::vector<ProcessInfo> out;
  for (const auto* slots : {&records_, &standbys_})
    for (const auto& [name, r] : *slots)
      out.push_back(r.info);
  return out;
}

uint64_t Supervisor::unrequestedExitCount() const
{
  std::lock_guard<std::mutex> lock(mutex_);
  return unrequested_exit_count_;
}

std::vector<std::string> Supervisor::takeUnrequestedExits()
{
  std::lock_guard<std::mutex> lock(mutex_);
  std::vector<std::string> out;
  out.swap(unrequested_exits_);
  return out;
}

void Supervisor::stopAll()
{
  std::vector<std::string> names;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    for (const auto& [name, r] : records_)
      if (isAlive(r))
        names.push_back(name);
  }
  for (const auto& n : names)
    stop(n);
  std::vector<std::string> standby_names;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    for (const auto& [name, r] : standbys_)
      standby_names.push_back(name);
  }
  for (const auto& n : standby_names)
    stopStandby(n);
  const double limit = options_.sigint_timeout_s + options_.sigterm_timeout_s + 5.0;
  for (const auto& n : names)
    waitGone(n, limit);
  // Standbys, and leftover members of groups whose leader is gone.
  const auto deadline = Clock::now() + seconds(limit);
  for (;;)
  {
    poll();
    {
      std::lock_guard<std::mutex> lock(mutex_);
      const bool standby_alive = std::any_of(standbys_.begin(), standbys_.end(),
                                             [](const auto& kv) { return isAlive(kv.second); });
      if ((orphan_groups_.empty() && !standby_alive) || Clock::now() >= deadline)
        break;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
}

}  // namespace anyscale_agent
