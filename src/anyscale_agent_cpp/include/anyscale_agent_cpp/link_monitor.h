// Probing of the link to the master scale over ROS topics; echoing probes on the master.
#pragma once

#include <ros/ros.h>

#include <anyscale_msgs/LinkProbe.h>
#include <anyscale_msgs/LinkStatistics.h>

#include <atomic>
#include <condition_variable>
#include <functional>
#include <limits>
#include <memory>
#include <mutex>
#include <string>
#include <thread>

#include "anyscale_agent_cpp/icmp_echo.h"
#include "anyscale_agent_cpp/link_estimator.h"

namespace anyscale_agent
{

struct LinkOptions
{
  double probe_period_s = 0.5;
  double timeout_s = 1.0;
  int bulk_bytes = 32768;
  double bulk_period_s = 1.0;  // a bulk echo of ~20 ms of the link: 2 % of it
  bool icmp = true;  // bulk probes by ICMP echo where the kernel allows it; false: over ROS
};

// Topics, not a service: a roscpp service call has no timeout and would block for as long as
// TCP retries while the link is down, whereas a probe that gets no echo simply counts as lost.
// The probes travel the same TCP path as node traffic between the two scales.
class LinkMonitor
{
public:
  // `renew_also(now, may_call_master)` runs in the renewal thread about once a second (steady
  // clock `now`): the agent's other subscriptions across the link can die the same way, and are
  // renewed under the same rule (may_call_master: see renewWhenAsked).
  using RenewAlso = std::function<void(double now, const std::function<bool()>& may_call_master)>;
  LinkMonitor(ros::NodeHandle nh, std::string scale, bool is_master, std::string master_scale,
              LinkOptions options, RenewAlso renew_also = {});
  ~LinkMonitor();
  anyscale_msgs::LinkStatistics stats();
  // "ICMP echo to ADDRESS" or "ROS probes" (and why): how the bandwidth is measured.
  const std::string& bandwidthMethod() const { return bandwidth_method_; }

private:
  void onProbe(const anyscale_msgs::LinkProbe::ConstPtr& probe);  // on the master: echo it
  void onEcho(const anyscale_msgs::LinkProbe::ConstPtr& echo);    // elsewhere: an answer
  void onTimer(const ros::SteadyTimerEvent&);
  void send(double t, ProbeKind kind);  // with mutex_ held
  void subscribe();                     // probes on the master, echoes elsewhere
  void resubscribeIfSilent(double t);   // timer thread: asks the renewal thread
  void renewWhenAsked();                // the renewal thread's loop
  void measureByEcho();                 // the ICMP thread's loop
  static double now();

  static constexpr double kResubscribeAfterS = 5.0;
  static constexpr double kMasterReachableWithinS = 1.0;
  ros::NodeHandle nh_;
  RenewAlso renew_also_;
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
  std::atomic<double> last_heard_{
      std::numeric_limits<double>::quiet_NaN()};  // last probe/echo [steady s]
  const double started_at_;                       // [steady s]
  std::atomic<double> resubscribed_at_{0.0};
  double silence_logged_ = std::numeric_limits<double>::quiet_NaN();  // start of the silence logged
  // Renewals in a thread of their own: a subscribe calls the master and waits as long as TCP
  // does, and the timer thread must go on sending probes meanwhile.
  std::mutex renew_mutex_;
  std::condition_variable wake_renewal_;
  bool renewal_wanted_ = false;
  bool renew_stopping_ = false;
  std::thread renew_thread_;
  std::string bandwidth_method_;
  // Bulk probes by ICMP echo where the kernel lets this process send them (see icmp_echo.h),
  // in a thread of their own: a reading blocks for up to two timeouts.
  std::unique_ptr<IcmpEcho> icmp_;
  std::condition_variable wake_icmp_;
  bool stopping_ = false;
  std::thread icmp_thread_;
};

}  // namespace anyscale_agent
