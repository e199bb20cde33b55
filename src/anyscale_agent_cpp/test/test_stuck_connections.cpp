// Stuck connections: /proc/net/tcp lines, the tracking of how long one stays open, breaking one.
#include <gtest/gtest.h>

#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <sys/stat.h>

#include "anyscale_agent_cpp/stuck_connections.h"
#include "anyscale_agent_cpp/unique_fd.h"

using namespace anyscale_agent;

namespace
{
const char* kProcNetTcp =
    "  sl  local_address rem_address   st tx_queue rx_queue tr tm->when retrnsmt   uid  timeout "
    "inode\n"
    "   0: 00000000:2C2F 00000000:0000 0A 00000000:00000000 00:00000000 00000000     0        0 "
    "1001 1 0 100 0 0 10 0\n"
    "   1: 0207D50A:A1B2 0107D50A:2C2F 01 0000012C:00000000 01:00000030 00000002     0        0 "
    "1002 1 0 20 4 30 10 -1\n"
    "   2: 0207D50A:A1B4 0107D50A:2C2F 02 00000000:00000000 01:00000100 00000003     0        0 "
    "1003 1 0 20 4 30 10 -1\n"
    "   3: 0207D50A:A1B6 0107D50A:2C2F 08 00000000:00000000 00:00000000 00000000     0        0 "
    "1004 1 0 20 4 30 10 -1\n"
    "   4: 0207D50A:A1B8 0107D50A:9C40 01 0000012C:00000000 00:00000000 00000000     0        0 "
    "1005 1 0 20 4 30 10 -1\n"
    "   5: 0207D50A:A1BA 0107D50A:2C2F 01 00000000:00000000 00:00000000 00000000     0        0 "
    "1006 1 0 20 4 30 10 -1\n"
    "garbage\n";
}  // namespace

TEST(StuckConnections, ParsesProcNetTcp)
{
  const auto entries = parseProcNetTcp(kProcNetTcp);
  ASSERT_EQ(entries.size(), 6u);
  EXPECT_EQ(entries[1].tx_queue, 300u);
  EXPECT_EQ(entries[1].remote, "10.213.7.1:11311");
  EXPECT_EQ(entries[1].state, 1);
  EXPECT_EQ(entries[1].inode, 1002u);
  EXPECT_EQ(entries[2].state, 2);
  EXPECT_EQ(entries[4].remote, "10.213.7.1:40000");
  EXPECT_EQ(remoteFromHex("0100007F:0050"), "127.0.0.1:80");
  EXPECT_EQ(remoteFromHex("nonsense"), "");
}

TEST(StuckConnections, OnlyOpenConnectionsToTheRemoteOpenLongEnough)
{
  StuckConnections stuck("10.213.7.1:11311", 3.0);
  const auto entries = parseProcNetTcp(kProcNetTcp);
  EXPECT_TRUE(stuck.update(entries, 100.0).empty());  // first seen now
  EXPECT_TRUE(stuck.update(entries, 102.9).empty());
  // ESTABLISHED with 300 bytes unacknowledged 1002 and SYN_SENT 1003; not CLOSE_WAIT 1004, not
  // another port (1005), not an idle keep-alive connection (1006).
  EXPECT_EQ(stuck.update(entries, 103.0), (std::vector<uint64_t>{1002, 1003}));
  // A connection that closed and another that opened: the new one starts from zero.
  auto later = entries;
  later.erase(later.begin() + 1);
  later[1].inode = 2002;
  EXPECT_TRUE(stuck.update(later, 104.0).empty());
  EXPECT_EQ(stuck.update(later, 107.0), (std::vector<uint64_t>{2002}));
}

TEST(StuckConnections, BreaksAnEstablishedConnectionOfThisProcess)
{
  UniqueFd server(::socket(AF_INET, SOCK_STREAM, 0));
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  socklen_t len = sizeof(a);
  ASSERT_EQ(::bind(server.get(), reinterpret_cast<sockaddr*>(&a), len), 0);
  ASSERT_EQ(::listen(server.get(), 1), 0);
  ASSERT_EQ(::getsockname(server.get(), reinterpret_cast<sockaddr*>(&a), &len), 0);
  UniqueFd client(::socket(AF_INET, SOCK_STREAM, 0));
  ASSERT_EQ(::connect(client.get(), reinterpret_cast<sockaddr*>(&a), len), 0);
  UniqueFd accepted(::accept(server.get(), nullptr, nullptr));
  struct stat st
  {};
  ASSERT_EQ(fstat(client.get(), &st), 0);
  EXPECT_EQ(socketFdOfInode(st.st_ino), client.get());
  EXPECT_FALSE(breakConnection(client.get(), st.st_ino + 1));  // not that socket
  EXPECT_TRUE(breakConnection(client.get(), st.st_ino));
  // The peer sees the connection end.
  pollfd p{accepted.get(), POLLIN, 0};
  ASSERT_EQ(::poll(&p, 1, 1000), 1);
  char byte;
  EXPECT_LE(::recv(accepted.get(), &byte, 1, 0), 0);
}
