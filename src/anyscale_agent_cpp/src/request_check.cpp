// Checks and quoting of service request fields (request_check.h).
#include "anyscale_agent_cpp/request_check.h"

#include <yaml-cpp/yaml.h>

#include <cmath>
#include <cstdio>
#include <vector>

namespace anyscale_agent
{

std::string quoted(const std::string& text, std::size_t max_bytes)
{
  std::string out = "'";
  for (std::size_t i = 0; i < text.size() && i < max_bytes; ++i)
  {
    const unsigned char c = static_cast<unsigned char>(text[i]);
    if (c >= 0x20 && c < 0x7f && c != '\\')
    {
      out += char(c);
    }
    else
    {
      char hex[5];
      std::snprintf(hex, sizeof hex, "\\x%02x", c);
      out += hex;
    }
  }
  out += "'";
  if (text.size() > max_bytes)
    out += "... (" + std::to_string(text.size()) + " bytes)";
  return out;
}

std::string checkSeconds(const std::string& field, double seconds, bool zero_allowed, double max_s)
{
  if (std::isfinite(seconds) && (zero_allowed ? seconds >= 0.0 : seconds > 0.0) && seconds <= max_s)
    return "";
  char range[96];
  std::snprintf(range, sizeof range, "%s 0 and at most %.0f seconds", zero_allowed ? ">=" : ">",
                max_s);
  return field + " must be " + range + ", got " + std::to_string(seconds);
}

std::string checkAmount(const std::string& field, double amount, double max,
                        const std::string& unit)
{
  if (std::isfinite(amount) && amount >= 0.0 && amount <= max)
    return "";
  char range[96];
  std::snprintf(range, sizeof range, " must be >= 0 and at most %g %s, got ", max, unit.c_str());
  return field + range + std::to_string(amount);
}

bool parseYamlBool(const std::string& text, bool* value)
{
  static const std::vector<std::string> yes{"true", "True", "TRUE", "yes", "Yes",
                                            "YES",  "on",   "On",   "ON"};
  static const std::vector<std::string> no{"false", "False", "FALSE", "no", "No",
                                           "NO",    "off",   "Off",   "OFF"};
  for (const auto& y : yes)
    if (text == y)
      return *value = true, true;
  for (const auto& n : no)
    if (text == n)
      return *value = false, true;
  return false;
}

bool parseYamlSpecialFloat(const std::string& text, double* value)
{
  static const std::vector<std::string> nan{".nan", ".NaN", ".NAN"};
  static const std::vector<std::string> inf{".inf", ".Inf", ".INF", "+.inf", "+.Inf", "+.INF"};
  static const std::vector<std::string> minus_inf{"-.inf", "-.Inf", "-.INF"};
  for (const auto& [spellings, v] :
       {std::make_pair(&nan, std::nan("")), std::make_pair(&inf, HUGE_VAL),
        std::make_pair(&minus_inf, -HUGE_VAL)})
    for (const auto& s : *spellings)
      if (text == s)
        return *value = v, true;
  return false;
}

std::string checkOverrideKeys(const NodeDecl& decl,
                              const std::map<std::string, std::string>& overrides)
{
  for (const auto& kv : overrides)
    if (!decl.handoff_keys.count(kv.first))
    {
      std::string declared;
      for (const auto& key : decl.handoff_keys)
        declared += (declared.empty() ? "" : ", ") + key;
      return "param override " + quoted(kv.first) +
             ": not a parameter of the model's state hand-off of " + decl.name +
             (declared.empty() ? " (it declares none)" : " (" + declared + ")");
    }
  return "";
}

std::string checkOverrideValue(const std::string& key, const std::string& yaml_text)
{
  const std::string refused = "param override " + quoted(key) + ": value " + quoted(yaml_text);
  YAML::Node parsed;
  try
  {
    parsed = YAML::Load(yaml_text);
  }
  catch (const YAML::Exception& e)
  {
    return refused + " is not YAML: " + e.what();
  }
  if (!parsed.IsScalar() || parsed.Tag() != "?")  // "!": quoted; anything else: an explicit tag
    return refused +
           " must be a number or true/false (a state hand-off), not a string, list or map";
  const std::string& text = parsed.Scalar();
  double d;
  bool b;
  if (parseYamlSpecialFloat(text, &d) || parseYamlBool(text, &b))
    return "";
  try
  {
    std::size_t used = 0;
    std::stod(text, &used);
    if (used == text.size())
      return "";
  }
  catch (const std::exception&)
  {}
  return refused + " must be a number or true/false (a state hand-off), not a string";
}

}  // namespace anyscale_agent
