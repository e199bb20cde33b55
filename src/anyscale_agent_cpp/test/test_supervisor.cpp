// gtest: the supervisor with real child processes: exit codes, signals, escalation, no zombies.
// Its warm standbys are tested in test_supervisor_standby.cpp.
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <fstream>
#include <string>
#include <thread>

#include "anyscale_agent_cpp/process_priority.h"
#include "anyscale_agent_cpp/supervisor.h"
#include "supervisor_test_util.h"

using namespace anyscale_agent;
using namespace supervisor_test;

TEST(Supervisor, ReportsExitCodeOfUnrequestedExit)
{
  Supervisor s;
  std::string err;
  const int pid = s.start("quitter", sh("exit 3"), tempLog("quitter"), &err);
  ASSERT_GT(pid, 0) << err;
  ASSERT_TRUE(s.waitGone("quitter", 10.0));
  const auto info = s.info("quitter").value();
  EXPECT_EQ(info.state, ProcState::Exited);
  EXPECT_EQ(info.exit_code, 3);
  EXPECT_EQ(info.exit_signal, 0);
  EXPECT_EQ(info.pid, 0);
  EXPECT_TRUE(processGone(pid));
  const auto exits = s.takeUnrequestedExits();
  ASSERT_EQ(exits.size(), 1u);
  EXPECT_EQ(exits[0], "quitter");
  EXPECT_EQ(s.unrequestedExitCount(), 1u) << "taking the names leaves the count";
}

TEST(Supervisor, StopEndsWithSigintAndLeavesNoZombie)
{
  Supervisor s;
  std::string err;
  const int pid = s.start("sleeper", {"/bin/sleep", "30"}, tempLog("sleeper"), &err);
  ASSERT_GT(pid, 0) << err;
  EXPECT_EQ(getpgid(pid), pid);  // own process group (setsid)
  EXPECT_EQ(getsid(pid), pid);
  ASSERT_TRUE(s.stop("sleeper"));
  ASSERT_TRUE(s.waitGone("sleeper", 10.0));
  const auto info = s.info("sleeper").value();
  EXPECT_EQ(info.exit_signal, SIGINT);
  EXPECT_EQ(info.exit_code, -1);
  EXPECT_TRUE(processGone(pid));
  EXPECT_TRUE(s.takeUnrequestedExits().empty());
  EXPECT_EQ(s.unrequestedExitCount(), 0u);
}

TEST(Supervisor, ChildIgnoringSigintGetsSigterm)
{
  SupervisorOptions o;
  o.sigint_timeout_s = 0.3;
  o.sigterm_timeout_s = 5.0;
  Supervisor s(o);
  std::string err;
  // exec (not a child) so the trapped shell itself is the leader that must be ended.
  const int pid =
      s.start("stubborn", sh("trap '' INT; while :; do sleep 0.05; done"), tempLog("int"), &err);
  ASSERT_GT(pid, 0) << err;
  std::this_thread::sleep_for(std::chrono::milliseconds(200));  // let the trap be installed
  const auto t0 = Clock::now();
  s.stop("stubborn");
  ASSERT_TRUE(s.waitGone("stubborn", 10.0));
  EXPECT_GE(std::chrono::duration<double>(Clock::now() - t0).count(), 0.29);
  EXPECT_EQ(s.info("stubborn")->exit_signal, SIGTERM);
  EXPECT_TRUE(groupGone(pid));
}

