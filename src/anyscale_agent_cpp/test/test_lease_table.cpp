// gtest: lease grant, renewal and expiry.
#include <gtest/gtest.h>

#include "anyscale_agent_cpp/lease_table.h"

using anyscale_agent::LeaseTable;

TEST(LeaseTable, ExpiresOnlyUnrenewed)
{
  LeaseTable t;
  t.grant("amcl", 0.0, 2.0);
  t.grant("ar", 0.0, 2.0);
  EXPECT_TRUE(t.takeExpired(1.9).empty());
  EXPECT_TRUE(t.renew("ar", 1.5, 2.0));  // now ends at 3.5
  const auto expired = t.takeExpired(2.0);
  ASSERT_EQ(expired.size(), 1u);
  EXPECT_EQ(expired[0], "amcl");
  EXPECT_FALSE(t.expiry("amcl"));
  EXPECT_TRUE(t.takeExpired(3.4).empty());
  EXPECT_EQ(t.takeExpired(3.5).size(), 1u);
}

TEST(LeaseTable, RenewNeedsAnExistingLease)
{
  LeaseTable t;
  EXPECT_FALSE(t.renew("nobody", 0.0, 1.0));
  t.grant("a", 0.0, 1.0);
  EXPECT_FALSE(t.renew("a", 0.5, 0.0));  // a zero renewal is refused, not an instant expiry
  EXPECT_DOUBLE_EQ(t.expiry("a").value(), 1.0);
  t.grant("a", 0.5, 0.0);  // no lease any more: runs until stopped
  EXPECT_FALSE(t.expiry("a"));
  t.grant("b", 0.0, 1.0);
  t.remove("b");
  EXPECT_TRUE(t.takeExpired(10.0).empty());
}

TEST(LeaseTable, ARenewalNeverShortensALease)
{
  // renew_leases{lease_s: 1e-6} ended a node whose lease had seconds left.
  LeaseTable t;
  t.grant("amcl", 0.0, 3.0);
  EXPECT_TRUE(t.renew("amcl", 1.0, 1e-6));
  EXPECT_DOUBLE_EQ(t.expiry("amcl").value(), 3.0);
  EXPECT_TRUE(t.takeExpired(2.9).empty());
  EXPECT_TRUE(t.renew("amcl", 2.0, 3.0));
  EXPECT_DOUBLE_EQ(t.expiry("amcl").value(), 5.0);
}
