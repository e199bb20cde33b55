// The bytes of a request, checked against its message's layout before roscpp deserialises it
// (no ROS). roscpp sizes an array for the count a message claims before it looks for the bytes:
// a 12-byte renew_leases claiming 60 million names built 2 GB of strings, a start_node's
// param_overrides 3.8 GB, before any check of the agent's could run.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace anyscale_agent
{

// One field of a message in ROS 1's serialisation: little-endian; a string is its uint32 length
// and bytes, an array its uint32 count and its elements (KeyValue: two strings).
struct WireField
{
  enum Kind
  {
    String,
    Bool,
    UInt32,
    Float32,
    ByteArray,
    StringArray,
    KeyValueArray
  };
  Kind kind;
  const char* name;
};
using WireLayout = std::vector<WireField>;

// "" if data[0, size) is exactly one message of `layout`; else what is wrong, naming the field
// (an array's claim is weighed against the bytes left before anything of it is read).
std::string checkWire(const uint8_t* data, std::size_t size, const WireLayout& layout);

// The agent's service requests (anyscale_msgs/srv) and link probes (anyscale_msgs/LinkProbe).
extern const WireLayout kStartNodeWire;
extern const WireLayout kStopNodeWire;
extern const WireLayout kRenewLeasesWire;
extern const WireLayout kListNodesWire;
extern const WireLayout kSetWatchedTopicsWire;
extern const WireLayout kLinkProbeWire;

}  // namespace anyscale_agent
