// Supervisor, the restart side: the state file of running nodes, the adoption of the nodes a
// killed predecessor left running, and watching adopted nodes, which are not our children.
#include "anyscale_agent_cpp/supervisor.h"

#include <poll.h>
#include <sys/syscall.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>

#include "anyscale_agent_cpp/node_state_file.h"
#include "anyscale_agent_cpp/proc_reader.h"

#ifndef SYS_pidfd_open
#define SYS_pidfd_open 434  // the same number on every architecture
#endif

namespace anyscale_agent
{
namespace
{
using Clock = std::chrono::steady_clock;

// A pidfd pins the process: unlike a pid it can never come to mean another one. -1 with errno
// set if the kernel has no pidfd_open (ENOSYS) or there is no such process (ESRCH).
UniqueFd openPidfd(int pid)
{
  return UniqueFd(int(::syscall(SYS_pidfd_open, pid, 0)));  // close-on-exec by the kernel
}

std::optional<ProcStat> readStat(int pid)
{
  const auto text = readFile("/proc/" + std::to_string(pid) + "/stat");
  return text ? parseProcStat(*text) : std::nullopt;
}

const char* stateName(ProcState s)
{
  switch (s)
  {
    case ProcState::Starting: return kNodeStates[0];
    case ProcState::Paused: return kNodeStates[2];
    case ProcState::Stopping: return kNodeStates[3];
    default: return kNodeStates[1];
  }
}

// When the process started, on the steady clock. /proc's start time counts clock ticks on
// CLOCK_BOOTTIME.
Clock::time_point startedAt(uint64_t start_ticks)
{
  timespec boot{};
  ::clock_gettime(CLOCK_BOOTTIME, &boot);
  const double age = double(boot.tv_sec) + 1e-9 * double(boot.tv_nsec) -
                     double(start_ticks) / double(::sysconf(_SC_CLK_TCK));
  return Clock::now() - std::chrono::duration_cast<Clock::duration>(
                            std::chrono::duration<double>(std::max(0.0, age)));
}
}  // namespace

AdoptionReport Supervisor::adopt(const std::string& state_file)
{
  AdoptionReport report;
  std::optional<NodeState> previous;
  try
  {
    previous = readNodeStateFile(state_file);
  }
  catch (const NodeStateError& e)
  {
    report.warning = std::string(e.what()) + "; no node is adopted, the file is written anew";
  }
  {
    StateLock lock(*this);
    state_file_.setPath(state_file);
    adoptLocked(previous, report);
  }  // the file is written here
  if (const std::string error = state_file_.error(); !error.empty())
    report.warning += (report.warning.empty() ? "" : "; ") + error +
                      ": a restarted agent will not find these nodes";
  state_file_.takeNotes();  // said in the report
  return report;
}

void Supervisor::adoptLocked(const std::optional<NodeState>& previous, AdoptionReport& report)
{
  boot_id_ = currentBootId();
  std::vector<std::string> resume_stop;
  for (const auto& e : previous ? previous->nodes : std::vector<NodeStateEntry>{})
  {
    auto drop = [&](const std::string& why) {
      report.dropped.push_back(e.name + " (pid " + std::to_string(e.pid) + "): " + why);
    };
    // A node that ended while no agent ran is shown as ended by itself (exit status unknown),
    // as if it had ended under this agent: the decision node starts again a node its agent
    // reports EXITED, and would never learn of one that is simply missing.
    auto ended = [&](const std::string& why) {
      drop(why);
      if (const auto it = records_.find(e.name); it != records_.end())
        return;
      Record r;
      r.info.name = e.name;
      r.info.state = ProcState::Exited;
      r.info.log_file = e.log_file;
      r.info.started = startedAt(e.start_time);
      r.info.adopted = true;
      r.group = Group{e.pid, 3, Clock::time_point::max()};
      records_[e.name] = std::move(r);
      // Paused, it was a spare (the node runs elsewhere); stopping, its end was asked for.
      if (e.state == kNodeStates[0] || e.state == kNodeStates[1])
        unrequested_exits_.push_back(e.name);
    };
    // Start times count from boot; after a reboot they could match a stranger.
    if (previous->boot_id != boot_id_ || boot_id_.empty())
    {
      ended("the file is from an earlier boot");
      continue;
    }
    if (const auto it = records_.find(e.name); it != records_.end() && isAlive(it->second))
    {
      drop("a node of that name already runs here (pid " + std::to_string(it->second.info.pid) +
           ")");
      continue;
    }
    // The pidfd first, then the checks: a process that ends and whose pid is reused between
    // the two is caught by its start time, and once the checks pass the pidfd is that process.
    UniqueFd pidfd;
    if (options_.use_pidfd)
    {
      pidfd = openPidfd(e.pid);
      if (pidfd.get() < 0 && errno == ESRCH)
      {
        ended("it has ended");
        continue;
      }
    }
    const auto stat = readStat(e.pid);
    const auto cmdline = readFile("/proc/" + std::to_string(e.pid) + "/cmdline");
    const IdentityCheck check = checkIdentity(e, stat, parseCmdline(cmdline.value_or("")));
    if (check.identity == Identity::Gone)
    {
      ended(check.why);
      continue;
    }
    if (check.identity == Identity::Changed)
    {
      // Not ours to end or to count: a process we cannot identify is left alone (the line
      // names its pid).
      drop(check.why);
      continue;
    }
    Record r;
    r.info.name = e.name;
    r.info.pid = e.pid;
    r.info.log_file = e.log_file;
    r.info.started = startedAt(e.start_time);
    r.info.adopted = true;
    // A paused node stays paused: it is the master scale's spare of a node that runs on
    // another scale, and the next start here resumes it, as if the agent had never gone.
    // Paused if the file says so or the kernel shows it stopped ('T'): the leader of a group
    // stopped while it vfork()ed shows 'D' until its stopped child runs, and the file may lag
    // a SIGSTOP by one write.
    // A node the predecessor was stopping is stopped again from SIGINT: someone asked for
    // it, and its stop's progress died with the predecessor.
    r.info.state = e.state == kNodeStates[2] || stat->state == 'T' ? ProcState::Paused
                   : e.state == kNodeStates[0]                     ? ProcState::Starting
                                                                   : ProcState::Running;
    if (e.state == kNodeStates[3])
      resume_stop.push_back(e.name);
    r.group = Group{e.pid, 0, Clock::time_point::max()};
    r.argv = e.argv;
    r.start_time = e.start_time;
    r.lease_end_s = e.lease_end_s;
    r.pidfd = std::move(pidfd);
    report.adopted.push_back({r.info, e.lease_end_s});
    records_[e.name] = std::move(r);
  }
  for (const auto& name : resume_stop)
    stopLocked(name, ProcState::Exited, 0.0);
  for (auto& a : report.adopted)
    a.info = records_[a.info.name].info;
  // Warm standbys are not in the file: a standby holds no state and no registration, and its
  // stdin is a socket whose other end was its agent's, so it ends by itself at end-of-file
  // when that agent dies; this agent prepares new ones.
  saveStateLocked();
  changed_.notify_all();
}

void Supervisor::setLeaseEnds(const std::map<std::string, double>& lease_ends)
{
  StateLock lock(*this);
  bool changed = false;
  for (const auto& [name, end] : lease_ends)
    if (auto it = records_.find(name);
        it != records_.end() && isAlive(it->second) && it->second.lease_end_s != end)
    {
      it->second.lease_end_s = end;
      changed = true;
    }
  if (changed)
    saveStateLocked();
}

std::vector<std::string> Supervisor::takeStateFileNotes()
{
  return state_file_.takeNotes();
}

bool Supervisor::adoptedExited(const Record& r) const
{
  if (r.pidfd.get() >= 0)
  {
    // Readable once the process has exited (zombie or reaped by its parent, init or another
    // subreaper). Its exit status goes to that parent, not to us.
    pollfd p{r.pidfd.get(), POLLIN, 0};
    return ::poll(&p, 1, 0) > 0;
  }
  // No pidfd (ENOSYS): the pid with another start time is another process, ours is gone.
  const auto stat = readStat(r.info.pid);
  return !stat || stat->start_time != r.start_time || stat->state == 'Z' || stat->state == 'X';
}

void Supervisor::saveStateLocked()
{
  if (state_file_.path().empty() || left_running_)
    return;
  NodeState state;
  state.boot_id = boot_id_;
  for (const auto& [name, r] : records_)
    if (isAlive(r))
    {
      NodeStateEntry e;
      e.name = name;
      e.pid = r.info.pid;
      e.start_time = r.start_time;
      e.argv = r.argv;
      e.log_file = r.info.log_file;
      e.state = stateName(r.info.state);
      // A successor enforces a lease only on a node that outlives this agent: the others die
      // with it (parent_death_signal), so their renewals need no write.
      e.lease_end_s = options_.parent_death_signal == 0 || r.info.adopted ? r.lease_end_s : 0.0;
      state.nodes.push_back(std::move(e));
    }
  if (auto staged = state_file_.stage(state))
    staged_state_ = std::move(staged);
}

std::vector<std::string> Supervisor::leaveRunning()
{
  std::vector<std::string> left;
  StateLock lock(*this);
  saveStateLocked();  // staged: the StateLock writes it, the last write of this supervisor
  left_running_ = true;
  for (auto it = records_.begin(); it != records_.end();)
  {
    if (isAlive(it->second))
    {
      left.push_back(it->first);
      it = records_.erase(it);
    }
    else
      ++it;
  }
  return left;
}

}  // namespace anyscale_agent
