// Parsing of the getBusStats, getBusInfo and getPid replies of roscpp and rospy nodes.
#include "anyscale_agent_cpp/bus_stats_reply.h"

#include <cstdlib>

namespace anyscale_agent
{
namespace
{
using XmlRpc::XmlRpcValue;

bool isArray(const XmlRpcValue& v, int min_size = 0)
{
  return v.getType() == XmlRpcValue::TypeArray && v.size() >= min_size;
}

bool isInt(const XmlRpcValue& v)
{
  return v.getType() == XmlRpcValue::TypeInt;
}

// The payload of a [code, msg, payload] reply, or nullptr with the reason.
const XmlRpcValue* payload(const XmlRpcValue& reply, std::string* why)
{
  if (!isArray(reply, 3) || !isInt(reply[0]))
  {
    *why = "not a [code, message, value] reply";
    return nullptr;
  }
  if (int(reply[0]) != 1)
  {
    const std::string msg =
        reply[1].getType() == XmlRpcValue::TypeString ? std::string(reply[1]) : "";
    *why = "the node answered code " + std::to_string(int(reply[0])) +
           (msg.empty() ? "" : " (" + msg + ")");
    return nullptr;
  }
  return &reply[2];
}

bool fail(std::string* error, const std::string& why)
{
  if (error)
    *error = why;
  return false;
}

}  // namespace

bool parseBusStats(const XmlRpcValue& reply, SubscribedCounts* out, std::string* error)
{
  // rospy: [code, msg, [pub, sub, svc]]; roscpp: [pub, sub] (its callback leaves out the code).
  const XmlRpcValue* stats = &reply;
  if (isArray(reply, 1) && isInt(reply[0]))
  {
    std::string why;
    stats = payload(reply, &why);
    if (!stats)
      return fail(error, "getBusStats: " + why);
  }
  if (!isArray(*stats, 2))
    return fail(error, "getBusStats: no [publishStats, subscribeStats, ...] list");
  const XmlRpcValue& subs = (*stats)[1];
  if (!isArray(subs))
    return fail(error, "getBusStats: subscribeStats is not a list");
  SubscribedCounts parsed;
  for (int i = 0; i < subs.size(); ++i)
  {
    const XmlRpcValue& entry = subs[i];
    if (!isArray(entry, 2) || entry[0].getType() != XmlRpcValue::TypeString || !isArray(entry[1]))
      return fail(error, "getBusStats: subscribeStats entry " + std::to_string(i) +
                             " is not [topic, [connections]]");
    const std::string topic = entry[0];
    auto& conns = parsed[topic];
    for (int j = 0; j < entry[1].size(); ++j)
    {
      const XmlRpcValue& c = entry[1][j];
      if (!isArray(c, 3) || !isInt(c[0]) || !isInt(c[1]) || !isInt(c[2]))
        return fail(error, "getBusStats: connection " + std::to_string(j) + " of " + topic +
                               " is not [id, bytes, messages, ...] integers");
      ConnectionCount count;
      count.id = int(c[0]);
      count.bytes = uint32_t(int(c[1]));
      count.messages = uint32_t(int(c[2]));
      conns.push_back(count);
    }
  }
  *out = std::move(parsed);
  return true;
}

bool parseBusInfo(const XmlRpcValue& reply, InboundPublishers* out, std::string* error)
{
  std::string why;
  const XmlRpcValue* info = payload(reply, &why);
  if (!info)
    return fail(error, "getBusInfo: " + why);
  if (!isArray(*info))
    return fail(error, "getBusInfo: no list of connections");
  InboundPublishers parsed;
  for (int i = 0; i < info->size(); ++i)
  {
    const XmlRpcValue& c = (*info)[i];
    if (!isArray(c, 5) || !isInt(c[0]) || c[1].getType() != XmlRpcValue::TypeString ||
        c[2].getType() != XmlRpcValue::TypeString || c[4].getType() != XmlRpcValue::TypeString)
      return fail(error, "getBusInfo: connection entry " + std::to_string(i) +
                             " is not [id, destination, direction, transport, topic, ...]");
    if (std::string(c[2]) == "i")
      parsed[std::string(c[4])][int(c[0])] = std::string(c[1]);
  }
  *out = std::move(parsed);
  return true;
}

int parsePidReply(const XmlRpcValue& reply)
{
  std::string why;
  const XmlRpcValue* pid = payload(reply, &why);
  return pid && isInt(*pid) && int(*pid) > 0 ? int(*pid) : 0;
}

int uriPort(const std::string& uri)
{
  const auto scheme = uri.find("://");
  const std::size_t host = scheme == std::string::npos ? 0 : scheme + 3;
  const auto colon = uri.rfind(':');
  if (colon == std::string::npos || colon < host)
    return 0;
  char* end = nullptr;
  const long port = std::strtol(uri.c_str() + colon + 1, &end, 10);
  if (end == uri.c_str() + colon + 1 || (*end != '\0' && *end != '/') || port <= 0 || port > 65535)
    return 0;
  return int(port);
}

}  // namespace anyscale_agent
