"""The host-speed normalisation of the CPU quotas (host_speed.py): the cores for a measured
workload time, the rolling median, the controller on a fake clock and fake quotas, and
CpuQuota.set_cores on a directory standing in for the cgroup (no root)."""
import threading
import time

import pytest

from anyscale_testbed.host_speed import (REFERENCE_IDLE_MS, CpuNormaliser, HostSpeedMonitor,
                                         RollingMedian, host_factor, idle_cpu_ms,
                                         normalised_cores, reference_workload, workload_cpu_ms)
from anyscale_testbed.two_scale_testbed import CpuQuota


# --- the idle reading and the host factor ---------------------------------------------
def test_the_idle_reading_is_the_median_of_its_samples():
    readings = iter([9.0, 45.0, 10.0, 11.0, 8.0])
    assert idle_cpu_ms(5, lambda: next(readings)) == 10.0
    with pytest.raises(ValueError, match="at least one sample"):
        idle_cpu_ms(0)


def test_the_host_factor_is_the_reading_over_the_reference_day_and_never_below_one():
    assert host_factor(REFERENCE_IDLE_MS) == 1.0
    assert host_factor(7.0) == 1.0                      # a faster day changes nothing
    assert host_factor(43.2) == pytest.approx(43.2 / REFERENCE_IDLE_MS)   # 2026-11-28, idle


# --- normalised_cores -----------------------------------------------------------------------
def test_a_slower_host_gets_more_cores_and_a_faster_one_fewer():
    # Today's figures: reference 15.5 ms; the workload took 11.8-16.5 ms.
    assert normalised_cores(0.34, 15.5, 15.5, 0.1, 1.0) == pytest.approx(0.34)
    assert normalised_cores(0.34, 15.5, 16.5, 0.1, 1.0) == pytest.approx(0.34 * 16.5 / 15.5)
    assert normalised_cores(0.34, 15.5, 11.8, 0.1, 1.0) == pytest.approx(0.2588, abs=1e-4)
    assert normalised_cores(0.9, 15.5, 31.0, 0.1, 2.0) == pytest.approx(1.8)


def test_the_cores_are_clipped_to_the_bounds():
    assert normalised_cores(0.34, 15.5, 100.0, 0.17, 0.51) == 0.51
    assert normalised_cores(0.34, 15.5, 1.0, 0.17, 0.51) == 0.17


@pytest.mark.parametrize("reference,measured,lowest,highest", [
    (0.0, 15.0, 0.1, 1.0), (15.0, 0.0, 0.1, 1.0), (15.0, float("nan"), 0.1, 1.0),
    (15.0, 15.0, 1.0, 0.1)])
def test_nonsense_inputs_are_refused(reference, measured, lowest, highest):
    with pytest.raises(ValueError):
        normalised_cores(0.34, reference, measured, lowest, highest)


# --- the rolling median -------------------------------------------------------------------------
def test_the_rolling_median_keeps_the_last_k_and_ignores_one_outlier():
    m = RollingMedian(3)
    assert m.value is None
    assert m.add(10.0) == 10.0
    assert m.add(20.0) == 15.0              # even count: the mean of the middle two
    assert m.add(100.0) == 20.0             # one outlier does not move it far
    assert m.add(30.0) == 30.0              # 10 dropped: 20, 100, 30
    assert m.add(31.0) == 31.0              # 20 dropped: 100, 30, 31
    assert len(m) == 3


def test_a_rolling_median_needs_a_window():
    with pytest.raises(ValueError):
        RollingMedian(0)


# --- the workload -------------------------------------------------------------------------------
def test_the_workload_is_the_calibrated_one_and_is_timed_on_the_thread_clock():
    # The arrays and loop counts reference_cpu_ms was measured with give the same sum.
    import numpy as np
    rng = np.random.default_rng(0)
    a = rng.random((256, 341))
    idx = rng.integers(0, 256 * 341, size=(256, 341))
    s = 0.0
    for _ in range(30):
        t = np.take(a.ravel(), idx)
        t *= t
        np.exp(-t, out=t)
        s += float(t.sum())
    for i in range(100000):
        s += i * 0.5
    assert reference_workload() == s
    ticks = iter([1.0, 1.0125])
    assert workload_cpu_ms(work=lambda: None, clock=lambda: next(ticks)) == pytest.approx(12.5)
    assert workload_cpu_ms() > 0


# --- the controller -----------------------------------------------------------------------------
class FakeQuota:
    def __init__(self, fail=False):
        self.set = []
        self.fail = fail

    def set_cores(self, cores):
        if self.fail:
            raise OSError("No such file or directory")
        self.set.append(cores)


