// YAML -> XML-RPC conversion and parameter-server writes for node starts.
#include "anyscale_agent_cpp/param_loader.h"

#include <ros/param.h>

#include <vector>

#include "anyscale_agent_cpp/request_check.h"

namespace anyscale_agent
{
namespace
{
XmlRpc::XmlRpcValue scalar(const YAML::Node& node, const PackageLocator& locate)
{
  const std::string text = node.Scalar();
  // A quoted scalar ("1.5") is a string, as in PyYAML; only plain scalars are typed.
  if (node.Tag() != "!")
  {
    try
    {
      std::size_t used = 0;
      const long long i = std::stoll(text, &used, 0);
      if (used == text.size() && i >= INT32_MIN && i <= INT32_MAX)
        return XmlRpc::XmlRpcValue(int(i));
    }
    catch (const std::exception&)
    {}
    try
    {
      std::size_t used = 0;
      const double d = std::stod(text, &used);
      if (used == text.size())
        return XmlRpc::XmlRpcValue(d);
    }
    catch (const std::exception&)
    {}
    double special;
    if (parseYamlSpecialFloat(text, &special))
      return XmlRpc::XmlRpcValue(special);
    bool b;
    if (parseYamlBool(text, &b))
      return XmlRpc::XmlRpcValue(b);
  }
  return XmlRpc::XmlRpcValue(substituteFind(text, locate));
}
}  // namespace

XmlRpc::XmlRpcValue yamlToXmlRpc(const YAML::Node& node, const PackageLocator& locate,
                                 const std::string& where)
{
  switch (node.Type())
  {
    case YAML::NodeType::Scalar: return scalar(node, locate);
    case YAML::NodeType::Sequence:
    {
      XmlRpc::XmlRpcValue v;
      v.setSize(int(node.size()));
      for (std::size_t i = 0; i < node.size(); ++i)
        v[int(i)] = yamlToXmlRpc(node[i], locate, where + "[" + std::to_string(i) + "]");
      return v;
    }
    case YAML::NodeType::Map:
    {
      XmlRpc::XmlRpcValue v;
      v.begin();  // makes an empty struct even for {}
      for (const auto& kv : node)
        v[kv.first.as<std::string>()] =
            yamlToXmlRpc(kv.second, locate, where + "." + kv.first.as<std::string>());
      return v;
    }
    default: throw ModelError(where + ": a null or undefined value cannot be a ROS parameter");
  }
}

void setNodeParams(const std::string& node_name, const YAML::Node& params,
                   const std::map<std::string, std::string>& overrides,
                   const PackageLocator& locate, bool clear_first, const std::string& copy_from)
{
  const std::string ns = "/" + node_name;
  std::vector<std::pair<std::string, XmlRpc::XmlRpcValue>> values;
  if (params && params.IsMap())
    for (const auto& kv : params)
    {
      const std::string key = kv.first.as<std::string>();
      values.emplace_back(key, yamlToXmlRpc(kv.second, locate, "param '" + key + "'"));
    }
  for (const auto& [key, text] : overrides)
  {
    if (key.empty() || key[0] == '/' || key[0] == '~' || !isValidNodeName(key))
      throw ModelError("param override " + quoted(key) +
                       ": must be a name relative to the node, e.g. initial_pose_x");
    if (const std::string why = checkOverrideValue(key, text); !why.empty())
      throw ModelError(why);
    YAML::Node parsed;
    try
    {
      parsed = YAML::Load(text);
    }
    catch (const YAML::Exception& e)
    {
      throw ModelError("param override '" + key + "': value is not YAML: " + e.what());
    }
    values.emplace_back(key, yamlToXmlRpc(parsed, locate, "param override '" + key + "'"));
  }
  if (clear_first && ros::param::has(ns))
    ros::param::del(ns);
  XmlRpc::XmlRpcValue declared;
  if (!copy_from.empty() && copy_from != node_name && ros::param::get("/" + copy_from, declared) &&
      declared.getType() == XmlRpc::XmlRpcValue::TypeStruct)
    ros::param::set(ns, declared);
  for (const auto& [key, value] : values)
    ros::param::set(ns + "/" + key, value);
}

}  // namespace anyscale_agent
