// The allow-list of nodes an agent may start: the `nodes` of the system model (no ROS).
#pragma once

#include <yaml-cpp/yaml.h>

#include <functional>
#include <map>
#include <optional>
#include <set>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace anyscale_agent
{

struct ModelError : std::runtime_error
{
  using std::runtime_error::runtime_error;
};

struct NodeDecl
{
  std::string name;  // graph name without leading slash, e.g. "amcl" or "robot/amcl"
  std::string package;
  std::string type;
  std::vector<std::string> args;
  std::vector<std::pair<std::string, std::string>> remaps;
  YAML::Node params;        // map of private parameters (may be null)
  bool warm_start = false;  // keep a warm standby (scripts/python_standby) on every scale
  int nice = 0;  // CPU priority it runs at, -20..19 (roslaunch: launch-prefix="nice -n N")
  bool pause_at_home = false;  // launch.pause_at_home: the master scale may pause it (SIGSTOP)
  // The parameters its state hand-off sets (state_handoff.kind): the only overrides a start takes.
  std::set<std::string> handoff_keys;
  // The smallest tolerance (s) of the model's connections this node publishes, 0 if none has
  // one: how long its output may stay below the connection's minimum rate (OutputBoosts).
  double output_tolerance_s = 0.0;
};

// Package name -> its source/share directory, or "" if unknown (rospack in the ROS layer).
using PackageLocator = std::function<std::string(const std::string&)>;

class NodeModel
{
public:
  // Reads the `nodes` list of a system model, and from its `connections` the tolerance of each
  // node's output and which node subscribes to which topic. Throws ModelError naming the file,
  // the node or connection and the key that is wrong. The rest of the model is the decision
  // node's business.
  static NodeModel load(const std::string& path);
  static NodeModel parse(const YAML::Node& root, const std::string& source);

  // Accepts "amcl" and "/amcl"; nullopt if not declared.
  const NodeDecl* find(const std::string& name) const;
  std::vector<std::string> names() const;
  // Whether a connection of the model has declared node `node` ("amcl" or "/amcl") subscribe to
  // `topic` ("/scan"; a relative topic of the model counts as global).
  bool subscribes(const std::string& node, const std::string& topic) const;
  // The `memory_mb` of a scale of the model's `scales` list; nullopt if it has none.
  std::optional<double> scaleMemoryMb(const std::string& scale) const;

private:
  void readConnections(const YAML::Node& connections, const std::string& source);
  void readScales(const YAML::Node& scales, const std::string& source);

  std::map<std::string, NodeDecl> nodes_;
  std::set<std::pair<std::string, std::string>> subscriptions_;  // (declared node, /topic)
  std::map<std::string, double> scale_memory_mb_;                // scale -> memory_mb
};

// A node's launch.params, aliases expanded, hold at most this many values (each scalar, list and
// map) nested at most this deep: an alias bomb in a few lines expands to billions, converted into
// parameters at every start.
constexpr std::size_t kMaxParamValues = 10000;
constexpr int kMaxParamDepth = 32;

// The parameters a state hand-off of `kind` sets (as the decision node's
// decision_types.pose_handoff_params names them); throws ModelError for an unknown kind.
std::set<std::string> handoffKeys(const std::string& kind);

// Graph-name rules of ROS (names.h): a base name starts with a letter and holds only
// letters, digits and '_'; namespaces are joined by single '/'.
bool isValidNodeName(const std::string& name);
bool isValidPackageName(const std::string& name);
// An executable name: a plain file name, never a path ("/", ".." or a leading '-' refused).
bool isValidExecutableName(const std::string& name);

// Replaces every $(find pkg) as roslaunch does; throws ModelError for an unknown package or
// any other $(...) substitution, which the agent does not evaluate.
std::string substituteFind(const std::string& text, const PackageLocator& locate);

// Where rosrun / roslaunch would find `type` of `package`: <prefix>/lib/<package>/<type> for
// each prefix in order (catkin's libexec), else a single executable file of that name anywhere
// below the package directory. Throws ModelError saying what was looked for where.
std::string resolveExecutable(const std::string& package, const std::string& type,
                              const std::vector<std::string>& prefixes,
                              const PackageLocator& locate);

// CMAKE_PREFIX_PATH split on ':', plus /usr, which Debian's catkin always searches as a
// workspace (catkin/workspace.py get_workspaces()).
std::vector<std::string> catkinPrefixes(const char* cmake_prefix_path);

// The name a node's instance registers under on a scale: the declared name on the master scale,
// "<declared>__<scale>" on any other. The ROS master shuts down the older of two processes that
// register one name, and across a partition that rule ends the wrong one: a request a dead
// remote instance sent before the link went (a TCP retransmission, delivered once the link is
// back) hands the name to the dead instance and shuts down the live one on the robot. With a
// name per scale, instances on different scales never compete for a name, so a stale request
// can only ever touch its own scale's name; and a planned move can start the new instance
// while the old one still runs (make before break). Works on plain and qualified names.
std::string instanceName(const std::string& declared, const std::string& scale, bool on_master);
// What instanceName appends: "" on the master scale, "__<scale>" elsewhere.
std::string instanceSuffix(const std::string& scale, bool on_master);
// The name with a leading '/' ("relay" and "/relay" give "/relay"), as the supervisor keys it.
std::string qualifiedName(const std::string& name);

// "__" in a declared name would let it collide with another node's instance name.
constexpr const char* kInstanceSeparator = "__";

// The command line of a declared node: executable, args, remaps "from:=to", and the name
// given as __name (plus __ns for a namespaced name), with `name_suffix` appended to the base
// name (an instance name, see instanceName). Parameters are not on the command line; the ROS
// layer sets them on the parameter server first, as roslaunch does.
std::vector<std::string> buildArgv(const NodeDecl& decl, const std::string& executable,
                                   const PackageLocator& locate,
                                   const std::string& name_suffix = "");

}  // namespace anyscale_agent
