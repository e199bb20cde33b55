// Parsing of /proc/stat, /proc/PID/stat, /proc/meminfo, /proc/cpuinfo and /proc/self/cgroup.
#include "anyscale_agent_cpp/proc_reader.h"

#include <dirent.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cstdlib>
#include <fstream>
#include <memory>
#include <sstream>

namespace anyscale_agent
{

std::optional<ProcStat> parseProcStat(const std::string& text)
{
  const auto open = text.find('(');
  const auto close = text.rfind(')');
  if (open == std::string::npos || close == std::string::npos || close < open)
    return std::nullopt;
  ProcStat s;
  char* end = nullptr;
  s.pid = int(std::strtol(text.c_str(), &end, 10));
  if (end == text.c_str() || s.pid <= 0)
    return std::nullopt;
  s.comm = text.substr(open + 1, close - open - 1);
  // Fields after comm, counted from 0 = field 3 (state) of proc(5). Read with strtoull rather
  // than a stream: the agent parses every process's stat each sample period.
  const char* p = text.c_str() + close + 1;
  while (*p == ' ')
    ++p;
  if (*p == '\0' || (p[1] != ' ' && p[1] != '\0'))
    return std::nullopt;
  s.state = *p++;
  uint64_t f[22] = {};
  for (int i = 1; i < 22; ++i)
  {
    char* next = nullptr;
    errno = 0;
    const long long v = std::strtoll(p, &next, 10);
    if (next == p || errno != 0)
      return std::nullopt;
    f[i] = uint64_t(v);
    p = next;
  }
  s.ppid = int(f[1]);
  s.pgrp = int(f[2]);
  s.utime = f[11];
  s.stime = f[12];
  s.start_time = f[19];
  s.rss_pages = int64_t(f[21]);
  return s;
}

std::optional<CpuTimes> parseProcStatCpu(const std::string& text)
{
  std::istringstream in(text);
  std::string line;
  while (std::getline(in, line))
  {
    std::istringstream ls(line);
    std::string label;
    ls >> label;
    if (label != "cpu")
      continue;
    std::vector<uint64_t> v;
    for (uint64_t x; ls >> x;)
      v.push_back(x);
    if (v.size() < 4)
      return std::nullopt;
    v.resize(8, 0);  // user nice system idle iowait irq softirq steal
    CpuTimes t;
    const uint64_t idle = v[3] + v[4];
    for (std::size_t i = 0; i < 8; ++i)
      t.total += v[i];
    t.busy = t.total - idle;
    return t;
  }
  return std::nullopt;
}

double cpuPercentBetween(const CpuTimes& before, const CpuTimes& after)
{
  if (after.total <= before.total || after.busy < before.busy)
    return 0.0;
  const double pct = 100.0 * double(after.busy - before.busy) / double(after.total - before.total);
  return std::clamp(pct, 0.0, 100.0);
}

std::optional<MemInfo> parseMemInfo(const std::string& text)
{
  std::istringstream in(text);
  std::string key;
  uint64_t kb = 0;
  std::string unit;
  std::optional<uint64_t> total, available;
  std::string line;
  while (std::getline(in, line))
  {
    std::istringstream ls(line);
    if (!(ls >> key >> kb))
      continue;
    if (key == "MemTotal:")
      total = kb * 1024;
    else if (key == "MemAvailable:")
      available = kb * 1024;
  }
  if (!total || !available)
    return std::nullopt;
  return MemInfo{*total, *available};
}

double parseCpuInfoMaxGhz(const std::string& text)
{
  double best_mhz = 0.0;
  std::istringstream in(text);
  std::string line;
  while (std::getline(in, line))
  {
    if (line.rfind("cpu MHz", 0) != 0)
      continue;
    const auto colon = line.find(':');
    if (colon == std::string::npos)
      continue;
    try
    {
      best_mhz = std::max(best_mhz, std::stod(line.substr(colon + 1)));
    }
    catch (const std::exception&)
    {}
  }
  return best_mhz / 1000.0;
}

std::optional<std::string> parseCgroupPath(const std::string& text, const std::string& controller)
{
  std::istringstream in(text);
  std::string line;
  while (std::getline(in, line))
  {
    const auto c1 = line.find(':');
    const auto c2 = c1 == std::string::npos ? c1 : line.find(':', c1 + 1);
    if (c2 == std::string::npos)
      continue;
    std::istringstream controllers(line.substr(c1 + 1, c2 - c1 - 1));
    for (std::string name; std::getline(controllers, name, ',');)
      if (name == controller)
        return line.substr(c2 + 1);
  }
  return std::nullopt;
}

std::optional<std::string> readFile(const std::string& path)
{
  std::ifstream f(path);
  if (!f)
    return std::nullopt;
  std::ostringstream ss;
  ss << f.rdbuf();
  if (f.bad())
    return std::nullopt;
  return ss.str();
}

uint64_t CpuTimeTracker::update(const std::vector<ProcStat>& now)
{
  std::map<std::pair<int, uint64_t>, uint64_t> next;
  uint64_t delta = 0;
  for (const auto& p : now)
  {
    const auto key = std::make_pair(p.pid, p.start_time);
    const uint64_t ticks = p.utime + p.stime;
    const auto it = last_.find(key);
    const uint64_t before = it == last_.end() ? 0 : it->second;
    delta += ticks >= before ? ticks - before : 0;
    next[key] = ticks;
  }
  last_.swap(next);
  return delta;
}

std::vector<ProcStat> readAllProcStats(const std::string& proc_root)
{
  std::vector<ProcStat> out;
  std::unique_ptr<DIR, int (*)(DIR*)> dir(opendir(proc_root.c_str()), &closedir);
  if (!dir)
    return out;
  while (const dirent* e = readdir(dir.get()))
  {
    if (!std::isdigit(static_cast<unsigned char>(e->d_name[0])))
      continue;
    if (auto text = readFile(proc_root + "/" + e->d_name + "/stat"))
      if (auto s = parseProcStat(*text))
        out.push_back(std::move(*s));
  }
  return out;
}

}  // namespace anyscale_agent
