// gtest: ICMP echo with kernel receive timestamps, on loopback (needs root or ping sockets).
#include <gtest/gtest.h>

#include <unistd.h>
#include <cmath>
#include <memory>
#include <stdexcept>

#include "anyscale_agent_cpp/icmp_echo.h"

using anyscale_agent::IcmpEcho;

namespace
{
std::unique_ptr<IcmpEcho> openOrNull(std::string* why)
{
  try
  {
    return std::make_unique<IcmpEcho>("127.0.0.1");
  }
  catch (const std::runtime_error& e)
  {
    *why = e.what();
    return nullptr;
  }
}
}  // namespace

TEST(IcmpEcho, ASmallAndABulkEchoOnLoopbackGiveAFiniteBandwidth)
{
  std::string why;
  auto echo = openOrNull(&why);
  if (!echo)
    GTEST_SKIP() << "no ICMP socket here (not root, ping sockets off): " << why;
  uint16_t seq = 0;
  anyscale_agent::RttFloor floor;
  const double mbps = anyscale_agent::measureEchoBandwidth(*echo, 60000, 1.0, 0.5, &seq, floor);
  EXPECT_TRUE(std::isfinite(mbps));
  EXPECT_GT(mbps, 0.0);
  EXPECT_EQ(seq, 2);
}

TEST(IcmpEcho, RepliesCarryTheirSequenceNumberAndComeAfterTheSend)
{
  std::string why;
  auto echo = openOrNull(&why);
  if (!echo)
    GTEST_SKIP() << "no ICMP socket here (not root, ping sockets off): " << why;
  const double sent = echo->send(7, 1000);
  std::vector<std::pair<uint16_t, double>> got;
  for (int i = 0; i < 100 && got.empty(); ++i)
  {
    usleep(10000);
    got = echo->receive();
  }
  ASSERT_EQ(got.size(), 1u);
  EXPECT_EQ(got[0].first, 7);
  EXPECT_GE(got[0].second, sent);
  EXPECT_LT(got[0].second - sent, 1.0);
}

TEST(IcmpEcho, AnUnknownHostIsAClearError)
{
  try
  {
    IcmpEcho echo("no-such-host.invalid");
    FAIL() << "resolved an invalid host";
  }
  catch (const std::runtime_error& e)
  {
    EXPECT_NE(std::string(e.what()).find("no-such-host.invalid"), std::string::npos) << e.what();
  }
}

TEST(IcmpEcho, TheBulkIsAbout20MsOfTheEstimateWithinItsBounds)
{
  using anyscale_agent::echoBulkBytes;
  EXPECT_EQ(echoBulkBytes(std::nan(""), 32768), 4096u);  // nothing measured: start small
  EXPECT_EQ(echoBulkBytes(0.5, 32768), 4096u);
  EXPECT_EQ(echoBulkBytes(3.0, 32768), 7500u);              // fits a 50 ms shaper queue (18.7 kB)
  EXPECT_EQ(echoBulkBytes(27.0, 32768), 32768u);            // capped by ~link_bulk_bytes
  EXPECT_EQ(echoBulkBytes(27.0, 1000000), 67500u - 2500u);  // and by what a datagram holds
}

TEST(RttFloor, TheLeastOfTheLastReadings)
{
  anyscale_agent::RttFloor floor(3);
  EXPECT_TRUE(std::isnan(floor.least()));
  floor.add(0.050);
  floor.add(0.002);
  floor.add(std::nan(""));  // an unanswered echo says nothing of the floor
  floor.add(0.040);
  EXPECT_DOUBLE_EQ(floor.least(), 0.002);
  floor.add(0.030);  // 0.050 and then 0.002 leave the window
  floor.add(0.045);
  EXPECT_DOUBLE_EQ(floor.least(), 0.030);
}

TEST(EchoBandwidth, ABulkEchoThatMetAQueueReadsWhatTheLinkLeft)
{
  using anyscale_agent::echoBandwidthMbps;
  // 15 kB each way at 6 Mbit/s: 20 ms a direction, 40 ms over the floor of an empty link.
  EXPECT_NEAR(echoBandwidthMbps(15000, 0.042, 0.002), 6.0, 1e-9);
  // The same echo behind 40 ms of the link's own traffic reads half of it.
  EXPECT_NEAR(echoBandwidthMbps(15000, 0.082, 0.002), 3.0, 1e-9);
  EXPECT_TRUE(std::isfinite(echoBandwidthMbps(15000, 0.001, 0.002)));  // below the floor: bounded
}
