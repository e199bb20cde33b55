// Wire checks in roscpp's callback helpers (wire_checked.h).
#include "anyscale_agent_cpp/wire_checked.h"

#include <ros/console.h>

#include <stdexcept>

#include "anyscale_agent_cpp/request_check.h"

namespace anyscale_agent
{
namespace
{
std::string caller(const boost::shared_ptr<ros::M_string>& header)
{
  if (!header)
    return "''";
  const auto it = header->find("callerid");
  return quoted(it == header->end() ? "" : it->second);
}
}  // namespace

WireCheckedService::WireCheckedService(ros::ServiceCallbackHelperPtr inner,
                                       const WireLayout& layout, std::string service)
  : inner_(std::move(inner)), layout_(layout), service_(std::move(service))
{}

bool WireCheckedService::call(ros::ServiceCallbackHelperCallParams& params)
{
  const ros::SerializedMessage& m = params.request;
  const std::size_t size = m.num_bytes - std::size_t(m.message_start - m.buf.get());
  if (const std::string why = checkWire(m.message_start, size, layout_); !why.empty())
  {
    ROS_WARN("%s from caller %s: refused before it was read: %s", service_.c_str(),
             caller(params.connection_header).c_str(), why.c_str());
    throw std::runtime_error("refused: " + why);
  }
  return inner_->call(params);
}

WireCheckedSubscription::WireCheckedSubscription(ros::SubscriptionCallbackHelperPtr inner,
                                                 const WireLayout& layout, std::string topic)
  : inner_(std::move(inner)), layout_(layout), topic_(std::move(topic))
{}

ros::VoidConstPtr WireCheckedSubscription::deserialize(
    const ros::SubscriptionCallbackHelperDeserializeParams& params)
{
  if (const std::string why = checkWire(params.buffer, params.length, layout_); !why.empty())
  {
    ROS_WARN_THROTTLE(10.0, "%s from %s: dropped before it was read: %s", topic_.c_str(),
                      caller(params.connection_header).c_str(), why.c_str());
    return ros::VoidConstPtr();
  }
  return inner_->deserialize(params);
}

}  // namespace anyscale_agent