class FakeClock:
    def __init__(self):
        self.t = 1000.0

    def __call__(self):
        return self.t


def flat(rows):
    return [v for row in rows for v in row]


def normaliser(measurements, window=3, **kw):
    clock, lines = FakeClock(), []
    quotas = {"robot": FakeQuota(), "laptop": FakeQuota()}
    it = iter(measurements)
    n = CpuNormaliser(quotas, {"robot": 0.34, "laptop": 0.9}, reference_cpu_ms=15.5,
                      window=window, initial_samples=1, measure=lambda: next(it), clock=clock,
                      log=lines.append, host_cores=2.0, **kw)
    return n, quotas, clock, lines


def test_each_tick_sets_every_quota_to_its_normalised_cores_from_the_median():
    n, quotas, clock, lines = normaliser([15.5, 17.05, 17.05, 12.4])
    n.tick()
    clock.t += 5
    n.tick()                                # median of 15.5, 17.05: 16.275
    clock.t += 5
    n.tick()                                # median 17.05: +10 %
    clock.t += 5
    n.tick()                                # 17.05, 17.05, 12.4: still 17.05
    assert quotas["robot"].set == pytest.approx([0.34, 0.357, 0.374, 0.374])
    assert quotas["laptop"].set == pytest.approx([0.9, 0.945, 0.99, 0.99])
    assert flat(n.history) == pytest.approx(flat([
        (1000.0, 0.34, 0.9, 15.5), (1005.0, 0.357, 0.945, 16.275),
        (1010.0, 0.374, 0.99, 17.05), (1015.0, 0.374, 0.99, 17.05)]))


def test_a_line_only_when_a_quota_moved_more_than_5_percent_since_the_last_line():
    # +3 %: no line; +6 % from the calibrated value: a line; +6 % again and +3 % (within 5 %
    # of that line's 0.360 / 0.954): none; back to the calibration (-5.7 %): a line.
    factors = [1.03, 1.06, 1.06, 1.03, 1.0]
    n, quotas, clock, lines = normaliser([15.5 * f for f in factors], window=1)
    counts = []
    for _ in factors:
        n.tick()
        counts.append(len(lines))
    assert counts == [0, 1, 1, 1, 2]
    assert "robot 0.340 -> 0.360" in lines[0] and "laptop 0.900 -> 0.954" in lines[0]
    assert "16.4 ms" in lines[0]
    assert "robot 0.360 -> 0.340" in lines[1]


def test_the_quotas_stay_within_the_bounds_and_the_host():
    n, quotas, clock, lines = normaliser([100.0, 1.0], window=1)
    n.tick()
    assert quotas["robot"].set[-1] == pytest.approx(0.51)      # 1.5 x 0.34
    assert quotas["laptop"].set[-1] == pytest.approx(1.35)
    n.tick()
    assert quotas["robot"].set[-1] == pytest.approx(0.17)
    assert quotas["laptop"].set[-1] == pytest.approx(0.45)
    capped, quotas, _, _ = normaliser([100.0], window=1, highest_factor=3.0)
    capped.tick()
    assert quotas["laptop"].set[-1] == pytest.approx(2.0)      # the host has 2 cores


def test_without_follow_the_host_speed_is_recorded_and_the_quotas_left_alone():
    clock, lines = FakeClock(), []
    robot = FakeQuota()
    n = CpuNormaliser({"robot": robot}, {"robot": 0.34}, reference_cpu_ms=None, follow=False,
                      initial_samples=1, measure=lambda: 31.0, clock=clock, log=lines.append)
    n.tick()
    assert robot.set == [] and lines == []
    assert flat(n.history) == pytest.approx([1000.0, 0.34, 0.0, 31.0])
    with pytest.raises(ValueError, match="reference_cpu_ms must be positive"):
        CpuNormaliser({"robot": robot}, {"robot": 0.34}, reference_cpu_ms=None)


def test_a_scale_without_a_quota_is_left_alone_and_recorded_as_0():
    clock, lines = FakeClock(), []
    robot = FakeQuota()
    n = CpuNormaliser({"robot": robot}, {"robot": 0.34, "laptop": 0.0}, reference_cpu_ms=15.5,
                      initial_samples=1, measure=lambda: 31.0, clock=clock, log=lines.append)
    n.tick()
    assert robot.set == pytest.approx([0.51])
    assert flat(n.history) == pytest.approx([1000.0, 0.51, 0.0, 31.0])


