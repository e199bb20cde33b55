// Periodic /proc and cgroup sampling: CPU and memory of the scale and of node process groups.
#pragma once

#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "anyscale_agent_cpp/proc_reader.h"

namespace anyscale_agent
{

struct ScaleUsage
{
  unsigned cores = 0;
  double cpu_max_ghz = 0.0;
  double quota_cores = 0.0;  // 0 = no cgroup CPU quota
  double cpu_percent = 0.0;  // of all cores, or of the quota when there is one
  uint64_t memory_total_bytes = 0;
  uint64_t memory_available_bytes = 0;
};

struct GroupUsage
{
  double cpu_percent = 0.0;  // of one core, top's convention
  uint64_t rss_bytes = 0;
  std::size_t processes = 0;
};

class SystemSampler
{
public:
  explicit SystemSampler(std::string proc_root = "/proc",
                         std::string cgroup_root = "/sys/fs/cgroup");

  // One pass over /proc at monotonic time `now_s`. Per group, CPU is utime+stime of every
  // process whose process group is `pgid` (rosmon's method): a node started through a wrapper
  // (rosrun, a shell script) is measured with its real worker, not as the idle wrapper.
  void sample(double now_s, const std::vector<int>& pgids);

  const ScaleUsage& scale() const { return scale_; }
  std::optional<GroupUsage> group(int pgid) const;
  double periodSeconds() const { return period_s_; }

private:
  void sampleQuota(const std::vector<ProcStat>& all, double elapsed);

  std::string proc_root_;
  std::string cgroup_root_;
  long ticks_per_s_;
  long page_bytes_;
  double last_t_ = -1.0;
  double period_s_ = 0.0;
  std::optional<CpuTimes> last_cpu_;
  std::map<int, CpuTimeTracker> group_trackers_;
  std::map<int, GroupUsage> groups_;
  CpuTimeTracker cgroup_tracker_;
  std::optional<uint64_t> last_cpuacct_ns_;
  ScaleUsage scale_;
};

}  // namespace anyscale_agent
