"""What the fault soak reads of /proc besides the monitor's census of the nodes
(testbed_monitor_ros.node_processes, which it shares): every live process of a ROS system (by
its ROS_MASTER_URI), its rosmaster, and the memory and file descriptors of a process. ROS-free."""
import os
from typing import List, Optional, Tuple

from .testbed_teardown import is_alive


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


def memory_and_fds(pid: int) -> Optional[Tuple[float, int]]:
    """(resident memory in MB, open file descriptors) of a process; None if it is gone."""
    try:
        with open(f"/proc/{pid}/statm") as f:
            resident_pages = int(f.read().split()[1])
        fds = len(os.listdir(f"/proc/{pid}/fd"))
    except (OSError, IndexError, ValueError):
        return None
    return resident_pages * os.sysconf("SC_PAGE_SIZE") / 1e6, fds
