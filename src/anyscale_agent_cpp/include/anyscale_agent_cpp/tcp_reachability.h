// Whether a TCP connection to a host and port opens within a timeout (no ROS).
#pragma once

#include <string>

namespace anyscale_agent
{

// Why: roscpp's calls to the master have no timeout (XmlRpcClient waits for as long as TCP
// retries), and a subscribe holds roscpp's subscription lock for the whole call. Started on a
// link that comes and goes, one such call held a laptop agent for 220 s. A connect that must
// succeed within `timeout_s` tells, without committing to anything, whether a call could go
// through now. Returns false on any error (resolution, refusal, unreachable, timeout).
bool tcpConnects(const std::string& host, int port, double timeout_s);

}  // namespace anyscale_agent