TEST(Supervisor, ChildIgnoringSigintAndSigtermIsKilledAfterBothTimeouts)
{
  SupervisorOptions o;
  o.sigint_timeout_s = 0.3;
  o.sigterm_timeout_s = 0.3;
  Supervisor s(o);
  std::string err;
  const int pid =
      s.start("deaf", sh("trap '' INT TERM; while :; do sleep 0.05; done"), tempLog("deaf"), &err);
  ASSERT_GT(pid, 0) << err;
  std::this_thread::sleep_for(std::chrono::milliseconds(200));
  const auto t0 = Clock::now();
  s.stop("deaf");
  EXPECT_EQ(s.info("deaf")->state, ProcState::Stopping);
  ASSERT_TRUE(s.waitGone("deaf", 10.0));
  const double took = std::chrono::duration<double>(Clock::now() - t0).count();
  EXPECT_GE(took, 0.59);
  EXPECT_LT(took, 8.0);
  const auto info = s.info("deaf").value();
  EXPECT_EQ(info.exit_signal, SIGKILL);
  EXPECT_EQ(info.state, ProcState::Exited);
  // The sleep children ignored the signals too (SIG_IGN is inherited); the group must be empty.
  EXPECT_TRUE(waitUntil([&] { return groupGone(pid); }, 5.0, s));
}

TEST(Supervisor, ShortGraceGoesFromSigintStraightToSigkill)
{
  Supervisor s;  // staged defaults of 15 s + 2 s, which a migration's stop does not wait for
  std::string err;
  const int pid =
      s.start("slow", sh("trap '' INT TERM; while :; do sleep 0.05; done"), tempLog("slow"), &err);
  ASSERT_GT(pid, 0) << err;
  std::this_thread::sleep_for(std::chrono::milliseconds(200));
  const auto t0 = Clock::now();
  ASSERT_TRUE(s.stop("slow", ProcState::Exited, 0.3));
  ASSERT_TRUE(s.waitGone("slow", 10.0));
  const double took = std::chrono::duration<double>(Clock::now() - t0).count();
  EXPECT_GE(took, 0.29);
  EXPECT_LT(took, 1.5);
  EXPECT_EQ(s.info("slow")->exit_signal, SIGKILL);
  EXPECT_TRUE(waitUntil([&] { return groupGone(pid); }, 5.0, s));
}

TEST(Supervisor, KillNowCutsAStopShortButOnlyAStop)
{
  Supervisor s;
  std::string err;
  const int pid = s.start("lingering", sh("trap '' INT TERM; while :; do sleep 0.05; done"),
                          tempLog("linger"), &err);
  ASSERT_GT(pid, 0) << err;
  std::this_thread::sleep_for(std::chrono::milliseconds(200));
  EXPECT_FALSE(s.killNow("lingering"));  // not being stopped: left alone
  EXPECT_FALSE(s.killNow("unknown"));
  ASSERT_TRUE(s.stop("lingering", ProcState::Exited, 30.0));
  const auto t0 = Clock::now();
  ASSERT_TRUE(s.killNow("lingering"));
  ASSERT_TRUE(s.waitGone("lingering", 10.0));
  EXPECT_LT(std::chrono::duration<double>(Clock::now() - t0).count(), 1.5);  // not the 30 s grace
  const auto info = s.info("lingering").value();
  EXPECT_EQ(info.exit_signal, SIGKILL);
  EXPECT_EQ(info.state, ProcState::Exited);
  EXPECT_TRUE(waitUntil([&] { return groupGone(pid); }, 5.0, s));
}

TEST(Supervisor, ExpiredLeaseKillsAtOnceWithoutTheGracefulStages)
{
  Supervisor s;  // roslaunch's 15 s + 2 s grace: a lease end must not wait for them
  std::string err;
  const int pid = s.start("cut_off", sh("trap '' INT TERM; while :; do sleep 0.05; done"),
                          tempLog("cut"), &err);
  ASSERT_GT(pid, 0) << err;
  std::this_thread::sleep_for(std::chrono::milliseconds(200));
  const auto t0 = Clock::now();
  s.stop("cut_off", ProcState::LeaseExpired);
  ASSERT_TRUE(s.waitGone("cut_off", 10.0));
  EXPECT_LT(std::chrono::duration<double>(Clock::now() - t0).count(), 2.0);
  const auto info = s.info("cut_off").value();
  EXPECT_EQ(info.exit_signal, SIGKILL);
  EXPECT_EQ(info.state, ProcState::LeaseExpired);
  EXPECT_TRUE(waitUntil([&] { return groupGone(pid); }, 5.0, s));
}

