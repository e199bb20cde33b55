// Files only the agent's user writes, each in a directory of its own, never through a link (no
// ROS): the state file (node_state_file.h) and the capacity ledger (capacity_ledger.h).
#pragma once

#include <string>

#include "anyscale_agent_cpp/unique_fd.h"

namespace anyscale_agent
{

// Our own file: regular, one name, this process's user. Anything else at a name the agent writes
// (a symbolic or hard link to another file, a FIFO, another user's file) is never written into.
bool ownRegularFile(int fd);

// The temporary file `name` in `dir`, empty and ours: an entry found there that is not (left by a
// crash, or put there) is removed, the entry itself and never what it points to, and the file
// created anew.
UniqueFd openTemporary(int dir, const char* name);

// `path` (a name in the directory `dir_path`) replaced by `text` atomically: written to
// `<name>.tmp` beside it, then renamed over it, so a reader sees the old text or the new one,
// never half of one; both names are resolved in that directory and no link is followed. False
// with the reason in *error.
bool replaceFileAtomically(const std::string& path, const std::string& text, std::string* error);

// The directory and file name of `path` ("." for a bare name); the name may be empty.
void splitPath(const std::string& path, std::string* dir, std::string* name);

}  // namespace anyscale_agent
