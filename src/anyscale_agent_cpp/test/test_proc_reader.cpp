// gtest: /proc text parsing from fixtures, and CPU accounting across process exits.
#include <gtest/gtest.h>
#include <unistd.h>

#include "anyscale_agent_cpp/proc_reader.h"

using namespace anyscale_agent;

TEST(ProcStat, ParsesCommWithSpacesAndParentheses)
{
  // comm "a) (b c" : a naive split on spaces or on the first ')' shifts every later field.
  const std::string text =
      "4242 (a) (b c) S 1 4242 4242 0 -1 4194560 100 0 0 0 250 75 3 4 20 0 1 0 123456 1000000 "
      "321 18446744073709551615 1 1 0 0 0 0 0 0 0 0 0 0 17 1 0 0 0 0 0\n";
  const auto s = parseProcStat(text);
  ASSERT_TRUE(s);
  EXPECT_EQ(s->pid, 4242);
  EXPECT_EQ(s->comm, "a) (b c");
  EXPECT_EQ(s->state, 'S');
  EXPECT_EQ(s->ppid, 1);
  EXPECT_EQ(s->pgrp, 4242);
  EXPECT_EQ(s->utime, 250u);
  EXPECT_EQ(s->stime, 75u);
  EXPECT_EQ(s->start_time, 123456u);
  EXPECT_EQ(s->rss_pages, 321);
}

TEST(ProcStat, RejectsTruncatedOrGarbage)
{
  EXPECT_FALSE(parseProcStat(""));
  EXPECT_FALSE(parseProcStat("12 (x) S 1 2"));
  EXPECT_FALSE(parseProcStat("abc (x) S 1 2 3 4 5 6 7 8 9 10 11 12 13 14 15 16 17 18 19 20 21 22"));
  EXPECT_FALSE(parseProcStat("12 x S 1 2 3 4 5 6 7 8 9 10 11 12 13 14 15 16 17 18 19 20 21 22"));
}

TEST(ProcStat, ReadsOwnProcess)
{
  const auto text = readFile("/proc/self/stat");
  ASSERT_TRUE(text);
  const auto s = parseProcStat(*text);
  ASSERT_TRUE(s);
  EXPECT_EQ(s->pid, getpid());
  EXPECT_GT(s->rss_pages, 0);
}

TEST(ProcStatCpu, BusyExcludesIdleAndIowait)
{
  const std::string a = "cpu  100 10 50 800 40 0 0 0 0 0\ncpu0 50 5 25 400 20 0 0 0 0 0\nintr 1\n";
  const std::string b =
      "cpu  200 10 100 950 40 0 0 0 0 0\ncpu0 100 5 50 475 20 0 0 0 0 0\nintr 1\n";
  const auto ta = parseProcStatCpu(a), tb = parseProcStatCpu(b);
  ASSERT_TRUE(ta && tb);
  EXPECT_EQ(ta->total, 1000u);
  EXPECT_EQ(ta->busy, 160u);
  // 150 busy of 300 jiffies.
  EXPECT_DOUBLE_EQ(cpuPercentBetween(*ta, *tb), 50.0);
  EXPECT_DOUBLE_EQ(cpuPercentBetween(*tb, *ta), 0.0);  // counters never go back; no negative
  EXPECT_FALSE(parseProcStatCpu("intr 1 2 3\n"));
}

TEST(MemInfo, TotalAndAvailableInBytes)
{
  const auto m =
      parseMemInfo("MemTotal:       24576000 kB\nMemFree:  100 kB\nMemAvailable:   12288000 kB\n");
  ASSERT_TRUE(m);
  EXPECT_EQ(m->total_bytes, 24576000ull * 1024);
  EXPECT_EQ(m->available_bytes, 12288000ull * 1024);
  EXPECT_FALSE(parseMemInfo("MemTotal: 5 kB\n"));
}

TEST(CpuInfo, HighestClockInGhz)
{
  EXPECT_DOUBLE_EQ(parseCpuInfoMaxGhz("cpu MHz\t\t: 1600.000\nfoo: 1\ncpu MHz\t\t: 2800.5\n"),
                   2.8005);
  EXPECT_DOUBLE_EQ(parseCpuInfoMaxGhz("model name: x\n"), 0.0);
}

TEST(Cgroup, FindsControllerPath)
{
  const std::string text = "4:memory:/m\n3:cpu,cpuacct:/robot\n0::/\n";
  EXPECT_EQ(parseCgroupPath(text, "cpu").value(), "/robot");
  EXPECT_EQ(parseCgroupPath(text, "cpuacct").value(), "/robot");
  EXPECT_FALSE(parseCgroupPath(text, "pids"));
}

TEST(CpuTimeTracker, SurvivesExitAndPidReuse)
{
  CpuTimeTracker t;
  ProcStat a;
  a.pid = 10;
  a.start_time = 1;
  a.utime = 100;
  ProcStat b = a;
  b.pid = 11;
  b.utime = 50;
  EXPECT_EQ(t.update({a, b}), 150u);
  a.utime = 130;
  // b exited: the group's total dropped, but the period's usage is still a's 30 ticks.
  EXPECT_EQ(t.update({a}), 30u);
  // pid 10 reused by a new process (other start time): counted from zero, not as 5 - 130.
  ProcStat reused = a;
  reused.start_time = 99;
  reused.utime = 5;
  EXPECT_EQ(t.update({reused}), 5u);
}
