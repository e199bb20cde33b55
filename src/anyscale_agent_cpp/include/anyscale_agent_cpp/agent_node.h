// The roscpp agent of one scale: parameters, services, timers and status over the core library.
#pragma once

#include <diagnostic_updater/diagnostic_updater.h>
#include <ros/callback_queue.h>
#include <ros/ros.h>

#include <anyscale_msgs/ListNodes.h>
#include <anyscale_msgs/RenewLeases.h>
#include <anyscale_msgs/ScaleStatus.h>
#include <anyscale_msgs/SetWatchedTopics.h>
#include <anyscale_msgs/StartNode.h>
#include <anyscale_msgs/StopNode.h>

#include <atomic>
#include <map>
#include <memory>
#include <mutex>
#include <set>
#include <string>

#include "anyscale_agent_cpp/agent_config.h"
#include "anyscale_agent_cpp/capacity_ledger.h"
#include "anyscale_agent_cpp/graph_monitor.h"
#include "anyscale_agent_cpp/lease_table.h"
#include "anyscale_agent_cpp/link_monitor.h"
#include "anyscale_agent_cpp/master_call_watchdog.h"
#include "anyscale_agent_cpp/node_model.h"
#include "anyscale_agent_cpp/output_boosts.h"
#include "anyscale_agent_cpp/request_wire.h"
#include "anyscale_agent_cpp/supervisor.h"
#include "anyscale_agent_cpp/system_sampler.h"
#include "anyscale_agent_cpp/topic_watcher.h"

namespace anyscale_agent
{

class AgentNode
{
public:
  // Reads the model named by `config` and the parameters; throws std::runtime_error with the
  // reason if they are bad.
  AgentNode(ros::NodeHandle nh, ros::NodeHandle pnh, const AgentConfig& config);
  // Stops every node it still supervises before the ROS connection goes away.
  ~AgentNode();

  // Serves until ROS shuts down. A shutdown not `by_signal` (roscpp's XML-RPC `shutdown`, e.g.
  // `rosnode kill`, which anyone on the graph may call) leaves nodes that outlive the agent
  // running for its successor, as a kill would; a signal (roslaunch, Ctrl-C) stops them all.
  void spin(const std::atomic<bool>& by_signal);

private:
  // Service entry points (agent_requests.cpp): each answer that refuses a request is logged
  // with the caller's node name (ROS 1 has no authentication; the name is what it says).
  template <class Srv>
  using Event = ros::ServiceEvent<typename Srv::Request, typename Srv::Response>;
  bool onStart(Event<anyscale_msgs::StartNode>& event);
  bool onStop(Event<anyscale_msgs::StopNode>& event);
  bool onRenew(Event<anyscale_msgs::RenewLeases>& event);
  bool onList(Event<anyscale_msgs::ListNodes>& event);
  // A service whose requests are checked against `layout` before roscpp reads them (a claim of
  // millions of entries in a few bytes is refused, not allocated; wire_checked.h).
  template <class Req, class Res>
  ros::ServiceServer advertise(const std::string& name,
                               bool (AgentNode::*callback)(ros::ServiceEvent<Req, Res>&),
                               const WireLayout& layout);
  bool onSetWatched(Event<anyscale_msgs::SetWatchedTopics>& event);
  // What they do (agent_services.cpp).
  void startNode(const anyscale_msgs::StartNode::Request& req,
                 anyscale_msgs::StartNode::Response& res);
  void stopNode(const anyscale_msgs::StopNode::Request& req,
                anyscale_msgs::StopNode::Response& res);
  void pauseNode(const std::string& name, anyscale_msgs::StopNode::Response& res);
  void renewLeases(const anyscale_msgs::RenewLeases::Request& req,
                   anyscale_msgs::RenewLeases::Response& res);
  void setWatched(const anyscale_msgs::SetWatchedTopics::Request& req,
                  anyscale_msgs::SetWatchedTopics::Response& res);

  // Timers (agent_node.cpp).
  void onSupervise(const ros::SteadyTimerEvent&);  // reaping, signal escalation, leases, standbys
  void onGraph(const ros::SteadyTimerEvent&);      // master queries: registration, local topics
  void onGraphQueries();
  // The processes that run here (declared name -> name under which it runs here, process group).
  std::map<std::string, TopicWatcher::RunningNode> runningNodes() const;
  // Status (agent_status.cpp).
  void onSample(const ros::SteadyTimerEvent&);  // /proc, topics, link -> /anyscale/status
  void onUplink(const ros::SteadyTimerEvent&);  // carrier of ~uplink_interface; status on change
  void publishStatusNow();  // the last sample with the processes as they are now
  void applyUplink(anyscale_msgs::LinkStatistics& link) const;
  std::vector<anyscale_msgs::NodeProcess> nodeProcesses();

  // Restarts (agent_restarts.cpp). The nodes a killed predecessor left running (~state_file):
  // adopted, with their leases.
  void adoptNodes(const std::string& state_file);
  // The lease of an instance of `name` just started (lease_s > 0; else none), also in the
  // supervisor's state file.
  void grantLease(const std::string& name, double lease_s);
  // A running instance's lease, if it has one, ends no earlier than lease_s from now.
  void renewLease(const std::string& name, double lease_s);

