// gtest: the supervisor's state file (round trip, atomic write, corrupt and truncated files)
// and the rules that decide whether a live process is the node an entry names; the writer that
// writes only a changed list and never an older one after a newer.
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <random>
#include <string>

#include "anyscale_agent_cpp/node_state_file.h"
#include "supervisor_test_util.h"

using namespace anyscale_agent;

namespace
{
NodeState sample()
{
  NodeState s;
  s.boot_id = "5d8c1f0e-3a2b-4c1d-9e8f-0a1b2c3d4e5f";
  NodeStateEntry amcl;
  amcl.name = "/amcl";
  amcl.pid = 4242;
  amcl.start_time = 1234567;
  amcl.argv = {"/opt/ws/devel/lib/anyscale_nav_demo/amcl", "scan:=/base_scan", "__name:=amcl"};
  amcl.log_file = "/home/robot/.ros/log/anyscale/robot/amcl.log";
  amcl.state = "running";
  NodeStateEntry odd;  // every kind of text an argument may hold
  odd.name = "/ns/odd";
  odd.pid = 31337;
  odd.start_time = 18446744073709551615ull;
  odd.argv = {"/usr/lib/x y/node",
              "",
              "a b",
              "#not a comment",
              "key: value",
              "- item",
              "[1, 2]",
              "null",
              "~",
              "123",
              "quote\"d",
              "it's",
              "line\nbreak",
              "tab\there",
              "\xff\xfe raw bytes",
              "é ü",
              "&anchor",
              "*alias"};
  odd.log_file = "/tmp/odd: log.log";
  odd.state = "paused";
  odd.lease_end_s = 123456.789012345;
  s.nodes = {amcl, odd};
  return s;
}

std::string fileText(const std::string& path)
{
  return supervisor_test::readFile(path);
}
}  // namespace

TEST(NodeStateFile, RoundTripKeepsEveryField)
{
  const NodeState s = sample();
  const NodeState back = parseNodeState(formatNodeState(s), "test");
  EXPECT_EQ(back.boot_id, s.boot_id);
  ASSERT_EQ(back.nodes.size(), 2u);
  EXPECT_EQ(back.nodes[0], s.nodes[0]);
  EXPECT_EQ(back.nodes[1], s.nodes[1]);
  EXPECT_EQ(back.nodes[1].argv, s.nodes[1].argv);
  EXPECT_EQ(back.nodes[1].lease_end_s, s.nodes[1].lease_end_s);
  // An empty list too (a clean shutdown leaves one).
  NodeState empty;
  empty.boot_id = "b";
  EXPECT_TRUE(parseNodeState(formatNodeState(empty), "test").nodes.empty());
}

TEST(NodeStateFile, WriteIsAtomicAndReadBack)
{
  supervisor_test::TempDir dir;
  const std::string path = dir.path() + "/nodes.yaml";
  EXPECT_FALSE(readNodeStateFile(path).has_value()) << "no file: a first start, not an error";
  std::string err;
  ASSERT_TRUE(writeNodeStateFile(path, sample(), &err)) << err;
  const auto back = readNodeStateFile(path);
  ASSERT_TRUE(back.has_value());
  EXPECT_EQ(back->nodes, sample().nodes);
  EXPECT_FALSE(std::filesystem::exists(path + ".tmp")) << "the temporary file is renamed";
  // Rewriting replaces the whole file.
  NodeState one = sample();
  one.nodes.pop_back();
  ASSERT_TRUE(writeNodeStateFile(path, one, &err)) << err;
  EXPECT_EQ(readNodeStateFile(path)->nodes.size(), 1u);
  // A directory that does not exist: a reason, no exception.
  EXPECT_FALSE(writeNodeStateFile(dir.path() + "/missing/nodes.yaml", one, &err));
  EXPECT_NE(err.find("missing"), std::string::npos) << err;
}

namespace
{
std::string contents(const std::string& path)
{
  std::ifstream f(path);
  return std::string(std::istreambuf_iterator<char>(f), {});
}
}  // namespace

