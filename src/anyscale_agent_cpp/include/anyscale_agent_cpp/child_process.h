// Starting a node's process: fork/exec with the child set up for the supervisor.
#pragma once

#include <string>
#include <vector>

namespace anyscale_agent
{

// Forks and execs argv (argv[0] an absolute path; no PATH search, no shell) in a new session
// and process group, with stdin from `stdin_fd`, stdout and stderr to `log_fd`, default signal
// dispositions and an empty mask, no other descriptor of the caller, nice `nice`, and
// `death_signal` (0: none) when the thread that forked ends. Returns the pid, or 0 with the reason
// in *error (an exec failure gives its errno text). Call it from one long-lived thread: the death
// signal follows the forking thread, not the process.
int spawnChild(const std::vector<std::string>& argv, int stdin_fd, int log_fd, int death_signal,
               int nice, std::string* error);

}  // namespace anyscale_agent
