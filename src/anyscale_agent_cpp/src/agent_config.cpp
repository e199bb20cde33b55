// The agent's configuration from its command line (agent_config.h).
#include "anyscale_agent_cpp/agent_config.h"

#include <stdexcept>

#include "anyscale_agent_cpp/node_model.h"
#include "anyscale_agent_cpp/request_check.h"

namespace anyscale_agent
{

const char* const kCommandLineSettings[8] = {"scale",       "is_master",  "model",
                                             "log_dir",     "state_file", "nodes_outlive_agent",
                                             "ledger_file", "robot"};

namespace
{
const char kNamePrefix[] = "/anyscale_agent_";

bool boolean(const std::map<std::string, std::string>& args, const std::string& key, bool fallback)
{
  const auto it = args.find(key);
  if (it == args.end())
    return fallback;
  bool value;
  if (it->second == "1" || it->second == "0")
    return it->second == "1";
  if (parseYamlBool(it->second, &value))
    return value;
  throw std::runtime_error("_" + key + ":= must be true or false, got " + quoted(it->second));
}

std::string text(const std::map<std::string, std::string>& args, const std::string& key,
                 const std::string& fallback)
{
  const auto it = args.find(key);
  if (it == args.end())
    return fallback;
  if (it->second.empty())
    throw std::runtime_error("_" + key + ":= must not be empty");
  return it->second;
}
}  // namespace

std::map<std::string, std::string> privateArguments(int argc, const char* const* argv)
{
  std::map<std::string, std::string> out;
  for (int i = 1; i < argc; ++i)
  {
    const std::string arg = argv[i];
    const auto sep = arg.find(":=");
    if (sep != std::string::npos && sep > 1 && arg[0] == '_' && arg[1] != '_')
      out[arg.substr(1, sep - 1)] = arg.substr(sep + 2);
  }
  return out;
}

AgentConfig agentConfig(const std::map<std::string, std::string>& args,
                        const std::string& node_name, const std::string& log_base)
{
  AgentConfig c;
  const std::string prefix = kNamePrefix;
  const bool conventional = node_name.rfind(prefix, 0) == 0;
  c.scale = text(args, "scale", conventional ? node_name.substr(prefix.size()) : "");
  if (!isValidPackageName(c.scale))
    throw std::runtime_error(
        "_scale:= must be a scale name of the model (letters, digits, '_'), got " +
        quoted(c.scale));
  c.is_master = boolean(args, "is_master", false);
  const auto model = args.find("model");
  if (model == args.end() || model->second.empty())
    throw std::runtime_error(
        "the system model is required on the command line: _model:=PATH (agent.launch "
        "passes its model arg so); ~model on the parameter server is not read, since "
        "anyone on the graph may set it");
  c.model_path = model->second;
  // Empty is none: agent.launch passes both, given or not.
  const auto ledger = args.find("ledger_file");
  c.ledger_file = ledger == args.end() ? "" : ledger->second;
  const auto robot = args.find("robot");
  c.robot = robot == args.end() ? "" : robot->second;
  if (!c.robot.empty() && !isValidPackageName(c.robot))
    throw std::runtime_error("_robot:= must be a robot id (letters, digits, '_'), got " +
                             quoted(c.robot));
  if (!c.ledger_file.empty() && c.robot.empty())
    throw std::runtime_error(
        "_ledger_file:= needs _robot:=ID: the ledger holds each robot's nodes under its id, and "
        "every agent sharing it serves another robot");
  if (!c.ledger_file.empty() && c.is_master)
    throw std::runtime_error(
        "_ledger_file:= is for a scale that robots share: a master scale is "
        "its robot's own (give _is_master:=false, or no ledger)");
  c.log_dir = text(args, "log_dir",
                   log_base + "/anyscale/" + c.scale + (c.robot.empty() ? "" : "/" + c.robot));
  c.state_file = text(args, "state_file", c.log_dir + "/running_nodes.yaml");
  c.nodes_outlive_agent = boolean(args, "nodes_outlive_agent", c.is_master);
  return c;
}

}  // namespace anyscale_agent
