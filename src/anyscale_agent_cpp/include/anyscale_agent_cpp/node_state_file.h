// The supervisor's state file (the nodes it runs, for a restarted agent to adopt), its writer,
// and the rules that decide whether a live process is still the node an entry names. No ROS;
// gtested.
#pragma once

#include <atomic>
#include <cstdint>
#include <mutex>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "anyscale_agent_cpp/proc_reader.h"

namespace anyscale_agent
{

// One running node as its agent left it.
struct NodeStateEntry
{
  std::string name;
  int pid = 0;                    // also its process group id (the supervisor setsid()s it)
  uint64_t start_time = 0;        // /proc/PID/stat field 22, clock ticks after boot
  std::vector<std::string> argv;  // what was exec'd (a warm standby's command line, if it was one)
  std::string log_file;
  std::string state = "running";  // one of kNodeStates
  double lease_end_s = 0.0;  // CLOCK_MONOTONIC seconds (shared by all processes of a boot); 0: none

  bool operator==(const NodeStateEntry& o) const
  {
    return name == o.name && pid == o.pid && start_time == o.start_time && argv == o.argv &&
           log_file == o.log_file && state == o.state && lease_end_s == o.lease_end_s;
  }
};

// The states a live node is written with (the supervisor's Starting, Running, Paused, Stopping).
extern const char* const kNodeStates[4];

struct NodeState
{
  std::string boot_id;  // /proc/sys/kernel/random/boot_id: start times count from this boot
  std::vector<NodeStateEntry> nodes;

  bool operator==(const NodeState& o) const { return boot_id == o.boot_id && nodes == o.nodes; }
};

// A state file that is not one this agent wrote completely: the message names the file and
// what is wrong with it.
class NodeStateError : public std::runtime_error
{
public:
  using std::runtime_error::runtime_error;
};

// The file's text (YAML, readable by hand) and back. parseNodeState throws NodeStateError for
// anything else than the complete text of a formatNodeState (`source` names it in the message).
std::string formatNodeState(const NodeState& state);
NodeState parseNodeState(const std::string& text, const std::string& source);

// Writes `path` atomically (a temporary file beside it, then rename), so a reader sees the old
// list or the new one, never half of one; both names are resolved in the file's own directory
// and no link is followed, so nothing outside it is written. False with the reason in *error.
bool writeNodeStateFile(const std::string& path, const NodeState& state, std::string* error);
// nullopt if there is no such file (a first start); throws NodeStateError if it is unreadable,
// malformed, a symbolic link, not a regular file, or another user's.
std::optional<NodeState> readNodeStateFile(const std::string& path);

// One state file kept current by threads that change the state under a lock of their own (the
// supervisor's), without holding that lock for the file I/O: each state is staged under the
// lock, in the order of the changes, and written after the lock is released. A state equal to
// the one staged last is not written again, and a staged state that a later one overtook is not
// written at all, so the file never goes back to an older list.
class NodeStateWriter
{
public:
  struct Staged
  {
    uint64_t seq = 0;  // the order of staging
    std::string path;
    NodeState state;
  };

  // Under the caller's lock. "" (the default): there is no file, nothing is staged.
  void setPath(const std::string& path) { path_ = path; }
  const std::string& path() const { return path_; }
  // Under the caller's lock: what writes `state`, or nullopt if there is no file or `state` is
  // the one staged last (and the last write did not fail: a failed write is tried again).
  std::optional<Staged> stage(const NodeState& state);
  // Without the caller's lock: writes `staged` unless a later state was written already.
  void write(const Staged& staged);

  // The last write's failure, "" while writes work.
  std::string error() const;
  // Changes in the file's health since the last call (a write failed, or works again), one
  // line each, for the caller to log.
  std::vector<std::string> takeNotes();

private:
  // Guarded by the caller's lock.
  std::string path_;
  uint64_t staged_seq_ = 0;
  std::optional<NodeState> staged_last_;
  // Guarded by mutex_, held for each write.
  mutable std::mutex mutex_;
  uint64_t written_seq_ = 0;
  std::string error_;
  std::vector<std::string> notes_;
  std::atomic<bool> failed_{false};  // the last write failed (read by stage())
};

// This boot's id, "" if the kernel does not say.
std::string currentBootId();

// /proc/PID/cmdline text: NUL-terminated arguments.
std::vector<std::string> parseCmdline(const std::string& raw);

// Whether /proc/PID/cmdline shows the command line `argv` was exec'd with. A script's
// interpreter comes first there ("#!/usr/bin/env python3" gives "python3 /path/script args"),
// so one or two words before the exact argv count as the same command line.
bool sameCommandLine(const std::vector<std::string>& argv, const std::vector<std::string>& cmdline);

// Whether the process at the entry's pid (`stat` and `cmdline`, read AFTER the pid was pinned
// with a pidfd; nullopt `stat`: no such process) is the node the entry names.
enum class Identity
{
  Same,     // adopt it
  Gone,     // the node's process has ended (the pid is free, a zombie, or another process's)
  Changed,  // the same process (pid and start time), but not as written: it exec'd another
            // program or left its process group
};
struct IdentityCheck
{
  Identity identity;
  std::string why;  // for the log; "" when Same
};
IdentityCheck checkIdentity(const NodeStateEntry& entry, const std::optional<ProcStat>& stat,
                            const std::vector<std::string>& cmdline);

}  // namespace anyscale_agent
