// Supervisor, the starting side: the spawner thread that does every fork, node and standby
// starts into their slots, and a standby's activation through its socket pair.
#include "anyscale_agent_cpp/supervisor.h"

#include <fcntl.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

#include "anyscale_agent_cpp/child_process.h"
#include "anyscale_agent_cpp/proc_reader.h"

namespace anyscale_agent
{
namespace
{
using Clock = std::chrono::steady_clock;
}  // namespace

void Supervisor::spawnerLoop()
{
  std::unique_lock<std::mutex> lock(spawn_mutex_);
  for (;;)
  {
    spawn_cv_.wait(lock, [this] { return spawner_quit_ || spawn_job_; });
    if (spawn_job_)
    {
      spawn_job_();
      spawn_job_ = nullptr;
      spawn_cv_.notify_all();
    }
    else if (spawner_quit_)
    {
      return;
    }
  }
}

int Supervisor::start(const std::string& name, const std::vector<std::string>& argv,
                      const std::string& log_file, std::string* error)
{
  return launch(name, argv, log_file, false, error);
}

int Supervisor::startStandby(const std::string& name, const std::vector<std::string>& argv,
                             const std::string& log_file, std::string* error)
{
  return launch(name, argv, log_file, true, error);
}

int Supervisor::launch(const std::string& name, const std::vector<std::string>& argv,
                       const std::string& log_file, bool standby, std::string* error)
{
  StateLock lock(*this);
  auto fail = [&](const std::string& why) {
    if (error)
      *error = why;
    return 0;
  };
  if (argv.empty() || argv[0].empty() || argv[0][0] != '/')
    return fail("executable must be an absolute path");
  auto& slots = standby ? standbys_ : records_;
  const auto existing = slots.find(name);
  if (existing != slots.end() && isAlive(existing->second))
    return fail(std::string(standby ? "a standby of '" : "node '") + name +
                "' is already running here (pid " + std::to_string(existing->second.info.pid) +
                ")");

  // Not through a link, and only into a file of one name: a link planted in the log directory
  // would have a node's output appended to any file the agent may write.
  UniqueFd log(::open(log_file.c_str(),
                      O_WRONLY | O_CREAT | O_APPEND | O_NOFOLLOW | O_NONBLOCK | O_CLOEXEC, 0644));
  if (log.get() < 0)
    return fail("cannot open log file '" + log_file +
                "': " + (errno == ELOOP ? "it is a symbolic link" : std::strerror(errno)));
  struct stat st;
  if (::fstat(log.get(), &st) != 0 || !S_ISREG(st.st_mode) || st.st_nlink != 1)
    return fail("cannot open log file '" + log_file + "': not a regular file of one name");
  // O_NONBLOCK only kept a FIFO there from blocking the open.
  ::fcntl(log.get(), F_SETFL, O_APPEND);
  // The child's stdin: /dev/null, or for a standby one end of a socket pair it waits on (a
  // socket, so that writing to a standby that just died gives EPIPE, not SIGPIPE).
  UniqueFd child_stdin, activation;
  if (standby)
  {
    int fds[2];
    if (::socketpair(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0, fds) != 0)
      return fail(std::string("socketpair: ") + std::strerror(errno));
    child_stdin = UniqueFd(fds[0]);
    activation = UniqueFd(fds[1]);
  }
  else
  {
    child_stdin = UniqueFd(::open("/dev/null", O_RDONLY | O_CLOEXEC));
  }
  int child_pid = 0;
  {
    std::unique_lock<std::mutex> spawn_lock(spawn_mutex_);
    spawn_cv_.wait(spawn_lock, [this] { return !spawn_job_; });
    bool done = false;
    spawn_job_ = [&] {
      child_pid = spawnChild(argv, child_stdin.get(), log.get(), options_.parent_death_signal,
                             options_.child_nice, error);
      done = true;
    };
    spawn_cv_.notify_all();
    spawn_cv_.wait(spawn_lock, [&] { return done; });
  }
  if (child_pid <= 0)
    return 0;
  const pid_t pid = child_pid;

  Record r;
  r.info.name = name;
  r.info.pid = pid;
  r.info.state = standby ? ProcState::Standby : ProcState::Starting;
  r.info.log_file = log_file;
  r.info.started = Clock::now();
  r.group = Group{pid, 0, Clock::time_point::max()};
  r.activation = std::move(activation);
  r.argv = argv;
  // Set at fork and kept through exec: a successor tells this process from a later one with
  // the same pid by it. 0 if it ended already (then there is nothing to adopt anyway).
  if (const auto text = readFile("/proc/" + std::to_string(pid) + "/stat"))
    if (const auto stat = parseProcStat(*text))
      r.start_time = stat->start_time;
  slots[name] = std::move(r);
  if (!standby)
    saveStateLocked();
  changed_.notify_all();
  return pid;
}

int Supervisor::activate(const std::string& name, std::string* error)
{
  StateLock lock(*this);
  reapLocked();  // a standby that died since the last poll must not count as ready
  auto fail = [&](const std::string& why) {
    if (error)
      *error = why;
    return 0;
  };
  auto it = standbys_.find(name);
  if (it == standbys_.end() || !isAlive(it->second) || it->second.info.state != ProcState::Standby)
    return fail("no warm standby of '" + name + "' is waiting");
  if (const auto node = records_.find(name); node != records_.end() && isAlive(node->second))
    return fail("'" + name + "' still runs here (pid " + std::to_string(node->second.info.pid) +
                ")");
  Record& r = it->second;
  static const char kStart[] = "start\n";
  if (::send(r.activation.get(), kStart, sizeof kStart - 1, MSG_NOSIGNAL) !=
      ssize_t(sizeof kStart - 1))
    return fail("cannot activate the standby of '" + name + "': " + std::strerror(errno));
  r.activation.reset();  // the node sees end-of-file on stdin, as with /dev/null
  r.info.state = ProcState::Starting;
  r.info.started = Clock::now();
  const int pid = r.info.pid;
  records_[name] = std::move(r);  // the standby is the node now
  standbys_.erase(it);
  saveStateLocked();
  changed_.notify_all();
  return pid;
}

}  // namespace anyscale_agent
