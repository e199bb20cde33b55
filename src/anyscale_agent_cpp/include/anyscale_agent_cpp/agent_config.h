// What the agent is and which files it may run and write: from its own command line, never
// from the parameter server (no ROS). ROS 1 has no authentication: anyone on the graph may set
// the agent's private parameters, and a `rosparam set ~state_file /etc/<file>` followed by a
// restart of the agent had it replace that file; `~model` replaced the allow-list.
#pragma once

#include <map>
#include <string>

namespace anyscale_agent
{

struct AgentConfig
{
  std::string scale;
  bool is_master = false;
  std::string model_path;
  std::string log_dir;
  std::string state_file;
  bool nodes_outlive_agent = false;
  std::string robot;        // the robot this agent serves on a shared scale ("" : not shared)
  std::string ledger_file;  // the shared scale's capacity ledger ("" : none, admit as always)
};

// The settings AgentConfig holds, as the names of their arguments (`_model:=PATH`).
extern const char* const kCommandLineSettings[8];

// The `_name:=value` arguments of a command line by name ("model" for `_model:=/m.yaml`): how
// rosrun and a launch file's `args` pass a node's private parameters. `__name:=` and other
// remappings are not among them.
std::map<std::string, std::string> privateArguments(int argc, const char* const* argv);

// The configuration from those arguments. Defaults: `scale` the node name's suffix after
// "/anyscale_agent_"; `is_master` false; `log_dir` log_base + "/anyscale/<scale>" (+ "/<robot>"
// with `robot`); `state_file` log_dir + "/running_nodes.yaml"; `nodes_outlive_agent` is_master;
// `robot` and `ledger_file` none (empty). `model` is required, and `robot` with `ledger_file`.
// Throws std::runtime_error naming the argument that is missing or wrong.
AgentConfig agentConfig(const std::map<std::string, std::string>& args,
                        const std::string& node_name, const std::string& log_base);

}  // namespace anyscale_agent
