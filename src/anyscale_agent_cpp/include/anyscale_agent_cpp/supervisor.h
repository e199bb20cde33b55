// Process supervisor: node processes in their own session and process group (stops and reaping
// in supervisor.cpp; starts and warm standbys in supervisor_spawn.cpp; the state file and
// adoption in supervisor_adopt.cpp).
#pragma once

#include <signal.h>

#include <chrono>
#include <cstdint>

#include <condition_variable>
#include <functional>
#include <map>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "anyscale_agent_cpp/node_state_file.h"
#include "anyscale_agent_cpp/unique_fd.h"

namespace anyscale_agent
{

enum class ProcState
{
  Starting,  // forked and exec'd; not yet seen registered (the ROS layer calls markRunning)
  Running,
  Stopping,      // SIGINT / SIGTERM / SIGKILL sequence under way
  Exited,        // ended by itself or by a stop
  Replaced,      // ended because a same-name node registered elsewhere (set by the ROS layer)
  LeaseExpired,  // stopped because its lease ran out
  Standby,       // a warm standby: started, imports done or under way, waiting for activate()
  Paused,        // a running node stopped with SIGSTOP by pause(), until resume() or a stop
};
const char* toString(ProcState s);

struct ProcessInfo
{
  std::string name;
  int pid = 0;  // also its process group id; 0 once it has exited
  ProcState state = ProcState::Starting;
  int exit_code = -1;   // exit status when it exited normally
  int exit_signal = 0;  // signal that ended it
  bool stop_requested = false;
  std::string log_file;
  std::chrono::steady_clock::time_point started;
  // Taken over from the agent before this one (adopt()): not our child, so its exit status is
  // unknown (exit_code -1, exit_signal 0) unless it was re-parented to us.
  bool adopted = false;
};

// What adopt() found in the state file a predecessor left.
struct AdoptionReport
{
  struct Adopted
  {
    ProcessInfo info;
    double lease_end_s = 0.0;  // CLOCK_MONOTONIC seconds; 0: it ran without a lease
  };
  std::vector<Adopted> adopted;
  std::vector<std::string> dropped;  // one line per entry not adopted: name, pid and why
  std::string warning;               // the file could not be used, or cannot be written
};

struct SupervisorOptions
{
  // roslaunch's defaults (_TIMEOUT_SIGINT = 15 s, _TIMEOUT_SIGTERM = 2 s): a node gets time to
  // shut down cleanly (unregister from the master) before harsher signals.
  double sigint_timeout_s = 15.0;
  double sigterm_timeout_s = 2.0;
  // Become a child subreaper (prctl), so grandchildren a node leaves behind are re-parented to
  // the agent and reaped by it rather than by init, out of our sight.
  bool subreaper = true;
  // Sent to the children when the agent dies without stopping them, so that a remote node never
  // outlives the agent enforcing its lease; SIGKILL, as a handled signal may never end a rospy
  // node (docs/design/agent.md). 0: none (~nodes_outlive_agent; a successor adopts them).
  int parent_death_signal = SIGKILL;
  // Watch adopted nodes with pidfd_open(2) (Linux >= 5.3). False, or a kernel without it
  // (ENOSYS): /proc/PID/stat is read at every poll() instead. A switch for the tests.
  bool use_pidfd = true;
  // The nice a node starts at: the agent's own before it raised its priority (~control_nice),
  // so that a node declared at nice 0 keeps the priority the user gave the whole stack.
  int child_nice = 0;
};

class Supervisor
{
public:
  explicit Supervisor(SupervisorOptions options = {});
  // Stops everything still running (the full signal sequence) and reaps it.
  ~Supervisor();
  Supervisor(const Supervisor&) = delete;
  Supervisor& operator=(const Supervisor&) = delete;

  // Starts argv[0] (an absolute path; no PATH search, no shell) with its stdout and stderr
  // appended to `log_file`, in a new session and process group. Returns the pid, or 0 with the
  // reason in *error (name in use, log not writable, exec failure with errno text).
  int start(const std::string& name, const std::vector<std::string>& argv,
            const std::string& log_file, std::string* error);

  // Starts a warm standby of `name` like start(), in state Standby, in a slot of its own beside
  // the node's (it may wait while the node runs), with a socket on its stdin: it becomes the node
  // on the line "start" and quits at end of input (scripts/python_standby).
  int startStandby(const std::string& name, const std::vector<std::string>& argv,
                   const std::string& log_file, std::string* error);
  // Sends "start" to the standby of `name`, which becomes the node (an ordinary Starting node);
  // its pid, or 0 with the reason if there is no live standby or the node still runs.
  int activate(const std::string& name, std::string* error);
  // The standby of `name`, if one was started (pid 0 once it ended).
  std::optional<ProcessInfo> standby(const std::string& name) const;
  // Ends the standby of `name` (SIGKILL: it holds no state); false if there is none alive.
  bool stopStandby(const std::string& name);

  // Begins the stop sequence; returns at once. `final_state` is what the node shows once gone
  // (Exited, or LeaseExpired: then SIGKILL at once, no SIGINT/SIGTERM grace). With
  // kill_after_s > 0, SIGKILL follows SIGINT after that long instead of the staged timeouts.
  // False if `name` is not alive.
  bool stop(const std::string& name, ProcState final_state = ProcState::Exited,
            double kill_after_s = 0.0);

  // Pauses a running node's whole process group (SIGSTOP): it keeps its state, its master
  // registration and its connections, and uses no CPU. False, with the reason, unless it is
  // Running (a node still starting has not registered; one stopping is on its way out).
  bool pause(const std::string& name, std::string* error);
  // Resumes a paused node (SIGCONT): Running again, in the time the kernel takes to schedule
  // it. Its pid, or 0 with the reason if `name` is not paused.
  int resume(const std::string& name, std::string* error);

