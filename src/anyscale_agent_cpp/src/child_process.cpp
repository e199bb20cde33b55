// fork/exec of a node process: new session, stdio redirected, signals and nice reset, agent
// fds closed.
#include "anyscale_agent_cpp/child_process.h"

#include <fcntl.h>
#include <signal.h>
#include <sys/prctl.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

#include "anyscale_agent_cpp/unique_fd.h"

namespace anyscale_agent
{
namespace
{
int failSpawn(std::string* error, const std::string& why)
{
  if (error)
    *error = why;
  return 0;
}
}  // namespace

int spawnChild(const std::vector<std::string>& argv, int stdin_fd, int log_fd, int death_signal,
               int nice, std::string* error)
{
  int pipe_fds[2];
  if (::pipe2(pipe_fds, O_CLOEXEC) != 0)
    return failSpawn(error, std::string("pipe2: ") + std::strerror(errno));
  UniqueFd err_read(pipe_fds[0]), err_write(pipe_fds[1]);
  const pid_t parent = ::getpid();

  // Everything the child needs is prepared before fork: between fork and exec only
  // async-signal-safe calls are allowed (the agent is multi-threaded).
  std::vector<char*> cargv;
  for (const auto& a : argv)
    cargv.push_back(const_cast<char*>(a.c_str()));
  cargv.push_back(nullptr);

  const pid_t pid = ::fork();
  if (pid < 0)
    return failSpawn(error, std::string("fork: ") + std::strerror(errno));
  if (pid == 0)
  {
    ::setsid();
    if (death_signal > 0)
    {
      ::prctl(PR_SET_PDEATHSIG, death_signal);
      if (::getppid() != parent)  // the agent died before prctl took effect
        ::_exit(127);
    }
    // Dispositions set to SIG_IGN (roscpp ignores SIGPIPE) and the signal mask survive exec.
    for (int sig = 1; sig < NSIG; ++sig)
      if (sig != SIGKILL && sig != SIGSTOP)
        ::signal(sig, SIG_DFL);
    sigset_t none;
    sigemptyset(&none);
    ::sigprocmask(SIG_SETMASK, &none, nullptr);
    // Not the forking thread's nice: the agent may run at a raised priority (~control_nice)
    // so that its calls are answered on a CPU-starved robot, and a node that inherited it would
    // compete with the agent at its level. Lowering one's own priority needs no privilege.
    ::setpriority(PRIO_PROCESS, 0, nice);
    ::dup2(stdin_fd, STDIN_FILENO);
    ::dup2(log_fd, STDOUT_FILENO);
    ::dup2(log_fd, STDERR_FILENO);
    // The agent's sockets (its XML-RPC port, topic connections) must not live on in children.
    const int keep = err_write.get();
    if (keep > 3)
      ::close_range(3, keep - 1, 0);
    ::close_range(keep + 1, ~0U, 0);
    ::execv(cargv[0], cargv.data());
    const int e = errno;
    ssize_t ignored = ::write(err_write.get(), &e, sizeof e);
    (void)ignored;
    ::_exit(127);
  }

  err_write.reset();
  int child_errno = 0;
  ssize_t n;
  do
    n = ::read(err_read.get(), &child_errno, sizeof child_errno);
  while (n < 0 && errno == EINTR);
  if (n == sizeof child_errno)
  {
    int status;
    ::waitpid(pid, &status, 0);
    return failSpawn(error, "cannot execute '" + argv[0] + "': " + std::strerror(child_errno));
  }

  return pid;
}

}  // namespace anyscale_agent
