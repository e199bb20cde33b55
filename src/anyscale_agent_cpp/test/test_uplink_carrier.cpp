// The uplink carrier reader: up, missing, and down in a fresh network namespace.
#include <gtest/gtest.h>

#include <sched.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>

#include "anyscale_agent_cpp/uplink_carrier.h"

using anyscale_agent::Carrier;
using anyscale_agent::interfaceNames;
using anyscale_agent::readCarrier;

TEST(UplinkCarrier, LoopbackIsUpAndListed)
{
  EXPECT_EQ(readCarrier("lo"), Carrier::Up);
  const auto names = interfaceNames();
  EXPECT_NE(std::find(names.begin(), names.end(), "lo"), names.end());
}

TEST(UplinkCarrier, UnknownInterfaceIsMissing)
{
  EXPECT_EQ(readCarrier("anyscale_nonexistent0"), Carrier::Missing);
}

TEST(UplinkCarrier, AnswersForTheCallersNetworkNamespace)
{
  // A new network namespace has only its own loopback, and that one is down: what an agent
  // started inside a namespace must see, whatever /sys shows.
  if (::geteuid() != 0)
    GTEST_SKIP() << "needs root to create a network namespace (unshare CLONE_NEWNET)";
  const pid_t child = ::fork();
  ASSERT_GE(child, 0);
  if (child == 0)
  {
    if (::unshare(CLONE_NEWNET) != 0)
      ::_exit(2);
    ::_exit(readCarrier("lo") == Carrier::Down ? 0 : 1);
  }
  int status = 0;
  ASSERT_EQ(::waitpid(child, &status, 0), child);
  ASSERT_TRUE(WIFEXITED(status));
  if (WEXITSTATUS(status) == 2)
    GTEST_SKIP() << "unshare(CLONE_NEWNET) refused here (no network namespaces)";
  EXPECT_EQ(WEXITSTATUS(status), 0) << "loopback of a fresh namespace was not reported down";
}
