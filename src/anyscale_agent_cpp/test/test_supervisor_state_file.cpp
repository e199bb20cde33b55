// gtest: the supervisor's state file is written when its list of running nodes changes (not on
// lease renewals where nodes die with the agent), and outside the supervisor's lock.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <sys/stat.h>
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
#include "anyscale_agent_cpp/supervisor.h"
#include "supervisor_test_util.h"

using namespace anyscale_agent;
using namespace supervisor_test;

TEST(SupervisorStateFile, LeaseRenewalsAreWrittenOnlyWhereNodesOutliveTheAgent)
{
  for (const bool outlive : {false, true})
  {
    SCOPED_TRACE(outlive ? "nodes outlive the agent" : "nodes die with the agent");
    TempDir dir;
    const std::string path = dir.path() + "/nodes.yaml";
    SupervisorOptions o;
    if (outlive)
      o.parent_death_signal = 0;
    Supervisor s(o);
    s.adopt(path);
    std::string err;
    ASSERT_GT(s.start("/leased", {"/bin/sleep", "30"}, tempLog("leased"), &err), 0) << err;
    s.markRunning("/leased");
    const std::string untouched = "not written since\n";
    std::ofstream(path) << untouched;
    s.setLeaseEnds({{"/leased", 1234.5}});
    if (outlive)
      EXPECT_EQ(readNodeStateFile(path)->nodes.at(0).lease_end_s, 1234.5);
    else
      EXPECT_EQ(supervisor_test::readFile(path), untouched)
          << "a successor has no lease to enforce";
    // A change a successor needs is written, with the lease end only where it enforces one.
    ASSERT_TRUE(s.pause("/leased", &err)) << err;
    const NodeStateEntry e = readNodeStateFile(path)->nodes.at(0);
    EXPECT_EQ(e.state, "paused");
    EXPECT_EQ(e.lease_end_s, outlive ? 1234.5 : 0.0);
    ASSERT_TRUE(s.stop("/leased"));
    ASSERT_TRUE(s.waitGone("/leased", 10.0));
    EXPECT_TRUE(readNodeStateFile(path)->nodes.empty());
  }
}

TEST(SupervisorStateFile, QueriesDoNotWaitForTheFileToBeWritten)
{
  TempDir dir;
  const std::string path = dir.path() + "/nodes.yaml";
  Supervisor s;
  s.adopt(path);
  // A disk that does not answer: the next write blocks in open(2) of its temporary file, a
  // FIFO, until the FIFO has a reader.
  const std::string tmp = path + ".tmp";
  ASSERT_EQ(::mkfifo(tmp.c_str(), 0600), 0) << std::strerror(errno);
  std::atomic<bool> started{false};
  std::thread starter([&] {
    std::string err;
    s.start("/slow_disk", {"/bin/sleep", "30"}, tempLog("slow_disk"), &err);
    started = true;
  });
  auto listed = std::async(std::launch::async, [&] {
    const auto end = Clock::now() + std::chrono::seconds(5);
    for (; Clock::now() < end; std::this_thread::sleep_for(std::chrono::milliseconds(5)))
      if (const auto info = s.info("/slow_disk"); info && info->pid > 0)
        return true;
    return false;
  });
  const bool answered =
      listed.wait_for(std::chrono::seconds(6)) == std::future_status::ready && listed.get();
  EXPECT_TRUE(answered) << "a query waited for the state file's write";
  EXPECT_FALSE(started) << "the start returns once its write is done";

  // The disk answers: the FIFO, no file of the agent's, is replaced by one, with the node in it.
  const int fifo = ::open(tmp.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC);
  ASSERT_GE(fifo, 0) << std::strerror(errno);
  starter.join();
  ::close(fifo);
  EXPECT_TRUE(started);
  EXPECT_EQ(readNodeStateFile(path)->nodes.at(0).name, "/slow_disk");
  ASSERT_TRUE(s.stop("/slow_disk"));
  ASSERT_TRUE(s.waitGone("/slow_disk", 10.0));
  EXPECT_TRUE(readNodeStateFile(path)->nodes.empty());
}

TEST(SupervisorStateFile, LeaveRunningLetsTheNodesGoAndKeepsThemListedForASuccessor)
{
  TempDir dir;
  const std::string path = dir.path() + "/nodes.yaml";
  int pid = 0;
  {
    SupervisorOptions o;
    o.parent_death_signal = 0;
    Supervisor s(o);
    s.adopt(path);
    std::string err;
    pid = s.start("/driver", {"/bin/sleep", "30"}, tempLog("driver"), &err);
    ASSERT_GT(pid, 0) << err;
    s.markRunning("/driver");
    EXPECT_EQ(s.leaveRunning(), std::vector<std::string>{"/driver"});
    s.stopAll();  // as the agent's shutdown does after it: nothing left to stop
  }               // nor does the destructor stop it, nor write the file again
  EXPECT_EQ(::kill(pid, 0), 0) << "the node was stopped";
  const auto left = readNodeStateFile(path);
  ASSERT_TRUE(left && left->nodes.size() == 1);
  EXPECT_EQ(left->nodes[0].pid, pid);
  Supervisor successor;
  const AdoptionReport report = successor.adopt(path);
  ASSERT_EQ(report.adopted.size(), 1u) << (report.dropped.empty() ? "" : report.dropped[0]);
  ASSERT_TRUE(successor.stop("/driver"));
  EXPECT_TRUE(successor.waitGone("/driver", 10.0));
}
