"""The robot's quota for the day on the test bed: short runs of scripts/run_testbed.py with
every node home, stepped by quota_calibration.calibrate_quota until AMCL runs at the premise's
2 Hz, each calibration kept in its own directory (calibration.json), so that a resumed
evaluation or bench runs at the quota its recorded runs had. Used by run_evaluation.py,
bench_tolerances.py and run_testbed.py (--robot-cpu auto, which scripts/run_demo.sh passes)."""
import json
import math
import os
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


def read_calibration(path: str) -> Optional[Tuple[float, List[QuotaPoint]]]:
    """A calibration.json written by write_calibration; None if there is none or it is not
    one (then the calibration runs again)."""
    try:
        with open(path) as f:
            d = json.load(f)
        return float(d["robot_cpu"]), [QuotaPoint(float(q), float(hz)) for q, hz in d["points"]]
    except (OSError, ValueError, KeyError, TypeError):
        return None


def write_calibration(path: str, quota: float, points: Sequence[QuotaPoint]):
    with open(path, "w") as f:
        json.dump({"robot_cpu": quota, "points": [[p.quota, p.amcl_hz] for p in points]}, f)
        f.write("\n")


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
            quota, points = saved
            measured = ", ".join(f"{p.quota:g} cores: {p.amcl_hz:.2f} Hz" for p in points)
            lines.append(f"| {key} | {quota:g} | {measured} |")
    if not lines:
        return ""
    return ("\n## The robot's quota for the day (--robot-cpu auto)\n\n"
            "| calibration | robot quota, cores | AMCL at home, measured |\n|---|---|---|\n"
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
                if self.start is None:
                    self.start = newest_calibrated_quota(self.out) or quota_cores(None, 1.0)[0]
                runs = iter(range(1, 100))
                quota, points = calibrate_quota(
                    self.start, lambda q: self._home_rate(q, cal_dir, next(runs)),
                    log=lambda line: self.log(f"  {key}: {line}"))
                write_calibration(os.path.join(cal_dir, CALIBRATION_FILE), quota, points)
            else:
                quota = saved[0]
                self.log(f"  {key}: robot {quota:g} cores, calibrated already")
            self.quotas[key] = self.start = quota   # the next calibration starts from here
        return self.quotas[key]

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
