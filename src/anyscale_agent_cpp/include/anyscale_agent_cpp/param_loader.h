// Puts a node's declared parameters and hand-off overrides on the parameter server.
#pragma once

#include <XmlRpcValue.h>
#include <yaml-cpp/yaml.h>

#include <map>
#include <string>

#include "anyscale_agent_cpp/node_model.h"

namespace anyscale_agent
{

// YAML as roslaunch's rosparam loader reads it: int, double, bool, string, list, map. $(find)
// is substituted in strings. Throws ModelError for what XML-RPC cannot carry (e.g. null).
XmlRpc::XmlRpcValue yamlToXmlRpc(const YAML::Node& node, const PackageLocator& locate,
                                 const std::string& where);

// Private parameters of node `node_name` (graph name without leading slash): the model's
// `params`, then `overrides` (key -> YAML text) on top. With clear_first, the node's private
// namespace is deleted first, like roslaunch's clear_params="true", so an override from an
// earlier hand-off cannot outlive the start it was meant for. With `copy_from` (the declared
// name of a node started under an instance name), what the parameter server holds under
// /copy_from (e.g. set by the user's launch files) is copied under /node_name first, so the
// instance reads the private parameters the declared node would. Everything is converted
// before anything is written, so a bad value leaves the server untouched. Throws ModelError.
void setNodeParams(const std::string& node_name, const YAML::Node& params,
                   const std::map<std::string, std::string>& overrides,
                   const PackageLocator& locate, bool clear_first,
                   const std::string& copy_from = "");

}  // namespace anyscale_agent
