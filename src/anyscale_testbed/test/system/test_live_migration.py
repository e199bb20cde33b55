"""System tests of live migration on the two-scale test bed (root: network namespaces, tc,
cgroups): the navigation demo with AnyScale deciding, the link following a scripted schedule.

One run of scripts/run_testbed.py serves every test here; each test reads what its monitor
recorded. The schedule, on the small loop world:
    0 s   27 Mbit/s   AMCL, then AR move to the laptop            (1)
    40 s   6 Mbit/s   below AR's 6.27 Mbit/s + 15 %: AR comes back, AMCL stays (2)
    52 s   link down  AMCL comes back, /amcl_pose silent < 2 s     (3)
    57 s   27 Mbit/s  they move out again, AMCL only after T        (4)
and throughout: never two live instances while the link is up (5), critical nodes stay (6),
AMCL stays localised (7).

The robot runs at ROBOT_CPU_CORES, not at the evaluation's premise (0.34 cores in
testbed_calibration.yaml, where AMCL on the robot only reaches its 2 Hz minimum); the
evaluation and tests/bench/bench_tolerances.py measure Δ there. These tests check the
mechanism, and that the link-loss return, a resume of the paused robot instance, keeps AMCL's
tolerance."""
import glob
import os
import subprocess
import sys

import numpy as np
import pytest

from anyscale_testbed.testbed_figures import (HANDOVER_S, duplicate_instances, handover_windows,
                                              link_transitions, longest_gap, pose_errors,
                                              reaction_s)
from anyscale_testbed.testbed_record import TestbedRecord, mapping_at

# Judges the moves' timings and AMCL's tolerance at ROBOT_CPU_CORES, in the slow-day mode on a
# slower host (conftest.py).
pytestmark = pytest.mark.fixed_cpu_quota

# the repository root: this file is src/anyscale_testbed/test/system/ below it
ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", "..", "..", ".."))

# The robot's whole node set takes 15-17 s to come up under its quota, and AR goes out only
# once the link estimate has held its need plus the margin for ~bandwidth_hold_s: 40 s of good
# link leave room for both moves (35 s did not, in one run of three). 6 Mbit/s, not less:
# robot.launch's weak_link_mbps (5.5) brings AMCL home from a link on 802.11's two lowest rates
# (3 and 4.5 Mbit/s usable). The moves out after T come at about 63 s: the loop has taken
# 71-83 s with AMCL on the laptop this long (at 66 s for the link's return, a loop done at
# 71 s left them out of the run; a clean-clone CI's loop was done at 70 s, 1 s into the moves
# out after T, so the robot drives the loop twice and the run ends at DURATION_S). The hold
# after a loss (robot.launch: 20 s, AMCL's 0, see
# test_long_outage.py) is off here: (4) is about T.
SCHEDULE = "[[0, 27], [40, 6], [52, 0], [57, 27]]"
HYSTERESIS_S = 10.0
DURATION_S = 105.0
MIGRATABLE = ("amcl", "ar_recognition")
CRITICAL = ("odometry", "ekf", "navigation")
AMCL_POSE_TOLERANCE_S = 2.0      # Table I
ROBOT_CPU_CORES = 0.37           # the quota these timings were measured at; see above
# Room for AMCL and AR both: on the laptop AR sees every camera frame and took 0.68-0.75 cores
# (a lower bound, the laptop saturated) beside AMCL's 0.19. At the calibrated 0.9 cores AR came
# home over capacity and, in one clean-clone CI run, was not out again before the weak phase;
# a laptop too small is test_weak_laptop.py's case, this one is about the link.
LAPTOP_CPU_CORES = 1.4


@pytest.fixture(scope="module")
def run(tmp_path_factory, slow_host_argv, host_factor):
    out = tmp_path_factory.mktemp("testbed")
    done = subprocess.run(
        [sys.executable, os.path.join(ROOT, "scripts", "run_testbed.py"), "--world",
         "small_loop", "--link", "schedule", "--schedule", SCHEDULE, "--duration",
         str(DURATION_S), "--loops", "2", "--hysteresis", str(HYSTERESIS_S),
         "--robot-cpu", str(ROBOT_CPU_CORES), "--laptop-cpu", str(LAPTOP_CPU_CORES),
         "--hold-after-loss", "0", "--out", str(out)]
        + slow_host_argv, capture_output=True, text=True, timeout=DURATION_S + 120 * host_factor)
    records = glob.glob(str(out / "*" / "record.json"))
    assert done.returncode == 0 and records, done.stdout[-3000:] + done.stderr[-3000:]
    print(done.stdout)      # the run's own account, shown with -s or on failure
    return TestbedRecord.load(records[0])


