// The supervisor's state file: YAML text, atomic writes, their ordering outside the supervisor's
// lock, strict reading, and adoption matching.
#include "anyscale_agent_cpp/node_state_file.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>
#include <yaml-cpp/yaml.h>

#include <cerrno>
#include <cmath>
#include <cstring>
#include <set>
#include <utility>

#include "anyscale_agent_cpp/own_file.h"

namespace anyscale_agent
{

const char* const kNodeStates[4] = {"starting", "running", "paused", "stopping"};

namespace
{
const char kFormat[] = "anyscale_agent_node_state/1";
// The last line. A file cut short (copied half, a full disk under an editor) can still be
// valid YAML that says something else: "- 30" cut to "- 3", or a list missing its last
// nodes. Only a file that ends with this line is read at all.
const char kTrailer[] = "# end of node state\n";

NodeStateError bad(const std::string& source, const std::string& what)
{
  return NodeStateError("node state file " + source + ": " + what);
}

YAML::Node need(const YAML::Node& node, const char* key, const std::string& where,
                const std::string& source)
{
  // operator[] on a const node does not insert; a missing key gives an invalid node.
  const YAML::Node found = node[key];
  if (!found)
    throw bad(source, where + ": missing '" + key + "'");
  return found;
}

template <class T>
T scalar(const YAML::Node& node, const char* key, const std::string& where,
         const std::string& source)
{
  const YAML::Node v = need(node, key, where, source);
  if (!v.IsScalar())
    throw bad(source, where + ": '" + key + "' must be a single value");
  try
  {
    return v.as<T>();
  }
  catch (const YAML::Exception&)
  {
    throw bad(source, where + ": '" + key + "' has the wrong type ('" + v.Scalar() + "')");
  }
}

bool knownState(const std::string& s)
{
  for (const char* k : kNodeStates)
    if (s == k)
      return true;
  return false;
}

NodeStateEntry parseEntry(const YAML::Node& n, const std::string& where, const std::string& source)
{
  if (!n.IsMap())
    throw bad(source, where + " is not a map");
  NodeStateEntry e;
  e.name = scalar<std::string>(n, "name", where, source);
  const std::string at = where + " (" + e.name + ")";
  e.pid = scalar<int>(n, "pid", at, source);
  e.start_time = scalar<uint64_t>(n, "start_time", at, source);
  e.state = scalar<std::string>(n, "state", at, source);
  e.lease_end_s = scalar<double>(n, "lease_end_s", at, source);
  e.log_file = scalar<std::string>(n, "log_file", at, source);
  const YAML::Node argv = need(n, "argv", at, source);
  if (!argv.IsSequence())
    throw bad(source, at + ": 'argv' must be a list");
  for (const auto& a : argv)
  {
    if (!a.IsScalar())
      throw bad(source, at + ": 'argv' must be a list of strings");
    e.argv.push_back(a.as<std::string>());
  }
  if (e.name.empty() || e.name[0] != '/')
    throw bad(source, at + ": 'name' must be a node name starting with '/'");
  if (e.pid <= 0)
    throw bad(source, at + ": 'pid' must be positive");
  if (!knownState(e.state))
    throw bad(source, at + ": unknown state '" + e.state + "'");
  if (!std::isfinite(e.lease_end_s) || e.lease_end_s < 0.0)
    throw bad(source, at + ": 'lease_end_s' must be 0 or a time");
  if (e.argv.empty() || e.argv[0].empty() || e.argv[0][0] != '/')
    throw bad(source, at + ": 'argv' must start with an absolute path");
  return e;
}
}  // namespace

std::string formatNodeState(const NodeState& state)
{
  YAML::Emitter out;
  out.SetDoublePrecision(17);  // a lease end read back must be the one written
  out << YAML::BeginMap;
  out << YAML::Key << "format" << YAML::Value << kFormat;
  out << YAML::Key << "boot_id" << YAML::Value << state.boot_id;
  out << YAML::Key << "count" << YAML::Value << state.nodes.size();
  out << YAML::Key << "nodes" << YAML::Value;
  if (state.nodes.empty())
    out << YAML::Flow;
  out << YAML::BeginSeq;
  for (const auto& e : state.nodes)
  {
    out << YAML::BeginMap;
    out << YAML::Key << "name" << YAML::Value << e.name;
    out << YAML::Key << "pid" << YAML::Value << e.pid;
    out << YAML::Key << "start_time" << YAML::Value << e.start_time;
    out << YAML::Key << "state" << YAML::Value << e.state;
    out << YAML::Key << "lease_end_s" << YAML::Value << e.lease_end_s;
    out << YAML::Key << "log_file" << YAML::Value << e.log_file;
    out << YAML::Key << "argv" << YAML::Value << YAML::Flow << e.argv;
    out << YAML::EndMap;
  }
  out << YAML::EndSeq << YAML::EndMap;
  return std::string(
             "# AnyScale agent: the nodes it runs, for the agent's next start to adopt (see its "
             "README,\n"
             "# \"Agent restarts\"). Rewritten on every start, stop and exit; do not edit.\n") +
         out.c_str() + "\n" + kTrailer;
}

NodeState parseNodeState(const std::string& text, const std::string& source)
{
  const std::string trailer(kTrailer);
  const std::string bare =
      trailer.substr(0, trailer.size() - 1);  // a lost final newline is no loss
  const bool complete =
      (text.size() >= trailer.size() &&
       text.compare(text.size() - trailer.size(), trailer.size(), trailer) == 0) ||
      (text.size() >= bare.size() + 1 &&
       text.compare(text.size() - bare.size(), bare.size(), bare) == 0 &&
       text[text.size() - bare.size() - 1] == '\n');
  if (!complete)
    throw bad(source, "incomplete (it does not end with the line '" + bare + "')");
  YAML::Node root;
  try
  {
    root = YAML::Load(text);
  }
  catch (const YAML::Exception& e)
  {
    throw bad(source, std::string("not YAML: ") + e.what());
  }
  if (!root.IsMap())
    throw bad(source, "not a map");
  const std::string format = scalar<std::string>(root, "format", "top level", source);
  if (format != kFormat)
    throw bad(source, "unknown format '" + format + "' (this agent reads " + kFormat + ")");
  NodeState state;
  state.boot_id = scalar<std::string>(root, "boot_id", "top level", source);
  const auto count = scalar<std::size_t>(root, "count", "top level", source);
  const YAML::Node nodes = need(root, "nodes", "top level", source);
  if (!nodes.IsSequence())
    throw bad(source, "'nodes' must be a list");
  if (nodes.size() != count)
    throw bad(source, "lists " + std::to_string(nodes.size()) + " nodes, but says " +
                          std::to_string(count));
  std::set<std::string> names;
  for (std::size_t i = 0; i < nodes.size(); ++i)
  {
    state.nodes.push_back(parseEntry(nodes[i], "node " + std::to_string(i + 1), source));
    if (!names.insert(state.nodes.back().name).second)
      throw bad(source, "node " + state.nodes.back().name + " listed twice");
  }
  return state;
}

bool writeNodeStateFile(const std::string& path, const NodeState& state, std::string* error)
{
  return replaceFileAtomically(path, formatNodeState(state), error);
}

std::optional<NodeStateWriter::Staged> NodeStateWriter::stage(const NodeState& state)
{
  if (path_.empty() || (staged_last_ && *staged_last_ == state && !failed_))
    return std::nullopt;
  staged_last_ = state;
  return Staged{++staged_seq_, path_, state};
}

void NodeStateWriter::write(const Staged& staged)
{
  std::lock_guard<std::mutex> lock(mutex_);
  if (staged.seq <= written_seq_)
    return;  // overtaken: the file holds a later state already
  written_seq_ = staged.seq;
  std::string error;
  if (writeNodeStateFile(staged.path, staged.state, &error))
  {
    if (!error_.empty())
      notes_.push_back("node state file " + staged.path + " is written again");
    error_.clear();
    failed_ = false;
    return;
  }
  failed_ = true;
  if (error != error_)
  {
    error_ = error;
    notes_.push_back("node state file: " + error + ": a restarted agent will not find the nodes");
  }
}

std::string NodeStateWriter::error() const
{
  std::lock_guard<std::mutex> lock(mutex_);
  return error_;
}

std::vector<std::string> NodeStateWriter::takeNotes()
{
  std::lock_guard<std::mutex> lock(mutex_);
  return std::exchange(notes_, {});
}

std::optional<NodeState> readNodeStateFile(const std::string& path)
{
  // Not through a link, not a FIFO (O_NONBLOCK: its open would wait for a writer), and only
  // this user's own file: what it lists, the agent adopts and may signal.
  UniqueFd fd(::open(path.c_str(), O_RDONLY | O_NOFOLLOW | O_NONBLOCK | O_CLOEXEC));
  if (fd.get() < 0)
  {
    if (errno == ENOENT)
      return std::nullopt;
    if (errno == ELOOP)
      throw bad(path, "is a symbolic link: not read");
    throw bad(path, std::string("cannot open: ") + std::strerror(errno));
  }
  struct stat st;
  if (::fstat(fd.get(), &st) != 0 || !S_ISREG(st.st_mode))
    throw bad(path, "is not a regular file: not read");
  if (st.st_uid != ::geteuid())
    throw bad(path, "belongs to user " + std::to_string(st.st_uid) + ", not to the agent's (" +
                        std::to_string(::geteuid()) + "): not read");
  std::string text;
  char buf[4096];
  for (;;)
  {
    const ssize_t n = ::read(fd.get(), buf, sizeof buf);
    if (n < 0 && errno == EINTR)
      continue;
    if (n < 0)
      throw bad(path, std::string("cannot read: ") + std::strerror(errno));
    if (n == 0)
      break;
    text.append(buf, std::size_t(n));
    if (text.size() > (16u << 20))  // a few hundred bytes per node: this is no state file
      throw bad(path, "larger than 16 MB");
  }
  return parseNodeState(text, path);
}

std::string currentBootId()
{
  auto id = readFile("/proc/sys/kernel/random/boot_id");
  if (!id)
    return "";
  while (!id->empty() && (id->back() == '\n' || id->back() == ' '))
    id->pop_back();
  return *id;
}

std::vector<std::string> parseCmdline(const std::string& raw)
{
  std::vector<std::string> out;
  std::size_t begin = 0;
  while (begin < raw.size())
  {
    std::size_t end = raw.find('\0', begin);
    if (end == std::string::npos)
      end = raw.size();
    out.push_back(raw.substr(begin, end - begin));
    begin = end + 1;
  }
  return out;
}

bool sameCommandLine(const std::vector<std::string>& argv, const std::vector<std::string>& cmdline)
{
  if (argv.empty() || cmdline.size() < argv.size())
    return false;
  const std::size_t extra = cmdline.size() - argv.size();
  // 0: a binary; 1: "#!/usr/bin/python3" or "#!/usr/bin/env python3" (env execs the
  // interpreter, which shows "python3"); 2: an interpreter line with one argument
  // ("#!/bin/sh -e"). More is another program that happens to end with these words.
  if (extra > 2)
    return false;
  for (std::size_t i = 0; i < argv.size(); ++i)
    if (cmdline[extra + i] != argv[i])
      return false;
  return true;
}

IdentityCheck checkIdentity(const NodeStateEntry& entry, const std::optional<ProcStat>& stat,
                            const std::vector<std::string>& cmdline)
{
  const std::string pid = "pid " + std::to_string(entry.pid);
  if (!stat)
    return {Identity::Gone, "it has ended"};
  if (stat->state == 'Z' || stat->state == 'X')
    return {Identity::Gone, "it has ended (a zombie now)"};
  // The pid alone may have been handed to another process since: the start time tells them apart.
  if (stat->start_time != entry.start_time)
    return {Identity::Gone, "it has ended; " + pid + " is another process now (started at tick " +
                                std::to_string(stat->start_time) + ", not " +
                                std::to_string(entry.start_time) + ")"};
  if (!sameCommandLine(entry.argv, cmdline))
    return {Identity::Changed,
            pid + " runs another command line now (it exec'd another program); left alone"};
  // Stops signal the whole group; a process that left it could not be stopped that way.
  if (stat->pgrp != entry.pid)
    return {Identity::Changed,
            pid + " left its process group (now " + std::to_string(stat->pgrp) + "); left alone"};
  return {Identity::Same, ""};
}

}  // namespace anyscale_agent