def test_a_group_that_is_gone_is_said_once_and_the_others_still_follow():
    clock, lines = FakeClock(), []
    gone, laptop = FakeQuota(fail=True), FakeQuota()
    n = CpuNormaliser({"robot": gone, "laptop": laptop}, {"robot": 0.34, "laptop": 0.9},
                      reference_cpu_ms=15.5, initial_samples=1, measure=lambda: 15.5,
                      clock=clock, log=lines.append)
    n.tick()
    n.tick()
    assert [line for line in lines if "cannot set the robot quota" in line] == [lines[0]]
    assert len(lines) == 1
    assert laptop.set == pytest.approx([0.9, 0.9])


def test_start_seeds_the_median_then_the_thread_measures_each_period_until_stopped():
    calls = []
    seen = threading.Event()

    def measure():
        calls.append(1)
        if len(calls) >= 5:
            seen.set()
        return 15.5

    quota = FakeQuota()
    n = CpuNormaliser({"robot": quota}, {"robot": 0.34}, reference_cpu_ms=15.5, period_s=0.01,
                      initial_samples=3, measure=measure, log=lambda line: None)
    n.start()
    assert len(calls) >= 3 and len(quota.set) >= 1      # seeded and applied before the thread
    assert seen.wait(5.0)
    n.stop()
    after = len(calls)
    time.sleep(0.05)
    assert len(calls) == after                          # stopped means stopped
    assert len(n.history_copy()) == len(calls) - 2


def test_a_failing_measurement_ends_the_thread_with_a_line():
    lines = []
    values = iter([15.5])

    def measure():
        return next(values)             # StopIteration on the thread's first tick

    m = HostSpeedMonitor(period_s=0.01, initial_samples=1, measure=measure, log=lines.append)
    m.start()
    for _ in range(500):
        if lines:
            break
        time.sleep(0.01)
    m.stop()
    assert lines and "measuring stopped" in lines[0]
    assert m.medians and m.medians[0][1] == 15.5


# --- CpuQuota.set_cores -------------------------------------------------------------------------
def test_set_cores_rewrites_the_quota_of_an_existing_group(tmp_path):
    q = CpuQuota("anyscale_robot", 0.34, root=str(tmp_path))
    q.create()
    quota_file = tmp_path / "anyscale_robot" / "cpu.cfs_quota_us"
    assert quota_file.read_text() == "34000"
    q.set_cores(0.37)
    assert quota_file.read_text() == "37000" and q.cores == 0.37
    assert (tmp_path / "anyscale_robot" / "cpu.cfs_period_us").read_text() == "100000"
    q.set_cores(0)
    assert quota_file.read_text() == "-1"


def test_a_shorter_cfs_period_keeps_the_share_and_set_cores_keeps_the_period(tmp_path):
    q = CpuQuota("anyscale_robot", 0.34, root=str(tmp_path), period_us=10_000)
    q.create()
    group = tmp_path / "anyscale_robot"
    assert (group / "cpu.cfs_period_us").read_text() == "10000"
    assert (group / "cpu.cfs_quota_us").read_text() == "3400"
    q.set_cores(0.3)
    assert (group / "cpu.cfs_quota_us").read_text() == "3000"


def test_the_first_settle_s_make_no_median_and_then_none_of_fewer_than_initial_samples():
    # An idle host's 10.5 ms before the nodes load it must not set the quotas (issue 13's
    # first --normalise-cpu run: 10.4 ms, then the robot at 0.22-0.29 cores, AMCL 1.58 Hz).
    clock, quota = FakeClock(), FakeQuota()
    values = iter([10.5, 10.5, 16.0, 16.0, 16.0, 16.0])
    n = CpuNormaliser({"robot": quota}, {"robot": 0.34}, reference_cpu_ms=16.0, window=12,
                      initial_samples=3, measure=lambda: next(values), clock=clock,
                      log=lambda line: None, settle_s=30.0)
    n.start()           # no measurement at once: the scales are not loaded yet
    n.stop()
    medians = []
    for _ in range(6):
        clock.t += 10
        medians.append(n.tick())
    assert medians == [None, None, None, None, 16.0, 16.0]    # settled at t+30, 3 samples
    assert n.samples == [10.5, 10.5, 16.0, 16.0, 16.0, 16.0]
    assert quota.set == pytest.approx([0.34, 0.34])


def test_a_negative_settle_time_is_refused():
    with pytest.raises(ValueError, match="settle time"):
        HostSpeedMonitor(settle_s=-1.0)
