// ShapeShifter subscriptions feeding one RateWindow per watched topic.
#include "anyscale_agent_cpp/topic_watcher.h"

#include <ros/names.h>

#include <chrono>
#include <limits>

#include "anyscale_agent_cpp/request_check.h"

namespace anyscale_agent
{

namespace
{

double steadyNow()
{
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

}  // namespace

void InlineCallbackQueue::addCallback(const ros::CallbackInterfacePtr& callback, uint64_t)
{
  // TryAgain (the subscription queue busy elsewhere) leaves the message queued; the next
  // arrival calls again and takes it, so nothing is lost.
  callback->call();
}

void InlineCallbackQueue::removeByID(uint64_t)
{
  // Nothing is ever held here.
}

TopicWatcher::TopicWatcher(ros::NodeHandle nh, double window_s, int queue_size, bool watch_all,
                           bool by_bus_stats, double bus_stats_period_s, double bus_stats_timeout_s,
                           PublisherSeen on_publisher)
  : nh_(nh),
    window_s_(window_s),
    queue_size_(queue_size),
    watch_all_(watch_all),
    by_bus_stats_(by_bus_stats),
    on_publisher_(std::move(on_publisher))
{
  nh_.setCallbackQueue(&inline_queue_);
  poller_ = std::make_unique<BusStatsPoller>(window_s, bus_stats_period_s, bus_stats_timeout_s,
                                             ros::this_node::getName(), on_publisher_);
}

bool TopicWatcher::setWatched(const std::vector<std::string>& topics,
                              const std::vector<std::string>& subscribers, std::string* error)
{
  for (const auto& t : topics)
  {
    std::string why;
    if (t.empty() || t[0] != '/' || !ros::names::validate(t, why))
    {
      if (error)
        *error = "topic " + quoted(t) + " is not a valid resolved name (e.g. /scan)" +
                 (why.empty() ? "" : ": " + quoted(why, 200));
      return false;
    }
  }
  for (const auto& n : subscribers)
  {
    std::string why;
    if (!n.empty() && (n[0] != '/' || !ros::names::validate(n, why)))
    {
      if (error)
        *error = "subscriber " + quoted(n) +
                 " is not a fully qualified node name (e.g. /amcl) or \"\"" +
                 (why.empty() ? "" : ": " + quoted(why, 200));
      return false;
    }
  }
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (!watched_.assign(topics, subscribers, error))
      return false;
  }
  apply();
  return true;
}

std::vector<std::string> TopicWatcher::watched() const
{
  std::lock_guard<std::mutex> lock(mutex_);
  return watched_.topics();
}

void TopicWatcher::subscribe(const std::string& topic, const std::shared_ptr<Counter>& c)
{
  std::weak_ptr<Counter> weak = c;
  boost::function<void(const ros::MessageEvent<topic_tools::ShapeShifter const>&)> cb =
      [weak,
       seen = on_publisher_](const ros::MessageEvent<topic_tools::ShapeShifter const>& event) {
        const auto counter = weak.lock();
        if (!counter)
          return;
        {
          const auto& msg = event.getConstMessage();
          std::lock_guard<std::mutex> lock(counter->mutex);
          // Receipt time is stamped by the transport thread when the message arrives.
          counter->window.add(event.getReceiptTime().toSec(), msg->size());
          counter->last_seen = steadyNow();
          if (counter->datatype.empty())
            counter->datatype = msg->getDataType();
        }
        if (seen)
          seen(event.getPublisherName());
      };
  {
    std::lock_guard<std::mutex> lock(c->mutex);
    c->subscribed_at = steadyNow();
  }
  c->sub = nh_.subscribe<topic_tools::ShapeShifter>(
      topic, uint32_t(queue_size_), cb, ros::VoidConstPtr(), ros::TransportHints().tcpNoDelay());
}

void TopicWatcher::update(const std::set<std::string>& local_topics)
{
  {
    std::lock_guard<std::mutex> lock(mutex_);
    local_topics_ = local_topics;
  }
  apply();
}

void TopicWatcher::setRunning(const std::map<std::string, RunningNode>& running,
                              const std::function<bool()>& may_call_master)
{
  Plan p;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    running_.clear();
    for (const auto& entry : running)
      running_.insert(entry.first);
    running_nodes_ = running;
    p = plan();
  }
  applyBus();
  bool same;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    same = p.subscribed.size() == counters_.size();
    for (auto it = p.subscribed.begin(); same && it != p.subscribed.end(); ++it)
      same = counters_.count(*it) > 0;
  }
  // roscpp's subscribe and unsubscribe call the master and retry until it answers.
  if (!same && may_call_master())
    apply();
}