@pytest.fixture(scope="module")
def phases(run):
    """When the link became weak, went down and came back, on the record's clock: the
    schedule's times shifted by when the shaper started, which reactions faster than that
    shift (the uplink's carrier) would otherwise seem to precede."""
    changes = [t for (t, a), (_, b) in zip(run.bandwidth, run.bandwidth[1:]) if a != b]
    assert len(changes) == 3, run.bandwidth
    return changes


def moves(rec, kind, node=None):
    return [e for e in rec.events
            if e.kind == kind and e.success and (node is None or e.node == node)]


def test_nothing_is_left_behind(run):
    namespaces = subprocess.run(["ip", "netns", "list"], capture_output=True, text=True).stdout
    assert "anyscale_robot" not in namespaces and "anyscale_laptop" not in namespaces
    assert not os.path.exists("/sys/fs/cgroup/cpu/anyscale_robot")
    assert processes_of_the_testbed() == []


def processes_of_the_testbed():
    """Live processes that talk to the test bed's master (its ROS_MASTER_URI)."""
    tag = b"ROS_MASTER_URI=http://10.213.7.1:11311"
    found = []
    for pid in filter(str.isdigit, os.listdir("/proc")):
        try:
            with open(f"/proc/{pid}/environ", "rb") as f:
                if tag in f.read().split(b"\0"):
                    found.append(int(pid))
        except OSError:
            continue
    return found


def test_1_good_link_moves_amcl_then_ar_to_the_laptop(run, phases):
    weak_at = phases[0]
    # In the order decided: the event of a move is recorded when it has run, and AR's start
    # can end before AMCL's that was decided first.
    out = sorted((e for e in moves(run, "migrate") if e.decided_t < weak_at),
                 key=lambda e: e.decided_t)
    assert [e.node for e in out][:2] == ["amcl", "ar_recognition"], out
    assert mapping_at(run, weak_at - 1.0) == {**mapping_at(run, weak_at - 1.0),
                                              "amcl": "laptop", "ar_recognition": "laptop"}


def test_1_the_record_names_each_handover_of_amcl_pose(run, phases):
    """The record keeps which instance sent /amcl_pose (the handover's silence of a move comes
    from it): the robot's, the laptop's after the move out, the robot's after the loss."""
    _, down_at, up_at = phases
    out = min(e.decided_t for e in moves(run, "migrate", "amcl"))
    senders = run.senders["/amcl_pose"]
    first = senders[0][1]
    laptop = [name for t, name in senders if out <= t < down_at and name != first]
    assert laptop, senders
    assert any(name == first for t, name in senders if down_at <= t <= up_at + 5.0), senders


def test_2_bandwidth_below_ars_need_brings_ar_back_and_amcl_stays(run, phases):
    weak_at, down_at, _ = phases
    # The mapping says where each node runs from the decision on. The move's event is published
    # only once the new instance is seen registered, which may come after the run has ended
    # (the decision node waits up to 30 s for it): one CI run of this test had no event in the
    # window, and nothing else to say why, so the failure prints what the record holds.
    context = window_account(run, weak_at - 5.0, down_at + 1.0)
    assert mapping_at(run, down_at - 0.5).get("ar_recognition") == "robot", context
    assert mapping_at(run, down_at - 0.5).get("amcl") == "laptop", context
    back = [e for e in run.events
            if e.kind == "migrate_back" and weak_at <= e.decided_t < down_at]
    assert [e.node for e in back][:1] in ([], ["ar_recognition"]), context
    # Either rule may fire first on the weak link: the bandwidth estimate falling below AR's
    # need, or a connection of AR spending part of its tolerance (below freq_min, or silent).
    assert not back or "bandwidth" in back[0].reason or \
        "spending its tolerance" in back[0].reason, \
        context


def window_account(rec, start, end):
    """The record's mappings (of the migratable nodes) and events from start to end."""
    lines = [f"mappings and events from t={start:.1f} to {end:.1f} s:"]
    lines += [f"  {t:7.1f}  mapping " + ", ".join(f"{n}@{m.get(n)}" for n in MIGRATABLE)
              for t, m, _, _ in rec.mappings if start <= t <= end]
    lines += [f"  {e.decided_t:7.1f}  {e.kind} {e.node} {e.from_scale}->{e.to_scale} "
              f"success={e.success}: {e.reason}" for e in rec.events
              if start <= e.decided_t <= end]
    return "\n".join(lines)


def test_3_link_down_brings_both_back(run, phases):
    _, down_at, up_at = phases
    back = [e for e in moves(run, "migrate_back", "amcl") if down_at <= e.decided_t < up_at]
    assert back and "down" in back[0].reason
    # The robot's agent sees the veth lose its carrier: no status_timeout_s (1.0 s) to wait.
    assert back[0].decided_t - down_at < 0.5
    assert set(mapping_at(run, up_at - 0.5)[n] for n in MIGRATABLE) == {"robot"}


