// Checks of a message's bytes against its layout (request_wire.h).
#include "anyscale_agent_cpp/request_wire.h"

#include <cstring>

namespace anyscale_agent
{

const WireLayout kStartNodeWire{{WireField::String, "node"},
                                {WireField::KeyValueArray, "param_overrides"},
                                {WireField::Float32, "lease_s"},
                                {WireField::Float32, "cpu_percent"},
                                {WireField::Float32, "memory_mb"}};
const WireLayout kStopNodeWire{{WireField::String, "node"},
                               {WireField::Bool, "wait"},
                               {WireField::Float32, "sigint_timeout_s"},
                               {WireField::Bool, "pause"}};
const WireLayout kRenewLeasesWire{{WireField::StringArray, "nodes"},
                                  {WireField::Float32, "lease_s"}};
const WireLayout kListNodesWire{};
const WireLayout kSetWatchedTopicsWire{{WireField::StringArray, "topics"},
                                       {WireField::StringArray, "subscribers"}};
const WireLayout kLinkProbeWire{{WireField::String, "scale"},
                                {WireField::UInt32, "seq"},
                                {WireField::Bool, "bulk"},
                                {WireField::ByteArray, "payload"}};

namespace
{
class Cursor
{
public:
  Cursor(const uint8_t* data, std::size_t size) : data_(data), left_(size) {}

  std::size_t left() const { return left_; }

  // Skips n bytes; false (nothing skipped) if fewer are left.
  bool skip(std::size_t n)
  {
    if (n > left_)
      return false;
    data_ += n;
    left_ -= n;
    return true;
  }

  bool u32(uint32_t* v)
  {
    if (left_ < 4)
      return false;
    // Little-endian on the wire, as on every platform roscpp builds for (it copies too).
    std::memcpy(v, data_, 4);
    return skip(4);
  }

  bool string()
  {
    uint32_t n;
    return u32(&n) && skip(n);
  }

private:
  const uint8_t* data_;
  std::size_t left_;
};

std::size_t fixedSize(WireField::Kind kind)
{
  switch (kind)
  {
    case WireField::Bool: return 1;
    case WireField::UInt32:
    case WireField::Float32: return 4;
    default: return 0;
  }
}

// The fewest bytes one element of an array takes; 0 for a field that is no array.
std::size_t elementSize(WireField::Kind kind)
{
  switch (kind)
  {
    case WireField::ByteArray: return 1;
    case WireField::StringArray: return 4;
    case WireField::KeyValueArray: return 8;
    default: return 0;
  }
}

std::string cut(const WireField& f, const Cursor& c)
{
  return std::string(f.name) + " is cut short (" + std::to_string(c.left()) + " bytes left)";
}
}  // namespace

std::string checkWire(const uint8_t* data, std::size_t size, const WireLayout& layout)
{
  Cursor c(data, size);
  for (const WireField& f : layout)
  {
    if (const std::size_t n = fixedSize(f.kind))
    {
      if (!c.skip(n))
        return cut(f, c);
      continue;
    }
    if (f.kind == WireField::String)
    {
      if (!c.string())
        return cut(f, c);
      continue;
    }
    uint32_t count;
    if (!c.u32(&count))
      return cut(f, c);
    const std::size_t least = elementSize(f.kind);
    if (count > c.left() / least)
      return std::string(f.name) + " claims " + std::to_string(count) + " entries of at least " +
             std::to_string(least) + " bytes each in " + std::to_string(c.left()) + " bytes";
    if (f.kind == WireField::ByteArray)
    {
      c.skip(count);
      continue;
    }
    const int strings = f.kind == WireField::KeyValueArray ? 2 : 1;
    for (uint32_t i = 0; i < count; ++i)
      for (int s = 0; s < strings; ++s)
        if (!c.string())
          return std::string(f.name) + "[" + std::to_string(i) + "] is cut short";
  }
  if (c.left() != 0)
    return std::to_string(c.left()) + " bytes after the last field";
  return "";
}

}  // namespace anyscale_agent
