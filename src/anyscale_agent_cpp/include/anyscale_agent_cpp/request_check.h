// Checks of what a service request carries before the agent acts on it, and quoting of request
// text for answers and logs (no ROS). ROS 1 has no authentication: any caller may send anything.
#pragma once

#include <cstddef>
#include <map>
#include <string>

#include "anyscale_agent_cpp/node_model.h"

namespace anyscale_agent
{

// A lease longer than a day is refused: its expiry, as a ros::Duration in the status, threw
// out of the sampling timer and ended the agent (issue 15's fuzzing).
constexpr double kMaxLeaseS = 86400.0;
// A stop's SIGINT grace beyond an hour is refused (it was converted to nanoseconds unchecked).
constexpr double kMaxSigintTimeoutS = 3600.0;
// A start's expected CPU (% of the scale) and memory (MB) beyond these is no estimate.
constexpr double kMaxExpectedCpuPercent = 10000.0;
constexpr double kMaxExpectedMemoryMb = 1e9;
// More watched topics than any ROS system has is a flood, not a configuration.
constexpr std::size_t kMaxWatchedTopics = 1000;
// How much of a name from a request goes into an answer or a log line.
constexpr std::size_t kMaxQuotedBytes = 80;

// 'text' with every byte outside printable ASCII as \xNN, cut after max_bytes (the length then
// said): a name from a request can neither forge log lines nor flood the log.
std::string quoted(const std::string& text, std::size_t max_bytes = kMaxQuotedBytes);

// "" if `seconds` is finite, >= 0 (> 0 unless zero_allowed) and at most max_s; else why not,
// naming `field`.
std::string checkSeconds(const std::string& field, double seconds, bool zero_allowed, double max_s);

// "" if `amount` is finite, >= 0 and at most `max`; else why not, naming `field` and `unit`.
std::string checkAmount(const std::string& field, double amount, double max,
                        const std::string& unit);

// "" if a param override's value (YAML text) is a plain number or boolean; else why not. A state
// hand-off is numbers (a pose); a string, list or map could name a file, a command or a plugin
// that a declared node acts on, which the model did not declare.
std::string checkOverrideValue(const std::string& key, const std::string& yaml_text);

// "" if every key of `overrides` is a parameter the state hand-off of `decl` sets; else why not.
// Any other private parameter (max_particles: 2147483647, update_min_d: .nan) changes what the
// node does, which the model did not declare.
std::string checkOverrideKeys(const NodeDecl& decl,
                              const std::map<std::string, std::string>& overrides);

// YAML 1.1 booleans as PyYAML (and so roslaunch) reads them: true/yes/on and false/no/off in
// lower, Title and UPPER case. False if `text` is none of them.
bool parseYamlBool(const std::string& text, bool* value);
// YAML's .nan, .inf and -.inf (as ros_convert.yaml_scalar writes NaN and infinities). False if
// `text` is none of them.
bool parseYamlSpecialFloat(const std::string& text, double* value);

}  // namespace anyscale_agent