def test_3_the_robot_instance_waits_paused_and_the_loss_resumes_it(run, phases):
    _, down_at, up_at = phases
    # AMCL is on the laptop until the loss, its robot instance paused (launch.pause_at_home).
    before = [s for s in run.processes if down_at - 5.0 <= s.t < down_at]
    assert before and all("/amcl" in s.paused for s in before), before
    robot = before[0].instances["ekf"][0]       # the robot's network namespace
    after = [s for s in run.processes if down_at + 2.0 <= s.t < up_at]
    assert after and all("/amcl" not in s.paused and robot in s.instances["amcl"]
                         for s in after), after


def test_3_amcl_publishes_on_the_robot_within_its_tolerance_of_the_loss(run, phases):
    # With AMCL's robot instance paused rather than stopped, the return is a resume (1.34 and
    # 1.66 s here; started from a standby it took 1.08-2.16 s).
    _, down_at, up_at = phases
    back = [e for e in moves(run, "migrate_back", "amcl") if down_at <= e.decided_t < up_at]
    reaction = reaction_s(run.receipts["/amcl_pose"], down_at, back[0].decided_t)
    assert reaction < AMCL_POSE_TOLERANCE_S, \
        f"/amcl_pose on the robot {reaction:.2f} s after the loss"


def test_3_amcl_pose_on_the_robot_never_silent_longer_than_its_tolerance(run):
    poses = run.receipts["/amcl_pose"]
    gap = longest_gap(poses, poses[0], run.finished_t)
    assert gap <= AMCL_POSE_TOLERANCE_S, f"/amcl_pose silent for {gap:.2f} s on the robot"


def test_4_after_the_link_returns_they_move_out_again_only_after_t(run, phases):
    up_at = phases[2]
    backs = moves(run, "migrate_back")
    again = [e for e in moves(run, "migrate") if e.decided_t >= up_at]
    assert {e.node for e in again} == set(MIGRATABLE), again
    for e in again:
        # T counts from the node's latest return before this move.
        returned = max(b.decided_t for b in backs
                       if b.node == e.node and b.decided_t < e.decided_t)
        assert e.decided_t >= returned + HYSTERESIS_S - 0.01, e
    assert [t for t, up in link_transitions(run.bandwidth)] != []


def test_5_never_two_instances_where_both_could_publish(run, phases, host_factor):
    up_at = phases[2]
    overlap_s = HANDOVER_S * host_factor    # a slower host takes longer to a start's outputs
    assert run.processes, "no process samples recorded"
    # Two only during a planned move's overlap (make before break), bounded in time.
    assert duplicate_instances(run.processes, MIGRATABLE, run.events, overlap_s) == []
    # The master's view agrees: while the link is up, one registered publisher per output
    # topic outside a planned move's overlap, besides a paused instance (launch.pause_at_home),
    # which stays registered and publishes nothing. (In a partition the cut-off instance stays
    # registered until its lease has ended it and the decision node has removed its
    # registration; the resumed one is registered at once.)
    windows = handover_windows(run.events, overlap_s)
    samples = {s.t: s for s in run.processes}
    checked = 0
    for t, publishers in run.master_publishers:
        if not samples[t].link_up:
            continue
        checked += 1
        for topic, node in (("/amcl_pose", "amcl"), ("/ar_markers", "ar_recognition")):
            if not any(a <= t <= b for a, b in windows.get(node, [])):
                live = [p for p in publishers.get(topic, []) if p not in samples[t].paused]
                assert len(live) <= 1, (t, topic, publishers)
    assert checked > 100
    # After the partition healed: never two outside an overlap, one of each at the end.
    healed = [s for s in run.processes if s.t > up_at]
    assert healed and duplicate_instances(healed, MIGRATABLE, run.events, overlap_s) == []
    settled = [s for s in healed
               if not any(a <= s.t <= b for ws in windows.values() for a, b in ws)]
    assert settled and all(len(settled[-1].instances[n]) == 1 for n in MIGRATABLE), settled[-1:]


def test_6_critical_nodes_never_move(run):
    assert not [e for e in run.events if e.node in CRITICAL and e.kind != "start"]
    for _, mapping, _, _ in run.mappings:
        assert all(mapping[n] == "robot" for n in CRITICAL)


def test_7_navigation_stays_localised_across_every_move(run):
    errors = pose_errors(run.truth, run.estimate)
    assert errors.size > 100
    # Alone, the demo's AMCL stays within 0.12 m on this loop; a lost AMCL is metres off.
    assert errors.max() < 0.5, f"AMCL off by {errors.max():.2f} m"
    assert np.sqrt(np.mean(errors ** 2)) < 0.2
    statuses = [s for _, s in run.navigation_status]
    assert statuses and not any(s.startswith("stopped") for s in statuses), statuses[-3:]
