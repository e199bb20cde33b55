// roscpp callback helpers that check a message's bytes against its layout (request_wire.h)
// before roscpp deserialises them: a request that claims more entries than it carries fails
// with the reason, and such a message on a topic is dropped, before roscpp would allocate for
// the claim.
#pragma once

#include <ros/service_callback_helper.h>
#include <ros/subscription_callback_helper.h>

#include <string>

#include "anyscale_agent_cpp/request_wire.h"

namespace anyscale_agent
{

class WireCheckedService : public ros::ServiceCallbackHelper
{
public:
  WireCheckedService(ros::ServiceCallbackHelperPtr inner, const WireLayout& layout,
                     std::string service);
  // Throws std::runtime_error("refused: ...") for a refused request: roscpp answers the call as
  // failed with that text.
  bool call(ros::ServiceCallbackHelperCallParams& params) override;

private:
  ros::ServiceCallbackHelperPtr inner_;
  const WireLayout& layout_;
  std::string service_;
};

class WireCheckedSubscription : public ros::SubscriptionCallbackHelper
{
public:
  WireCheckedSubscription(ros::SubscriptionCallbackHelperPtr inner, const WireLayout& layout,
                          std::string topic);
  // Null for a refused message: roscpp then calls no callback.
  ros::VoidConstPtr deserialize(
      const ros::SubscriptionCallbackHelperDeserializeParams& params) override;
  void call(ros::SubscriptionCallbackHelperCallParams& params) override { inner_->call(params); }
  const std::type_info& getTypeInfo() override { return inner_->getTypeInfo(); }
  bool isConst() override { return inner_->isConst(); }
  bool hasHeader() override { return inner_->hasHeader(); }

private:
  ros::SubscriptionCallbackHelperPtr inner_;
  const WireLayout& layout_;
  std::string topic_;
};

}  // namespace anyscale_agent
