// gtest: the supervisor's warm standbys with real child processes: waiting beside the node,
// activation into a node, and ends that are no node exits.
#include <gtest/gtest.h>

#include <chrono>
#include <cstdio>
#include <string>
#include <thread>
#include <vector>

#include "anyscale_agent_cpp/supervisor.h"
#include "supervisor_test_util.h"

using namespace anyscale_agent;
using namespace supervisor_test;

static bool standbyGone(Supervisor& s, const std::string& name)
{
  return waitUntil([&] { return !s.standby(name) || s.standby(name)->pid == 0; }, 10.0, s);
}

TEST(Supervisor, StandbyWaitsForActivationThenRunsAsANode)
{
  const std::string log = tempLog("standby");
  std::remove(log.c_str());
  Supervisor s;
  std::string err;
  const int pid = s.startStandby("warm", sh("read line; echo \"got:$line\"; exit 4"), log, &err);
  ASSERT_GT(pid, 0) << err;
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  EXPECT_EQ(s.standby("warm")->state, ProcState::Standby);
  EXPECT_FALSE(s.info("warm")) << "a standby is no node";
  EXPECT_EQ(supervisor_test::readFile(log), "");  // still waiting
  EXPECT_EQ(s.startStandby("warm", {"/bin/true"}, log, &err), 0) << "one standby per node";

  EXPECT_EQ(s.activate("warm", &err), pid) << err;
  EXPECT_EQ(s.info("warm")->state, ProcState::Starting);
  EXPECT_FALSE(s.standby("warm")) << "the standby became the node";
  ASSERT_TRUE(s.waitGone("warm", 10.0));
  EXPECT_EQ(supervisor_test::readFile(log), "got:start\n");
  EXPECT_EQ(s.info("warm")->exit_code, 4);
  // Once activated it is a node like any other: its own exit is reported.
  EXPECT_EQ(s.takeUnrequestedExits(), std::vector<std::string>{"warm"});
}

TEST(Supervisor, StandbyWaitsBesideTheRunningNodeAndTakesOverWhenItHasGone)
{
  Supervisor s;
  std::string err;
  const int node = s.start("n", {"/bin/sleep", "30"}, tempLog("n"), &err);
  ASSERT_GT(node, 0) << err;
  const int standby = s.startStandby("n", sh("read line; sleep 30"), tempLog("n_standby"), &err);
  ASSERT_GT(standby, 0) << err;
  EXPECT_EQ(s.info("n")->pid, node);
  EXPECT_EQ(s.standby("n")->pid, standby);
  EXPECT_EQ(s.snapshot().size(), 2u);  // the node, then its standby
  EXPECT_EQ(s.activate("n", &err), 0);
  EXPECT_NE(err.find("still runs"), std::string::npos) << err;
  ASSERT_TRUE(s.stop("n"));
  ASSERT_TRUE(s.waitGone("n", 10.0));
  EXPECT_EQ(s.standby("n")->pid, standby) << "stopping the node leaves its standby";
  EXPECT_EQ(s.activate("n", &err), standby) << err;
  EXPECT_EQ(s.info("n")->pid, standby);
  s.stop("n");
  ASSERT_TRUE(s.waitGone("n", 10.0));
}

TEST(Supervisor, StandbyThatEndsIsNoNodeExitAndCannotBeActivated)
{
  Supervisor s;
  std::string err;
  ASSERT_GT(s.startStandby("broken", sh("exit 1"), tempLog("broken"), &err), 0) << err;
  ASSERT_TRUE(standbyGone(s, "broken"));
  EXPECT_TRUE(s.takeUnrequestedExits().empty());
  EXPECT_EQ(s.activate("broken", &err), 0);
  EXPECT_NE(err.find("no warm standby"), std::string::npos) << err;

  ASSERT_GT(s.start("plain", {"/bin/sleep", "30"}, tempLog("plain"), &err), 0) << err;
  EXPECT_EQ(s.activate("plain", &err), 0) << "a running node is no standby";
  s.stop("plain");
  ASSERT_TRUE(s.waitGone("plain", 10.0));
}

TEST(Supervisor, StoppedStandbyEndsAndIsNoNodeExit)
{
  Supervisor s;
  std::string err;
  const int pid = s.startStandby("waiting", sh("read line; sleep 30"), tempLog("waiting"), &err);
  ASSERT_GT(pid, 0) << err;
  EXPECT_FALSE(s.stop("waiting")) << "stop() is for nodes";
  ASSERT_TRUE(s.stopStandby("waiting"));
  ASSERT_TRUE(standbyGone(s, "waiting"));
  EXPECT_TRUE(processGone(pid));
  EXPECT_TRUE(s.takeUnrequestedExits().empty());
}

TEST(Supervisor, DestructorEndsStandbysToo)
{
  int pid = 0;
  {
    Supervisor s;
    std::string err;
    pid = s.startStandby("left_waiting", sh("read line; sleep 30"), tempLog("left_waiting"), &err);
    ASSERT_GT(pid, 0) << err;
  }
  EXPECT_TRUE(processGone(pid));
}
