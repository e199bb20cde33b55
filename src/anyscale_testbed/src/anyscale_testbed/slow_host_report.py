"""The slow-host bench's figures (tests/bench/bench_slow_host.py), pure: what a fixed-quota system
test relies on, read from one test-bed run, so that a configuration on a slower host can be set
beside the reference day's. A run has every node home (the link down) or AMCL and AR out (a
clean link); its figures are the rates and longest gaps of the judged outputs and of the
robot's drivers, the moves back that nothing but load caused, and the cores each CPU group used
against its quota and against the emulated machine."""
from dataclasses import dataclass
from typing import Dict, List, Mapping, Optional, Sequence, Tuple

import numpy as np

from .testbed_record import TestbedRecord

TOPICS = ("/amcl_pose", "/ar_markers", "/scan", "/joint_states", "/odom")
GROUPS = ("robot", "laptop", "world")
# (t, {pid: (cgroup, CPU seconds so far)}): a sample of every process of the run's ROS system
CpuSample = Tuple[float, Mapping[int, Tuple[str, float]]]


def group_of(cgroup: str) -> str:
    """robot, laptop or world (the bed's own group, or outside every quota) for a CPU cgroup."""
    name = cgroup.rstrip("/").rsplit("/", 1)[-1]
    return next((g for g in ("robot", "laptop") if name.endswith("_" + g)), "world")


def cores_per_group(samples: Sequence[CpuSample], start: float) -> Dict[str, float]:
    """The cores each group used on average from the first sample at or after `start` to the
    last: each process's CPU between consecutive samples (all of it for one that appeared
    between them, so it started then)."""
    window = [s for s in samples if s[0] >= start]
    used = {g: 0.0 for g in GROUPS}
    if len(window) < 2:
        return used
    for (_, before), (_, after) in zip(window, window[1:]):
        for pid, (cgroup, seconds) in after.items():
            was = before.get(pid)
            used[group_of(cgroup)] += max(0.0, seconds - (was[1] if was else 0.0))
    span = window[-1][0] - window[0][0]
    return {g: s / span for g, s in used.items()}


def throttled_share(before: Tuple[int, int], after: Tuple[int, int]) -> float:
    """The share of a group's CFS periods in which it was throttled, from two readings of
    (nr_periods, nr_throttled) of its cpu.stat; NaN without a period."""
    periods = after[0] - before[0]
    return (after[1] - before[1]) / periods if periods > 0 else float("nan")


def rate_and_gap(receipts: Sequence[float], start: float, end: float) -> Tuple[float, float]:
    """(messages per second, longest gap in s) of a topic from start to end; NaN, NaN with
    fewer than two messages."""
    t = np.asarray([x for x in receipts if start <= x <= end], dtype=float)
    if len(t) < 2:
        return float("nan"), float("nan")
    return len(t) / (end - start), float(max(np.diff(t).max(), t[0] - start, end - t[-1]))


@dataclass
class RunFigures:
    mode: str
    case: str                                   # home or out
    topics: Dict[str, Tuple[float, float]]      # topic -> (Hz, longest gap s)
    first_pose_s: float                         # start-up: the first /amcl_pose
    moves_back: int                             # migrate_back events after the start-up
    cores: Dict[str, float]                     # group -> cores used
    machine_cores: float                        # the (emulated) machine's CPUs
    throttled: Dict[str, float]                 # group -> share of periods throttled

    @property
    def machine_share(self) -> float:
        return sum(self.cores.values()) / self.machine_cores


def run_figures(mode: str, case: str, rec: TestbedRecord, samples: Sequence[CpuSample],
                skip_s: float, machine_cores: float,
                throttled: Optional[Dict[str, float]] = None) -> RunFigures:
    """A run's figures from `skip_s` (its start-up left out) to its end."""
    end = rec.finished_t or max((max(v) for v in rec.receipts.values() if v), default=skip_s)
    poses = rec.receipts.get("/amcl_pose", [])
    return RunFigures(
        mode, case, {t: rate_and_gap(rec.receipts.get(t, []), skip_s, end) for t in TOPICS},
        min(poses) if poses else float("nan"),
        sum(1 for e in rec.events if e.kind == "migrate_back" and e.decided_t >= skip_s),
        cores_per_group(samples, skip_s), machine_cores, dict(throttled or {}))


def format_table(rows: List[RunFigures]) -> str:
    head = (f"{'mode':<24} {'case':<5} " + " ".join(f"{t[1:]:>16}" for t in TOPICS)
            + f" {'1st pose':>8} {'back':>4} " + " ".join(f"{g:>7}" for g in GROUPS)
            + f" {'machine':>8} {'throttled r/l':>13}")
    lines = [head, "  (each topic: Hz / longest gap s; cores per group; their sum against the "
                   "(emulated) machine's CPUs)"]
    for r in rows:
        lines.append(
            f"{r.mode:<24} {r.case:<5} "
            + " ".join(f"{r.topics[t][0]:7.2f}/{r.topics[t][1]:5.2f} s" for t in TOPICS)
            + f" {r.first_pose_s:7.1f}s {r.moves_back:>4} "
            + " ".join(f"{r.cores.get(g, 0.0):7.3f}" for g in GROUPS)
            + f" {100 * r.machine_share:7.0f}%"
            + f" {100 * r.throttled.get('robot', float('nan')):6.0f}/"
            + f"{100 * r.throttled.get('laptop', float('nan')):.0f}%")
    return "\n".join(lines)