TopicWatcher::Plan TopicWatcher::plan() const
{
  Plan p;
  const std::set<std::string> wanted = watched_.toCount(local_topics_, running_, watch_all_);
  std::set<std::string>
      receiving;  // a paused node receives nothing: its inputs are not its to count
  for (const auto& [name, node] : running_nodes_)
    if (!node.paused && node.pid > 0)
      receiving.insert(name);
  for (const auto& [topic, name] :
       watched_.runningSubscribers(by_bus_stats_ ? receiving : std::set<std::string>{}))
  {
    const RunningNode& node = running_nodes_.at(name);
    p.polled[topic] = {node.instance, node.pid};
  }
  // Still polled while refused, so that a node whose replies are good again takes its topics back.
  p.refused = poller_->refused();
  for (const auto& t : wanted)
  {
    if (p.polled.count(t) && !p.refused.count(t))
      p.by_bus.insert(t);
    else
      p.subscribed.insert(t);
  }
  return p;
}

std::string TopicWatcher::describeLocked() const
{
  std::string graph, running;
  for (const auto& t : local_topics_)
    graph += (graph.empty() ? "" : " ") + t;
  for (const auto& n : running_)
    running += (running.empty() ? "" : " ") + n;
  return "subscribed here by the graph: [" + graph + "]; nodes run here: [" + running + "]";
}

void TopicWatcher::applyBus()
{
  // Recomputed here, one caller at a time: a plan made before another thread's newer one must
  // not be applied after it.
  std::lock_guard<std::mutex> applying(applying_bus_);
  Plan p;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    p = plan();
  }
  poller_->setTargets(p.polled, [this] {
    std::vector<BusStatsPoller::Node> out;
    std::lock_guard<std::mutex> lock(mutex_);
    for (const auto& entry : running_nodes_)
      out.push_back({entry.second.instance, entry.second.pid});
    return out;
  }());
  std::map<std::string, std::string> now;
  for (const auto& t : p.by_bus)
    now[t] = p.polled.at(t).name;
  std::map<std::string, std::string> before;
  std::string why;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (now == by_bus_)
      return;
    before = by_bus_;
    by_bus_ = now;
    why = describeLocked();
  }
  // A switch between a node's bus statistics and a subscription changes what crosses the link.
  for (const auto& [topic, node] : before)
    if (now.count(topic) == 0 || now.at(topic) != node)
    {
      const auto refused = p.refused.find(topic);
      ROS_INFO("topic counter: no longer counting %s from the bus statistics of %s (%s; %s)",
               topic.c_str(), node.c_str(),
               refused != p.refused.end() ? ("its replies are refused: " + refused->second).c_str()
                                          : "it no longer runs here, or is paused",
               why.c_str());
    }
  for (const auto& [topic, node] : now)
    if (before.count(topic) == 0 || before.at(topic) != node)
      ROS_INFO(
          "topic counter: counting %s from the bus statistics of %s, a node run here that "
          "subscribes to it: "
          "no subscription of the agent's, so the topic does not cross a link twice (%s)",
          topic.c_str(), node.c_str(), why.c_str());
}

