"""The robot's quota for the day on the test bed: short runs of scripts/run_testbed.py with
every node home, stepped by quota_calibration.calibrate_quota until AMCL runs at the premise's
2 Hz, each calibration kept in its own directory (calibration.json), so that a resumed
evaluation or bench runs at the quota its recorded runs had. Used by run_evaluation.py,
bench_tolerances.py and run_testbed.py (--robot-cpu auto, which scripts/run_demo.sh passes)."""
import json
import math
import os
import statistics
import sys
from typing import Callable, Dict, List, Optional, Sequence, Tuple

from .bench_runs import latest_record, run_logged
from .calibration_file import quota_cores
from .premise_figures import START_UP_S, figures_with_every_node_home
from .quota_calibration import MAX_RUNS, QuotaPoint, calibrate_quota

CALIBRATION_FILE = "calibration.json"
# A calibration run: START_UP_S of start-up, then this long of AMCL's rate with every node home
# (about 150 poses at the premise's 2 Hz).
CALIBRATION_MEASURE_S = 75.0
CALIBRATION_RUN_S = START_UP_S + CALIBRATION_MEASURE_S
# No migration: the link is down throughout, so every node stays on the robot.
EVERY_NODE_HOME_LINK = ["--link", "schedule", "--schedule", "[[0, 0]]"]


def read_calibration(path: str) -> Optional[Tuple[float, List[QuotaPoint], Optional[float]]]:
    """A calibration.json written by write_calibration: the quota, its measurements and the
    host speed it was found at (None in older files); None if there is none or it is not one
    (then the calibration runs again)."""
    try:
        with open(path) as f:
            d = json.load(f)
        found_at = d.get("host_cpu_ms")
        return (float(d["robot_cpu"]), [QuotaPoint(float(q), float(hz)) for q, hz in d["points"]],
                None if found_at is None else float(found_at))
    except (OSError, ValueError, KeyError, TypeError, AttributeError):
        return None


def write_calibration(path: str, quota: float, points: Sequence[QuotaPoint],
                      host_cpu_ms: Optional[float] = None):
    with open(path, "w") as f:
        json.dump({"robot_cpu": quota, "points": [[p.quota, p.amcl_hz] for p in points],
                   "host_cpu_ms": host_cpu_ms}, f)
        f.write("\n")


def host_cpu_ms_measured(rec, skip_s: float = START_UP_S) -> Optional[float]:
    """The host's speed over a run's measurement (the median of the workload's rolling medians
    from skip_s on, all of them if none is that late), None if the run timed none."""
    medians = [ms for t, _, _, ms in rec.cpu_normalisation]
    late = [ms for t, _, _, ms in rec.cpu_normalisation if t >= skip_s]
    return statistics.median(late or medians) if medians else None


def host_speed_found_at(quota: float, points: Sequence[QuotaPoint],
                        host_ms: Sequence[Optional[float]]) -> Optional[float]:
    """The host speed a calibration's quota holds for: that of the run that measured the quota
    kept; for a quota stepped to but not measured (no run settled), the median over the runs
    whose fit chose it. host_ms[i] belongs to points[i]; None where a run timed none."""
    if points and points[-1].quota == quota:
        return host_ms[-1] if host_ms else None
    known = [ms for ms in host_ms if ms is not None]
    return statistics.median(known) if known else None


def normalise_cpu_argv(normalise_cpu: bool, found_at_ms: Optional[float]) -> List[str]:
    """run_testbed.py's options for a run whose quotas follow the host's speed (none without
    normalise_cpu): relative to found_at_ms, the speed its quota was found at, if known."""
    if not normalise_cpu:
        return []
    return ["--normalise-cpu"] + ([] if found_at_ms is None
                                  else ["--reference-cpu-ms", f"{found_at_ms:.3f}"])


def newest_calibrated_quota(out: str) -> Optional[float]:
    """The quota of the calibration written last in a directory of `out` (None: none yet): a
    resumed evaluation's next calibration starts from it, not from the calibration file's
    quota of another day (0.34 cores read 4.33 Hz one night, one run lost)."""
    found = []
    for key in os.listdir(out):
        path = os.path.join(out, key, CALIBRATION_FILE)
        saved = read_calibration(path)
        if saved is not None:
            found.append((os.path.getmtime(path), saved[0]))
    return max(found)[1] if found else None


