"""The fault soak's verdict on growth, pure (no ROS): the memory and file descriptors of the
agents and the decision node, sampled by the soak's census thread, judged per process over
its own life (a process respawned mid-soak is judged from its start).

Every time here is on the record's clock (s since the monitor started)."""
from dataclasses import dataclass
import statistics
from typing import Callable, Dict, Hashable, List, Optional, Sequence, Tuple

# Growth: a process sampled for at least MIN_SPAN_S after its first WARMUP_S (imports,
# connections being made) is judged on the median of its last third against its first third.
# 30 s is 60 samples, 20 in a third, at the census's 2 Hz: enough for a median, and short
# enough that an agent or decision node respawned mid-soak, and the CI soak's processes, are
# judged too. A process sampled for less is named as not judged (unjudged_growth).
# Only samples taken while the system was in the same state as at the process's last sample
# count (`state_at`: where each node has a live instance): a process holds a connection to
# each publisher of what it subscribes to, so its descriptors follow the instances that run
# (the decision node of the soak of 2026-11-27, seed 3, had 22 with every node home and 27
# after AMCL and AR had moved out and back within 20 s, their laptop instances still alive on
# their leases).
WARMUP_S = 20.0
MIN_SPAN_S = 30.0
RSS_GROWTH_MB = 5.0
RSS_GROWTH_SHARE = 0.10
FD_GROWTH = 5


@dataclass
class ResourceSample:
    t: float
    role: str
    pid: int
    rss_mb: float
    fds: int


@dataclass
class Growth:
    role: str
    pid: int
    span_s: float
    rss_first_mb: float
    rss_last_mb: float
    fds_first: float
    fds_last: float
    grew: List[str]         # what grew, in words; empty if nothing did


def growth(samples: Sequence[ResourceSample],
           state_at: Optional[Callable[[float], Hashable]] = None) -> List[Growth]:
    """For each process (role and pid) sampled long enough: its memory and file descriptors,
    first third against last third (medians) after its warm-up, and whether they grew. With
    `state_at` (t -> the system's state), only its samples in the state of its last one."""
    out = []
    for (role, pid), judged in sorted(_after_warmup(samples, state_at).items()):
        if _span(judged) < MIN_SPAN_S:
            continue
        third = len(judged) // 3
        first, last = judged[:third], judged[-third:]
        rss0 = statistics.median(s.rss_mb for s in first)
        rss1 = statistics.median(s.rss_mb for s in last)
        fd0 = statistics.median(s.fds for s in first)
        fd1 = statistics.median(s.fds for s in last)
        grew = []
        if rss1 - rss0 > max(RSS_GROWTH_MB, RSS_GROWTH_SHARE * rss0):
            grew.append(f"memory {rss0:.1f} -> {rss1:.1f} MB")
        if fd1 - fd0 >= FD_GROWTH:
            grew.append(f"file descriptors {fd0:g} -> {fd1:g}")
        out.append(Growth(role, pid, _span(judged), rss0, rss1, fd0, fd1, grew))
    return out


def unjudged_growth(samples: Sequence[ResourceSample],
                    state_at: Optional[Callable[[float], Hashable]] = None) -> List[str]:
    """The processes growth() leaves out, in words: sampled too briefly after their warm-up
    (e.g. killed by the soak soon after their start), or in the state of their last sample."""
    where = (" with the nodes' instances where they were at its last sample" if state_at
             else "")
    return [f"growth of {role} pid {pid}: sampled {_span(judged):.0f} s after its "
            f"{WARMUP_S:g} s warm-up{where}, judged from {MIN_SPAN_S:g} s"
            for (role, pid), judged in sorted(_after_warmup(samples, state_at).items())
            if _span(judged) < MIN_SPAN_S]


def _after_warmup(samples: Sequence[ResourceSample],
                  state_at: Optional[Callable[[float], Hashable]] = None
                  ) -> Dict[Tuple[str, int], List[ResourceSample]]:
    """(role, pid) -> its samples after its first WARMUP_S, in time order; with state_at, only
    those in the state of its last sample."""
    by_process: Dict[Tuple[str, int], List[ResourceSample]] = {}
    for s in sorted(samples, key=lambda s: s.t):
        by_process.setdefault((s.role, s.pid), []).append(s)
    out = {}
    for key, series in by_process.items():
        judged = [s for s in series if s.t >= series[0].t + WARMUP_S]
        if state_at is not None and judged:
            last = state_at(judged[-1].t)
            judged = [s for s in judged if state_at(s.t) == last]
        out[key] = judged
    return out


def _span(series: Sequence[ResourceSample]) -> float:
    """The time the samples cover; 0 for fewer than 6 (thirds of 2 make no median)."""
    return series[-1].t - series[0].t if len(series) >= 6 else 0.0