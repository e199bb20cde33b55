// gtest: pausing a running node (SIGSTOP) and resuming it (SIGCONT), with real child processes.
#include <gtest/gtest.h>
#include <signal.h>
#include <unistd.h>

#include <chrono>
#include <string>
#include <thread>

#include "anyscale_agent_cpp/supervisor.h"
#include "supervisor_test_util.h"

using namespace anyscale_agent;
using namespace supervisor_test;

namespace
{
std::size_t fileSize(const std::string& path)
{
  return supervisor_test::readFile(path).size();
}
}  // namespace

TEST(SupervisorPause, APausedNodeDoesNothingAndResumesWhereItWas)
{
  Supervisor s;
  std::string err;
  const std::string ticks = tempLog("ticks") + ".out";
  const int pid = s.start("ticker", sh("while true; do echo x >> " + ticks + "; sleep 0.02; done"),
                          tempLog("ticker"), &err);
  ASSERT_GT(pid, 0) << err;
  s.markRunning("ticker");
  ASSERT_TRUE(waitUntil([&] { return fileSize(ticks) > 0; }, 5.0, s));

  ASSERT_TRUE(s.pause("ticker", &err)) << err;
  EXPECT_EQ(s.info("ticker")->state, ProcState::Paused);
  ASSERT_TRUE(waitUntil([&] { return groupStopped(pid); }, 2.0, s))
      << "leader's state " << procState(pid);
  const std::size_t paused_at = fileSize(ticks);
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  s.poll();
  EXPECT_EQ(fileSize(ticks), paused_at) << "a paused group must not run";
  EXPECT_EQ(s.info("ticker")->pid, pid);

  EXPECT_EQ(s.resume("ticker", &err), pid) << err;
  EXPECT_EQ(s.info("ticker")->state, ProcState::Running);
  EXPECT_TRUE(waitUntil([&] { return fileSize(ticks) > paused_at; }, 2.0, s));
  EXPECT_TRUE(s.takeUnrequestedExits().empty());
}

TEST(SupervisorPause, OnlyARunningNodeIsPausedAndOnlyAPausedOneResumed)
{
  Supervisor s;
  std::string err;
  EXPECT_FALSE(s.pause("nobody", &err));
  EXPECT_NE(err.find("not running"), std::string::npos) << err;
  ASSERT_GT(s.start("young", {"/bin/sleep", "30"}, tempLog("young"), &err), 0) << err;
  // Still starting: not registered yet, so there is no instance in use to keep.
  EXPECT_FALSE(s.pause("young", &err));
  EXPECT_NE(err.find("starting"), std::string::npos) << err;
  s.markRunning("young");
  EXPECT_EQ(s.resume("young", &err), 0);
  EXPECT_NE(err.find("not paused"), std::string::npos) << err;
  ASSERT_TRUE(s.pause("young", &err)) << err;
  EXPECT_FALSE(s.pause("young", &err)) << "paused twice";
}

TEST(SupervisorPause, AStopEndsAPausedNodeWithItsOwnCleanShutdown)
{
  SupervisorOptions o;
  o.sigint_timeout_s = 5.0;
  Supervisor s(o);
  std::string err;
  const int pid = s.start("sleeper", {"/bin/sleep", "30"}, tempLog("paused_sleeper"), &err);
  ASSERT_GT(pid, 0) << err;
  s.markRunning("sleeper");
  ASSERT_TRUE(s.pause("sleeper", &err)) << err;
  ASSERT_TRUE(s.stop("sleeper"));
  const auto began = Clock::now();
  ASSERT_TRUE(s.waitGone("sleeper", 10.0));
  // SIGINT reached it (it was continued), well before the SIGTERM stage.
  EXPECT_EQ(s.info("sleeper")->exit_signal, SIGINT);
  EXPECT_LT(std::chrono::duration<double>(Clock::now() - began).count(), 2.0);
  EXPECT_TRUE(processGone(pid));
  EXPECT_TRUE(s.takeUnrequestedExits().empty());
}

TEST(SupervisorPause, APausedNodeKilledFromOutsideIsNoNodeExit)
{
  Supervisor s;
  std::string err;
  const int pid = s.start("victim", {"/bin/sleep", "30"}, tempLog("victim"), &err);
  ASSERT_GT(pid, 0) << err;
  s.markRunning("victim");
  ASSERT_TRUE(s.pause("victim", &err)) << err;
  ASSERT_EQ(::kill(pid, SIGKILL), 0);
  ASSERT_TRUE(s.waitGone("victim", 5.0));
  // The node runs on another scale: the paused instance was a spare, not the node.
  EXPECT_TRUE(s.takeUnrequestedExits().empty());
  EXPECT_EQ(s.resume("victim", &err), 0);
  // And the slot is free for a fresh start.
  EXPECT_GT(s.start("victim", {"/bin/sleep", "30"}, tempLog("victim2"), &err), 0) << err;
}

TEST(SupervisorPause, TheDestructorEndsPausedNodes)
{
  int pid = 0;
  {
    Supervisor s;
    std::string err;
    pid = s.start("held", {"/bin/sleep", "30"}, tempLog("held"), &err);
    ASSERT_GT(pid, 0) << err;
    s.markRunning("held");
    ASSERT_TRUE(s.pause("held", &err)) << err;
  }
  EXPECT_TRUE(processGone(pid));
}