  // A shared scale's capacity ledger (agent_ledger.cpp; none without _ledger_file:=).
  void openLedger(const AgentConfig& config);  // after adoption: re-adopts this robot's entries
  // Whether the start of `name` may go ahead: always without a ledger; else admitted by it (the
  // caller holds ledger_mutex_ until the node's lease is granted), or refused into `res`.
  bool admit(const std::string& name, const anyscale_msgs::StartNode::Request& req,
             anyscale_msgs::StartNode::Response& res);
  // This robot's entries follow its live nodes and their leases (CapacityLedger::sync).
  void syncLedger();
  void syncLedgerLocked();    // under ledger_mutex_
  void syncLedgerOnChange();  // on the supervision thread: when a node began or ended
  float cpuHeldByOthers();    // ScaleStatus.cpu_held_percent

  // Priorities (agent_priority.cpp): the agent's ~control_nice; a node's launch.nice, at
  // ~start_boost_nice from its start until its first output, and while its output is late
  // (~late_boost_fraction of its tolerance), for ~start_boost_s at most (OutputBoosts).
  void raiseControlPriority(int control_nice);
  void setStartPriority(const NodeDecl& decl, const std::string& name, int pid);
  void watchOutput(const NodeDecl& decl, const std::string& name, int pid);  // an adopted node
  void updateBoosts();  // on the supervision thread
  // A message counted, in a topic counter's thread: ends a boost, dates the output.
  void outputSeen(const std::string& publisher);
  void applyBoost(const OutputBoosts::Change& change);
  std::string publisherName(const std::string& name) const;  // the caller id of its messages

  // Warm standbys (agent_standbys.cpp): one per warm_start node, also while it runs here.
  void keepStandbysReady();
  void hurryStandby(const std::string& name, int pid, const char* why);
  std::vector<std::string> standbyArgv(const NodeDecl& decl);
  std::string logFile(const std::string& node) const;  // <log_dir>/<name with '/' as '.'>.log
  // The name a node runs under on this scale (see instanceName): the supervisor keeps the
  // declared name, the master and the graph know this one.
  std::string rosName(const std::string& qualified_name) const
  {
    return instanceName(qualified_name, scale_, is_master_);
  }

  // Diagnostics (agent_diagnostics.cpp).
  void diagnoseNodes(diagnostic_updater::DiagnosticStatusWrapper& stat);
  void diagnoseScale(diagnostic_updater::DiagnosticStatusWrapper& stat);
  void diagnoseLink(diagnostic_updater::DiagnosticStatusWrapper& stat);
  void diagnoseTopics(diagnostic_updater::DiagnosticStatusWrapper& stat);

  static double steadyNow();
  std::string locatePackage(const std::string& package) const;

  ros::NodeHandle nh_, pnh_;
  std::string scale_;
  bool is_master_ = false;
  std::string model_path_;
  std::string log_dir_;
  bool clear_params_ = true;
  double sample_period_s_ = 0.5;
  bool warm_start_ = true;        // ~warm_start: false ignores the model's launch.warm_start
  double standby_delay_s_ = 2.0;  // the next standby this long after the last one became the node
  uint64_t unrequested_exits_seen_ = 0;  // the supervisor's count at the last status sent for one
  std::set<std::string> ended_unasked_;  // nodes that ended unasked here: standbys import at once
  std::map<std::string, double> standby_due_;    // node -> steady time its standby may start
  std::map<std::string, int> last_standby_pid_;  // node -> pid of the standby started last
  OutputBoosts boosts_;  // ~start_boost_nice, ~start_boost_s, ~late_boost_fraction
  std::mutex boost_mutex_;
  std::string uplink_interface_;  // ~uplink_interface: whose carrier loss cuts the other scales off
  std::atomic<bool> uplink_up_{true};

  NodeModel model_;
  Supervisor supervisor_;
  std::string robot_;                       // _robot:=, on a shared scale
  std::unique_ptr<CapacityLedger> ledger_;  // _ledger_file:=; null: no shared scale
  // Held from a start's admission to its lease's grant, and for every sync: a sync in between
  // would free the entry of a node not yet forked. Taken before leases_mutex_.
  std::mutex ledger_mutex_;
  std::set<std::string> ledger_live_;  // the nodes of the last sync that worked
  std::string ledger_error_;           // why the last sync failed; "" when it worked
  LeaseTable leases_;
  std::mutex leases_mutex_;
  SystemSampler sampler_;
  std::mutex sample_mutex_;
  anyscale_msgs::ScaleStatus last_status_;
  std::unique_ptr<TopicWatcher> topics_;
  std::unique_ptr<LinkMonitor> link_;
  std::unique_ptr<MasterCallWatchdog> master_calls_;  // away from the master's machine only
  GraphMonitor graph_;

  // Supervision runs on its own queue and thread, and master queries on another, so neither
  // a blocking XML-RPC call nor a stop that waits can delay a lease expiry.
  ros::CallbackQueue supervise_queue_, graph_queue_;
  ros::Publisher status_pub_;
  std::vector<ros::ServiceServer> services_;
  ros::SteadyTimer sample_timer_, supervise_timer_, graph_timer_, uplink_timer_;
  diagnostic_updater::Updater diagnostics_;
};

}  // namespace anyscale_agent
