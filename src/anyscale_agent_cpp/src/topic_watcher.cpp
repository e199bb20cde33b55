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
                           PublisherSeen on_publisher)
  : nh_(nh), window_s_(window_s), queue_size_(queue_size), watch_all_(watch_all), on_publisher_(std::move(on_publisher))
{
  nh_.setCallbackQueue(&inline_queue_);
}

bool TopicWatcher::setWatched(const std::vector<std::string>& topics, const std::vector<std::string>& subscribers,
                              std::string* error)
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
        *error = "subscriber " + quoted(n) + " is not a fully qualified node name (e.g. /amcl) or \"\"" +
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
      [weak, seen = on_publisher_](const ros::MessageEvent<topic_tools::ShapeShifter const>& event) {
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
  c->sub = nh_.subscribe<topic_tools::ShapeShifter>(topic, uint32_t(queue_size_), cb, ros::VoidConstPtr(),
                                                      ros::TransportHints().tcpNoDelay());
}

void TopicWatcher::update(const std::set<std::string>& local_topics)
{
  {
    std::lock_guard<std::mutex> lock(mutex_);
    local_topics_ = local_topics;
  }
  apply();
}

void TopicWatcher::setRunning(const std::set<std::string>& running, const std::function<bool()>& may_call_master)
{
  {
    std::lock_guard<std::mutex> lock(mutex_);
    running_ = running;
    const std::set<std::string> wanted = watched_.toCount(local_topics_, running_, watch_all_);
    bool same = wanted.size() == counters_.size();
    for (auto it = wanted.begin(); same && it != wanted.end(); ++it)
      same = counters_.count(*it) > 0;
    if (same)
      return;
  }
  // roscpp's subscribe and unsubscribe call the master and retry until it answers.
  if (may_call_master())
    apply();
}

void TopicWatcher::apply()
{
  std::lock_guard<std::mutex> subscribing(subscribing_);
  std::map<std::string, std::shared_ptr<Counter>> dropped, added;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    const std::set<std::string> wanted = watched_.toCount(local_topics_, running_, watch_all_);
    for (auto it = counters_.begin(); it != counters_.end();)
    {
      if (!wanted.count(it->first))
      {
        dropped.insert(*it);
        it = counters_.erase(it);
      }
      else
      {
        ++it;
      }
    }
    for (const auto& t : wanted)
      if (!counters_.count(t))
        added[t] = counters_[t] = std::make_shared<Counter>(window_s_);
  }
  // Counters come and go with moves, a few times a run: each change is logged with what it was
  // based on. (A counter dropped while its node still ran here once made the decision node
  // bring AMCL and AR home from a 27 Mbit/s link; the log could not say why.)
  if (!dropped.empty() || !added.empty())
  {
    std::string graph, running;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      for (const auto& t : local_topics_)
        graph += (graph.empty() ? "" : " ") + t;
      for (const auto& n : running_)
        running += (running.empty() ? "" : " ") + n;
    }
    for (const auto& entry : dropped)
      ROS_INFO("topic counter: stopped counting %s (subscribed here by the graph: [%s]; nodes run here: [%s])",
               entry.first.c_str(), graph.c_str(), running.c_str());
    for (const auto& entry : added)
      ROS_INFO("topic counter: counting %s (subscribed here by the graph: [%s]; nodes run here: [%s])",
               entry.first.c_str(), graph.c_str(), running.c_str());
  }
  for (auto& [topic, c] : dropped)
    c->sub.shutdown();
  for (auto& [topic, c] : added)
    subscribe(topic, c);
}

void TopicWatcher::renewSilent(double now, double silent_s, const std::function<bool()>& may_call_master)
{
  std::lock_guard<std::mutex> subscribing(subscribing_);
  std::map<std::string, std::shared_ptr<Counter>> silent;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    for (const auto& [topic, c] : counters_)
    {
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
        ROS_INFO("topic counter: nothing on %s for %.1f s: subscribing again", topic.c_str(), now - c->last_seen);
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
  {
    std::lock_guard<std::mutex> lock(mutex_);
    counters = counters_;
  }
  std::vector<anyscale_msgs::TopicStatistics> out;
  for (const auto& [topic, c] : counters)
  {
    std::lock_guard<std::mutex> lock(c->mutex);
    const RateStats s = c->window.stats(now.toSec());
    anyscale_msgs::TopicStatistics m;
    m.topic = topic;
    m.datatype = c->datatype;
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
