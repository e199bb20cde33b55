// Carrier state of a network interface from getifaddrs(3).
#include "anyscale_agent_cpp/uplink_carrier.h"

#include <ifaddrs.h>
#include <net/if.h>

#include <algorithm>
#include <memory>

namespace anyscale_agent
{
namespace
{
using IfAddrs = std::unique_ptr<ifaddrs, decltype(&::freeifaddrs)>;

IfAddrs readIfAddrs()
{
  ifaddrs* list = nullptr;
  if (::getifaddrs(&list) != 0)
    list = nullptr;
  return IfAddrs(list, &::freeifaddrs);
}
}  // namespace

Carrier readCarrier(const std::string& interface)
{
  const IfAddrs list = readIfAddrs();
  // One entry per address family; every entry of an interface carries the same flags.
  for (const ifaddrs* a = list.get(); a != nullptr; a = a->ifa_next)
    if (a->ifa_name != nullptr && interface == a->ifa_name)
      return (a->ifa_flags & IFF_UP) && (a->ifa_flags & IFF_RUNNING) ? Carrier::Up : Carrier::Down;
  return Carrier::Missing;
}

std::vector<std::string> interfaceNames()
{
  std::vector<std::string> names;
  const IfAddrs list = readIfAddrs();
  for (const ifaddrs* a = list.get(); a != nullptr; a = a->ifa_next)
    if (a->ifa_name != nullptr && std::find(names.begin(), names.end(), a->ifa_name) == names.end())
      names.emplace_back(a->ifa_name);
  return names;
}

const char* toString(Carrier c)
{
  switch (c)
  {
    case Carrier::Up: return "up";
    case Carrier::Down: return "down";
    case Carrier::Missing: return "missing";
  }
  return "?";
}

}  // namespace anyscale_agent
