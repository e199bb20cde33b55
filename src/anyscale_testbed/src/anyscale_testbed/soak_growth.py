"""The fault soak's verdict on growth, pure (no ROS): the memory and file descriptors of the
agents and the decision node, sampled by the soak's census thread, judged per process over
its own life (a process respawned mid-soak is judged from its start).

Every time here is on the record's clock (s since the monitor started)."""
from dataclasses import dataclass
import statistics
from typing import Dict, List, Sequence, Tuple

# Growth: a process sampled for at least MIN_SPAN_S after its first WARMUP_S (imports,
# connections being made) is judged on the median of its last third against its first third.
# 30 s is 60 samples, 20 in a third, at the census's 2 Hz: enough for a median, and short
# enough that an agent or decision node respawned mid-soak, and the CI soak's processes, are
# judged too. A process sampled for less is named as not judged (unjudged_growth).
WARMUP_S = 20.0
MIN_SPAN_S = 30.0
RSS_GROWTH_MB = 5.0
RSS_GROWTH_SHARE = 0.10
# Descriptors are judged without the established TCP connections among them: those follow the
# ROS graph (each publisher of a topic the process subscribes, each subscriber of its topics,
# each service call under way). In a 10-minute soak the decision node held 22-33 descriptors,
# up and down with the moves and faults, which a threshold of 5 on all of them took for growth
# (seed 3: 22 -> 27). A leaked socket, its peer gone, is not ESTABLISHED and still counts.
FD_GROWTH = 5


@dataclass
class ResourceSample:
    t: float
    role: str
    pid: int
    rss_mb: float
    fds: int
    connections: int = 0    # of fds, established TCP connections (0: not recorded)

    @property
    def held(self) -> int:
        """The descriptors judged for growth: all but the established connections."""
        return self.fds - self.connections


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


def growth(samples: Sequence[ResourceSample]) -> List[Growth]:
    """For each process (role and pid) sampled long enough: its memory and file descriptors,
    first third against last third (medians) after its warm-up, and whether they grew."""
    out = []
    for (role, pid), judged in sorted(_after_warmup(samples).items()):
        if _span(judged) < MIN_SPAN_S:
            continue
        third = len(judged) // 3
        first, last = judged[:third], judged[-third:]
        rss0 = statistics.median(s.rss_mb for s in first)
        rss1 = statistics.median(s.rss_mb for s in last)
        fd0 = statistics.median(s.held for s in first)
        fd1 = statistics.median(s.held for s in last)
        grew = []
        if rss1 - rss0 > max(RSS_GROWTH_MB, RSS_GROWTH_SHARE * rss0):
            grew.append(f"memory {rss0:.1f} -> {rss1:.1f} MB")
        if fd1 - fd0 >= FD_GROWTH:
            grew.append(f"file descriptors (besides connections) {fd0:g} -> {fd1:g}")
        out.append(Growth(role, pid, _span(judged), rss0, rss1, fd0, fd1, grew))
    return out


def unjudged_growth(samples: Sequence[ResourceSample]) -> List[str]:
    """The processes growth() leaves out, in words: sampled too briefly after their warm-up
    (e.g. killed by the soak soon after their start)."""
    return [f"growth of {role} pid {pid}: sampled {_span(judged):.0f} s after its "
            f"{WARMUP_S:g} s warm-up, judged from {MIN_SPAN_S:g} s"
            for (role, pid), judged in sorted(_after_warmup(samples).items())
            if _span(judged) < MIN_SPAN_S]


def _after_warmup(
        samples: Sequence[ResourceSample]) -> Dict[Tuple[str, int], List[ResourceSample]]:
    """(role, pid) -> its samples after its first WARMUP_S, in time order."""
    by_process: Dict[Tuple[str, int], List[ResourceSample]] = {}
    for s in sorted(samples, key=lambda s: s.t):
        by_process.setdefault((s.role, s.pid), []).append(s)
    return {key: [s for s in series if s.t >= series[0].t + WARMUP_S]
            for key, series in by_process.items()}


def _span(series: Sequence[ResourceSample]) -> float:
    """The time the samples cover; 0 for fewer than 6 (thirds of 2 make no median)."""
    return series[-1].t - series[0].t if len(series) >= 6 else 0.0
