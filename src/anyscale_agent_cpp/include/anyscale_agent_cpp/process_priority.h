// CPU priority (nice, scheduling policy) of all the threads of a process.
#pragma once

#include <string>
#include <vector>

namespace anyscale_agent
{

// Sets the nice value of every thread of `pid`: Linux keeps nice per thread, and a thread
// inherits its creator's, so threads the process starts later follow its main thread. False
// with the reason in *error if a thread could not be set; raising the priority (a lower nice)
// needs CAP_SYS_NICE or a high enough RLIMIT_NICE.
bool setProcessNice(int pid, int nice, std::string* error);

// The nice value of each thread of `pid`; empty if the process is gone.
std::vector<int> threadNices(int pid);

// Moves every thread of `pid` from SCHED_IDLE to SCHED_OTHER (at the thread's nice); threads
// in other policies are left as they are. Leaving SCHED_IDLE for another process needs
// CAP_SYS_NICE (the agent runs as root on the test bed; see sched(7)). False with the reason
// in *error if a thread could not be moved or the process is gone.
bool leaveIdleScheduling(int pid, std::string* error);

// Whether any thread of `pid` is in SCHED_IDLE.
bool inIdleScheduling(int pid);

}  // namespace anyscale_agent
