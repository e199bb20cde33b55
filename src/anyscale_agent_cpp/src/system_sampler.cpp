// Scale and process-group CPU/memory from /proc, and CPU use under a cgroup v1 quota.
#include "anyscale_agent_cpp/system_sampler.h"

#include <unistd.h>

#include <algorithm>
#include <set>
#include <sstream>

namespace anyscale_agent
{

SystemSampler::SystemSampler(std::string proc_root, std::string cgroup_root)
  : proc_root_(std::move(proc_root)),
    cgroup_root_(std::move(cgroup_root)),
    ticks_per_s_(::sysconf(_SC_CLK_TCK)),
    page_bytes_(::sysconf(_SC_PAGESIZE))
{
  const long online = ::sysconf(_SC_NPROCESSORS_ONLN);
  scale_.cores = online > 0 ? unsigned(online) : 1;
  // cpufreq is absent on most virtual machines; /proc/cpuinfo's current clock is the fallback.
  if (auto khz = readFile("/sys/devices/system/cpu/cpu0/cpufreq/cpuinfo_max_freq"))
  {
    try
    {
      scale_.cpu_max_ghz = std::stod(*khz) / 1e6;
    }
    catch (const std::exception&)
    {}
  }
  if (scale_.cpu_max_ghz <= 0.0)
    if (auto info = readFile(proc_root_ + "/cpuinfo"))
      scale_.cpu_max_ghz = parseCpuInfoMaxGhz(*info);
}

std::optional<GroupUsage> SystemSampler::group(int pgid) const
{
  const auto it = groups_.find(pgid);
  if (it == groups_.end())
    return std::nullopt;
  return it->second;
}

void SystemSampler::sample(double now_s, const std::vector<int>& pgids)
{
  const double elapsed = last_t_ < 0.0 ? 0.0 : now_s - last_t_;
  last_t_ = now_s;
  period_s_ = elapsed;

  if (auto mem = readFile(proc_root_ + "/meminfo"))
    if (auto m = parseMemInfo(*mem))
    {
      scale_.memory_total_bytes = m->total_bytes;
      scale_.memory_available_bytes = m->available_bytes;
    }
  std::optional<CpuTimes> cpu;
  if (auto stat = readFile(proc_root_ + "/stat"))
    cpu = parseProcStatCpu(*stat);
  if (cpu && last_cpu_)
    scale_.cpu_percent = cpuPercentBetween(*last_cpu_, *cpu);
  last_cpu_ = cpu;

  const std::vector<ProcStat> all = readAllProcStats(proc_root_);
  std::map<int, std::vector<ProcStat>> by_group;
  const std::set<int> wanted(pgids.begin(), pgids.end());
  for (const auto& p : all)
    if (wanted.count(p.pgrp))
      by_group[p.pgrp].push_back(p);

  std::map<int, GroupUsage> groups;
  std::map<int, CpuTimeTracker> trackers;
  for (int pgid : pgids)
  {
    CpuTimeTracker& tracker = trackers[pgid];
    if (auto it = group_trackers_.find(pgid); it != group_trackers_.end())
      tracker = std::move(it->second);
    const bool first = group_trackers_.count(pgid) == 0;
    GroupUsage g;
    const auto& members = by_group[pgid];
    const uint64_t ticks = tracker.update(members);
    // The first sample of a group has no period to divide by; it reports 0 rather than its
    // lifetime total as if spent in one period.
    if (!first && elapsed > 0.0)
      g.cpu_percent = 100.0 * double(ticks) / double(ticks_per_s_) / elapsed;
    for (const auto& p : members)
      g.rss_bytes += uint64_t(std::max<int64_t>(p.rss_pages, 0)) * uint64_t(page_bytes_);
    g.processes = members.size();
    groups[pgid] = g;
  }
  group_trackers_.swap(trackers);
  groups_.swap(groups);
  sampleQuota(all, elapsed);
}

void SystemSampler::sampleQuota(const std::vector<ProcStat>& all, double elapsed)
{
  const auto cgroups = readFile(proc_root_ + "/self/cgroup");
  const auto cpu_path = cgroups ? parseCgroupPath(*cgroups, "cpu") : std::nullopt;
  if (!cpu_path)
  {
    scale_.quota_cores = 0.0;
    return;
  }
  const std::string dir = cgroup_root_ + "/cpu" + *cpu_path;
  double quota = 0.0;
  const auto q = readFile(dir + "/cpu.cfs_quota_us");
  const auto p = readFile(dir + "/cpu.cfs_period_us");
  try
  {
    if (q && p && std::stol(*q) > 0 && std::stol(*p) > 0)
      quota = double(std::stol(*q)) / double(std::stol(*p));
  }
  catch (const std::exception&)
  {}
  scale_.quota_cores = quota;
  if (quota <= 0.0)
    return;

  // Usage of the quota's group: cpuacct.usage when cpuacct puts us in the same group; else
  // the summed CPU time of the group's processes (the test bed makes its groups under cpu only).
  double used_s = -1.0;
  const auto acct_path = parseCgroupPath(*cgroups, "cpuacct");
  if (acct_path && *acct_path == *cpu_path)
  {
    const std::string acct_dir = cgroup_root_ + "/cpuacct" + *acct_path;
    const auto acct_file = readFile(acct_dir + "/cpuacct.usage");
    const auto merged_file = acct_file ? acct_file : readFile(dir + "/cpuacct.usage");
    try
    {
      if (merged_file)
      {
        const uint64_t ns = std::stoull(*merged_file);
        if (last_cpuacct_ns_ && ns >= *last_cpuacct_ns_)
          used_s = double(ns - *last_cpuacct_ns_) / 1e9;
        last_cpuacct_ns_ = ns;
      }
    }
    catch (const std::exception&)
    {}
  }
  if (used_s < 0.0)
  {
    std::set<int> members;
    if (auto procs = readFile(dir + "/cgroup.procs"))
    {
      std::istringstream in(*procs);
      for (int pid; in >> pid;)
        members.insert(pid);
    }
    std::vector<ProcStat> in_group;
    for (const auto& s : all)
      if (members.count(s.pid))
        in_group.push_back(s);
    used_s = double(cgroup_tracker_.update(in_group)) / double(ticks_per_s_);
  }
  if (elapsed > 0.0)
    scale_.cpu_percent = std::clamp(100.0 * used_s / elapsed / quota, 0.0, 100.0);
}

}  // namespace anyscale_agent
