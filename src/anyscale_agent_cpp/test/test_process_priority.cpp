// Nice values set on every thread of a process, and back.
#include <gtest/gtest.h>

#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <thread>

#include "anyscale_agent_cpp/process_priority.h"

extern char** environ;

namespace
{
using anyscale_agent::inIdleScheduling;
using anyscale_agent::leaveIdleScheduling;
using anyscale_agent::setProcessNice;
using anyscale_agent::threadNices;

// A child with two threads (Python's main thread and one it starts), ended by the destructor.
class TwoThreadChild
{
public:
  // idle: the child puts itself in SCHED_IDLE first, as scripts/python_standby does.
  explicit TwoThreadChild(bool idle = false)
  {
    const char* argv[] = {
        "/usr/bin/python3", "-c",
        idle ? "import os, threading, time\n"
               "os.sched_setscheduler(0, os.SCHED_IDLE, os.sched_param(0))\n"
               "threading.Thread(target=time.sleep, args=(60,), daemon=True).start()\n"
               "time.sleep(60)\n"
             : "import threading, time\n"
               "threading.Thread(target=time.sleep, args=(60,), daemon=True).start()\n"
               "time.sleep(60)\n",
        nullptr};
    if (::posix_spawn(&pid_, argv[0], nullptr, nullptr, const_cast<char**>(argv), environ) != 0)
      pid_ = 0;
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(10);
    while (pid_ > 0 && threadNices(pid_).size() < 2 && std::chrono::steady_clock::now() < deadline)
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  ~TwoThreadChild()
  {
    if (pid_ > 0)
    {
      ::kill(pid_, SIGKILL);
      ::waitpid(pid_, nullptr, 0);
    }
  }
  pid_t pid() const { return pid_; }

private:
  pid_t pid_ = 0;
};
}  // namespace

TEST(ProcessPriority, NiceReachesEveryThread)
{
  TwoThreadChild child;
  ASSERT_GT(child.pid(), 0);
  ASSERT_EQ(threadNices(child.pid()).size(), 2u);
  std::string error;
  ASSERT_TRUE(setProcessNice(child.pid(), 7, &error)) << error;
  EXPECT_EQ(threadNices(child.pid()), (std::vector<int>{7, 7}));
}

TEST(ProcessPriority, BoostAndBackWithPrivilege)
{
  if (::geteuid() != 0)
    GTEST_SKIP() << "a negative nice needs root (CAP_SYS_NICE)";
  TwoThreadChild child;
  ASSERT_GT(child.pid(), 0);
  std::string error;
  ASSERT_TRUE(setProcessNice(child.pid(), -5, &error)) << error;
  EXPECT_EQ(threadNices(child.pid()), (std::vector<int>{-5, -5}));
  ASSERT_TRUE(setProcessNice(child.pid(), 0, &error)) << error;
  EXPECT_EQ(threadNices(child.pid()), (std::vector<int>{0, 0}));
}

TEST(ProcessPriority, GoneProcessIsAnError)
{
  pid_t pid = 0;
  const char* argv[] = {"/bin/true", nullptr};
  ASSERT_EQ(::posix_spawn(&pid, argv[0], nullptr, nullptr, const_cast<char**>(argv), environ), 0);
  ::waitpid(pid, nullptr, 0);
  std::string error;
  EXPECT_FALSE(setProcessNice(pid, 3, &error));
  EXPECT_NE(error.find("gone"), std::string::npos) << error;
  EXPECT_TRUE(threadNices(pid).empty());
  EXPECT_FALSE(leaveIdleScheduling(pid, &error));
  EXPECT_FALSE(inIdleScheduling(pid));
}

TEST(ProcessPriority, IdleThreadsLeaveSchedIdle)
{
  if (::geteuid() != 0)
    GTEST_SKIP() << "leaving SCHED_IDLE for another process needs root (CAP_SYS_NICE)";
  TwoThreadChild child(true);
  ASSERT_GT(child.pid(), 0);
  ASSERT_EQ(threadNices(child.pid()).size(), 2u);
  EXPECT_TRUE(inIdleScheduling(child.pid()));
  std::string error;
  ASSERT_TRUE(leaveIdleScheduling(child.pid(), &error)) << error;
  EXPECT_FALSE(inIdleScheduling(child.pid()));
  TwoThreadChild normal;
  EXPECT_FALSE(inIdleScheduling(normal.pid()));
  EXPECT_TRUE(leaveIdleScheduling(normal.pid(), &error)) << error;  // nothing to move
}
