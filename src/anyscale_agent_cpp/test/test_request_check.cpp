// gtest: checks of service request fields (lease and timeout bounds, override values) and the
// quoting of request text in answers and logs.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "anyscale_agent_cpp/request_check.h"

using namespace anyscale_agent;

TEST(RequestCheck, QuotedEscapesControlAndNonAsciiBytesAndCutsLongText)
{
  EXPECT_EQ(quoted("amcl"), "'amcl'");
  EXPECT_EQ(quoted("a\nb\\"), "'a\\x0ab\\x5c'");  // a newline cannot forge a log line
  EXPECT_EQ(quoted("n\xc3\xa9"), "'n\\xc3\\xa9'");
  const std::string q = quoted(std::string(100000, 'x'));
  EXPECT_LT(q.size(), 120u);
  EXPECT_NE(q.find("(100000 bytes)"), std::string::npos);
}

TEST(RequestCheck, SecondsMustBeFiniteAndBounded)
{
  EXPECT_EQ(checkSeconds("lease_s", 0.0, true, kMaxLeaseS), "");
  EXPECT_EQ(checkSeconds("lease_s", 3.0, false, kMaxLeaseS), "");
  EXPECT_NE(checkSeconds("lease_s", 0.0, false, kMaxLeaseS), "");
  for (double bad :
       {-1.0, std::nan(""), HUGE_VAL, -HUGE_VAL, 3e9, double(std::numeric_limits<float>::max())})
  {
    const std::string why = checkSeconds("lease_s", bad, true, kMaxLeaseS);
    EXPECT_NE(why, "") << bad;
    EXPECT_EQ(why.rfind("lease_s must be", 0), 0u) << why;
  }
}

TEST(RequestCheck, ExpectedAmountsMustBeFiniteAndBounded)
{
  EXPECT_EQ(checkAmount("cpu_percent", 0.0, kMaxExpectedCpuPercent, "%"), "");
  EXPECT_EQ(checkAmount("cpu_percent", 150.0, kMaxExpectedCpuPercent, "%"), "");  // no fit, no lie
  for (double bad : {-1.0, std::nan(""), HUGE_VAL, 3e38})
    EXPECT_EQ(checkAmount("memory_mb", bad, kMaxExpectedMemoryMb, "MB")
                  .rfind("memory_mb must be >= 0 and at most 1e+09 MB", 0),
              0u)
        << bad;
}

TEST(RequestCheck, OverrideValuesAreNumbersOrBooleansOnly)
{
  for (const char* ok : {"1.5", "-3", "1e-3", ".nan", "-.inf", "true", "off"})
    EXPECT_EQ(checkOverrideValue("initial_pose_x", ok), "") << ok;
  for (const char* bad :
       {"/bin/sh", "'1.5'", "$(find pkg)/x", "{a: 1}", "[1, 2]", "!!str 1", "", "~", "[", "a\nb"})
    EXPECT_NE(checkOverrideValue("k", bad), "") << bad;
}

TEST(RequestCheck, YamlSpecialFloats)
{
  double v = 0.0;
  EXPECT_TRUE(parseYamlSpecialFloat(".nan", &v) && std::isnan(v));
  EXPECT_TRUE(parseYamlSpecialFloat("-.inf", &v) && v < 0 && std::isinf(v));
  EXPECT_FALSE(parseYamlSpecialFloat("nan", &v));
}

TEST(RequestCheck, OverrideKeysAreTheStateHandOffsOnly)
{
  NodeDecl amcl;
  amcl.name = "amcl";
  amcl.handoff_keys = handoffKeys("pose");
  EXPECT_EQ(checkOverrideKeys(amcl, {{"initial_pose_x", "1.5"}, {"initial_pose_stamp", "12.0"}}),
            "");
  EXPECT_EQ(checkOverrideKeys(amcl, {}), "");
  const std::string why =
      checkOverrideKeys(amcl, {{"initial_pose_x", "1"}, {"max_particles", "2147483647"}});
  EXPECT_NE(why.find("'max_particles': not a parameter of the model's state hand-off of amcl"),
            std::string::npos)
      << why;
  NodeDecl laser;
  laser.name = "laser";
  EXPECT_NE(checkOverrideKeys(laser, {{"initial_pose_x", "1"}}).find("declares none"),
            std::string::npos);
}
