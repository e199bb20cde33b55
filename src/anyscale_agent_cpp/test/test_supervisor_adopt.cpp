// gtest: a restarted supervisor adopts the nodes its predecessor left running (state file,
// pid + start time + command line), watches them without being their parent, and stops them.
// When the state file is written: test_supervisor_state_file.cpp.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/prctl.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <chrono>
#include <cstring>
#include <fstream>
#include <future>
#include <string>
#include <thread>

#include "anyscale_agent_cpp/node_state_file.h"
#include "anyscale_agent_cpp/proc_reader.h"
#include "anyscale_agent_cpp/supervisor.h"
#include "supervisor_test_util.h"

using namespace anyscale_agent;
using namespace supervisor_test;

namespace
{
// A node left by another agent: a process in a session of its own whose parent is a stand-in
// for that agent (not this test), which reaps it when it ends, as init would.
struct ForeignNode
{
  int pid = 0;
  int parent = 0;
  std::vector<std::string> argv;
  uint64_t start_time = 0;

  ForeignNode(std::vector<std::string> command) : argv(std::move(command))
  {
    std::vector<char*> cargv;
    for (auto& a : argv)
      cargv.push_back(a.data());
    cargv.push_back(nullptr);
    int fds[2];
    if (::pipe(fds) != 0)
      return;
    parent = ::fork();
    if (parent == 0)
    {
      const pid_t node = ::fork();
      if (node == 0)
      {
        // As spawnChild sets up a node: default dispositions and an empty mask. A test run in
        // the background of a non-interactive shell inherits SIGINT ignored, and a node that
        // ignores it outlasts a stop's SIGINT phase.
        for (const int sig : {SIGINT, SIGTERM, SIGQUIT, SIGHUP})
          ::signal(sig, SIG_DFL);
        sigset_t none;
        ::sigemptyset(&none);
        ::sigprocmask(SIG_SETMASK, &none, nullptr);
        ::setsid();
        ::execv(cargv[0], cargv.data());
        ::_exit(127);
      }
      ssize_t w = ::write(fds[1], &node, sizeof node);
      (void)w;
      int status;
      ::waitpid(node, &status, 0);
      ::_exit(0);
    }
    ::close(fds[1]);
    if (::read(fds[0], &pid, sizeof pid) != ssize_t(sizeof pid))
      pid = 0;
    ::close(fds[0]);
    // Adoption compares the command line, so wait until the exec has happened.
    const auto end = Clock::now() + std::chrono::seconds(5);
    while (Clock::now() < end &&
           parseCmdline(anyscale_agent::readFile(procPath("cmdline")).value_or("")) != argv)
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    start_time = startTime();
  }
  ~ForeignNode()
  {
    if (pid > 0 && startTime() == start_time)  // still that process, not a later one with its pid
      ::kill(pid, SIGKILL);
    int status;
    if (parent > 0)
      ::waitpid(parent, &status, 0);  // ECHILD if a supervisor's waitpid(-1) took it first
  }
  std::string procPath(const std::string& file) const
  {
    return "/proc/" + std::to_string(pid) + "/" + file;
  }
  uint64_t startTime() const
  {
    const auto stat = parseProcStat(anyscale_agent::readFile(procPath("stat")).value_or(""));
    return stat ? stat->start_time : 0;
  }
  NodeStateEntry entry(const std::string& name) const
  {
    NodeStateEntry e;
    e.name = name;
    e.pid = pid;
    e.start_time = startTime();
    e.argv = argv;
    e.log_file = tempLog(name.substr(1));
    return e;
  }
};

void writeState(const std::string& path, const std::vector<NodeStateEntry>& nodes)
{
  NodeState s;
  s.boot_id = currentBootId();
  s.nodes = nodes;
  std::string err;
  ASSERT_TRUE(writeNodeStateFile(path, s, &err)) << err;
}

}  // namespace

class SupervisorAdopt : public ::testing::TestWithParam<bool>  // pidfd, or the /proc fallback
{
protected:
  SupervisorOptions options() const
  {
    SupervisorOptions o;
    o.use_pidfd = GetParam();
    return o;
  }
  TempDir dir_;
  std::string path_ = dir_.path() + "/nodes.yaml";
};