def calibration_markdown(out: str) -> str:
    """The robot's quota of each calibration recorded in a directory of `out`, with what it
    measured ("" if none: the runs were at a given quota)."""
    lines = []
    for key in sorted(d for d in os.listdir(out) if os.path.isdir(os.path.join(out, d))):
        saved = read_calibration(os.path.join(out, key, CALIBRATION_FILE))
        if saved is not None:
            quota, points, found_at = saved
            measured = ", ".join(f"{p.quota:g} cores: {p.amcl_hz:.2f} Hz" for p in points)
            host = "-" if found_at is None else f"{found_at:.1f}"
            lines.append(f"| {key} | {quota:g} | {measured} | {host} |")
    if not lines:
        return ""
    return ("\n## The robot's quota for the day (--robot-cpu auto)\n\n"
            "| calibration | robot quota, cores | AMCL at home, measured | host speed: workload "
            "ms of CPU |\n|---|---|---|---|\n"
            + "\n".join(lines) + "\n")


class QuotaForTheDay:
    """The robot's quota of each run: `fixed` if given; else each calibration (a key, its
    directory under `out`) measured once, before its first run, and kept."""

    def __init__(self, run_testbed: str, world: str, out: str, fixed: Optional[float] = None,
                 extra_argv: Sequence[str] = (), log: Callable[[str], None] = None):
        """extra_argv: more run_testbed.py options for the calibration runs; log: where the
        progress lines go."""
        self.run_testbed, self.world, self.out, self.fixed = run_testbed, world, out, fixed
        self.extra_argv = list(extra_argv)
        self.log = log or (lambda line: print(line, flush=True))
        self.quotas: Dict[str, float] = {}
        self.found_at: Dict[str, Optional[float]] = {}
        self._host_ms: List[Optional[float]] = []      # of the calibration under way, per run
        self.start: Optional[float] = None    # the calibration file's, for the first one

    def quota(self, key: str) -> Optional[float]:
        """The quota to run at under calibration `key` (None: the calibration file's)."""
        if self.fixed is not None:
            return self.fixed
        if key not in self.quotas:
            cal_dir = os.path.join(self.out, key)
            os.makedirs(cal_dir, exist_ok=True)
            saved = read_calibration(os.path.join(cal_dir, CALIBRATION_FILE))
            if saved is None:
                self._host_ms = []
                if self.start is None:
                    self.start = newest_calibrated_quota(self.out) or quota_cores(None, 1.0)[0]
                runs = iter(range(1, 100))
                quota, points = calibrate_quota(
                    self.start, lambda q: self._home_rate(q, cal_dir, next(runs)),
                    log=lambda line: self.log(f"  {key}: {line}"))
                found_at = host_speed_found_at(quota, points, self._host_ms)
                write_calibration(os.path.join(cal_dir, CALIBRATION_FILE), quota, points,
                                  found_at)
            else:
                quota, _, found_at = saved
                self.log(f"  {key}: robot {quota:g} cores, calibrated already")
            self.quotas[key] = self.start = quota   # the next calibration starts from here
            self.found_at[key] = found_at
        return self.quotas[key]

    def found_at_ms(self, key: str) -> Optional[float]:
        """The host speed (workload CPU ms) at which calibration `key`'s quota was found; None
        for a fixed quota or a calibration whose runs timed none (older ones)."""
        return self.found_at.get(key)

    def _home_rate(self, quota: float, cal_dir: str, k: int) -> float:
        """AMCL's rate with every node home after START_UP_S, in a short run."""
        run_dir = os.path.join(cal_dir, f"run{k}")
        argv = [sys.executable, self.run_testbed, "--world", self.world, "--duration",
                f"{CALIBRATION_RUN_S:g}", "--robot-cpu", f"{quota:g}",
                "--out", run_dir] + EVERY_NODE_HOME_LINK + self.extra_argv
        self.log(f"  calibration run {k} (at most {MAX_RUNS}): robot {quota:g} cores, every "
                 f"node home, {CALIBRATION_RUN_S:g} s; log {run_dir}/console.log")
        run_logged(argv, run_dir)
        rec = latest_record(run_dir)
        self._host_ms.append(host_cpu_ms_measured(rec) if rec is not None else None)
        row = figures_with_every_node_home(rec, START_UP_S) if rec is not None else None
        return row["amcl_hz"] if row else math.nan


def parse_robot_cpu(text: str) -> Optional[float]:
    """--robot-cpu's value: None for auto, else cores; ValueError names what is wrong."""
    if text == "auto":
        return None
    try:
        cores = float(text)
    except ValueError:
        raise ValueError(f"--robot-cpu: expected cores or auto, got {text!r}") from None
    if not 0.05 <= cores <= 2.0:
        raise ValueError(f"--robot-cpu: expected 0.05 to 2 cores, got {cores:g}")
    return cores
