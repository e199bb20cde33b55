// gtest: rates from cumulative bus statistics counts, listening sockets in /proc, the nodes
// counted from.
#include <gtest/gtest.h>

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <optional>

#include "anyscale_agent_cpp/bus_stats_rate.h"
#include "anyscale_agent_cpp/listening_sockets.h"
#include "anyscale_agent_cpp/proc_net_tcp.h"
#include "anyscale_agent_cpp/unique_fd.h"
#include "anyscale_agent_cpp/watch_list.h"

using namespace anyscale_agent;

namespace
{

// Counts of a steady stream of `hz` on one connection, as a node would report them at `t`.
std::vector<ConnectionCount> steady(double hz, double t, int id = 0, uint32_t bytes_each = 100,
                                    double phase = 0.0)
{
  const uint32_t n = uint32_t(std::floor(hz * t + phase));
  return {{id, n * bytes_each, n}};
}

}  // namespace

TEST(BusStatsRate, SteadyStreamPolledAtAQuarterSecond)
{
  for (double hz : {1.0, 5.0, 10.0, 20.0, 30.0, 100.0})
    for (double phase : {0.0, 0.3, 0.7})
    {
      BusStatsRate r(2.0, 0.75);
      double t = 10.0;
      r.add(t, 100, steady(hz, t, 0, 100, phase));  // baseline
      for (int i = 0; i < 40; ++i)
      {
        t += 0.25;
        r.add(t, 100, steady(hz, t, 0, 100, phase));
      }
      const auto s = r.stats(t + 0.1);
      // The count of a poll says nothing of when in the period the messages came: about one
      // message per window of error at worst, far less at most phases.
      EXPECT_NEAR(s.rate_hz, hz, std::max(0.1 * hz, 0.5 * hz / (2.0 * hz - 1.0)))
          << hz << " Hz, phase " << phase;
      EXPECT_NEAR(s.bytes_per_second, 100.0 * hz, 100.0 * (1.0 / 2.0 + 0.05 * hz)) << hz;
      EXPECT_LT(s.last_message_age_s, std::max(1.0 / hz, 0.25) + 0.01) << hz;
      EXPECT_GT(s.window_messages, 0u);
    }
}

TEST(BusStatsRate, FirstReplyIsABaselineNotABurst)
{
  BusStatsRate r(2.0, 0.75);
  r.add(1.0, 100, {{0, 1000000, 50000}});  // a node that has run for an hour
  const auto s = r.stats(1.1);
  EXPECT_EQ(s.rate_hz, 0.0);
  EXPECT_EQ(s.window_messages, 0u);
  EXPECT_TRUE(std::isinf(s.last_message_age_s));
}

TEST(BusStatsRate, ConnectionsComingAndGoing)
{
  BusStatsRate r(2.0, 0.75);
  double t = 0.0;
  r.add(t, 100, {{0, 0, 0}});
  uint32_t a = 0, b = 0;
  for (int i = 1; i <= 8; ++i)  // 10 Hz on connection 0
  {
    t += 0.25;
    a = uint32_t(i * 10 / 4);
    r.add(t, 100, {{0, a * 10, a}});
  }
  // The publisher reconnects: connection 0 is gone, connection 1 is new and counts from 0.
  for (int i = 1; i <= 8; ++i)
  {
    t += 0.25;
    b = uint32_t(i * 10 / 4);
    const auto grew = r.add(t, 100, {{1, b * 10, b}});
    if (i % 2 == 0 || b > 0)
      EXPECT_TRUE(grew.empty() || grew == std::vector<int>{1});
  }
  auto s = r.stats(t);
  EXPECT_NEAR(s.rate_hz, 10.0, 1.0);
  // Two publishers at once: their counts add up.
  uint32_t c = 0;
  for (int i = 1; i <= 8; ++i)
  {
    t += 0.25;
    b += 2;  // 8 Hz
    c += 3;  // 12 Hz
    const auto grew = r.add(t, 100, {{1, b * 10, b}, {2, c * 10, c}});
    EXPECT_EQ(grew.size(), 2u);
  }
  s = r.stats(t);
  EXPECT_NEAR(s.rate_hz, 20.0, 1.0);
  EXPECT_NEAR(s.bytes_per_second, 200.0, 20.0);
}