TEST(Supervisor, GrandchildrenOfAnExitedLeaderAreCleared)
{
  // sh runs '&' jobs with SIGINT ignored (POSIX), so these need the SIGTERM stage.
  SupervisorOptions o;
  o.sigint_timeout_s = 0.3;
  Supervisor s(o);
  std::string err;
  const int pid = s.start("forker", sh("sleep 30 & sleep 30 & exit 0"), tempLog("forker"), &err);
  ASSERT_GT(pid, 0) << err;
  ASSERT_TRUE(s.waitGone("forker", 10.0));
  EXPECT_EQ(s.info("forker")->exit_code, 0);
  EXPECT_TRUE(waitUntil([&] { return groupGone(pid); }, 10.0, s));
}

TEST(Supervisor, RefusesBadStarts)
{
  Supervisor s;
  std::string err;
  EXPECT_EQ(s.start("x", {"/nonexistent/bin/thing"}, tempLog("x"), &err), 0);
  EXPECT_NE(err.find("No such file"), std::string::npos) << err;
  EXPECT_EQ(s.start("x", {"sleep", "1"}, tempLog("x"), &err), 0);
  EXPECT_NE(err.find("absolute"), std::string::npos) << err;
  EXPECT_EQ(s.start("x", {"/bin/sleep", "1"}, "/nonexistent/dir/x.log", &err), 0);
  EXPECT_NE(err.find("log file"), std::string::npos) << err;
  ASSERT_GT(s.start("dup", {"/bin/sleep", "30"}, tempLog("dup"), &err), 0);
  EXPECT_EQ(s.start("dup", {"/bin/sleep", "30"}, tempLog("dup"), &err), 0);
  EXPECT_NE(err.find("already running"), std::string::npos) << err;
  EXPECT_FALSE(s.stop("never_started"));
}

TEST(Supervisor, OutputGoesToTheLogFile)
{
  const std::string log = tempLog("out");
  std::remove(log.c_str());
  Supervisor s;
  std::string err;
  ASSERT_GT(s.start("echo", sh("echo hello-out; echo hello-err >&2"), log, &err), 0) << err;
  ASSERT_TRUE(s.waitGone("echo", 10.0));
  const std::string out = supervisor_test::readFile(log);
  EXPECT_NE(out.find("hello-out"), std::string::npos);
  EXPECT_NE(out.find("hello-err"), std::string::npos);
  EXPECT_EQ(s.info("echo")->log_file, log);
}

TEST(Supervisor, ALinkAtTheLogFileIsNotWrittenThrough)
{
  supervisor_test::TempDir elsewhere;
  const std::string victim = elsewhere.path() + "/victim";
  std::ofstream(victim) << "precious\n";
  Supervisor s;
  std::string err;
  for (const std::string tag : {"symlinked", "hardlinked"})
  {
    const std::string log = tempLog(tag);
    std::remove(log.c_str());
    ASSERT_EQ(tag == "symlinked" ? ::symlink(victim.c_str(), log.c_str())
                                 : ::link(victim.c_str(), log.c_str()),
              0);
    EXPECT_EQ(s.start(tag, sh("echo appended"), log, &err), 0) << tag;
    EXPECT_NE(err.find("log file"), std::string::npos) << err;
  }
  EXPECT_EQ(supervisor_test::readFile(victim), "precious\n");
}

namespace
{
// The nice of a node the supervisor starts when the supervisor was made on a thread running at
// `agent_nice` (nice is per thread on Linux, and the supervisor's spawn thread inherits it).
std::vector<int> nicesOfNodeStartedAt(int agent_nice, int child_nice)
{
  std::vector<int> nices;
  std::thread agent([&] {
    if (::setpriority(PRIO_PROCESS, 0, agent_nice) != 0)
      return;
    SupervisorOptions o;
    o.child_nice = child_nice;
    Supervisor s(o);
    std::string err;
    const int pid = s.start("niced", {"/bin/sleep", "30"}, tempLog("niced"), &err);
    if (pid > 0)
      nices = threadNices(pid);
  });
  agent.join();
  return nices;
}
}  // namespace

