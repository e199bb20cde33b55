// Parsing of /proc and /sys text into numbers the agent reports (no ROS; fixtures in gtest).
#pragma once

#include <cstdint>
#include <map>
#include <optional>
#include <set>
#include <string>
#include <vector>

namespace anyscale_agent
{

// The fields of /proc/PID/stat the agent needs. Times are in clock ticks (sysconf(_SC_CLK_TCK)).
struct ProcStat
{
  int pid = 0;
  std::string comm;
  char state = '?';
  int ppid = 0;
  int pgrp = 0;
  uint64_t utime = 0;
  uint64_t stime = 0;
  uint64_t start_time = 0;  // ticks after boot; tells a recycled pid from the one we saw before
  int64_t rss_pages = 0;
};

// Parses one /proc/PID/stat line. `comm` may hold spaces and parentheses, so the fields after
// it are located from the LAST ')' (proc(5)), never by splitting on spaces from the start.
std::optional<ProcStat> parseProcStat(const std::string& text);

// Aggregate jiffies of the "cpu" line of /proc/stat.
struct CpuTimes
{
  uint64_t busy = 0;
  uint64_t total = 0;
};
// iowait counts as idle, as top does; guest time is already included in user, so not added twice.
std::optional<CpuTimes> parseProcStatCpu(const std::string& text);

// Busy share of [0, 100] between two /proc/stat samples; 0 when no time passed.
double cpuPercentBetween(const CpuTimes& before, const CpuTimes& after);

struct MemInfo
{
  uint64_t total_bytes = 0;
  uint64_t available_bytes = 0;
};
std::optional<MemInfo> parseMemInfo(const std::string& text);

// Highest "cpu MHz" of /proc/cpuinfo in GHz, used when cpufreq's cpuinfo_max_freq is absent
// (virtual machines); 0 if none.
double parseCpuInfoMaxGhz(const std::string& text);

// Path of the cgroup v1 hierarchy holding `controller` from /proc/self/cgroup text
// ("4:cpu,cpuacct:/robot" -> "/robot"); nullopt if that controller is not listed.
std::optional<std::string> parseCgroupPath(const std::string& text, const std::string& controller);

// Reads a whole small file; nullopt if it cannot be read (process gone, no permission).
std::optional<std::string> readFile(const std::string& path);

// CPU time of a set of processes between samples. Kept per pid (and its start time, so a
// recycled pid starts from zero): summing the group's current totals and subtracting the last
// sum would go negative whenever a member exits, which is common with wrapper scripts.
class CpuTimeTracker
{
public:
  // Ticks consumed since the previous call by the processes in `now`; a process seen for the
  // first time contributes all its ticks (it started within the period, or is new to us).
  uint64_t update(const std::vector<ProcStat>& now);

private:
  std::map<std::pair<int, uint64_t>, uint64_t> last_;  // (pid, start_time) -> utime+stime
};

// One pass over /proc: the stat of every process (those that vanish meanwhile are skipped).
std::vector<ProcStat> readAllProcStats(const std::string& proc_root = "/proc");

}  // namespace anyscale_agent
