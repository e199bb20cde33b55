// gtest: the capacity ledger of a shared scale: admission and its refusals, renewals, expiry,
// frees, a restart, the file's rules, and processes racing to admit (fork).
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <fstream>
#include <random>
#include <set>

#include "anyscale_agent_cpp/capacity_ledger.h"
#include "anyscale_agent_cpp/node_state_file.h"
#include "supervisor_test_util.h"

using namespace anyscale_agent;

namespace
{
const LedgerCapacity kLaptop{100.0, 1000.0};

LedgerEntry ask(const std::string& node, double cpu, double memory, double lease_end)
{
  LedgerEntry e;
  e.master_uri = "http://robot:11311";
  e.node = "/" + node;
  e.instance = "/" + node + "__laptop";
  e.cpu_percent = cpu;
  e.memory_mb = memory;
  e.lease_end_s = lease_end;
  return e;
}

struct Shared
{
  supervisor_test::TempDir dir;
  std::string path = dir.path() + "/ledger/laptop.yaml";
  Shared() { prepareLedgerDirectory(path); }
  CapacityLedger of(const std::string& robot) const
  {
    return CapacityLedger(path, robot, "laptop", kLaptop);
  }
};

std::string refusal(const std::function<void()>& f)
{
  try
  {
    f();
  }
  catch (const LedgerError& e)
  {
    return e.what();
  }
  return "";
}
}  // namespace

TEST(CapacityLedger, AdmitsWithinCapacityAndARefusalNamesWhatWasShort)
{
  Shared s;
  CapacityLedger a = s.of("robot_a"), b = s.of("robot_b");
  EXPECT_TRUE(a.admit(ask("relay", 36, 100, 50), 10).admitted);
  const Admission second = b.admit(ask("relay", 36, 100, 50), 10);
  EXPECT_TRUE(second.admitted) << second.message;
  EXPECT_EQ(second.message, "admitted: CPU 72 % of 100 %, memory 200 MB of 1000 MB held on laptop");
  const Admission full = a.admit(ask("throttle", 36, 100, 50), 10);
  EXPECT_FALSE(full.admitted);
  EXPECT_EQ(full.message, "laptop full: CPU 72 % held by 2 robots + 36 % asked > 100 %");
  EXPECT_DOUBLE_EQ(full.cpu_free_percent, 28.0);
  EXPECT_DOUBLE_EQ(full.memory_free_mb, 800.0);
  EXPECT_EQ(b.admit(ask("amcl", 28, 900, 50), 10).message,
            "laptop full: memory 200 MB held by 2 robots + 900 MB asked > 1000 MB");
  EXPECT_EQ(b.admit(ask("amcl", 40.5, 900, 50), 10).message,
            "laptop full: CPU 72 % held by 2 robots + 40.5 % asked > 100 %; memory 200 MB held by "
            "2 robots + "
            "900 MB asked > 1000 MB");
  // What is left fits exactly.
  EXPECT_TRUE(a.admit(ask("throttle", 28, 800, 50), 10).admitted);
  const Holdings h = a.held(10);
  EXPECT_DOUBLE_EQ(h.cpu_percent, 100.0);
  EXPECT_DOUBLE_EQ(h.memory_mb, 1000.0);
  EXPECT_EQ(h.robots, 2u);
  EXPECT_EQ(h.entries, 3u);
  EXPECT_DOUBLE_EQ(a.held(10, true).cpu_percent, 36.0);  // robot_b's
}

TEST(CapacityLedger, ANodeStartedAgainReplacesItsOwnEntry)
{
  Shared s;
  CapacityLedger a = s.of("robot_a");
  EXPECT_TRUE(a.admit(ask("relay", 60, 10, 50), 10).admitted);
  // It crashed and starts again before the agent saw it end: its old entry is not held twice.
  EXPECT_TRUE(a.admit(ask("relay", 70, 10, 60), 11).admitted);
  EXPECT_EQ(a.entries(11).size(), 1u);
  EXPECT_DOUBLE_EQ(a.held(11).cpu_percent, 70.0);
  // Another robot's node of the same name is another entry.
  EXPECT_FALSE(s.of("robot_b").admit(ask("relay", 70, 10, 60), 11).admitted);
}

