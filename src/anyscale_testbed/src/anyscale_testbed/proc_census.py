"""What the fault soak reads of /proc besides the monitor's census of the nodes
(testbed_monitor_ros.node_processes, which it shares): every live process of a ROS system (by
its ROS_MASTER_URI), its rosmaster, the memory and file descriptors of a process, and its
CPU time, name and CPU cgroup. ROS-free."""
import os
from typing import List, Optional, Tuple

from .testbed_teardown import is_alive

# A warm standby (anyscale_agent_cpp's python_standby) carries its node's command line but is
# no instance of it: its comm is "python_standby" from its exec until it renames itself, then
# "standby:..." while it waits to become the node.
STANDBY_EXEC_COMM = b"python_standby"
STANDBY_COMM_PREFIX = b"standby:"


def is_standby_comm(comm: bytes) -> bool:
    return comm == STANDBY_EXEC_COMM or comm.startswith(STANDBY_COMM_PREFIX)


def is_standby(pid: int) -> bool:
    """Whether a process is a warm standby (False if it is gone)."""
    try:
        with open(f"/proc/{pid}/stat", "rb") as f:
            return is_standby_comm(f.read().split(b"(", 1)[1].rsplit(b")", 1)[0])
    except (OSError, IndexError):
        return False


def processes_with_master(master_uri: str) -> List[int]:
    """Live processes whose environment names `master_uri` (what a test bed leaves behind if
    its teardown missed something)."""
    tag = f"ROS_MASTER_URI={master_uri}".encode()
    found = []
    for pid in filter(str.isdigit, os.listdir("/proc")):
        try:
            with open(f"/proc/{pid}/environ", "rb") as f:
                if tag not in f.read().split(b"\0"):
                    continue
        except OSError:
            continue
        if is_alive(int(pid)):
            found.append(int(pid))
    return sorted(found)


def master_processes(master_uri: str) -> List[int]:
    """The rosmaster processes of this ROS system (roscore's master, or roslaunch's)."""
    found = []
    for pid in processes_with_master(master_uri):
        try:
            with open(f"/proc/{pid}/cmdline", "rb") as f:
                args = f.read().split(b"\0")
        except OSError:
            continue
        if any(os.path.basename(a) == b"rosmaster" for a in args[:2]):
            found.append(pid)
    return found


TCP_ESTABLISHED = "01"     # the st column of /proc/net/tcp


def memory_and_fds(pid: int) -> Optional[Tuple[float, int, int]]:
    """(resident memory in MB, open file descriptors, how many of those are established TCP
    connections) of a process; None if it is gone. A ROS node's connections come and go with
    the graph (a publisher that starts adds one to each subscriber); a socket whose peer has
    gone and that the process never closed is no longer ESTABLISHED (CLOSE_WAIT)."""
    try:
        with open(f"/proc/{pid}/statm") as f:
            resident_pages = int(f.read().split()[1])
        sockets = set()
        fds = 0
        for fd in os.listdir(f"/proc/{pid}/fd"):
            fds += 1
            try:
                target = os.readlink(f"/proc/{pid}/fd/{fd}")
            except OSError:
                continue                    # closed meanwhile
            if target.startswith("socket:["):
                sockets.add(target[8:-1])
        established = sum(1 for inode in established_inodes(pid) if inode in sockets)
    except (OSError, IndexError, ValueError):
        return None
    return resident_pages * os.sysconf("SC_PAGE_SIZE") / 1e6, fds, established


def established_inodes(pid: int) -> List[str]:
    """Socket inodes of the established TCP connections in the process's network namespace
    (/proc/PID/net/tcp and tcp6: the namespace's view, not the host's)."""
    inodes = []
    for name in ("tcp", "tcp6"):
        try:
            with open(f"/proc/{pid}/net/{name}") as f:
                next(f)                     # the header
                for line in f:
                    cols = line.split()
                    if len(cols) > 9 and cols[3] == TCP_ESTABLISHED:
                        inodes.append(cols[9])
        except (OSError, StopIteration):
            continue
    return inodes


def cpu_usage(pid: int) -> Optional[Tuple[str, str, float]]:
    """(name, CPU cgroup, CPU seconds used so far) of a process; None if it is gone. The name
    is its ROS node name (__name:=) if it has one, else its program's; the cgroup is the cpu
    controller's path ("/" outside every quota)."""
    try:
        with open(f"/proc/{pid}/stat", "rb") as f:
            fields = f.read().rsplit(b")", 1)[1].split()
        with open(f"/proc/{pid}/cmdline", "rb") as f:
            args = [a.decode(errors="replace") for a in f.read().split(b"\0") if a]
        with open(f"/proc/{pid}/cgroup") as f:
            groups = [line.strip().split(":", 2) for line in f if line.count(":") >= 2]
    except (OSError, IndexError):
        return None
    seconds = (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")   # utime, stime
    cgroup = next((path for _, controllers, path in groups if "cpu" in controllers.split(",")),
                  "/")
    return _name(args), cgroup, seconds


def _name(args: List[str]) -> str:
    named = [a.split(":=", 1)[1] for a in args if a.startswith("__name:=")]
    if named:
        return named[0]
    if not args:
        return "?"
    if os.path.basename(args[0]).startswith("python"):
        rest = args[1:]
        for i, a in enumerate(rest):
            if a in ("-c", "-m"):
                return "python " + a if a == "-c" or i + 1 == len(rest) else rest[i + 1]
            if not a.startswith("-"):
                return os.path.basename(a)
    return os.path.basename(args[0])
