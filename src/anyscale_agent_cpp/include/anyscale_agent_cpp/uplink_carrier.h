// Whether the network interface that carries the link to the other scales has a carrier.
#pragma once

#include <string>
#include <vector>

namespace anyscale_agent
{

enum class Carrier
{
  Up,       // administratively up and the kernel reports a carrier (IFF_UP and IFF_RUNNING)
  Down,     // present, but down or without carrier (a WiFi station that lost its access point)
  Missing,  // no interface of that name in this network namespace (e.g. a USB adapter unplugged)
};

// Reads the interface's flags with getifaddrs(3), which answers for the caller's network
// namespace; /sys/class/net would show the namespace /sys was mounted in, which is not always
// the caller's (a process moved into a namespace without remounting /sys).
Carrier readCarrier(const std::string& interface);

// The interface names of this network namespace, for error messages.
std::vector<std::string> interfaceNames();

const char* toString(Carrier c);

}  // namespace anyscale_agent