  // SIGKILL now for a node whose stop is under way, when its clean shutdown went far enough
  // (e.g. it left the master). False if `name` is not alive or not being stopped.
  bool killNow(const std::string& name);

  // Waits until `name` is no longer alive, polling itself; false on timeout.
  bool waitGone(const std::string& name, double timeout_s);

  // Reaps exited children and escalates signals whose timeout passed. Call it often (10 Hz).
  void poll();

  void markRunning(const std::string& name);
  // Sets the state a node that already exited shows (e.g. Replaced); false if it is alive.
  bool setFinalState(const std::string& name, ProcState state);

  // The node `name` (never its standby).
  std::optional<ProcessInfo> info(const std::string& name) const;
  // Every node, then every standby.
  std::vector<ProcessInfo> snapshot() const;
  // Names that exited since the previous call, without a stop request (crash, replacement).
  std::vector<std::string> takeUnrequestedExits();
  // How many nodes exited without a stop request since the supervisor was made: a change tells
  // a poller that one did, without taking the names from takeUnrequestedExits' caller.
  uint64_t unrequestedExitCount() const;

  // Stops all processes and waits for them; used on shutdown.
  void stopAll();
  // Lets go of every running node, unsignalled, as a kill of the agent would: the state file
  // keeps listing them for a successor to adopt, and is not written again. Their names.
  std::vector<std::string> leaveRunning();

  // Once, before any start: adopts each node of the predecessor's `state_file` whose process
  // still runs (same pid, start time and command line), then keeps the file listing the running
  // nodes. Never throws: an unusable file is a warning and adopts nothing.
  AdoptionReport adopt(const std::string& state_file);
  // The lease ends of running nodes (CLOCK_MONOTONIC s, 0: none) for the state file, so that a
  // successor enforces them; kept only for nodes that outlive this supervisor (others: 0, so a
  // renewal does not rewrite the file).
  void setLeaseEnds(const std::map<std::string, double>& lease_ends);
  // Changes in the state file's health since the last call (a write failed, or works again),
  // one line each, for the caller to log.
  std::vector<std::string> takeStateFileNotes();

  const SupervisorOptions& options() const { return options_; }

private:
  struct Group  // a process group still to be cleared of members after its leader exited
  {
    int pgid;
    int stage;  // 0 = nothing sent, 1 = SIGINT sent, 2 = SIGTERM sent, 3 = SIGKILL sent
    std::chrono::steady_clock::time_point deadline;
  };
  struct Record
  {
    ProcessInfo info;
    ProcState final_state = ProcState::Exited;
    Group group;
    UniqueFd activation;  // the agent's end of a standby's stdin
    // For the state file: what a successor checks before it adopts the process.
    std::vector<std::string> argv;
    uint64_t start_time = 0;  // /proc/PID/stat field 22
    double lease_end_s = 0.0;
    UniqueFd pidfd;  // an adopted node's pidfd (-1: watched through /proc)
  };
  // mutex_, for a call that may change the state file: what saveStateLocked() staged under
  // it is written when it is released, after mutex_ is given up (defined below the class).
  class StateLock;
  static bool isAlive(const Record& r);
  void escalate(Group& g, std::chrono::steady_clock::time_point now);
  void reapLocked();
  bool stopLocked(const std::string& name, ProcState final_state, double kill_after_s);
  void recordExitLocked(const std::string& name, Record& r, int exit_code, int exit_signal);
  void adoptLocked(const std::optional<NodeState>& previous, AdoptionReport& report);
  bool adoptedExited(const Record& r) const;
  // Stages the state file's list of running nodes, if it changed, for the StateLock held to write.
  void saveStateLocked();
  int launch(const std::string& name, const std::vector<std::string>& argv,
             const std::string& log_file, bool standby, std::string* error);
  void spawnerLoop();

  SupervisorOptions options_;
  mutable std::mutex mutex_;
  std::condition_variable changed_;
  std::map<std::string, Record> records_;   // the nodes
  std::map<std::string, Record> standbys_;  // their warm standbys
  std::vector<Group> orphan_groups_;        // leaders gone, members remain
  std::vector<std::string> unrequested_exits_;
  uint64_t unrequested_exit_count_ = 0;
  NodeStateWriter state_file_;  // no path until adopt(): no state file
  bool left_running_ = false;   // leaveRunning(): the file is a successor's
  std::optional<NodeStateWriter::Staged> staged_state_;  // for the StateLock to write
  std::string boot_id_;

  // All forks happen on this one thread: the parent-death signal fires when the *thread* that
  // forked ends, and ROS spinner threads end before the agent has stopped its children.
  std::mutex spawn_mutex_;
  std::condition_variable spawn_cv_;
  std::function<void()> spawn_job_;
  bool spawner_quit_ = false;
  std::thread spawner_;
};

class Supervisor::StateLock
{
public:
  explicit StateLock(Supervisor& s) : s_(s), lock_(s.mutex_) {}
  ~StateLock()
  {
    std::optional<NodeStateWriter::Staged> staged;
    staged.swap(s_.staged_state_);
    lock_.unlock();
    // A later state staged by another thread meanwhile overtakes this one (NodeStateWriter).
    if (staged)
      s_.state_file_.write(*staged);
  }
  StateLock(const StateLock&) = delete;
  StateLock& operator=(const StateLock&) = delete;

private:
  Supervisor& s_;
  std::unique_lock<std::mutex> lock_;
};

}  // namespace anyscale_agent