TEST(CapacityLedger, EntriesFollowTheirLeasesAndExpire)
{
  Shared s;
  CapacityLedger a = s.of("robot_a"), b = s.of("robot_b");
  EXPECT_TRUE(a.admit(ask("relay", 60, 10, 13), 10).admitted);
  EXPECT_FALSE(b.admit(ask("relay", 60, 10, 13), 12).admitted);
  a.sync({{"/relay", 20}}, 12);    // renewed with its lease
  a.sync({{"/relay", 15}}, 12.5);  // never shortened
  EXPECT_EQ(a.entries(12.5).at(0).lease_end_s, 20.0);
  EXPECT_FALSE(b.admit(ask("relay", 60, 10, 30), 19.9).admitted);
  // Not renewed (the robot is gone, or its agent): nothing held once its lease ended.
  EXPECT_DOUBLE_EQ(b.held(20).cpu_percent, 0.0);
  EXPECT_TRUE(b.admit(ask("relay", 60, 10, 30), 20).admitted);
  ASSERT_EQ(b.entries(20).size(), 1u);  // the expired entry is gone from the file too
  EXPECT_EQ(b.entries(20)[0].robot, "robot_b");
  std::ifstream f(s.path);
  const std::string text((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
  EXPECT_EQ(text.find("robot_a"), std::string::npos) << text;
}

TEST(CapacityLedger, AStoppedNodesEntryIsFreedAndOtherRobotsAreLeftAlone)
{
  Shared s;
  CapacityLedger a = s.of("robot_a"), b = s.of("robot_b");
  EXPECT_TRUE(a.admit(ask("relay", 30, 10, 50), 10).admitted);
  EXPECT_TRUE(a.admit(ask("throttle", 30, 10, 50), 10).admitted);
  EXPECT_TRUE(b.admit(ask("relay", 30, 10, 50), 10).admitted);
  a.sync({{"/throttle", 50}}, 11);  // the relay stopped here
  std::set<std::string> left;
  for (const auto& e : b.entries(11))
    left.insert(e.robot + e.node);
  EXPECT_EQ(left, (std::set<std::string>{"robot_a/throttle", "robot_b/relay"}));
  a.sync({}, 11);
  EXPECT_DOUBLE_EQ(b.held(11).cpu_percent, 30.0);
}

TEST(CapacityLedger, ARestartedAgentFindsItsEntriesAndAdoptsThem)
{
  Shared s;
  {
    CapacityLedger before = s.of("robot_a");
    EXPECT_TRUE(before.admit(ask("relay", 40, 10, 50), 10).admitted);
    EXPECT_TRUE(before.admit(ask("throttle", 40, 10, 50), 10).admitted);
  }
  // A new agent of the same robot: the file kept everything, and other robots see it held.
  CapacityLedger after = s.of("robot_a");
  EXPECT_DOUBLE_EQ(after.held(20).cpu_percent, 80.0);
  EXPECT_FALSE(s.of("robot_b").admit(ask("relay", 40, 10, 60), 20).admitted);
  // It adopted the relay, whose lease it enforces again; the throttle had ended meanwhile.
  after.sync({{"/relay", 52}}, 20);
  ASSERT_EQ(after.entries(20).size(), 1u);
  EXPECT_EQ(after.entries(20)[0].node, "/relay");
  EXPECT_EQ(after.entries(20)[0].lease_end_s, 52.0);
}

TEST(CapacityLedger, AnotherBootsEntriesHoldNothing)
{
  Shared s;
  EXPECT_TRUE(s.of("robot_a").admit(ask("relay", 90, 10, 1e9), 10).admitted);
  LedgerState old{"laptop", "another-boot", {ask("relay", 90, 10, 1e9)}};
  old.entries[0].robot = "robot_a";
  {
    std::ofstream f(s.path, std::ios::trunc);
    f << formatLedger(old);
  }
  EXPECT_DOUBLE_EQ(s.of("robot_b").held(10).cpu_percent, 0.0);
  EXPECT_TRUE(s.of("robot_b").admit(ask("relay", 90, 10, 50), 10).admitted);
}

TEST(CapacityLedger, TheTextRoundTripsAndOnlyACompleteLedgerIsRead)
{
  LedgerState state{"laptop", currentBootId(), {ask("relay", 12.25, 10, 1234.000001)}};
  state.entries[0].robot = "robot_a";
  const std::string text = formatLedger(state);
  EXPECT_EQ(parseLedger(text, "t"), state);
  const auto fails = [](const std::string& t) { return refusal([&] { parseLedger(t, "f"); }); };
  EXPECT_NE(fails(text.substr(0, text.size() - 3)).find("incomplete"), std::string::npos);
  std::string twice = text;
  twice.replace(twice.find("count: 1"), 8, "count: 2");
  EXPECT_NE(fails(twice).find("lists 1 entries, but says 2"), std::string::npos);
  std::string negative = text;
  negative.replace(negative.find("cpu_percent: 12.25"), 18, "cpu_percent: -1");
  EXPECT_NE(fails(negative).find("'cpu_percent' must be a number >= 0"), std::string::npos);
  std::string nan = text;
  nan.replace(nan.find("memory_mb: 10"), 13, "memory_mb: .nan");
  EXPECT_NE(fails(nan).find("'memory_mb' must be a number >= 0"), std::string::npos);
}

TEST(CapacityLedger, NothingButItsOwnFileIsReadOrWritten)
{
  Shared s;
  supervisor_test::TempDir elsewhere;
  const std::string victim = elsewhere.path() + "/victim";
  {
    std::ofstream f(victim);
    f << "precious\n";
  }
  ASSERT_EQ(::symlink(victim.c_str(), s.path.c_str()), 0);
  const std::string why = refusal([&] { s.of("robot_a").admit(ask("relay", 1, 1, 50), 10); });
  EXPECT_NE(why.find("is a symbolic link"), std::string::npos) << why;
  ASSERT_EQ(::unlink(s.path.c_str()), 0);
  ASSERT_EQ(::link(victim.c_str(), s.path.c_str()), 0);  // a hard link
  EXPECT_NE(refusal([&] { s.of("robot_a").held(10); }).find("a hard link"), std::string::npos);
  ASSERT_EQ(::unlink(s.path.c_str()), 0);
  EXPECT_EQ(supervisor_test::readFile(victim), "precious\n");
  // Another scale's ledger is not this one's, and a garbled one admits nothing.
  EXPECT_TRUE(s.of("robot_a").admit(ask("relay", 1, 1, 50), 10).admitted);
  CapacityLedger server(s.path, "robot_a", "server", kLaptop);
  EXPECT_NE(
      refusal([&] { server.held(10); }).find("is the ledger of scale 'laptop', not of 'server'"),
      std::string::npos);
  {
    std::ofstream f(s.path, std::ios::trunc);
    f << "entries: [\n";
  }
  EXPECT_NE(refusal([&] { s.of("robot_b").admit(ask("relay", 1, 1, 50), 10); }).find("incomplete"),
            std::string::npos);
  // Its directory must be the agent user's; one that is a link is refused.
  const std::string linked = s.dir.path() + "/linked";
  ASSERT_EQ(::symlink(elsewhere.path().c_str(), linked.c_str()), 0);
  EXPECT_NE(
      refusal([&] { prepareLedgerDirectory(linked + "/ledger.yaml"); }).find("not a directory"),
      std::string::npos);
  if (::geteuid() == 0)
  {
    const std::string others = s.dir.path() + "/others";
    ASSERT_EQ(::mkdir(others.c_str(), 0777), 0);
    ASSERT_EQ(::chown(others.c_str(), 65534, 65534), 0);
    EXPECT_NE(refusal([&] {
                prepareLedgerDirectory(others + "/ledger.yaml");
              }).find("belongs to user 65534"),
              std::string::npos);
  }
}

// Processes racing to admit: every read-modify-write is under the file's lock, so no admission
// is lost or made on a stale sum, and what is held never exceeds the capacity.
TEST(CapacityLedger, ProcessesRacingToAdmitNeverExceedTheCapacity)
{
  Shared s;
  constexpr int kRobots = 4;
  constexpr int kRounds = 150;
  const std::string beliefs = s.dir.path() + "/belief_";
  int go[2];
  ASSERT_EQ(::pipe(go), 0);
  std::vector<pid_t> children;
  for (int r = 0; r < kRobots; ++r)
  {
    const pid_t pid = ::fork();
    ASSERT_GE(pid, 0);
    if (pid == 0)
    {
      ::close(go[1]);
      char c;
      (void)!::read(go[0], &c, 1);  // all start at once, when the parent closes the pipe
      int code = 0;
      try
      {
        const std::string robot = "robot_" + std::to_string(r);
        CapacityLedger ledger(s.path, robot, "laptop", {100.0, 1e6});
        std::mt19937 rng(1000 + r);
        std::map<std::string, double> mine;  // node -> its CPU, as this robot believes
        for (int i = 0; i < kRounds && code == 0; ++i)
        {
          const std::string node = "/n" + std::to_string(rng() % 5);
          if (mine.count(node))  // it runs: stopped, as an agent frees a stopped node's entry
          {
            mine.erase(node);
            std::map<std::string, double> live;
            for (const auto& m : mine)
              live[m.first] = 1e9;
            ledger.sync(live, 1.0);
            continue;
          }
          const double cpu = 5.0 + double(rng() % 400) / 10.0;
          LedgerEntry e = ask(node.substr(1), cpu, 1, 1e9);
          if (ledger.admit(e, 1.0).admitted)
            mine[node] = cpu;
          if (ledger.held(1.0).cpu_percent > 100.0 + 1e-6)
            code = 3;
        }
        std::ofstream out(beliefs + robot);
        for (const auto& m : mine)
          out << m.first << " " << m.second << "\n";
      }
      catch (const std::exception& e)
      {
        std::fprintf(stderr, "robot_%d: %s\n", r, e.what());
        code = 4;
      }
      ::_exit(code);
    }
    children.push_back(pid);
  }
  ::close(go[0]);
  ::close(go[1]);
  for (const pid_t pid : children)
  {
    int status = 0;
    ASSERT_EQ(::waitpid(pid, &status, 0), pid);
    EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << "child status " << status;
  }
  // No update was lost: the file holds exactly what each robot believes it holds.
  std::set<std::pair<std::string, std::string>> believed, found;
  double sum = 0.0;
  for (int r = 0; r < kRobots; ++r)
  {
    std::ifstream in(beliefs + "robot_" + std::to_string(r));
    std::string node;
    double cpu;
    while (in >> node >> cpu)
      believed.emplace("robot_" + std::to_string(r), node);
  }
  for (const auto& e : s.of("observer").entries(1.0))
  {
    found.emplace(e.robot, e.node);
    sum += e.cpu_percent;
  }
  EXPECT_EQ(found, believed);
  EXPECT_LE(sum, 100.0 + 1e-6);
  EXPECT_FALSE(found.empty());
}