TEST(NodeStateFile, NothingOutsideItsDirectoryIsWrittenOrRead)
{
  // ~state_file came from the parameter server: `rosparam set` + a restart made the agent
  // (root on the test bed) replace any file. Now it comes from the command line, and a link
  // planted at either name the writer uses is replaced, never written through.
  supervisor_test::TempDir dir, elsewhere;
  const std::string path = dir.path() + "/nodes.yaml";
  const std::string victim = elsewhere.path() + "/passwd";
  std::ofstream(victim) << "root:x:0:0\n";
  std::string err;
  ASSERT_EQ(::symlink(victim.c_str(), (path + ".tmp").c_str()), 0);
  ASSERT_TRUE(writeNodeStateFile(path, sample(), &err)) << err;
  EXPECT_EQ(contents(victim), "root:x:0:0\n");
  EXPECT_EQ(readNodeStateFile(path)->nodes, sample().nodes);
  ASSERT_EQ(::link(victim.c_str(), (path + ".tmp").c_str()), 0);  // a hard link: same file
  ASSERT_TRUE(writeNodeStateFile(path, sample(), &err)) << err;
  EXPECT_EQ(contents(victim), "root:x:0:0\n");
  // A link at the file's own name: replaced by the write, refused by the read.
  ASSERT_EQ(::unlink(path.c_str()), 0);
  ASSERT_EQ(::symlink(victim.c_str(), path.c_str()), 0);
  try
  {
    readNodeStateFile(path);
    ADD_FAILURE() << "read through a symbolic link";
  }
  catch (const NodeStateError& e)
  {
    EXPECT_NE(std::string(e.what()).find("symbolic link"), std::string::npos) << e.what();
  }
  ASSERT_TRUE(writeNodeStateFile(path, sample(), &err)) << err;
  EXPECT_EQ(contents(victim), "root:x:0:0\n");
  EXPECT_FALSE(std::filesystem::is_symlink(path));
  EXPECT_THROW(readNodeStateFile(dir.path()), NodeStateError);  // a directory
  if (::geteuid() == 0)
  {
    // Another user's file lists processes the agent would adopt and signal.
    ASSERT_EQ(::chown(path.c_str(), 65534, 65534), 0);
    EXPECT_THROW(readNodeStateFile(path), NodeStateError);
  }
}

TEST(NodeStateFile, EveryTruncationIsRefusedOrReadsTheSame)
{
  const NodeState s = sample();
  const std::string text = formatNodeState(s);
  for (std::size_t len = 0; len < text.size(); ++len)
  {
    try
    {
      const NodeState back = parseNodeState(text.substr(0, len), "cut");
      // Only the final newline may be missing.
      EXPECT_EQ(len, text.size() - 1);
      EXPECT_EQ(back.nodes, s.nodes);
    }
    catch (const NodeStateError& e)
    {
      EXPECT_NE(std::string(e.what()).find("cut"), std::string::npos) << e.what();
    }
  }
}

TEST(NodeStateFile, CorruptFilesThrowOnlyNodeStateError)
{
  const std::string text = formatNodeState(sample());
  std::mt19937 rng(15);
  int refused = 0;
  for (int round = 0; round < 2000; ++round)
  {
    std::string t = text;
    const int edits = 1 + int(rng() % 4);
    for (int i = 0; i < edits; ++i)
    {
      const std::size_t at = rng() % t.size();
      switch (rng() % 3)
      {
        case 0: t[at] = char(rng() % 256); break;
        case 1: t.erase(at, 1 + rng() % 8); break;
        default: t.insert(at, 1, "\n:-[]{}\"'#&*!|>%@`,? \t0"[rng() % 24]); break;
      }
      if (t.empty())
        t = "x";
    }
    try
    {
      parseNodeState(t, "mutated");  // may still be a sound file (a changed digit of a pid)
    }
    catch (const NodeStateError&)
    {
      ++refused;
    }
  }
  EXPECT_GT(refused, 500);
}