TEST_P(SupervisorAdopt, AdoptsALiveNodeAndStopsIt)
{
  ForeignNode node({"/bin/sleep", "30"});
  ASSERT_GT(node.pid, 0);
  NodeStateEntry e = node.entry("/talker");
  e.lease_end_s = 98765.25;
  writeState(path_, {e});

  Supervisor s(options());
  const AdoptionReport report = s.adopt(path_);
  EXPECT_EQ(report.warning, "");
  EXPECT_TRUE(report.dropped.empty()) << report.dropped[0];
  ASSERT_EQ(report.adopted.size(), 1u);
  EXPECT_EQ(report.adopted[0].lease_end_s, 98765.25);
  const ProcessInfo info = s.info("/talker").value();
  EXPECT_EQ(info.pid, node.pid);
  EXPECT_EQ(info.state, ProcState::Running);
  EXPECT_TRUE(info.adopted);
  EXPECT_EQ(info.log_file, e.log_file);
  EXPECT_LT(std::chrono::duration<double>(Clock::now() - info.started).count(), 10.0);
  // A node like any other: it is listed, and a second start of its name is refused.
  ASSERT_EQ(s.snapshot().size(), 1u);
  std::string err;
  EXPECT_EQ(s.start("/talker", {"/bin/sleep", "30"}, tempLog("twice"), &err), 0);
  EXPECT_NE(err.find("already running"), std::string::npos) << err;
  // The file now lists it as this supervisor's.
  EXPECT_EQ(readNodeStateFile(path_)->nodes, std::vector<NodeStateEntry>{e});

  ASSERT_TRUE(s.stop("/talker"));
  ASSERT_TRUE(s.waitGone("/talker", 10.0));
  EXPECT_EQ(s.info("/talker")->state, ProcState::Exited);
  EXPECT_TRUE(s.takeUnrequestedExits().empty()) << "a requested stop";
  EXPECT_TRUE(waitUntil([&] { return processGone(node.pid); }, 5.0, s))
      << "its stand-in parent reaps it";
  EXPECT_TRUE(readNodeStateFile(path_)->nodes.empty());
}

TEST_P(SupervisorAdopt, AnAdoptedNodeThatExitsIsReportedExited)
{
  ForeignNode node({"/bin/sleep", "30"});
  ASSERT_GT(node.pid, 0);
  writeState(path_, {node.entry("/quitter")});
  Supervisor s(options());
  ASSERT_EQ(s.adopt(path_).adopted.size(), 1u);
  s.poll();
  EXPECT_EQ(s.info("/quitter")->pid, node.pid) << "still running";

  ASSERT_EQ(::kill(node.pid, SIGTERM), 0);
  ASSERT_TRUE(s.waitGone("/quitter", 5.0));
  const ProcessInfo info = s.info("/quitter").value();
  EXPECT_EQ(info.state, ProcState::Exited);
  // Its parent got the status, not us.
  EXPECT_EQ(info.exit_code, -1);
  EXPECT_EQ(info.exit_signal, 0);
  EXPECT_EQ(s.takeUnrequestedExits(), std::vector<std::string>{"/quitter"});
  EXPECT_TRUE(readNodeStateFile(path_)->nodes.empty());
  // And the name is free for a fresh start.
  std::string err;
  EXPECT_GT(s.start("/quitter", {"/bin/sleep", "30"}, tempLog("quitter2"), &err), 0) << err;
}

