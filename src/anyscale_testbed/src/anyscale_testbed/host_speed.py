"""How fast this host's CPU is right now, and CPU quotas that keep each emulated scale as fast
as it was calibrated (issue 13, the evaluation's premise; `run_testbed.py --normalise-cpu`).

A cgroup quota holds a scale at a fixed share of the host (CFS time), not at a fixed amount
of work per second: this machine is a shared VM whose per-CPU-second speed drifts. A fixed
workload (the one below) took 11.8-16.5 ms of CPU time at different times of one day, and over
7 office-floor runs at the same 0.34-core robot quota AMCL's rate with every node home went
from 3.18 to 1.77 Hz, correlated -0.92 with the workload's CPU ms; rate x CPU ms stayed about
30-32 (one run 37). So the premise (AMCL at its 2 Hz minimum on the robot) held only on some
runs. Scaling the quota by the workload's CPU ms keeps the work a scale gets done per second
what it was at the calibration. Not yet validated on test-bed runs.

Pure apart from the measuring thread: the controller takes its quotas, clock and measure
function as arguments, so the tests drive it with fakes.
"""
from collections import deque
import os
import statistics
import threading
import time
from typing import Callable, Dict, List, Optional, Tuple

import numpy as np

# (t, robot cores, laptop cores, median workload CPU ms); 0 cores = that scale has no quota.
HistoryEntry = Tuple[float, float, float, float]

# The workload must stay exactly this (arrays, seed, loop counts): the figures above (11.8-16.5
# ms, timed by a probe process running it every 5 s) and reference_cpu_ms in
# testbed_calibration.yaml were measured with it. Change it and those figures are void.
_SEED = 0
_SHAPE = (256, 341)
_NUMPY_PASSES = 30
_PYTHON_STEPS = 100000
_arrays = None


def _workload_arrays():
    """Built once per process, as the tool builds them once before its loop."""
    global _arrays
    if _arrays is None:
        rng = np.random.default_rng(_SEED)
        a = rng.random(_SHAPE)
        idx = rng.integers(0, _SHAPE[0] * _SHAPE[1], size=_SHAPE)
        _arrays = (a, idx)
    return _arrays


def reference_workload() -> float:
    """The fixed work: gathers and exp over a 256 x 341 array (memory and vector units), then
    a plain Python loop (the interpreter, as rospy nodes spend much of their time)."""
    a, idx = _workload_arrays()
    s = 0.0
    for _ in range(_NUMPY_PASSES):
        t = np.take(a.ravel(), idx)
        t *= t
        np.exp(-t, out=t)
        s += float(t.sum())
    for i in range(_PYTHON_STEPS):
        s += i * 0.5
    return s


def workload_cpu_ms(work: Callable[[], object] = reference_workload,
                    clock: Callable[[], float] = time.thread_time) -> float:
    """CPU time of one run of the workload, in ms. thread_time, not the tool's process_time:
    in a process with other threads (run_testbed.py's) only this thread's time is the
    workload's; in the single-threaded tool the two are the same. CPU time, not wall time, so
    being descheduled or throttled does not count: what is measured is how much a CPU-second
    of this host gets done."""
    _workload_arrays()              # building the arrays is not the workload
    start = clock()
    work()
    return (clock() - start) * 1e3


# The reference day of the system tests' slow-day mode (slow_host.py, system_test_gate.py): the
# idle reading of the day its figures were measured (2026-11-28, 9.4-9.9 ms; the fixed-quota
# tests were green at readings of 6.6-10.7 ms on earlier days, and failed at 40-46 ms).
REFERENCE_IDLE_MS = 9.5


def host_factor(idle_ms: float, reference_ms: float = REFERENCE_IDLE_MS) -> float:
    """How many times slower than the reference day this host is (1 if not slower)."""
    return max(1.0, idle_ms / reference_ms)


def idle_cpu_ms(samples: int = 9, measure: Callable[[], float] = workload_cpu_ms) -> float:
    """The median CPU ms of `samples` runs of the workload back to back, for a reading taken
    before a test bed loads the host."""
    if samples < 1:
        raise ValueError(f"at least one sample, got {samples}")
    return statistics.median(measure() for _ in range(samples))


