// The capacity ledger of a shared scale (no ROS): one file that every agent on the machine (one
// per robot, each joined to its own robot's master) reads and rewrites under an exclusive flock,
// holding what each node started there is expected to use until its lease ends. A start is
// admitted only if everything held plus its request stays within the scale's capacity, so
// robots that do not know of each other never over-commit the machine
// (docs/design/shared_scales.md).
#pragma once

#include <cstddef>
#include <functional>
#include <map>
#include <stdexcept>
#include <string>
#include <vector>

namespace anyscale_agent
{

// One node started on the shared scale for one robot.
struct LedgerEntry
{
  std::string robot;         // the robot's id (the agent's _robot:=)
  std::string master_uri;    // that robot's master, for whoever reads the file
  std::string node;          // declared name, qualified ("/relay")
  std::string instance;      // the name it runs under here ("/relay__laptop")
  double cpu_percent = 0.0;  // expected CPU, % of the scale's capacity
  double memory_mb = 0.0;    // expected memory
  double lease_end_s = 0.0;  // CLOCK_MONOTONIC s (the agents' lease clock): held until then

  bool operator==(const LedgerEntry& o) const
  {
    return robot == o.robot && master_uri == o.master_uri && node == o.node &&
           instance == o.instance && cpu_percent == o.cpu_percent && memory_mb == o.memory_mb &&
           lease_end_s == o.lease_end_s;
  }
};

struct LedgerState
{
  std::string scale;    // the scale whose capacity it shares
  std::string boot_id;  // lease ends count from this boot: another boot's entries hold nothing
  std::vector<LedgerEntry> entries;

  bool operator==(const LedgerState& o) const
  {
    return scale == o.scale && boot_id == o.boot_id && entries == o.entries;
  }
};

// A ledger that cannot be read or written; the message names the file and what is wrong.
class LedgerError : public std::runtime_error
{
public:
  using std::runtime_error::runtime_error;
};

// The file's text (YAML, readable by hand) and back; parseLedger throws LedgerError for anything
// else than the complete text of a formatLedger (`source` names it in the message).
std::string formatLedger(const LedgerState& state);
LedgerState parseLedger(const std::string& text, const std::string& source);

// What the scale offers every robot together.
struct LedgerCapacity
{
  double cpu_percent = 100.0;  // the whole scale: its cgroup quota, else its cores
  double memory_mb = 0.0;      // the model's memory_mb of the scale
};

// What the unexpired entries hold.
struct Holdings
{
  double cpu_percent = 0.0;
  double memory_mb = 0.0;
  std::size_t robots = 0;  // distinct robots holding something
  std::size_t entries = 0;
};

struct Admission
{
  bool admitted = false;
  std::string message;  // why not: "<scale> full: CPU 72 % held by 2 robots + 36 % asked > 100 %"
  double cpu_free_percent = 0.0;  // what the ledger had room for when it answered
  double memory_free_mb = 0.0;
};

// The ledger as one agent uses it: `robot` is its robot, whose entries it alone changes. Every
// call locks the file (flock, LOCK_EX), reads it, and writes it back only if it changed. The file
// lives in a directory of the agent's user; a link or another user's file at its name is never
// read or written (LedgerError). Times are CLOCK_MONOTONIC seconds given by the caller.
class CapacityLedger
{
public:
  CapacityLedger(std::string path, std::string robot, std::string scale, LedgerCapacity capacity);

  // Adds `request` (its robot must be this ledger's) if every unexpired entry of every robot,
  // but an older entry of the same node of this robot, plus the request stays within the
  // capacity; else names what was short. Throws LedgerError if the file cannot be used.
  Admission admit(const LedgerEntry& request, double now);

  // This robot's entries follow its running nodes: an entry of a node in `live` (node -> lease
  // end) takes that lease end, never an earlier one; the others are removed (the node stopped,
  // ended or lost its lease). Expired entries of any robot are dropped. Throws LedgerError.
  void sync(const std::map<std::string, double>& live, double now);

  // What the unexpired entries hold: of every robot, or of every robot but this one.
  Holdings held(double now, bool others_only = false) const;
  // The unexpired entries.
  std::vector<LedgerEntry> entries(double now) const;

  const std::string& path() const { return path_; }
  const LedgerCapacity& capacity() const { return capacity_; }

private:
  // Locks the file, reads it (another boot's entries dropped), calls `change` on its state and
  // writes it back if that changed it (or the file was new and empty).
  void update(const std::function<void(LedgerState&)>& change) const;

  std::string path_;
  std::string robot_;
  std::string scale_;
  LedgerCapacity capacity_;
};

// What `entries` hold at `now` (entries whose lease ended at or before now hold nothing).
Holdings holdings(const std::vector<LedgerEntry>& entries, double now,
                  const std::string& except_robot = "");

// Creates the ledger's directory (0700) if it is missing; throws LedgerError if it is not a
// directory of this process's user.
void prepareLedgerDirectory(const std::string& ledger_path);

}  // namespace anyscale_agent