TEST(BusStatsRate, ARestartedNodeCountsFromZeroAgain)
{
  BusStatsRate r(2.0, 0.75);
  double t = 0.0;
  uint32_t n = 1000;
  r.add(t, 100, {{5, n * 10, n}});
  for (int i = 0; i < 8; ++i)
  {
    t += 0.25;
    n += 5;  // 20 Hz
    r.add(t, 100, {{5, n * 10, n}});
  }
  // The node restarted (pid 200) between two polls: counts start again from 0, connection ids
  // too. Not a drop of 1000 messages, not a negative rate: 5 new messages.
  t += 0.25;
  const auto grew = r.add(t, 200, {{0, 50, 5}});
  EXPECT_EQ(grew, std::vector<int>{0});
  uint32_t m = 5;
  for (int i = 0; i < 7; ++i)
  {
    t += 0.25;
    m += 5;
    r.add(t, 200, {{0, m * 10, m}});
  }
  const auto s = r.stats(t);
  EXPECT_NEAR(s.rate_hz, 20.0, 1.0);
  EXPECT_LE(s.window_messages, 45u);
}

TEST(BusStatsRate, CountsWrapAt32Bits)
{
  BusStatsRate r(2.0, 0.75);
  uint32_t bytes = 0xFFFFFF00u;
  uint32_t n = 0;
  double t = 0.0;
  r.add(t, 100, {{0, bytes, n}});
  for (int i = 0; i < 8; ++i)
  {
    t += 0.25;
    bytes += 64;  // wraps after 4 polls
    n += 1;
    r.add(t, 100, {{0, bytes, n}});
  }
  const auto s = r.stats(t);
  EXPECT_NEAR(s.bytes_per_second, 64.0 * 8 / 2.0, 1e-6);
  EXPECT_NEAR(s.rate_hz, 4.0, 0.01);
}

TEST(BusStatsRate, SilenceMakesTheAgeGrowAndTheRateFall)
{
  BusStatsRate r(2.0, 0.75);
  double t = 0.0;
  uint32_t n = 0;
  r.add(t, 100, {{0, 0, 0}});
  for (int i = 0; i < 8; ++i)
  {
    t += 0.25;
    n += 5;
    r.add(t, 100, {{0, n, n}});
  }
  const double last = t;
  // The node answers, and has received nothing more.
  for (int i = 0; i < 4; ++i)
  {
    t += 0.25;
    r.add(t, 100, {{0, n, n}});
  }
  auto s = r.stats(t);
  EXPECT_NEAR(s.last_message_age_s, t - last + 0.25 / 6.0, 1e-9);
  // As RateWindow: 20 messages in the last second of the window, then a second of silence.
  EXPECT_NEAR(s.rate_hz, 20.0 / (1.0 + 1.0 + 0.25 / 6.0 - 0.05), 1e-6);
  // Gone quiet for good: the window empties.
  for (int i = 0; i < 10; ++i)
  {
    t += 0.25;
    r.add(t, 100, {{0, n, n}});
  }
  s = r.stats(t);
  EXPECT_EQ(s.rate_hz, 0.0);
  EXPECT_EQ(s.window_messages, 0u);
  EXPECT_NEAR(s.last_message_age_s, t - last + 0.25 / 6.0, 1e-9);
}

TEST(BusStatsRate, ANodeThatStopsAnsweringHasItsTopicAgeFromTheOverdueReply)
{
  BusStatsRate r(2.0, 0.75);
  double t = 0.0;
  uint32_t n = 0;
  r.add(t, 100, {{0, 0, 0}});
  for (int i = 0; i < 8; ++i)
  {
    t += 0.25;
    n += 5;
    r.add(t, 100, {{0, n, n}});
  }
  const double est = t - 0.25 / 6.0;
  // No reply since t: within the overdue time, nothing is known to be missing.
  EXPECT_NEAR(r.stats(t + 0.5).last_message_age_s, t - est, 1e-9);
  EXPECT_NEAR(r.stats(t + 0.5).rate_hz, 20.0, 0.5);
  // After it, the silence counts.
  EXPECT_NEAR(r.stats(t + 3.0).last_message_age_s, t + 3.0 - 0.75 - est, 1e-9);
  EXPECT_EQ(r.stats(t + 3.0).rate_hz, 0.0);
  // A reply after a gap longer than the window is a new baseline: its backlog is not a burst.
  t += 5.0;
  r.add(t, 100, {{0, n + 100, n + 100}});
  EXPECT_EQ(r.stats(t).window_messages, 0u);
}