class RollingMedian:
    """The median of the last `size` values: one slow or fast measurement (a burst of another
    job's cache traffic) does not move the quotas."""

    def __init__(self, size: int):
        if size < 1:
            raise ValueError(f"a rolling median needs a window of at least 1, got {size}")
        self.values = deque(maxlen=size)

    def add(self, value: float) -> float:
        self.values.append(float(value))
        return self.value

    @property
    def value(self) -> Optional[float]:
        return statistics.median(self.values) if self.values else None

    def __len__(self) -> int:
        return len(self.values)


def normalised_cores(calibrated_cores: float, reference_cpu_ms: float, measured_cpu_ms: float,
                     lowest: float, highest: float) -> float:
    """The quota that gets a scale the work per second it had at the calibration:
    calibrated_cores x measured / reference, clipped to [lowest, highest].

    The workload took `reference_cpu_ms` of CPU when the quota was calibrated; now it takes
    `measured_cpu_ms`, so a CPU-second of this host does reference/measured of the work it did
    then, and measured/reference times the cores do the same work per second. Every node in the
    group gets the same work done as at the calibration, whatever the rates' relation to the
    quota (not linear: the light nodes take their share first). Today's figures: the robot's
    0.34 cores were right (AMCL 2 Hz) where the workload took about 15.5 ms; at 11.8 ms AMCL
    ran 3.18 Hz (0.34 x 11.8 / 15.5 = 0.26 cores would have held it), at 16.5 ms 1.77 Hz
    (0.36 cores). The clip keeps one wild measurement from starving or freeing a scale."""
    if reference_cpu_ms <= 0 or not measured_cpu_ms > 0:
        raise ValueError(f"CPU ms must be positive: reference {reference_cpu_ms}, "
                         f"measured {measured_cpu_ms}")
    if lowest > highest:
        raise ValueError(f"lowest {lowest} cores above highest {highest}")
    return min(max(calibrated_cores * measured_cpu_ms / reference_cpu_ms, lowest), highest)


class HostSpeedMonitor:
    """Every `period_s`, runs the workload on a thread of its own and keeps the rolling median
    of its CPU ms (`medians`: (t, median) per measurement). start() measures `initial_samples`
    times at once (after settle_s: waits for as many), so the first median is not one
    measurement; stop() ends the thread.

    With `settle_s` > 0, the measurements of the first settle_s after start() are kept in
    `samples` but make no median: the workload's CPU ms depends on what else loads the host
    (the other vCPU's work shares caches and memory bandwidth: 10.2-10.7 ms between two
    test-bed runs, 15-16 ms during one), so a median taken before the scales' nodes run says
    how fast an idle host is, not the loaded one the reference was measured on."""

    def __init__(self, period_s: float = 5.0, window: int = 12, initial_samples: int = 3,
                 measure: Callable[[], float] = workload_cpu_ms,
                 clock: Callable[[], float] = time.time,
                 log: Callable[[str], None] = print, settle_s: float = 0.0):
        if period_s <= 0:
            raise ValueError(f"period must be positive, got {period_s}")
        if settle_s < 0:
            raise ValueError(f"settle time must not be negative, got {settle_s}")
        self.settle_s = settle_s
        self.settled_at = -float("inf")
        self.period_s = period_s
        self.median = RollingMedian(window)
        self.initial_samples = max(1, initial_samples)
        self.measure = measure
        self.clock = clock
        self.log = log
        self.medians: List[Tuple[float, float]] = []
        self.samples: List[float] = []
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread: Optional[threading.Thread] = None

    def tick(self) -> Optional[float]:
        """One measurement: the median updated, then on_median. Returns the median, None
        while settling."""
        ms = self.measure()
        t = self.clock()
        with self._lock:
            self.samples.append(ms)
            if t < self.settled_at:
                return None
            median = self.median.add(ms)
            if self.settle_s > 0 and len(self.median) < self.initial_samples:
                return None     # after settling: no median of one measurement either
            self.medians.append((t, median))
            self.on_median(t, median)
        return median

    def on_median(self, t: float, median_ms: float):
        """What a new median does (with the lock held); nothing here."""

    def start(self):
        if self.settle_s > 0:
            self.settled_at = self.clock() + self.settle_s
        else:
            for _ in range(self.initial_samples - 1):
                with self._lock:
                    self.samples.append(self.measure())
                    self.median.add(self.samples[-1])
            self.tick()
        self._stop.clear()
        self._thread = threading.Thread(target=self._run, name="host_speed", daemon=True)
        self._thread.start()
        return self

    def stop(self, timeout_s: float = 5.0):
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout_s)
            self._thread = None

    def __enter__(self):
        return self.start()

    def __exit__(self, *_):
        self.stop()
        return False

    def _run(self):
        while not self._stop.wait(self.period_s):
            try:
                self.tick()
            except Exception as e:      # noqa: BLE001 - a bug here must not end the run
                self.log(f"host speed: measuring stopped ({type(e).__name__}: {e}); the "
                         "quotas stay as they are")
                return


