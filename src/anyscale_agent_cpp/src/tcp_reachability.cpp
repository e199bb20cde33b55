// Whether a TCP connection opens within a timeout: a non-blocking connect and poll.
#include "anyscale_agent_cpp/tcp_reachability.h"

#include <fcntl.h>
#include <netdb.h>
#include <poll.h>
#include <sys/socket.h>

#include <cerrno>
#include <cmath>
#include <memory>

#include "anyscale_agent_cpp/unique_fd.h"

namespace anyscale_agent
{

bool tcpConnects(const std::string& host, int port, double timeout_s)
{
  addrinfo hints{};
  hints.ai_family = AF_UNSPEC;
  hints.ai_socktype = SOCK_STREAM;
  addrinfo* found = nullptr;
  if (port <= 0 || port > 65535 ||
      getaddrinfo(host.c_str(), std::to_string(port).c_str(), &hints, &found) != 0)
    return false;
  const std::unique_ptr<addrinfo, decltype(&freeaddrinfo)> addresses(found, &freeaddrinfo);
  const int timeout_ms = int(std::ceil(std::max(0.0, timeout_s) * 1000.0));
  for (const addrinfo* a = addresses.get(); a; a = a->ai_next)
  {
    UniqueFd fd(
        ::socket(a->ai_family, a->ai_socktype | SOCK_NONBLOCK | SOCK_CLOEXEC, a->ai_protocol));
    if (fd.get() < 0)
      continue;
    if (::connect(fd.get(), a->ai_addr, a->ai_addrlen) == 0)
      return true;
    if (errno != EINPROGRESS)
      continue;
    pollfd p{fd.get(), POLLOUT, 0};
    int ready;
    do
      ready = ::poll(&p, 1, timeout_ms);
    while (ready < 0 && errno == EINTR);
    int error = 0;
    socklen_t len = sizeof(error);
    if (ready == 1 && ::getsockopt(fd.get(), SOL_SOCKET, SO_ERROR, &error, &len) == 0 && error == 0)
      return true;
  }
  return false;
}

}  // namespace anyscale_agent