TEST(NodeStateFile, UnknownOrMalformedContentIsNamed)
{
  auto why = [](const std::string& text) {
    try
    {
      parseNodeState(text + "# end of node state\n", "f");
    }
    catch (const NodeStateError& e)
    {
      return std::string(e.what());
    }
    return std::string("accepted");
  };
  EXPECT_NE(why("format: anyscale_agent_node_state/2\nboot_id: b\ncount: 0\nnodes: []\n")
                .find("unknown format"),
            std::string::npos);
  EXPECT_NE(why("just text\n").find("not a map"), std::string::npos);
  const std::string head = "format: anyscale_agent_node_state/1\nboot_id: b\n";
  EXPECT_NE(why(head + "count: 1\nnodes: []\n").find("says 1"), std::string::npos);
  const std::string node =
      "  - {name: /a, pid: 5, start_time: 9, state: running, lease_end_s: 0, log_file: l, ";
  EXPECT_EQ(why(head + "count: 1\nnodes:\n" + node + "argv: [/bin/a]}\n"), "accepted");
  EXPECT_NE(why(head + "count: 1\nnodes:\n" + node + "argv: [a]}\n").find("absolute"),
            std::string::npos);
  EXPECT_NE(why(head + "count: 1\nnodes:\n" + node + "argv: /bin/a}\n").find("must be a list"),
            std::string::npos);
  const std::string bad_pid =
      "  - {name: /a, pid: five, start_time: 9, state: running, lease_end_s: 0, log_file: l, ";
  EXPECT_NE(why(head + "count: 1\nnodes:\n" + bad_pid + "argv: [/bin/a]}\n")
                .find("'pid' has the wrong type"),
            std::string::npos);
  const std::string bad_state =
      "  - {name: /a, pid: 5, start_time: 9, state: dancing, lease_end_s: 0, log_file: l, ";
  EXPECT_NE(
      why(head + "count: 1\nnodes:\n" + bad_state + "argv: [/bin/a]}\n").find("unknown state"),
      std::string::npos);
  EXPECT_NE(
      why(head + "count: 2\nnodes:\n" + node + "argv: [/bin/a]}\n" + node + "argv: [/bin/a]}\n")
          .find("twice"),
      std::string::npos);
}

TEST(NodeStateFile, CommandLineMatching)
{
  const std::vector<std::string> bin = {"/opt/lib/pkg/talker", "__name:=talker"};
  EXPECT_TRUE(sameCommandLine(bin, bin));
  EXPECT_TRUE(
      sameCommandLine(bin, parseCmdline(std::string("/opt/lib/pkg/talker\0__name:=talker\0", 35))));
  // A script: its interpreter comes first ("#!/usr/bin/env python3" shows "python3").
  EXPECT_TRUE(sameCommandLine(bin, {"python3", "/opt/lib/pkg/talker", "__name:=talker"}));
  EXPECT_TRUE(sameCommandLine(bin, {"/bin/sh", "-e", "/opt/lib/pkg/talker", "__name:=talker"}));
  EXPECT_FALSE(
      sameCommandLine(bin, {"/usr/bin/x", "a", "b", "/opt/lib/pkg/talker", "__name:=talker"}));
  EXPECT_FALSE(sameCommandLine(bin, {"/opt/lib/pkg/talker", "__name:=other"}));
  EXPECT_FALSE(sameCommandLine(bin, {"/opt/lib/pkg/talker", "__name:=talker", "extra"}));
  EXPECT_FALSE(sameCommandLine(bin, {"/opt/lib/pkg/talker"}));
  EXPECT_FALSE(sameCommandLine(bin, {}));  // a zombie or a kernel thread
  EXPECT_EQ(parseCmdline(std::string("a\0\0b\0", 5)), (std::vector<std::string>{"a", "", "b"}));
}

TEST(NodeStateFile, WhyAProcessIsNotTheNode)
{
  NodeStateEntry e;
  e.name = "/talker";
  e.pid = 4242;
  e.start_time = 777;
  e.argv = {"/bin/sleep", "30"};
  const auto stat = [](const std::string& fields_after_comm) {
    return parseProcStat("4242 (sleep) " + fields_after_comm);
  };
  // state ppid pgrp session tty tpgid flags minflt cminflt majflt cmajflt utime stime cutime
  // cstime priority nice threads itrealvalue starttime vsize rss
  const std::string tail = " 0 0 0 0 0 0 0 0 20 0 1 0 ";
  auto check = [&](const std::optional<ProcStat>& s, const std::vector<std::string>& cmdline) {
    return checkIdentity(e, s, cmdline);
  };
  EXPECT_EQ(check(stat("S 1 4242 4242 0 -1 0" + tail + "777 1000 10"), e.argv).identity,
            Identity::Same);
  EXPECT_EQ(check(stat("T 1 4242 4242 0 -1 0" + tail + "777 1000 10"), e.argv).identity,
            Identity::Same)
      << "paused";
  // Behind an interpreter (a script's "#!/usr/bin/env python3").
  EXPECT_EQ(
      check(stat("S 1 4242 4242 0 -1 0" + tail + "777 1000 10"), {"python3", "/bin/sleep", "30"})
          .identity,
      Identity::Same);
  EXPECT_EQ(check(std::nullopt, {}).identity, Identity::Gone);
  EXPECT_EQ(check(stat("Z 1 4242 4242 0 -1 0" + tail + "777 0 0"), {}).identity, Identity::Gone);
  const IdentityCheck reused = check(stat("S 1 4242 4242 0 -1 0" + tail + "778 1000 10"), e.argv);
  EXPECT_EQ(reused.identity, Identity::Gone);
  EXPECT_NE(reused.why.find("another process"), std::string::npos) << reused.why;
  const IdentityCheck exec =
      check(stat("S 1 4242 4242 0 -1 0" + tail + "777 1000 10"), {"/bin/bash"});
  EXPECT_EQ(exec.identity, Identity::Changed);
  EXPECT_NE(exec.why.find("another command line"), std::string::npos) << exec.why;
  const IdentityCheck group = check(stat("S 1 99 99 0 -1 0" + tail + "777 1000 10"), e.argv);
  EXPECT_EQ(group.identity, Identity::Changed);
  EXPECT_NE(group.why.find("process group"), std::string::npos) << group.why;
}