TEST(ProcNetTcp, ParsesTcpAndTheLocalSideOfTcp6)
{
  const std::string v4 =
      "  sl  local_address rem_address   st tx_queue rx_queue tr tm->when retrnsmt   uid  timeout "
      "inode\n"
      "   0: 00000000:A1B2 00000000:0000 0A 00000000:00000000 00:00000000 00000000     0        0 "
      "1746346 1 0\n"
      "   1: 0100007F:2B67 0100007F:D2A4 01 00000000:00000000 00:00000000 00000000     0        0 "
      "1746350 1 0\n"
      "   2: garbage\n";
  const auto e = parseProcNetTcp(v4);
  ASSERT_EQ(e.size(), 2u);
  EXPECT_EQ(e[0].local, "0.0.0.0");
  EXPECT_EQ(e[0].local_port, 0xA1B2);
  EXPECT_EQ(e[0].state, kTcpListen);
  EXPECT_EQ(e[0].inode, 1746346u);
  EXPECT_EQ(e[1].local, "127.0.0.1");
  EXPECT_EQ(e[1].remote, "127.0.0.1:53924");
  EXPECT_EQ(e[1].state, kTcpEstablished);
  const std::string v6 =
      "   0: 00000000000000000000000000000000:1F90 00000000000000000000000000000000:0000 0A "
      "00000000:00000000 "
      "00:00000000 00000000     0        0 11 1 0\n"
      "   1: 0000000000000000FFFF00000100007F:1F91 00000000000000000000000000000000:0000 0A "
      "00000000:00000000 "
      "00:00000000 00000000     0        0 12 1 0\n"
      "   2: 00000000000000000000000001000000:1F92 00000000000000000000000000000000:0000 0A "
      "00000000:00000000 "
      "00:00000000 00000000     0        0 13 1 0\n";
  const auto e6 = parseProcNetTcp(v6, true);
  ASSERT_EQ(e6.size(), 3u);
  EXPECT_EQ(e6[0].local, "::");
  EXPECT_EQ(e6[1].local, "127.0.0.1");
  EXPECT_EQ(e6[2].local, "::1");
}

TEST(ListeningSockets, FindsThisProcesssListeningSocketAndItsAcceptedConnections)
{
  UniqueFd server(::socket(AF_INET, SOCK_STREAM, 0));
  ASSERT_GE(server.get(), 0);
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_addr.s_addr = htonl(INADDR_ANY);
  ASSERT_EQ(::bind(server.get(), reinterpret_cast<sockaddr*>(&addr), sizeof addr), 0);
  ASSERT_EQ(::listen(server.get(), 4), 0);
  socklen_t len = sizeof addr;
  ASSERT_EQ(::getsockname(server.get(), reinterpret_cast<sockaddr*>(&addr), &len), 0);
  const int port = ntohs(addr.sin_port);
  const auto find = [port] {
    const auto all = listeningSockets({int(::getpid())});
    const auto it = std::find_if(all.begin(), all.end(),
                                 [port](const ListeningSocket& s) { return s.port == port; });
    return it == all.end() ? std::optional<ListeningSocket>() : std::optional<ListeningSocket>(*it);
  };
  auto s = find();
  ASSERT_TRUE(s);
  EXPECT_EQ(s->host, "127.0.0.1");
  EXPECT_FALSE(s->accepted);

  UniqueFd client(::socket(AF_INET, SOCK_STREAM, 0));
  sockaddr_in to = addr;
  to.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  ASSERT_EQ(::connect(client.get(), reinterpret_cast<sockaddr*>(&to), sizeof to), 0);
  UniqueFd accepted(::accept(server.get(), nullptr, nullptr));
  ASSERT_GE(accepted.get(), 0);
  s = find();
  ASSERT_TRUE(s);
  EXPECT_TRUE(s->accepted);

  const auto members = processGroupMembers(int(::getpgrp()));
  EXPECT_NE(std::find(members.begin(), members.end(), int(::getpid())), members.end());
  EXPECT_TRUE(listeningSockets({999999999}).empty());
}

TEST(WatchList, TheInputsOfRunningNodesAreCountedFromTheirBusStats)
{
  WatchList w;
  ASSERT_TRUE(w.assign({"/scan", "/scan", "/camera/image_raw", "/odom"},
                       {"/navigation", "/amcl", "/ar_recognition", ""}, nullptr));
  using Map = std::map<std::string, std::string>;
  EXPECT_EQ(w.runningSubscribers({}), Map());
  EXPECT_EQ(w.runningSubscribers({"/navigation"}), Map({{"/scan", "/navigation"}}));
  // Several run here: the first by name.
  EXPECT_EQ(w.runningSubscribers({"/navigation", "/amcl", "/ar_recognition"}),
            Map({{"/scan", "/amcl"}, {"/camera/image_raw", "/ar_recognition"}}));
}
