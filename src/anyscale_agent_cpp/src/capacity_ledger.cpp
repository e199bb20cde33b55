// The capacity ledger: its text, its file under flock, admission and the entries' lease ends.
#include "anyscale_agent_cpp/capacity_ledger.h"

#include <fcntl.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <set>
#include <utility>

#include "anyscale_agent_cpp/node_state_file.h"
#include "anyscale_agent_cpp/own_file.h"

namespace anyscale_agent
{
namespace
{
const char kFormat[] = "anyscale_capacity_ledger/1";
// Only a file that ends with this line is read at all (see node_state_file.cpp's trailer).
const char kTrailer[] = "# end of capacity ledger\n";
// A few hundred bytes per entry: a larger file is no ledger of this machine's nodes.
constexpr std::size_t kMaxBytes = 4u << 20;
// Another agent's rename between our open and our lock: open the new file and lock again.
constexpr int kMaxReopens = 1000;
constexpr double kSlack = 1e-9;

LedgerError bad(const std::string& source, const std::string& what)
{
  return LedgerError("capacity ledger " + source + ": " + what);
}

template <class T>
T scalar(const YAML::Node& node, const char* key, const std::string& where,
         const std::string& source)
{
  const YAML::Node v = node[key];
  if (!v)
    throw bad(source, where + ": missing '" + key + "'");
  if (!v.IsScalar())
    throw bad(source, where + ": '" + key + "' must be a single value");
  try
  {
    return v.as<T>();
  }
  catch (const YAML::Exception&)
  {
    throw bad(source, where + ": '" + key + "' has the wrong type ('" + v.Scalar() + "')");
  }
}

double figure(const YAML::Node& n, const char* key, const std::string& where,
              const std::string& source)
{
  const double v = scalar<double>(n, key, where, source);
  if (!std::isfinite(v) || v < 0.0)
    throw bad(source, where + ": '" + key + "' must be a number >= 0");
  return v;
}

LedgerEntry parseEntry(const YAML::Node& n, const std::string& where, const std::string& source)
{
  if (!n.IsMap())
    throw bad(source, where + " is not a map");
  LedgerEntry e;
  e.robot = scalar<std::string>(n, "robot", where, source);
  e.node = scalar<std::string>(n, "node", where, source);
  const std::string at = where + " (" + e.robot + " " + e.node + ")";
  e.master_uri = scalar<std::string>(n, "master_uri", at, source);
  e.instance = scalar<std::string>(n, "instance", at, source);
  e.cpu_percent = figure(n, "cpu_percent", at, source);
  e.memory_mb = figure(n, "memory_mb", at, source);
  e.lease_end_s = figure(n, "lease_end_s", at, source);
  if (e.robot.empty())
    throw bad(source, at + ": 'robot' must not be empty");
  if (e.node.empty() || e.node[0] != '/')
    throw bad(source, at + ": 'node' must be a node name starting with '/'");
  return e;
}

std::string amount(double v)
{
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.1f", v);
  std::string s = buf;
  if (s.size() > 2 && s.compare(s.size() - 2, 2, ".0") == 0)
    s.resize(s.size() - 2);
  return s;
}

std::string heldBy(std::size_t robots)
{
  if (robots == 0)
    return " held";
  return " held by " + std::to_string(robots) + (robots == 1 ? " robot" : " robots");
}

std::string readAll(int fd, const std::string& path)
{
  std::string text;
  char buf[8192];
  for (off_t at = 0;;)
  {
    const ssize_t n = ::pread(fd, buf, sizeof buf, at);
    if (n < 0 && errno == EINTR)
      continue;
    if (n < 0)
      throw bad(path, std::string("cannot read: ") + std::strerror(errno));
    if (n == 0)
      return text;
    text.append(buf, std::size_t(n));
    at += n;
    if (text.size() > kMaxBytes)
      throw bad(path, "larger than " + std::to_string(kMaxBytes >> 20) + " MB");
  }
}

bool sameFile(const struct stat& a, const struct stat& b)
{
  return a.st_dev == b.st_dev && a.st_ino == b.st_ino;
}
}  // namespace

std::string formatLedger(const LedgerState& state)
{
  YAML::Emitter out;
  out.SetDoublePrecision(17);  // a lease end read back must be the one written
  out << YAML::BeginMap;
  out << YAML::Key << "format" << YAML::Value << kFormat;
  out << YAML::Key << "scale" << YAML::Value << state.scale;
  out << YAML::Key << "boot_id" << YAML::Value << state.boot_id;
  out << YAML::Key << "count" << YAML::Value << state.entries.size();
  out << YAML::Key << "entries" << YAML::Value;
  if (state.entries.empty())
    out << YAML::Flow;
  out << YAML::BeginSeq;
  for (const auto& e : state.entries)
  {
    out << YAML::BeginMap;
    out << YAML::Key << "robot" << YAML::Value << e.robot;
    out << YAML::Key << "master_uri" << YAML::Value << e.master_uri;
    out << YAML::Key << "node" << YAML::Value << e.node;
    out << YAML::Key << "instance" << YAML::Value << e.instance;
    out << YAML::Key << "cpu_percent" << YAML::Value << e.cpu_percent;
    out << YAML::Key << "memory_mb" << YAML::Value << e.memory_mb;
    out << YAML::Key << "lease_end_s" << YAML::Value << e.lease_end_s;
    out << YAML::EndMap;
  }
  out << YAML::EndSeq << YAML::EndMap;
  return std::string(
             "# AnyScale capacity ledger: what each robot's nodes on this scale are expected to "
             "use,\n"
             "# until their leases end (CLOCK_MONOTONIC s). Kept by the agents under flock; do not "
             "edit.\n") +
         out.c_str() + "\n" + kTrailer;
}

LedgerState parseLedger(const std::string& text, const std::string& source)
{
  const std::string trailer(kTrailer);
  if (text.size() < trailer.size() ||
      text.compare(text.size() - trailer.size(), trailer.size(), trailer) != 0)
    throw bad(source, "incomplete (it does not end with the line '" +
                          trailer.substr(0, trailer.size() - 1) + "')");
  YAML::Node root;
  try
  {
    root = YAML::Load(text);
  }
  catch (const YAML::Exception& e)
  {
    throw bad(source, std::string("not YAML: ") + e.what());
  }
  if (!root.IsMap())
    throw bad(source, "not a map");
  const std::string format = scalar<std::string>(root, "format", "top level", source);
  if (format != kFormat)
    throw bad(source, "unknown format '" + format + "' (this agent reads " + kFormat + ")");
  LedgerState state;
  state.scale = scalar<std::string>(root, "scale", "top level", source);
  state.boot_id = scalar<std::string>(root, "boot_id", "top level", source);
  const auto count = scalar<std::size_t>(root, "count", "top level", source);
  const YAML::Node entries = root["entries"];
  if (!entries || !entries.IsSequence())
    throw bad(source, "'entries' must be a list");
  if (entries.size() != count)
    throw bad(source, "lists " + std::to_string(entries.size()) + " entries, but says " +
                          std::to_string(count));
  std::set<std::pair<std::string, std::string>> seen;
  for (std::size_t i = 0; i < entries.size(); ++i)
  {
    state.entries.push_back(parseEntry(entries[i], "entry " + std::to_string(i + 1), source));
    const auto& e = state.entries.back();
    if (!seen.emplace(e.robot, e.node).second)
      throw bad(source, "node " + e.node + " of robot " + e.robot + " listed twice");
  }
  return state;
}

Holdings holdings(const std::vector<LedgerEntry>& entries, double now,
                  const std::string& except_robot)
{
  Holdings h;
  std::set<std::string> robots;
  for (const auto& e : entries)
  {
    if (e.lease_end_s <= now || (!except_robot.empty() && e.robot == except_robot))
      continue;
    h.cpu_percent += e.cpu_percent;
    h.memory_mb += e.memory_mb;
    robots.insert(e.robot);
    ++h.entries;
  }
  h.robots = robots.size();
  return h;
}

void prepareLedgerDirectory(const std::string& ledger_path)
{
  std::string dir, name;
  splitPath(ledger_path, &dir, &name);
  if (name.empty() || name == "." || name == "..")
    throw bad(ledger_path, "names no file");
  if (dir.size() > 1 && dir.back() == '/')
    dir.pop_back();  // "d/" would be followed if d is a link
  if (::mkdir(dir.c_str(), 0700) != 0 && errno != EEXIST)
    throw bad(ledger_path, "cannot create its directory " + dir + ": " + std::strerror(errno));
  struct stat st;
  if (::lstat(dir.c_str(), &st) != 0)
    throw bad(ledger_path, "cannot read its directory " + dir + ": " + std::strerror(errno));
  if (!S_ISDIR(st.st_mode))
    throw bad(ledger_path, "its directory " + dir + " is not a directory (a link is not followed)");
  if (st.st_uid != ::geteuid())
    throw bad(ledger_path,
              "its directory " + dir + " belongs to user " + std::to_string(st.st_uid) +
                  ", not to the agent's (" + std::to_string(::geteuid()) +
                  "): give every agent sharing it the same user and a directory of its own");
}

CapacityLedger::CapacityLedger(std::string path, std::string robot, std::string scale,
                               LedgerCapacity capacity)
  : path_(std::move(path)), robot_(std::move(robot)), scale_(std::move(scale)), capacity_(capacity)
{}

void CapacityLedger::update(const std::function<void(LedgerState&)>& change) const
{
  std::string dir_path, name;
  splitPath(path_, &dir_path, &name);
  UniqueFd dir(::open(dir_path.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC));
  if (dir.get() < 0)
    throw bad(path_, "cannot open its directory: " + std::string(std::strerror(errno)));
  for (int attempt = 0; attempt < kMaxReopens; ++attempt)
  {
    // Not through a link, not a FIFO (O_NONBLOCK: its open would wait for a writer).
    UniqueFd fd(::openat(dir.get(), name.c_str(),
                         O_RDONLY | O_CREAT | O_NOFOLLOW | O_NONBLOCK | O_CLOEXEC, 0600));
    if (fd.get() < 0)
      throw bad(path_, errno == ELOOP ? std::string("is a symbolic link: not used")
                                      : "cannot open: " + std::string(std::strerror(errno)));
    struct stat locked, named;
    if (::fstat(fd.get(), &locked) != 0 || !S_ISREG(locked.st_mode) || locked.st_uid != ::geteuid())
      throw bad(path_, "is not a regular file of the agent's user: not used");
    while (::flock(fd.get(), LOCK_EX) != 0)
      if (errno != EINTR)
        throw bad(path_, "cannot lock: " + std::string(std::strerror(errno)));
    // A writer renames a new file over the name; whoever opened or waited on the old one holds a
    // file nobody reads any more, and must lock the one at the name now.
    if (::fstatat(dir.get(), name.c_str(), &named, AT_SYMLINK_NOFOLLOW) != 0 ||
        ::fstat(fd.get(), &locked) != 0 || !sameFile(locked, named))
      continue;
    if (!ownRegularFile(fd.get()))
      throw bad(path_, "has another name too (a hard link): not used");
    const std::string text = readAll(fd.get(), path_);
    const std::string boot_id = currentBootId();
    // Empty: created by the open above, never a file cut short (every write is a rename).
    LedgerState state = text.empty() ? LedgerState{scale_, boot_id, {}} : parseLedger(text, path_);
    if (state.scale != scale_)
      throw bad(path_, "is the ledger of scale '" + state.scale + "', not of '" + scale_ + "'");
    const LedgerState before = state;
    if (state.boot_id != boot_id)
      state = LedgerState{scale_, boot_id, {}};  // its lease ends are of another boot
    change(state);
    if (text.empty() || !(state == before))
    {
      std::string error;
      if (!replaceFileAtomically(path_, formatLedger(state), &error))
        throw bad(path_, error);
    }
    return;  // the lock goes with fd
  }
  throw bad(path_, "replaced by others " + std::to_string(kMaxReopens) +
                       " times while it was being locked");
}

Admission CapacityLedger::admit(const LedgerEntry& request, double now)
{
  Admission out;
  update([&](LedgerState& state) {
    std::vector<LedgerEntry> kept;
    for (auto& e : state.entries)
      if (e.lease_end_s > now && !(e.robot == robot_ && e.node == request.node))
        kept.push_back(std::move(e));
    state.entries = std::move(kept);
    const Holdings h = holdings(state.entries, now);
    out.cpu_free_percent = std::max(0.0, capacity_.cpu_percent - h.cpu_percent);
    out.memory_free_mb = std::max(0.0, capacity_.memory_mb - h.memory_mb);
    std::string shortfall;
    if (h.cpu_percent + request.cpu_percent > capacity_.cpu_percent + kSlack)
      shortfall = "CPU " + amount(h.cpu_percent) + " %" + heldBy(h.robots) + " + " +
                  amount(request.cpu_percent) + " % asked > " + amount(capacity_.cpu_percent) +
                  " %";
    if (h.memory_mb + request.memory_mb > capacity_.memory_mb + kSlack)
      shortfall += (shortfall.empty() ? "memory " : "; memory ") + amount(h.memory_mb) + " MB" +
                   heldBy(h.robots) + " + " + amount(request.memory_mb) + " MB asked > " +
                   amount(capacity_.memory_mb) + " MB";
    if (!shortfall.empty())
    {
      out.message = scale_ + " full: " + shortfall;
      return;  // expired entries dropped, if any, are written all the same
    }
    LedgerEntry entry = request;
    entry.robot = robot_;
    state.entries.push_back(std::move(entry));
    out.admitted = true;
    out.message = "admitted: CPU " + amount(h.cpu_percent + request.cpu_percent) + " % of " +
                  amount(capacity_.cpu_percent) + " %, memory " +
                  amount(h.memory_mb + request.memory_mb) + " MB of " +
                  amount(capacity_.memory_mb) + " MB held on " + scale_;
  });
  return out;
}

void CapacityLedger::sync(const std::map<std::string, double>& live, double now)
{
  update([&](LedgerState& state) {
    std::vector<LedgerEntry> kept;
    for (auto& e : state.entries)
    {
      if (e.robot == robot_)
      {
        const auto it = live.find(e.node);
        if (it == live.end())
          continue;
        e.lease_end_s = std::max(e.lease_end_s, it->second);
      }
      if (e.lease_end_s > now)
        kept.push_back(std::move(e));
    }
    state.entries = std::move(kept);
  });
}

Holdings CapacityLedger::held(double now, bool others_only) const
{
  Holdings h;
  update([&](LedgerState& state) { h = holdings(state.entries, now, others_only ? robot_ : ""); });
  return h;
}

std::vector<LedgerEntry> CapacityLedger::entries(double now) const
{
  std::vector<LedgerEntry> out;
  update([&](LedgerState& state) {
    for (const auto& e : state.entries)
      if (e.lease_end_s > now)
        out.push_back(e);
  });
  return out;
}

}  // namespace anyscale_agent