void TopicWatcher::apply()
{
  std::lock_guard<std::mutex> subscribing(subscribing_);
  std::map<std::string, std::shared_ptr<Counter>> dropped, added;
  Plan p;
  std::string why;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    p = plan();
    for (auto it = counters_.begin(); it != counters_.end();)
    {
      if (!p.subscribed.count(it->first))
      {
        dropped.insert(*it);
        it = counters_.erase(it);
      }
      else
      {
        ++it;
      }
    }
    for (const auto& t : p.subscribed)
      if (!counters_.count(t))
        added[t] = counters_[t] = std::make_shared<Counter>(window_s_);
    why = describeLocked();
  }
  applyBus();
  // Counters come and go with moves, a few times a run: each change is logged with what it was
  // based on. (A counter dropped while its node still ran here once made the decision node
  // bring AMCL and AR home from a 27 Mbit/s link; the log could not say why.)
  for (const auto& entry : dropped)
    ROS_INFO("topic counter: stopped counting %s with a subscription (%s%s)", entry.first.c_str(),
             p.by_bus.count(entry.first) ? "now counted from a node's bus statistics; " : "",
             why.c_str());
  for (const auto& entry : added)
  {
    const auto refused = p.refused.find(entry.first);
    const std::string reason =
        refused != p.refused.end()
            ? "the bus statistics of its subscriber here are refused: " + refused->second
        : watch_all_ ? "~watch_all, or no node run here subscribes to it"
                     : "no node run here subscribes to it, a node of this host does";
    ROS_INFO("topic counter: counting %s with a subscription of its own (%s; %s)",
             entry.first.c_str(), reason.c_str(), why.c_str());
  }
  for (auto& [topic, c] : dropped)
    c->sub.shutdown();
  for (auto& [topic, c] : added)
    subscribe(topic, c);
}

void TopicWatcher::renewSilent(double now, double silent_s,
                               const std::function<bool()>& may_call_master)
{
  std::lock_guard<std::mutex> subscribing(subscribing_);
  std::map<std::string, std::shared_ptr<Counter>> silent;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    for (const auto& [topic, c] : counters_)
    {
      if (by_bus_.count(topic))
        continue;
      std::lock_guard<std::mutex> counter_lock(c->mutex);
      if (now - std::max(c->last_seen, c->subscribed_at) >= silent_s)
        silent.emplace(topic, c);
    }
  }
  if (silent.empty() || !may_call_master())
    return;
  for (auto& [topic, c] : silent)
  {
    {
      // Once per silence: a topic whose publisher stopped is subscribed again every silent_s.
      std::lock_guard<std::mutex> counter_lock(c->mutex);
      if (c->last_seen >= c->subscribed_at)
        ROS_INFO("topic counter: nothing on %s for %.1f s: subscribing again", topic.c_str(),
                 now - c->last_seen);
    }
    // Released first: roscpp keeps one subscription per topic, and a new subscriber beside the
    // old one would only share its dead connection.
    c->sub.shutdown();
    subscribe(topic, c);
  }
}

std::vector<anyscale_msgs::TopicStatistics> TopicWatcher::stats(const ros::Time& now)
{
  std::map<std::string, std::shared_ptr<Counter>> counters;
  std::map<std::string, std::string> by_bus;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    counters = counters_;
    by_bus = by_bus_;
  }
  std::vector<std::pair<std::string, RateStats>> rates;
  std::map<std::string, std::string> datatypes;
  for (const auto& r : poller_->stats(steadyNow()))
    if (by_bus.count(r.topic))
      rates.emplace_back(r.topic, r.stats);  // no datatype: nothing of the message is seen
  for (const auto& [topic, c] : counters)
  {
    // A subscription still waiting for the master to let it go while the bus statistics count.
    if (by_bus.count(topic))
      continue;
    std::lock_guard<std::mutex> lock(c->mutex);
    rates.emplace_back(topic, c->window.stats(now.toSec()));
    datatypes[topic] = c->datatype;
  }
  std::vector<anyscale_msgs::TopicStatistics> out;
  for (const auto& [topic, s] : rates)
  {
    anyscale_msgs::TopicStatistics m;
    m.topic = topic;
    m.datatype = datatypes[topic];
    m.rate_hz = float(s.rate_hz);
    m.interval_min_s = float(s.interval_min_s);
    m.interval_max_s = float(s.interval_max_s);
    m.interval_std_s = float(s.interval_std_s);
    m.bytes_per_second = float(s.bytes_per_second);
    m.last_message_age_s = float(s.last_message_age_s);
    m.window_messages = uint32_t(s.window_messages);
    m.window_s = float(s.window_s);
    out.push_back(m);
  }
  return out;
}

}  // namespace anyscale_agent
