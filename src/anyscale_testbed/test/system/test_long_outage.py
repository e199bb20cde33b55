"""System test: after a long outage the nodes move out again as soon as the link has held
(root: network namespaces, tc, cgroups). TCP backs off its retransmissions exponentially while
the link is gone, and a connection that only waits shows no error: before the agents and the
decision node renewed silent subscriptions, a 60 s outage left the laptop's status and the link
probes stuck for tens of seconds after the link came back, and in the evaluation's office-floor
runs nothing moved out again for minutes after outages of 25-150 s.

The schedule, on the office floor (the small loop can end 8 s after the link's return, before
the move it waits for):
    0 s   27 Mbit/s   AMCL moves to the laptop
    30 s  link down   AMCL comes back (the robot's node set takes 15-17 s to come up, and on the
                      office floor AMCL first moved out at 17 s)
    90 s  27 Mbit/s   AMCL moves out again once the link has shown its bandwidth for
                      robot.launch's bandwidth_hold_s (5 s; AMCL's own hold after a loss,
                      robot.launch's node_hold_after_loss_s, is 0), and not before; AR
                      recognition waits for hold_after_loss_s (20 s)"""
import glob
import os
import subprocess
import sys

import pytest

from anyscale_testbed.testbed_record import TestbedRecord

# Judges the moves' timings and the rates counted at ROBOT_CPU_CORES, in the slow-day mode on a
# slower host (conftest.py).
pytestmark = pytest.mark.fixed_cpu_quota

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", "..", "..", ".."))
SCHEDULE = "[[0, 27], [30, 0], [90, 27]]"
DURATION_S = 130.0
ROBOT_CPU_CORES = 0.37          # as test_live_migration: the mechanism, not the premise
BANDWIDTH_HOLD_S = 5.0          # robot.launch's; AMCL's own hold after a loss is 0
HOLD_AFTER_LOSS_S = 20.0        # robot.launch's, every other node's
# + up to 5 s until the decision node subscribes to the laptop's status again, the link
# estimate's first readings and the move; under 20 s, which a 20 s hold of AMCL's would pass
OUT_AGAIN_WITHIN_S = BANDWIDTH_HOLD_S + 14.0


@pytest.fixture(scope="module")
def run(tmp_path_factory, slow_host_argv, host_factor):
    out = tmp_path_factory.mktemp("outage")
    done = subprocess.run(
        [sys.executable, os.path.join(ROOT, "scripts", "run_testbed.py"), "--world", "office_floor",
         "--link", "schedule", "--schedule", SCHEDULE, "--duration", str(DURATION_S),
         "--hysteresis", "10", "--robot-cpu", str(ROBOT_CPU_CORES), "--out", str(out)]
        + slow_host_argv, capture_output=True, text=True, timeout=DURATION_S + 120 * host_factor)
    records = glob.glob(str(out / "*" / "record.json"))
    assert done.returncode == 0 and records, done.stdout[-3000:] + done.stderr[-3000:]
    print(done.stdout)
    return TestbedRecord.load(records[0])


def test_amcl_moves_out_again_soon_after_a_60_s_outage(run):
    changes = [t for (t, a), (_, b) in zip(run.bandwidth, run.bandwidth[1:]) if a != b]
    assert len(changes) == 2, run.bandwidth
    down_at, up_at = changes
    out = [e for e in run.events if e.kind == "migrate" and e.success and e.node == "amcl"]
    assert any(e.decided_t < down_at for e in out), out
    again = [e.decided_t - up_at for e in out if e.decided_t > up_at]
    assert again and again[0] < OUT_AGAIN_WITHIN_S, \
        f"AMCL out again {again[0] if again else 'never'} s after the link came back"
    assert again[0] >= BANDWIDTH_HOLD_S - 1.0, f"out again after {again[0]:.1f} s of link only"
    ar_again = [e.decided_t - up_at for e in run.events if e.kind == "migrate" and e.success
                and e.node == "ar_recognition" and e.decided_t > up_at]
    assert not ar_again or ar_again[0] >= HOLD_AFTER_LOSS_S - 1.0, \
        f"AR recognition out again after {ar_again[0]:.1f} s of link only"


def test_no_node_is_sent_back_by_a_rate_counted_on_a_stale_connection(run):
    """The laptop's agent counts the rates of what its nodes receive; a subscription held up by
    TCP's backoff counted 0 Hz, and AMCL and AR came back 9 s after moving out, judged below
    freq_min while their outputs ran at full rate. A return for the laptop's CPU is none of
    this test's (AR recognition costs the laptop several times the model's 12 % and may be
    sent home over capacity: the placement learning's tests judge that)."""
    up_at = [t for (t, a), (_, b) in zip(run.bandwidth, run.bandwidth[1:]) if a != b][-1]
    backs = [(round(e.decided_t, 1), e.node, e.reason) for e in run.events
             if e.kind == "migrate_back" and e.decided_t > up_at
             and e.reason.startswith("connection spending its tolerance")]
    assert backs == [], backs
