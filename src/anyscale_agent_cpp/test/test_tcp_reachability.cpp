// tcpConnects: a listening port, a closed one, an address nobody answers, bad input.
#include <gtest/gtest.h>

#include <netinet/in.h>
#include <sys/socket.h>

#include <chrono>

#include "anyscale_agent_cpp/tcp_reachability.h"
#include "anyscale_agent_cpp/unique_fd.h"

using anyscale_agent::tcpConnects;
using anyscale_agent::UniqueFd;

namespace
{

// A socket listening on a free loopback port; returns the port.
int listenOnLoopback(UniqueFd& fd)
{
  fd = UniqueFd(::socket(AF_INET, SOCK_STREAM, 0));
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  socklen_t len = sizeof(a);
  if (::bind(fd.get(), reinterpret_cast<sockaddr*>(&a), len) != 0 || ::listen(fd.get(), 4) != 0 ||
      ::getsockname(fd.get(), reinterpret_cast<sockaddr*>(&a), &len) != 0)
    return -1;
  return ntohs(a.sin_port);
}

}  // namespace

TEST(TcpReachability, AListeningPortConnects)
{
  UniqueFd server;
  const int port = listenOnLoopback(server);
  ASSERT_GT(port, 0);
  EXPECT_TRUE(tcpConnects("127.0.0.1", port, 1.0));
  EXPECT_TRUE(tcpConnects("localhost", port, 1.0));
}

TEST(TcpReachability, AClosedPortDoesNot)
{
  int port;
  {
    UniqueFd server;
    port = listenOnLoopback(server);
  }  // closed again: nothing listens there now
  ASSERT_GT(port, 0);
  EXPECT_FALSE(tcpConnects("127.0.0.1", port, 1.0));
}

TEST(TcpReachability, AnAddressThatNeverAnswersTimesOut)
{
  // TEST-NET-1 (RFC 5737): never routed; where there is no route at all, connect fails at once.
  const auto t0 = std::chrono::steady_clock::now();
  EXPECT_FALSE(tcpConnects("192.0.2.1", 11311, 0.3));
  EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(), 2.0);
}

TEST(TcpReachability, BadInputIsFalseNotAnError)
{
  EXPECT_FALSE(tcpConnects("", 11311, 0.1));
  EXPECT_FALSE(tcpConnects("no such host.invalid", 11311, 0.1));
  EXPECT_FALSE(tcpConnects("127.0.0.1", 0, 0.1));
  EXPECT_FALSE(tcpConnects("127.0.0.1", 70000, 0.1));
}
