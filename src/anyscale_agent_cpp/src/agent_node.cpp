// The agent's setup (parameters, services, timers) and its supervision and graph timers. The status
// message is in agent_status.cpp, priorities in agent_priority.cpp, adoption and the lease ends of
// the state file in agent_restarts.cpp, services in agent_services.cpp.
#include "anyscale_agent_cpp/agent_node.h"

#include <ros/package.h>
#include <sys/resource.h>
#include <unistd.h>
#include <boost/make_shared.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>

#include "anyscale_agent_cpp/uplink_carrier.h"
#include "anyscale_agent_cpp/wire_checked.h"

namespace anyscale_agent
{
namespace
{
// A watched topic silent this long gets a new subscription: every topic of a model connection
// runs at 1 Hz or more (freq_min), so 3 s of nothing while its publisher runs is a dead
// connection; where the publisher is gone, the renewal costs a call to the master.
constexpr double kRenewCountersSilentS = 3.0;
constexpr double kSlowGraphPassS = 3.0;

template <typename T>
T param(const ros::NodeHandle& pnh, const std::string& name, const T& fallback)
{
  T value;
  pnh.param<T>(name, value, fallback);
  return value;
}

double positive(const ros::NodeHandle& pnh, const std::string& name, double fallback)
{
  const double v = param(pnh, name, fallback);
  if (!(v > 0.0) || !std::isfinite(v))
    throw std::runtime_error("parameter ~" + name +
                             " must be a positive number of seconds/Hz, got " + std::to_string(v));
  return v;
}

SupervisorOptions supervisorOptions(const ros::NodeHandle& pnh, const AgentConfig& config)
{
  SupervisorOptions o;
  o.sigint_timeout_s = positive(pnh, "sigint_timeout_s", o.sigint_timeout_s);
  o.sigterm_timeout_s = positive(pnh, "sigterm_timeout_s", o.sigterm_timeout_s);
  // On the master scale the nodes are the robot's own (drivers, localisation): a killed agent
  // must not take them down, as rosmon or systemd would not; its successor adopts them. On
  // any other scale a node must not outlive the agent that enforces its lease, or a robot
  // that already started its own instance would see two.
  if (config.nodes_outlive_agent)
    o.parent_death_signal = 0;
  // Read before the agent raises its own priority (AgentNode's constructor, ~control_nice).
  o.child_nice = ::getpriority(PRIO_PROCESS, 0);
  return o;
}

}  // namespace

template <class Req, class Res>
ros::ServiceServer AgentNode::advertise(const std::string& name,
                                        bool (AgentNode::*callback)(ros::ServiceEvent<Req, Res>&),
                                        const WireLayout& layout)
{
  ros::AdvertiseServiceOptions ops;
  ops.initBySpecType<ros::ServiceEvent<Req, Res>>(
      name, boost::bind(callback, this, boost::placeholders::_1));
  ops.helper = boost::make_shared<WireCheckedService>(ops.helper, layout, name);
  return nh_.advertiseService(ops);
}

AgentNode::AgentNode(ros::NodeHandle nh, ros::NodeHandle pnh, const AgentConfig& config)
  : nh_(nh), pnh_(pnh), supervisor_(supervisorOptions(pnh, config))
{
  const std::string node_name = ros::this_node::getName();
  scale_ = config.scale;
  if (node_name != "/anyscale_agent_" + scale_)
    ROS_WARN("agent node is named %s; the convention is /anyscale_agent_%s", node_name.c_str(),
             scale_.c_str());
  is_master_ = config.is_master;
  model_path_ = config.model_path;
  model_ = NodeModel::load(model_path_);  // ModelError is a runtime_error naming file and key
  log_dir_ = config.log_dir;
  std::error_code ec;
  std::filesystem::create_directories(log_dir_, ec);
  if (ec)
    throw std::runtime_error("cannot create ~log_dir '" + log_dir_ + "': " + ec.message());
  clear_params_ = param(pnh_, "clear_params", true);
  sample_period_s_ = 1.0 / positive(pnh_, "sample_rate_hz", 2.0);
  warm_start_ = param(pnh_, "warm_start", true);
  standby_delay_s_ = positive(pnh_, "standby_delay_s", standby_delay_s_);
  const int start_boost_nice = param(pnh_, "start_boost_nice", 0);
  if (start_boost_nice < -20 || start_boost_nice > 0)
    throw std::runtime_error(
        "parameter ~start_boost_nice must be a nice value from -20 to 0 (0: no boost), got " +
        std::to_string(start_boost_nice));
  const double late_boost_fraction = param(pnh_, "late_boost_fraction", 0.5);
  if (!(late_boost_fraction >= 0.0 && late_boost_fraction <= 1.0))
    throw std::runtime_error(
        "parameter ~late_boost_fraction must be a fraction of a node's output tolerance from 0 "
        "to 1 (0: no late boost), got " +
        std::to_string(late_boost_fraction));
  boosts_ =
      OutputBoosts(start_boost_nice, positive(pnh_, "start_boost_s", 3.0), late_boost_fraction);
  // Before any start: the nodes a killed predecessor left running are this agent's again.
  adoptNodes(config.state_file);
  openLedger(config);
  raiseControlPriority(param(pnh_, "control_nice", 0));

  topics_ = std::make_unique<TopicWatcher>(
      nh_, positive(pnh_, "rate_window_s", 2.0), std::max(1, param(pnh_, "topic_queue_size", 50)),
      param(pnh_, "watch_all", false),
      // Off by default: see the README's ~count_by_bus_stats
      // (the decision node's bandwidth rule still relies on
      // the second copy to see a link AR's stream saturates).
      param(pnh_, "count_by_bus_stats", false), positive(pnh_, "bus_stats_period_s", 0.25),
      positive(pnh_, "bus_stats_timeout_s", 0.25),
      [this](const std::string& publisher) { outputSeen(publisher); });
  std::string error;
  if (!topics_->setWatched(param(pnh_, "watched_topics", std::vector<std::string>{}), {}, &error))
    throw std::runtime_error("parameter ~watched_topics: " + error);

  LinkOptions link;
  link.probe_period_s = positive(pnh_, "link_probe_period_s", link.probe_period_s);
  link.timeout_s = positive(pnh_, "link_timeout_s", link.timeout_s);
  link.bulk_bytes = std::max(0, param(pnh_, "link_bulk_bytes", link.bulk_bytes));
  link.bulk_period_s = positive(pnh_, "link_bulk_period_s", link.bulk_period_s);
  link.icmp = param(pnh_, "link_bandwidth_by_icmp", link.icmp);
  if (!is_master_)
    master_calls_ =
        std::make_unique<MasterCallWatchdog>(ros::master::getHost(), int(ros::master::getPort()));
  link_ = std::make_unique<LinkMonitor>(
      nh_, scale_, is_master_, param<std::string>(pnh_, "master_scale", ""), link,
      [this](double now, const std::function<bool()>& may_call_master) {
        // Here, not in the graph thread: that one waits on every master query in turn.
        topics_->setRunning(runningNodes(), may_call_master);
        topics_->renewSilent(now, kRenewCountersSilentS, may_call_master);
      });

  status_pub_ = nh_.advertise<anyscale_msgs::ScaleStatus>("/anyscale/status", 10);
  const std::string ns = "/anyscale/" + scale_ + "/";
  services_.push_back(advertise(ns + "start_node", &AgentNode::onStart, kStartNodeWire));
  services_.push_back(advertise(ns + "stop_node", &AgentNode::onStop, kStopNodeWire));
  services_.push_back(advertise(ns + "renew_leases", &AgentNode::onRenew, kRenewLeasesWire));
  services_.push_back(advertise(ns + "list_nodes", &AgentNode::onList, kListNodesWire));
  services_.push_back(
      advertise(ns + "set_watched_topics", &AgentNode::onSetWatched, kSetWatchedTopicsWire));

  sample_timer_ =
      nh_.createSteadyTimer(ros::WallDuration(sample_period_s_), &AgentNode::onSample, this);
  ros::NodeHandle supervise_nh(nh_), graph_nh(nh_);
  supervise_nh.setCallbackQueue(&supervise_queue_);
  graph_nh.setCallbackQueue(&graph_queue_);
  supervise_timer_ =
      supervise_nh.createSteadyTimer(ros::WallDuration(0.1), &AgentNode::onSupervise, this);
  graph_timer_ = graph_nh.createSteadyTimer(
      ros::WallDuration(positive(pnh_, "graph_period_s", 1.0)), &AgentNode::onGraph, this);
  uplink_interface_ = param<std::string>(pnh_, "uplink_interface", "");
  if (!uplink_interface_.empty())
  {
    const Carrier carrier = readCarrier(uplink_interface_);
    if (carrier == Carrier::Missing)
    {
      std::string have;
      for (const auto& name : interfaceNames())
        have += (have.empty() ? "" : ", ") + name;
      throw std::runtime_error("parameter ~uplink_interface: no interface '" + uplink_interface_ +
                               "' in this network namespace (it has: " + have + ")");
    }
    uplink_up_ = carrier == Carrier::Up;
    ROS_INFO("watching the carrier of uplink %s (now %s)", uplink_interface_.c_str(),
             toString(carrier));
    // On the supervision thread: a file read every period, never blocked by a master query.
    uplink_timer_ = supervise_nh.createSteadyTimer(
        ros::WallDuration(positive(pnh_, "uplink_poll_period_s", 0.05)), &AgentNode::onUplink,
        this);
  }

  diagnostics_.setHardwareID(scale_);
  diagnostics_.add("nodes", this, &AgentNode::diagnoseNodes);
  diagnostics_.add("scale", this, &AgentNode::diagnoseScale);
  diagnostics_.add("link", this, &AgentNode::diagnoseLink);
  diagnostics_.add("topics", this, &AgentNode::diagnoseTopics);

  sampler_.sample(steadyNow(), {});
  ROS_INFO("anyscale agent of scale '%s'%s: %zu nodes declared in %s, logs in %s; nodes %s",
           scale_.c_str(), is_master_ ? " (master)" : "", model_.names().size(),
           model_path_.c_str(), log_dir_.c_str(),
           supervisor_.options().parent_death_signal ? "die with this agent"
                                                     : "outlive this agent if it is killed");
}

AgentNode::~AgentNode()
{
  sample_timer_.stop();
  supervise_timer_.stop();
  graph_timer_.stop();
  uplink_timer_.stop();
  supervisor_.stopAll();
  syncLedger();
}

void AgentNode::spin(const std::atomic<bool>& by_signal)
{
  ros::AsyncSpinner services_and_sampling(3);
  ros::AsyncSpinner supervision(1, &supervise_queue_);
  ros::AsyncSpinner graph(1, &graph_queue_);
  services_and_sampling.start();
  supervision.start();
  graph.start();
  ros::waitForShutdown();
  if (!by_signal && supervisor_.options().parent_death_signal == 0)
  {
    const auto left = supervisor_.leaveRunning();
    ROS_WARN(
        "anyscale agent of scale '%s' shut down over ROS, not by a signal: its %zu nodes run "
        "on for the next agent to adopt (stop them with a signal to the agent)",
        scale_.c_str(), left.size());
  }
  else
    ROS_INFO("anyscale agent of scale '%s' stopping the nodes it started", scale_.c_str());
  supervisor_.stopAll();
  syncLedger();  // their capacity is free at once, not when their leases end
}

double AgentNode::steadyNow()
{
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

std::string AgentNode::locatePackage(const std::string& package) const
{
  // rospack prints an error for an unknown package and returns ""; that is our "not found".
  return ros::package::getPath(package);
}

void AgentNode::onSupervise(const ros::SteadyTimerEvent&)
{
  supervisor_.poll();
  // A node that ended unasked is restarted by the decision node, which learns of it from our
  // status: sent now, not at the next sample (up to 1 / ~sample_rate_hz later), as every part
  // of a restart on the robot counts against the output's tolerance.
  if (const uint64_t exits = supervisor_.unrequestedExitCount(); exits != unrequested_exits_seen_)
  {
    unrequested_exits_seen_ = exits;
    publishStatusNow();
    for (const auto& p : supervisor_.snapshot())
      if (p.state == ProcState::Exited && !p.stop_requested)
        ended_unasked_.insert(p.name);
  }
  updateBoosts();
  std::vector<std::string> expired;
  {
    std::lock_guard<std::mutex> lock(leases_mutex_);
    expired = leases_.takeExpired(steadyNow());
  }
  for (const auto& name : expired)
    if (supervisor_.stop(name, ProcState::LeaseExpired))
      ROS_WARN("lease of %s expired: stopping it", name.c_str());
  for (const auto& note : supervisor_.takeStateFileNotes())
    ROS_WARN("%s", note.c_str());
  syncLedgerOnChange();
  // Here, not with the master queries: a standby is most needed right after a partition, when
  // those queries hang on the unreachable master.
  keepStandbysReady();
}

std::map<std::string, TopicWatcher::RunningNode> AgentNode::runningNodes() const
{
  std::map<std::string, TopicWatcher::RunningNode> out;
  for (const auto& p : supervisor_.snapshot())
    if (p.pid != 0 && p.state != ProcState::Standby)
    {
      std::string instance = rosName(p.name);
      if (instance.empty() || instance[0] != '/')
        instance.insert(0, "/");
      out[p.name] = {instance, p.pid, p.state == ProcState::Paused};
    }
  return out;
}

void AgentNode::onGraph(const ros::SteadyTimerEvent&)
{
  const double began = steadyNow();
  onGraphQueries();
  // Every question here is a call to the master (over the link, from a remote scale), one
  // after another. How long a pass can take was unknown when the counters depended on it;
  // logged so that a slow master shows in the agent's log.
  const double took = steadyNow() - began;
  if (took >= kSlowGraphPassS)
    ROS_WARN(
        "the master's graph took %.1f s to read (registrations, subscribers on this scale); "
        "the inputs of the nodes run here are counted without it",
        took);
}

void AgentNode::onGraphQueries()
{
  std::set<std::string> own;
  for (const auto& p : supervisor_.snapshot())
  {
    if (p.pid != 0 && p.state != ProcState::Standby)
      own.insert(rosName(p.name));
    if (p.state != ProcState::Starting)
      continue;
    // The registered process may be a child of the one we started (a wrapper script), so any
    // member of its process group counts.
    const auto reg = graph_.lookup(rosName(p.name));
    if (reg && reg->host == graph_.host() && reg->pid > 0 &&
        (reg->pid == p.pid || ::getpgid(reg->pid) == p.pid))
      supervisor_.markRunning(p.name);
  }
  for (const auto& name : supervisor_.takeUnrequestedExits())
  {
    // The master tells the older of two same-name nodes to shut down. If someone alive holds
    // the name now, ours was replaced; a stale entry of our dead process does not answer.
    const auto info = supervisor_.info(name);
    if (info && info->pid != 0)
    {
      // Started again (the decision node restarts a node at once) before this check ran.
      ROS_WARN("%s exited by itself and was started again (pid %d); log: %s", name.c_str(),
               info->pid, info->log_file.c_str());
      continue;
    }
    const auto reg = graph_.lookup(rosName(name));
    if (info && reg && reg->pid != 0)
    {
      supervisor_.setFinalState(name, ProcState::Replaced);
      ROS_WARN("%s exited: its name was taken by a node on %s (pid %d)", name.c_str(),
               reg->host.c_str(), reg->pid);
    }
    else if (info && info->adopted && info->exit_code == -1 && info->exit_signal == 0)
    {
      ROS_WARN(
          "%s exited by itself (exit status unknown: it was started by the agent before this one, "
          "so it is "
          "not this agent's child); log: %s",
          name.c_str(), info->log_file.c_str());
    }
    else if (info)
    {
      ROS_WARN("%s exited by itself (code %d, signal %d); log: %s", name.c_str(), info->exit_code,
               info->exit_signal, info->log_file.c_str());
    }
    std::lock_guard<std::mutex> lock(leases_mutex_);
    leases_.remove(name);
  }
  if (const auto local = graph_.localSubscribedTopics(own))
  {
    // The nodes run here first: a topic one of them subscribes to is counted from its bus
    // statistics, and the graph showing that subscription must not start a second one.
    topics_->setRunning(runningNodes(), [] { return false; });
    topics_->update(*local);
  }
}

}  // namespace anyscale_agent
