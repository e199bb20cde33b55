"""The nice value of every thread of this process (Linux keeps nice per thread)."""
import os
from typing import List, Optional


def thread_ids() -> List[int]:
    return [int(t) for t in os.listdir("/proc/self/task") if t.isdigit()]


def set_own_nice(nice: int) -> Optional[str]:
    """Sets the nice of every thread of this process; threads started afterwards inherit it
    from their creator. None, or why it could not be set (a negative value needs
    CAP_SYS_NICE)."""
    for tid in thread_ids():
        try:
            os.setpriority(os.PRIO_PROCESS, tid, nice)
        except ProcessLookupError:
            continue        # the thread ended meanwhile
        except OSError as e:
            return f"setpriority({tid}, {nice}): {e.strerror}"
    return None