TEST(NodeStateFile, BootIdIsRead)
{
  EXPECT_EQ(currentBootId().size(), 36u) << currentBootId();
}

TEST(NodeStateWriter, AStateIsWrittenOnlyWhenItChanged)
{
  supervisor_test::TempDir dir;
  const std::string path = dir.path() + "/nodes.yaml";
  NodeStateWriter writer;
  EXPECT_FALSE(writer.stage(sample()).has_value()) << "no path: no file";
  writer.setPath(path);
  const auto first = writer.stage(sample());
  ASSERT_TRUE(first.has_value());
  writer.write(*first);
  EXPECT_EQ(readNodeStateFile(path)->nodes, sample().nodes);
  // The same list again (e.g. a lease renewal of a node whose lease is not written) is no write.
  EXPECT_FALSE(writer.stage(sample()).has_value());
  NodeState paused = sample();
  paused.nodes[0].state = "paused";
  const auto second = writer.stage(paused);
  ASSERT_TRUE(second.has_value());
  EXPECT_GT(second->seq, first->seq);
  writer.write(*second);
  EXPECT_EQ(readNodeStateFile(path)->nodes, paused.nodes);
  EXPECT_TRUE(writer.takeNotes().empty());
}

TEST(NodeStateWriter, AStateOvertakenByALaterOneIsNotWritten)
{
  // Two threads stage in the order of their changes, and may write in the other order: the
  // file must end with the later list, not go back to the earlier one.
  supervisor_test::TempDir dir;
  const std::string path = dir.path() + "/nodes.yaml";
  NodeStateWriter writer;
  writer.setPath(path);
  NodeState earlier = sample();
  NodeState later = sample();
  later.nodes.pop_back();
  const auto a = writer.stage(earlier);
  const auto b = writer.stage(later);
  ASSERT_TRUE(a && b);
  writer.write(*b);
  writer.write(*a);
  EXPECT_EQ(readNodeStateFile(path)->nodes, later.nodes);
}

TEST(NodeStateWriter, AFailedWriteIsSaidOnceAndTriedAgain)
{
  supervisor_test::TempDir dir;
  const std::string sub = dir.path() + "/later";
  const std::string path = sub + "/nodes.yaml";
  NodeStateWriter writer;
  writer.setPath(path);
  writer.write(*writer.stage(sample()));
  EXPECT_NE(writer.error().find(sub), std::string::npos) << writer.error();
  const auto failed = writer.takeNotes();
  ASSERT_EQ(failed.size(), 1u);
  EXPECT_NE(failed[0].find("will not find the nodes"), std::string::npos) << failed[0];
  // The same list is staged again after a failure, and the same failure is not said again.
  const auto again = writer.stage(sample());
  ASSERT_TRUE(again.has_value());
  writer.write(*again);
  EXPECT_TRUE(writer.takeNotes().empty());
  ASSERT_TRUE(std::filesystem::create_directory(sub));
  writer.write(*writer.stage(sample()));
  EXPECT_EQ(writer.error(), "");
  EXPECT_EQ(writer.takeNotes(),
            std::vector<std::string>{"node state file " + path + " is written again"});
  EXPECT_EQ(readNodeStateFile(path)->nodes, sample().nodes);
  EXPECT_FALSE(writer.stage(sample()).has_value()) << "written: nothing to try again";
}
