// The agent's own files: checks, temporary files and atomic replacement (own_file.h).
#include "anyscale_agent_cpp/own_file.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

namespace anyscale_agent
{

bool ownRegularFile(int fd)
{
  struct stat st;
  return ::fstat(fd, &st) == 0 && S_ISREG(st.st_mode) && st.st_nlink == 1 &&
         st.st_uid == ::geteuid();
}

// Not O_EXCL from the start: a FIFO there blocks the open as a slow disk would
// (test_supervisor_state_file), and is then replaced.
UniqueFd openTemporary(int dir, const char* name)
{
  UniqueFd fd(::openat(dir, name, O_WRONLY | O_CREAT | O_NOFOLLOW | O_CLOEXEC, 0600));
  if (fd.get() >= 0 && ownRegularFile(fd.get()) && ::ftruncate(fd.get(), 0) == 0)
    return fd;
  if (fd.get() < 0 && errno != ELOOP)
    return fd;
  fd.reset();
  if (::unlinkat(dir, name, 0) != 0 && errno != ENOENT)
    return fd;
  return UniqueFd(::openat(dir, name, O_WRONLY | O_CREAT | O_EXCL | O_NOFOLLOW | O_CLOEXEC, 0600));
}

void splitPath(const std::string& path, std::string* dir, std::string* name)
{
  const auto slash = path.rfind('/');
  *dir = slash == std::string::npos ? "." : path.substr(0, slash + 1);
  *name = path.substr(slash == std::string::npos ? 0 : slash + 1);
}

bool replaceFileAtomically(const std::string& path, const std::string& text, std::string* error)
{
  auto fail = [&](const std::string& what) {
    if (error)
      *error = what + ": " + std::strerror(errno);
    return false;
  };
  // Every name below is resolved in the file's own directory, opened once: nothing written
  // follows a link out of it.
  std::string dir_path, name;
  splitPath(path, &dir_path, &name);
  const std::string tmp_name = name + ".tmp";
  const std::string tmp = path + ".tmp";
  if (name.empty() || name == "." || name == "..")
  {
    errno = EISDIR;
    return fail("cannot write " + path);
  }
  UniqueFd dir(::open(dir_path.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC));
  if (dir.get() < 0)
    return fail("cannot open the directory " + dir_path);
  {
    UniqueFd fd = openTemporary(dir.get(), tmp_name.c_str());
    if (fd.get() < 0)
      return fail("cannot create " + tmp);
    for (std::size_t done = 0; done < text.size();)
    {
      const ssize_t n = ::write(fd.get(), text.data() + done, text.size() - done);
      if (n < 0 && errno == EINTR)
        continue;
      if (n <= 0)
      {
        const int e = errno;
        ::unlinkat(dir.get(), tmp_name.c_str(), 0);
        errno = n == 0 ? ENOSPC : e;
        return fail("cannot write " + tmp);
      }
      done += std::size_t(n);
    }
    // No fsync: the file must survive the agent's crash, and the page cache does. After a
    // power loss no node survives anyway (and the boot id tells the next agent so).
    if (::close(fd.release()) != 0)
    {
      const int e = errno;
      ::unlinkat(dir.get(), tmp_name.c_str(), 0);
      errno = e;
      return fail("cannot write " + tmp);
    }
  }
  // rename(2) replaces the entry `name`, also a link there, and never writes through it.
  if (::renameat(dir.get(), tmp_name.c_str(), dir.get(), name.c_str()) != 0)
  {
    const int e = errno;
    ::unlinkat(dir.get(), tmp_name.c_str(), 0);
    errno = e;
    return fail("cannot replace " + path);
  }
  return true;
}

}  // namespace anyscale_agent