TEST_P(SupervisorAdopt, APidWithAnotherStartTimeOrCommandIsNotAdopted)
{
  ForeignNode node({"/bin/sleep", "30"});
  ASSERT_GT(node.pid, 0);
  NodeStateEntry reused = node.entry("/reused");
  reused.start_time += 1;  // the pid was handed to another process since
  NodeStateEntry other_command = node.entry("/other");
  other_command.argv = {"/bin/sleep", "31"};
  NodeStateEntry gone = node.entry("/gone");
  gone.pid = 4194304 + 1;  // above any pid_max: no such process
  writeState(path_, {reused, other_command, gone});

  Supervisor s(options());
  const AdoptionReport report = s.adopt(path_);
  EXPECT_TRUE(report.adopted.empty());
  EXPECT_EQ(report.warning, "");
  ASSERT_EQ(report.dropped.size(), 3u);
  std::string all;
  for (const auto& line : report.dropped)
    all += line + "\n";
  EXPECT_NE(all.find("/reused (pid " + std::to_string(node.pid) + "): it has ended; pid " +
                     std::to_string(node.pid) + " is another process now"),
            std::string::npos)
      << all;
  EXPECT_NE(all.find("/other (pid " + std::to_string(node.pid) + "): pid " +
                     std::to_string(node.pid) + " runs another command line"),
            std::string::npos)
      << all;
  EXPECT_NE(all.find("/gone (pid 4194305): it has ended"), std::string::npos) << all;
  // The nodes that ended while no agent ran are shown as ended by themselves (so that the
  // decision node starts them again); the process it cannot identify is not shown at all.
  for (const char* name : {"/reused", "/gone"})
  {
    const auto info = s.info(name);
    ASSERT_TRUE(info.has_value()) << name;
    EXPECT_EQ(info->state, ProcState::Exited);
    EXPECT_EQ(info->pid, 0);
    EXPECT_EQ(info->exit_code, -1);
    EXPECT_EQ(info->exit_signal, 0);
  }
  EXPECT_FALSE(s.info("/other").has_value());
  EXPECT_EQ(s.takeUnrequestedExits(), (std::vector<std::string>{"/reused", "/gone"}));
  EXPECT_TRUE(readNodeStateFile(path_)->nodes.empty());
  // A process it cannot identify is not its to end.
  s.poll();
  EXPECT_EQ(::kill(node.pid, 0), 0);
}

TEST_P(SupervisorAdopt, APausedNodeStaysPausedAndResumes)
{
  ForeignNode node({"/bin/sleep", "30"});
  ASSERT_GT(node.pid, 0);
  ASSERT_EQ(::kill(-node.pid, SIGSTOP), 0);
  const auto end = Clock::now() + std::chrono::seconds(2);
  while (procState(node.pid) != 'T' && Clock::now() < end)
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  NodeStateEntry e = node.entry("/spare");
  e.state = "paused";
  writeState(path_, {e});
  Supervisor s(options());
  ASSERT_EQ(s.adopt(path_).adopted.size(), 1u);
  EXPECT_EQ(s.info("/spare")->state, ProcState::Paused);
  EXPECT_EQ(procState(node.pid), 'T');
  std::string err;
  EXPECT_EQ(s.resume("/spare", &err), node.pid) << err;
  EXPECT_TRUE(waitUntil([&] { return procState(node.pid) == 'S'; }, 2.0, s));
  EXPECT_EQ(readNodeStateFile(path_)->nodes.at(0).state, "running");
}

TEST_P(SupervisorAdopt, ANodeItsPredecessorWasStoppingIsStopped)
{
  ForeignNode node({"/bin/sleep", "30"});
  ASSERT_GT(node.pid, 0);
  NodeStateEntry e = node.entry("/leaving");
  e.state = "stopping";
  writeState(path_, {e});
  Supervisor s(options());
  ASSERT_EQ(s.adopt(path_).adopted.size(), 1u);
  ASSERT_TRUE(s.waitGone("/leaving", 5.0));
  EXPECT_EQ(s.info("/leaving")->state, ProcState::Exited);
  EXPECT_TRUE(s.takeUnrequestedExits().empty());
}

INSTANTIATE_TEST_SUITE_P(Watch, SupervisorAdopt, ::testing::Values(true, false),
                         [](const auto& info) { return info.param ? "pidfd" : "proc"; });

