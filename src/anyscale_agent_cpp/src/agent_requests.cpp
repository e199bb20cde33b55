// The agent's service entry points: who asked, the answer, and a log line naming the caller for
// every refusal (an attacker on the network is seen by the node name it gives).
#include "anyscale_agent_cpp/agent_node.h"

#include <algorithm>

#include "anyscale_agent_cpp/request_check.h"

namespace anyscale_agent
{
namespace
{
// Refusals are answered and logged; other answers (a node not running here, a failed start)
// are the decision node's daily business and logged where they happen.
template <class Event>
void logRefusal(const char* service, Event& event)
{
  const std::string& message = event.getResponse().message;
  if (message.rfind("refused", 0) == 0)
    ROS_WARN("%s from caller %s: %s", service, quoted(event.getCallerName()).c_str(),
             message.c_str());
}
}  // namespace

bool AgentNode::onStart(Event<anyscale_msgs::StartNode>& event)
{
  startNode(event.getRequest(), event.getResponse());
  logRefusal("start_node", event);
  return true;
}

bool AgentNode::onStop(Event<anyscale_msgs::StopNode>& event)
{
  stopNode(event.getRequest(), event.getResponse());
  logRefusal("stop_node", event);
  return true;
}

bool AgentNode::onRenew(Event<anyscale_msgs::RenewLeases>& event)
{
  renewLeases(event.getRequest(), event.getResponse());
  logRefusal("renew_leases", event);
  return true;
}

bool AgentNode::onList(Event<anyscale_msgs::ListNodes>& event)
{
  std::lock_guard<std::mutex> lock(sample_mutex_);
  event.getResponse().nodes = nodeProcesses();
  return true;
}

bool AgentNode::onSetWatched(Event<anyscale_msgs::SetWatchedTopics>& event)
{
  setWatched(event.getRequest(), event.getResponse());
  logRefusal("set_watched_topics", event);
  return true;
}

void AgentNode::setWatched(const anyscale_msgs::SetWatchedTopics::Request& req,
                           anyscale_msgs::SetWatchedTopics::Response& res)
{
  res.success = false;
  if (req.topics.size() > kMaxWatchedTopics || req.subscribers.size() > kMaxWatchedTopics)
  {
    res.message =
        "refused: " + std::to_string(std::max(req.topics.size(), req.subscribers.size())) +
        " topics or subscribers, at most " + std::to_string(kMaxWatchedTopics) + " may be watched";
    return;
  }
  // A subscriber named here has its topic counted on this scale (pulled across the link if it
  // is published elsewhere): only the model's subscribers, for their own topics.
  for (std::size_t i = 0; i < req.subscribers.size() && i < req.topics.size(); ++i)
    if (!req.subscribers[i].empty() && !model_.subscribes(req.subscribers[i], req.topics[i]))
    {
      res.message = "refused: subscriber " + quoted(req.subscribers[i]) + " of " +
                    quoted(req.topics[i]) +
                    ": no connection of the model has that node subscribe to that topic";
      return;
    }
  std::string error;
  res.success = topics_->setWatched(req.topics, req.subscribers, &error);
  res.message = res.success ? "watching " + std::to_string(req.topics.size()) +
                                  " topics where a local node subscribes"
                            : "refused: " + error;
}

}  // namespace anyscale_agent