TEST(Supervisor, NodesStartAtTheChildNiceNotTheAgents)
{
  const int base = ::getpriority(PRIO_PROCESS, 0);
  if (base > 12)
    GTEST_SKIP() << "the test runs at nice " << base << ": no room to set two higher values";
  // Raising a nice value needs no privilege: an agent at base + 2, its node at base + 5.
  EXPECT_EQ(nicesOfNodeStartedAt(base + 2, base + 5), std::vector<int>{base + 5});
}

TEST(Supervisor, NodesDoNotInheritTheAgentsRaisedPriority)
{
  if (::geteuid() != 0)
    GTEST_SKIP() << "a negative nice (the agent's ~control_nice) needs root (CAP_SYS_NICE)";
  EXPECT_EQ(nicesOfNodeStartedAt(-4, 0), std::vector<int>{0});
}

TEST(Supervisor, DestructorStopsEverything)
{
  int pid = 0;
  {
    Supervisor s;
    std::string err;
    pid = s.start("left", {"/bin/sleep", "30"}, tempLog("left"), &err);
    ASSERT_GT(pid, 0) << err;
  }
  EXPECT_TRUE(processGone(pid));
}

TEST(Supervisor, RestartAfterExitIsAllowedAndMarkRunning)
{
  Supervisor s;
  std::string err;
  ASSERT_GT(s.start("n", {"/bin/sleep", "30"}, tempLog("n"), &err), 0);
  s.markRunning("n");
  EXPECT_EQ(s.info("n")->state, ProcState::Running);
  EXPECT_FALSE(s.setFinalState("n", ProcState::Replaced));  // still alive
  s.stop("n");
  ASSERT_TRUE(s.waitGone("n", 10.0));
  EXPECT_TRUE(s.setFinalState("n", ProcState::Replaced));
  EXPECT_EQ(s.info("n")->state, ProcState::Replaced);
  const int pid2 = s.start("n", {"/bin/sleep", "30"}, tempLog("n"), &err);
  EXPECT_GT(pid2, 0) << err;
  EXPECT_EQ(s.info("n")->state, ProcState::Starting);
}

TEST(Supervisor, ChildrenDieWithAKilledAgent)
{
  int fds[2];
  ASSERT_EQ(pipe(fds), 0);
  const pid_t agent = fork();
  ASSERT_GE(agent, 0);
  if (agent == 0)
  {
    // A stand-in agent that is SIGKILLed with a node running: no destructor, no stop.
    Supervisor s;
    std::string err;
    int pid = s.start("orphan", {"/bin/sleep", "30"}, tempLog("orphan"), &err);
    ssize_t w = write(fds[1], &pid, sizeof pid);
    (void)w;
    raise(SIGKILL);
  }
  close(fds[1]);
  int child = 0;
  ASSERT_EQ(read(fds[0], &child, sizeof child), ssize_t(sizeof child));
  close(fds[0]);
  ASSERT_GT(child, 0);
  int status;
  waitpid(agent, &status, 0);
  // Dead means gone, or a zombie waiting for whoever reaps it (init, or this test process if
  // an earlier test made it a subreaper).
  auto dead = [&] {
    std::ifstream f("/proc/" + std::to_string(child) + "/stat");
    if (!f)
      return true;
    std::string pid_s, comm, state;
    f >> pid_s >> comm >> state;  // comm is "(sleep)": no spaces
    if (state == "Z")
    {
      waitpid(child, &status, WNOHANG);
      return true;
    }
    return false;
  };
  const auto end = Clock::now() + std::chrono::seconds(10);
  while (!dead() && Clock::now() < end)
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  EXPECT_TRUE(dead());
  ::kill(child, SIGKILL);  // never leave it behind, even when the assertion failed
}