TEST(SupervisorAdoptFile, AnUnusableFileIsOneWarningAndNoNode)
{
  TempDir dir;
  const std::string path = dir.path() + "/nodes.yaml";
  {
    std::ofstream f(path);
    f << "format: anyscale_agent_node_state/1\nboot_id: x\ncount: 1\nnodes:\n  - {name: /a, pi";
  }
  Supervisor s;
  const AdoptionReport report = s.adopt(path);
  EXPECT_NE(report.warning.find(path), std::string::npos) << report.warning;
  EXPECT_NE(report.warning.find("incomplete"), std::string::npos) << report.warning;
  EXPECT_TRUE(report.adopted.empty());
  EXPECT_TRUE(report.dropped.empty());
  // Replaced by a sound file at once.
  EXPECT_TRUE(readNodeStateFile(path)->nodes.empty());

  // No file at all: a first start, nothing to say.
  TempDir fresh;
  Supervisor first;
  const AdoptionReport none = first.adopt(fresh.path() + "/nodes.yaml");
  EXPECT_EQ(none.warning, "");
  EXPECT_TRUE(none.adopted.empty() && none.dropped.empty());
  // A file it cannot write: a warning, and the supervisor works on.
  Supervisor blind;
  const AdoptionReport unwritable = blind.adopt(fresh.path() + "/no/such/dir/nodes.yaml");
  EXPECT_NE(unwritable.warning.find("will not find"), std::string::npos) << unwritable.warning;
  std::string err;
  EXPECT_GT(blind.start("/n", {"/bin/sleep", "30"}, tempLog("blind"), &err), 0) << err;
  EXPECT_TRUE(blind.takeStateFileNotes().empty()) << "the same failure is said once";
}

TEST(SupervisorAdoptFile, EntriesFromAnotherBootAreDropped)
{
  TempDir dir;
  const std::string path = dir.path() + "/nodes.yaml";
  ForeignNode node({"/bin/sleep", "30"});
  NodeState s;
  s.boot_id = "00000000-0000-0000-0000-000000000000";
  s.nodes = {node.entry("/old")};
  std::string err;
  ASSERT_TRUE(writeNodeStateFile(path, s, &err)) << err;
  Supervisor sup;
  const AdoptionReport report = sup.adopt(path);
  EXPECT_TRUE(report.adopted.empty());
  ASSERT_EQ(report.dropped.size(), 1u);
  EXPECT_NE(report.dropped[0].find("earlier boot"), std::string::npos) << report.dropped[0];
  EXPECT_EQ(sup.info("/old")->state, ProcState::Exited);
}

TEST(SupervisorAdoptFile, NodesOfAKilledAgentLiveOnAndAreAdopted)
{
  // The orphaned node comes to this process, which reaps it (init would, here, only later).
  ASSERT_EQ(::prctl(PR_SET_CHILD_SUBREAPER, 1), 0);
  TempDir dir;
  const std::string path = dir.path() + "/nodes.yaml";
  const std::string log = tempLog("survivor");
  int fds[2];
  ASSERT_EQ(::pipe(fds), 0);
  const pid_t agent = ::fork();
  ASSERT_GE(agent, 0);
  if (agent == 0)
  {
    // A stand-in master-scale agent, SIGKILLed with a node running: no destructor, no stop.
    SupervisorOptions o;
    o.parent_death_signal = 0;
    Supervisor s(o);
    s.adopt(path);
    std::string err;
    int pid = s.start("/survivor", {"/bin/sleep", "30"}, log, &err);
    s.markRunning("/survivor");
    ssize_t w = ::write(fds[1], &pid, sizeof pid);
    (void)w;
    ::raise(SIGKILL);
  }
  ::close(fds[1]);
  int pid = 0;
  ASSERT_EQ(::read(fds[0], &pid, sizeof pid), ssize_t(sizeof pid));
  ::close(fds[0]);
  ASSERT_GT(pid, 0);
  int status;
  ::waitpid(agent, &status, 0);
  std::this_thread::sleep_for(std::chrono::milliseconds(200));
  ASSERT_EQ(::kill(pid, 0), 0) << "the node outlives its agent";
  ASSERT_EQ(procState(pid), 'S');

  Supervisor s;
  const AdoptionReport report = s.adopt(path);
  EXPECT_EQ(report.warning, "");
  ASSERT_EQ(report.adopted.size(), 1u) << (report.dropped.empty() ? "" : report.dropped[0]);
  EXPECT_EQ(report.adopted[0].info.pid, pid);
  EXPECT_EQ(report.adopted[0].info.state, ProcState::Running);
  EXPECT_EQ(report.adopted[0].info.log_file, log);
  ASSERT_TRUE(s.stop("/survivor"));
  ASSERT_TRUE(s.waitGone("/survivor", 10.0));
  EXPECT_TRUE(processGone(pid));
  // Re-parented to us, so this time the status is known.
  EXPECT_EQ(s.info("/survivor")->exit_signal, SIGINT);
  if (!processGone(pid))
    ::kill(pid, SIGKILL);  // never leave it behind, even when an assertion failed
}