class CpuNormaliser(HostSpeedMonitor):
    """Keeps each scale's CPU quota at its normalised cores (normalised_cores) as the host's
    speed drifts: on every median, sets each quota (anything with set_cores(cores), e.g.
    two_scale_testbed.CpuQuota) and appends (t, robot, laptop, median) to `history`. Logs a
    line when a quota has moved more than `log_change` (5 %) from the value last logged (at
    first the calibrated one), so a slow creep is reported once it adds up, and a steady host
    prints nothing. Bounds: `lowest_factor`..`highest_factor` of the calibrated cores, at most
    the host's CPUs: today's drift was 0.76-1.06 of the reference, so a factor beyond 0.5-1.5
    says more about the measurement than about the host."""

    def __init__(self, quotas: Dict[str, object], calibrated: Dict[str, float],
                 reference_cpu_ms: Optional[float], lowest_factor: float = 0.5,
                 highest_factor: float = 1.5, log_change: float = 0.05,
                 host_cores: Optional[float] = None, follow: bool = True, **monitor):
        """follow=False: measure and keep the history, but leave the quotas as calibrated
        (every run records its host's speed; reference_cpu_ms may then be None)."""
        super().__init__(**monitor)
        if follow and not (reference_cpu_ms or 0) > 0:
            raise ValueError(f"reference_cpu_ms must be positive, got {reference_cpu_ms}")
        self.follow = follow
        self.quotas = dict(quotas)
        self.calibrated = {scale: calibrated[scale] for scale in self.quotas}
        self.reference_cpu_ms = reference_cpu_ms
        host = host_cores if host_cores is not None else float(os.cpu_count() or 1)
        self.bounds = {scale: (lowest_factor * cores, min(highest_factor * cores, host))
                       for scale, cores in self.calibrated.items()}
        self.log_change = log_change
        self.cores = dict(self.calibrated)          # what each quota is set to now
        self.logged = dict(self.calibrated)         # what the last line said
        self.history: List[HistoryEntry] = []
        self._failed: set = set()

    def on_median(self, t: float, median_ms: float):
        if not self.follow:
            self.history.append((t, self.cores.get("robot", 0.0),
                                 self.cores.get("laptop", 0.0), median_ms))
            return
        for scale, quota in self.quotas.items():
            cores = normalised_cores(self.calibrated[scale], self.reference_cpu_ms, median_ms,
                                     *self.bounds[scale])
            try:
                quota.set_cores(cores)
                self.cores[scale] = cores
            except OSError as e:    # the group went (teardown): say so once, keep measuring
                if scale not in self._failed:
                    self._failed.add(scale)
                    self.log(f"host speed: cannot set the {scale} quota: {e}")
        moved = [s for s in self.quotas
                 if abs(self.cores[s] - self.logged[s]) > self.log_change * self.logged[s]]
        if moved:
            self.log(quota_change_line(self.logged, self.cores, median_ms,
                                       self.reference_cpu_ms, len(self.median)))
            self.logged = dict(self.cores)
        self.history.append((t, self.cores.get("robot", 0.0), self.cores.get("laptop", 0.0),
                             median_ms))

    def history_copy(self) -> List[HistoryEntry]:
        with self._lock:
            return list(self.history)


def quota_change_line(before: Dict[str, float], after: Dict[str, float], median_ms: float,
                      reference_ms: float, samples: int) -> str:
    scales = ", ".join(f"{s} {before[s]:.3f} -> {after[s]:.3f}" for s in after)
    return (f"host speed: workload {median_ms:.1f} ms of CPU (median of {samples}; "
            f"calibrated at {reference_ms:g} ms): CPU quota {scales} cores")
