// Probing of the link to the master scale over ROS topics; echoing probes on the master.
#pragma once

#include <ros/ros.h>

#include <anyscale_msgs/LinkProbe.h>
#include <anyscale_msgs/LinkStatistics.h>

#include <mutex>
#include <string>

#include "anyscale_agent_cpp/link_estimator.h"

namespace anyscale_agent
{

struct LinkOptions
{
  double probe_period_s = 0.5;
  double timeout_s = 1.0;
  int bulk_bytes = 65536;
  double bulk_period_s = 5.0;
};

// Topics, not a service: a roscpp service call has no timeout and would block for as long as
// TCP retries while the link is down, whereas a probe that gets no echo simply counts as lost.
// The probes travel the same TCP path as node traffic between the two scales.
class LinkMonitor
{
public:
  LinkMonitor(ros::NodeHandle nh, std::string scale, bool is_master, std::string master_scale, LinkOptions options);
  anyscale_msgs::LinkStatistics stats();

private:
  void onProbe(const anyscale_msgs::LinkProbe::ConstPtr& probe);  // on the master: echo it
  void onEcho(const anyscale_msgs::LinkProbe::ConstPtr& echo);     // elsewhere: an answer
  void onTimer(const ros::SteadyTimerEvent&);
  void send(double t, ProbeKind kind);  // with mutex_ held
  static double now();

  std::string scale_;
  bool is_master_;
  std::string master_scale_;
  LinkOptions options_;
  ros::Publisher pub_;
  ros::Subscriber sub_;
  ros::SteadyTimer timer_;
  std::mutex mutex_;
  LinkEstimator estimator_;
  uint32_t seq_ = 0;
  double last_bulk_ = -1e9;
  bool peer_seen_ = false;
};

}  // namespace anyscale_agent
