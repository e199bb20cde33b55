// What a node's own XML-RPC API says it received: parsing of getBusStats and getBusInfo
// replies (no roscpp).
#pragma once

#include <xmlrpcpp/XmlRpcValue.h>

#include <cstdint>
#include <map>
#include <string>
#include <vector>

namespace anyscale_agent
{

// One inbound connection of a subscribed topic, as cumulative counts since it was made.
// XML-RPC integers are 32 bits: roscpp sends its 64-bit byte count cut to an int, so a long
// camera stream wraps; counts are kept as the low 32 bits and differenced modulo 2^32.
struct ConnectionCount
{
  int id = 0;
  uint32_t bytes = 0;
  uint32_t messages = 0;
};

// topic -> its inbound connections (a topic subscribed with no publisher connected: none).
using SubscribedCounts = std::map<std::string, std::vector<ConnectionCount>>;

// The subscribeStats of a getBusStats reply. Two shapes exist (ros_comm 1.15, checked on live
// nodes): rospy answers [1, msg, [publishStats, subscribeStats, serviceStats]] as the slave API
// says, roscpp answers [publishStats, subscribeStats] without code and message. Each
// subscribeStats entry is [topic, [[connectionId, bytesReceived, numMessages, drops,
// connected], ...]]. Returns false with the reason in *error for anything else (a fault
// code, a wrong type, a connection entry with fewer than three integers); *out is then left
// unchanged, so a partial reply is never taken for the node's state.
bool parseBusStats(const XmlRpc::XmlRpcValue& reply, SubscribedCounts* out, std::string* error);

// topic -> inbound connection id -> the publisher's XML-RPC URI, from a getBusInfo reply
// ([code, msg, [[connectionId, destination, direction, transport, topic, connected, info],
// ...]], destination being the publisher's URI where direction is "i"; both client libraries
// answer with a code here). Same failure rules as parseBusStats.
using InboundPublishers = std::map<std::string, std::map<int, std::string>>;
bool parseBusInfo(const XmlRpc::XmlRpcValue& reply, InboundPublishers* out, std::string* error);

// The pid of a getPid reply ([1, msg, pid]); 0 if it is not one.
int parsePidReply(const XmlRpc::XmlRpcValue& reply);

// The port of an "http://host:port/" URI; 0 if it has none.
int uriPort(const std::string& uri);

}  // namespace anyscale_agent
