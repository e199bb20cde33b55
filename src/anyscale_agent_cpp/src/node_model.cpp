// Loading and checking the model's node declarations; finding executables like rosrun.
#include "anyscale_agent_cpp/node_model.h"

#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <sstream>

namespace fs = std::filesystem;

namespace anyscale_agent
{
namespace
{
bool isBaseName(const std::string& s)
{
  if (s.empty() || !std::isalpha(static_cast<unsigned char>(s[0])))
    return false;
  for (char c : s)
    if (!std::isalnum(static_cast<unsigned char>(c)) && c != '_')
      return false;
  return true;
}

std::string scalarAt(const YAML::Node& map, const std::string& key, const std::string& where,
                     bool required)
{
  const YAML::Node v = map[key];
  if (!v)
  {
    if (required)
      throw ModelError(where + ": missing key '" + key + "'");
    return "";
  }
  if (!v.IsScalar())
    throw ModelError(where + ": '" + key + "' must be a string");
  return v.as<std::string>();
}

bool isExecutableFile(const fs::path& p)
{
  std::error_code ec;
  return fs::is_regular_file(p, ec) && ::access(p.c_str(), X_OK) == 0;
}

bool readBool(const YAML::Node& launch, const std::string& key, const std::string& where)
{
  const YAML::Node v = launch[key];
  if (!v)
    return false;
  if (!v.IsScalar() || (v.Scalar() != "true" && v.Scalar() != "false"))
    throw ModelError(where + ": launch." + key + " must be true or false");
  return v.Scalar() == "true";
}

// Walks a parameter value as a start converts it, every alias expanded, within `left` values.
void checkParamTree(const YAML::Node& v, const std::string& where, std::size_t& left, int depth)
{
  if (left == 0)
    throw ModelError(where + ": launch.params hold more than " + std::to_string(kMaxParamValues) +
                     " values with their aliases expanded");
  --left;
  if (depth > kMaxParamDepth)
    throw ModelError(where + ": launch.params nested deeper than " +
                     std::to_string(kMaxParamDepth));
  if (v.IsScalar())
    return;
  if (v.IsSequence())
  {
    for (std::size_t i = 0; i < v.size(); ++i)
      checkParamTree(v[i], where + "[" + std::to_string(i) + "]", left, depth + 1);
    return;
  }
  if (!v.IsMap())
    throw ModelError(where + ": a null value cannot be a ROS parameter");
  for (const auto& kv : v)
  {
    if (!kv.first.IsScalar())
      throw ModelError(where + ": a map key in launch.params must be a name");
    checkParamTree(kv.second, where + "." + kv.first.Scalar(), left, depth + 1);
  }
}

std::string globalTopic(const std::string& topic)
{
  return !topic.empty() && topic[0] == '/' ? topic : "/" + topic;
}
}  // namespace

std::set<std::string> handoffKeys(const std::string& kind)
{
  if (kind == "pose")
    return {"initial_pose_x", "initial_pose_y", "initial_pose_a",    "initial_cov_xx",
            "initial_cov_yy", "initial_cov_aa", "initial_pose_stamp"};
  throw ModelError("state_handoff.kind '" + kind + "' is not one of: pose");
}

bool isValidNodeName(const std::string& name)
{
  if (name.empty() || name.front() == '/' || name.back() == '/')
    return false;
  std::istringstream parts(name);
  for (std::string part; std::getline(parts, part, '/');)
    if (!isBaseName(part))
      return false;
  return true;
}

bool isValidPackageName(const std::string& name)
{
  return isBaseName(name);
}

bool isValidExecutableName(const std::string& name)
{
  if (name.empty() || name == "." || name == ".." || name[0] == '-' ||
      name.find("..") != std::string::npos)
    return false;
  for (char c : name)
    if (!std::isalnum(static_cast<unsigned char>(c)) && c != '_' && c != '-' && c != '.')
      return false;
  return true;
}

NodeModel NodeModel::load(const std::string& path)
{
  YAML::Node root;
  try
  {
    root = YAML::LoadFile(path);
  }
  catch (const YAML::Exception& e)
  {
    throw ModelError(path + ": cannot read YAML: " + e.what());
  }
  return parse(root, path);
}

NodeModel NodeModel::parse(const YAML::Node& root, const std::string& source)
{
  if (!root.IsMap() || !root["nodes"] || !root["nodes"].IsSequence())
    throw ModelError(source + ": expected a map with a 'nodes' list");
  NodeModel model;
  std::size_t index = 0;
  for (const auto& n : root["nodes"])
  {
    const std::string at = source + ": nodes[" + std::to_string(index++) + "]";
    if (!n.IsMap())
      throw ModelError(at + ": expected a map");
    NodeDecl d;
    d.name = scalarAt(n, "name", at, true);
    const std::string where = source + ": node '" + d.name + "'";
    if (!isValidNodeName(d.name))
      throw ModelError(
          where +
          ": 'name' is not a valid ROS node name (letters, digits, '_', '/'-separated, "
          "no leading '/')");
    if (d.name.find(kInstanceSeparator) != std::string::npos)
      throw ModelError(where + ": 'name' must not contain '" + kInstanceSeparator +
                       "' (reserved for instance names on remote scales, NAME__SCALE)");
    if (model.nodes_.count(d.name))
      throw ModelError(where + ": declared twice");
    const YAML::Node launch = n["launch"];
    if (!launch || !launch.IsMap())
      throw ModelError(where + ": missing map 'launch'");
    d.package = scalarAt(launch, "package", where + " launch", true);
    d.type = scalarAt(launch, "type", where + " launch", true);
    if (!isValidPackageName(d.package))
      throw ModelError(where + ": launch.package '" + d.package + "' is not a valid package name");
    if (!isValidExecutableName(d.type))
      throw ModelError(where + ": launch.type '" + d.type +
                       "' must be a plain executable name (no '/' or '..')");
    if (const YAML::Node args = launch["args"])
    {
      if (!args.IsSequence())
        throw ModelError(where + ": launch.args must be a list of strings");
      for (const auto& a : args)
      {
        if (!a.IsScalar())
          throw ModelError(where + ": launch.args must be a list of strings");
        d.args.push_back(a.as<std::string>());
      }
    }
    if (const YAML::Node remaps = launch["remaps"])
    {
      if (!remaps.IsMap())
        throw ModelError(where + ": launch.remaps must be a map {from: to}");
      for (const auto& kv : remaps)
      {
        if (!kv.first.IsScalar() || !kv.second.IsScalar())
          throw ModelError(where + ": launch.remaps must map names to names");
        d.remaps.emplace_back(kv.first.as<std::string>(), kv.second.as<std::string>());
      }
    }
    if (const YAML::Node params = launch["params"])
    {
      if (!params.IsMap())
        throw ModelError(where + ": launch.params must be a map {name: value}");
      // Checked here, not at the first start: a key that is a list made the start's
      // conversion throw a YAML exception out of the start_node service.
      std::size_t left = kMaxParamValues;
      for (const auto& kv : params)
      {
        if (!kv.first.IsScalar() || !isValidNodeName(kv.first.Scalar()))
          throw ModelError(where +
                           ": launch.params keys must be parameter names (letters, digits, '_')");
        checkParamTree(kv.second, where + " param '" + kv.first.Scalar() + "'", left, 1);
      }
      d.params = params;
    }
    d.warm_start = readBool(launch, "warm_start", where);
    d.pause_at_home = readBool(launch, "pause_at_home", where);
    if (const YAML::Node handoff = n["state_handoff"])
    {
      if (!handoff.IsMap())
        throw ModelError(where + ": state_handoff must be a map {kind: pose, topic: /name}");
      try
      {
        d.handoff_keys = handoffKeys(scalarAt(handoff, "kind", where + " state_handoff", true));
      }
      catch (const ModelError& e)
      {
        throw ModelError(where + ": " + e.what());
      }
    }
    if (const YAML::Node nice = launch["nice"])
    {
      int value = 0;
      if (!nice.IsScalar() || !YAML::convert<int>::decode(nice, value) || value < -20 || value > 19)
        throw ModelError(where + ": launch.nice must be an integer from -20 to 19");
      d.nice = value;
    }
    model.nodes_.emplace(d.name, std::move(d));
  }
  model.readConnections(root["connections"], source);
  model.readScales(root["scales"], source);
  return model;
}

void NodeModel::readScales(const YAML::Node& scales, const std::string& source)
{
  if (!scales)
    return;
  if (!scales.IsSequence())
    throw ModelError(source + ": 'scales' must be a list");
  std::size_t index = 0;
  for (const auto& s : scales)
  {
    const std::string at = source + ": scales[" + std::to_string(index++) + "]";
    if (!s.IsMap())
      throw ModelError(at + ": expected a map");
    const std::string name = scalarAt(s, "name", at, true);
    double memory_mb = 0.0;
    if (const YAML::Node m = s["memory_mb"];
        m && (!m.IsScalar() || !YAML::convert<double>::decode(m, memory_mb) || !(memory_mb > 0.0) ||
              !std::isfinite(memory_mb)))
      throw ModelError(at + " (" + name + "): 'memory_mb' must be a positive number");
    if (memory_mb > 0.0)
      scale_memory_mb_[name] = memory_mb;
  }
}

std::optional<double> NodeModel::scaleMemoryMb(const std::string& scale) const
{
  const auto it = scale_memory_mb_.find(scale);
  return it == scale_memory_mb_.end() ? std::nullopt : std::optional<double>(it->second);
}

void NodeModel::readConnections(const YAML::Node& connections, const std::string& source)
{
  if (!connections)
    return;
  if (!connections.IsSequence())
    throw ModelError(source + ": 'connections' must be a list");
  std::size_t index = 0;
  for (const auto& c : connections)
  {
    const std::string at = source + ": connections[" + std::to_string(index++) + "]";
    if (!c.IsMap())
      throw ModelError(at + ": expected a map");
    const std::string publisher = scalarAt(c, "publisher", at, true);
    if (const YAML::Node subscriber = c["subscriber"]; subscriber && subscriber.IsScalar())
      if (const YAML::Node topic = c["topic"]; topic && topic.IsScalar())
        subscriptions_.emplace(subscriber.Scalar(), globalTopic(topic.Scalar()));
    double tolerance = 0.0;
    if (const YAML::Node t = c["tolerance"])
      if (!t.IsScalar() || !YAML::convert<double>::decode(t, tolerance) ||
          !std::isfinite(tolerance) || tolerance < 0.0)
        throw ModelError(at + " (publisher '" + publisher +
                         "'): 'tolerance' must be a number of seconds >= 0");
    const auto node = nodes_.find(publisher);
    if (node == nodes_.end() || tolerance <= 0.0)
      continue;  // an unknown publisher is the decision node's error to report
    double& smallest = node->second.output_tolerance_s;
    smallest = smallest > 0.0 ? std::min(smallest, tolerance) : tolerance;
  }
}

const NodeDecl* NodeModel::find(const std::string& name) const
{
  const std::string key = !name.empty() && name[0] == '/' ? name.substr(1) : name;
  const auto it = nodes_.find(key);
  return it == nodes_.end() ? nullptr : &it->second;
}

bool NodeModel::subscribes(const std::string& node, const std::string& topic) const
{
  const NodeDecl* decl = find(node);
  return decl && subscriptions_.count({decl->name, globalTopic(topic)}) > 0;
}

std::vector<std::string> NodeModel::names() const
{
  std::vector<std::string> out;
  for (const auto& kv : nodes_)
    out.push_back(kv.first);
  return out;
}

std::string substituteFind(const std::string& text, const PackageLocator& locate)
{
  std::string out;
  std::size_t pos = 0;
  for (;;)
  {
    const auto start = text.find("$(", pos);
    if (start == std::string::npos)
      break;
    const auto end = text.find(')', start);
    if (end == std::string::npos)
      throw ModelError("unterminated substitution in '" + text + "'");
    std::istringstream words(text.substr(start + 2, end - start - 2));
    std::string verb, pkg, extra;
    words >> verb >> pkg >> extra;
    if (verb != "find" || pkg.empty() || !extra.empty())
      throw ModelError("only $(find pkg) is supported, got '" +
                       text.substr(start, end - start + 1) + "'");
    const std::string dir = isValidPackageName(pkg) ? locate(pkg) : "";
    if (dir.empty())
      throw ModelError("$(find " + pkg + "): package not found");
    out += text.substr(pos, start - pos) + dir;
    pos = end + 1;
  }
  return out + text.substr(pos);
}

std::string resolveExecutable(const std::string& package, const std::string& type,
                              const std::vector<std::string>& prefixes,
                              const PackageLocator& locate)
{
  if (!isValidPackageName(package))
    throw ModelError("invalid package name '" + package + "'");
  if (!isValidExecutableName(type))
    throw ModelError("invalid executable name '" + type + "'");
  for (const auto& prefix : prefixes)
  {
    const fs::path candidate = fs::path(prefix) / "lib" / package / type;
    if (isExecutableFile(candidate))
      return candidate.string();
  }
  const std::string dir = locate(package);
  if (dir.empty())
    throw ModelError("package '" + package + "' not found (not on ROS_PACKAGE_PATH)");
  std::vector<fs::path> found;
  std::error_code ec;
  for (fs::recursive_directory_iterator it(dir, fs::directory_options::skip_permission_denied, ec),
       end;
       !ec && it != end; it.increment(ec))
  {
    if (it->is_directory(ec) && it->path().filename().string().rfind('.', 0) == 0)
    {
      it.disable_recursion_pending();  // .git and the like
      continue;
    }
    if (it->path().filename() == type && isExecutableFile(it->path()))
      found.push_back(it->path());
  }
  if (found.empty())
    throw ModelError("no executable '" + type + "' in package '" + package +
                     "' (looked in <prefix>/lib/" + package + " and below " + dir + ")");
  if (found.size() > 1)
    throw ModelError("several executables named '" + type + "' in package '" + package +
                     "': " + found[0].string() + ", " + found[1].string());
  return found[0].string();
}

std::vector<std::string> catkinPrefixes(const char* cmake_prefix_path)
{
  std::vector<std::string> out;
  std::istringstream in(cmake_prefix_path ? cmake_prefix_path : "");
  for (std::string p; std::getline(in, p, ':');)
    if (!p.empty())
      out.push_back(p);
  if (std::find(out.begin(), out.end(), "/usr") == out.end())
    out.push_back("/usr");
  return out;
}

std::string instanceSuffix(const std::string& scale, bool on_master)
{
  return on_master ? "" : kInstanceSeparator + scale;
}

std::string qualifiedName(const std::string& name)
{
  return !name.empty() && name[0] == '/' ? name : "/" + name;
}

std::string instanceName(const std::string& declared, const std::string& scale, bool on_master)
{
  return declared + instanceSuffix(scale, on_master);
}

std::vector<std::string> buildArgv(const NodeDecl& decl, const std::string& executable,
                                   const PackageLocator& locate, const std::string& name_suffix)
{
  std::vector<std::string> argv{executable};
  for (const auto& a : decl.args)
    argv.push_back(substituteFind(a, locate));
  for (const auto& [from, to] : decl.remaps)
    argv.push_back(from + ":=" + to);
  const auto slash = decl.name.rfind('/');
  if (slash != std::string::npos)
    argv.push_back("__ns:=/" + decl.name.substr(0, slash));
  argv.push_back("__name:=" + decl.name.substr(slash == std::string::npos ? 0 : slash + 1) +
                 name_suffix);
  return argv;
}

}  // namespace anyscale_agent
