"""A node with a paused instance at home that crashes on the laptop comes home: its paused
instance is resumed, and its output is back well within its tolerance (issue 15: a SIGSEGV of
AMCL on the laptop left /amcl_pose silent 2.40 s, Δ 2 s, while a new instance started there
across the link; the decision node now resumes the one paused at home instead).

The stock relay (relay_model.yaml, with launch.pause_at_home) moves to the laptop over a clean
link, the robot's instance is paused; the test sends SIGSEGV to the laptop's relay."""
import os
import signal
import time

import pytest

from anyscale_core.polling import wait_for

from anyscale_testbed.testbed_session import NamespaceBed, TestbedSession, layout_with_cpu

from relay_bed import (launch_relay_bed, paused_at_home_model, process_state, receipts,
                       relay_in)

RELAY_TOLERANCE_S = 2.0        # relay_model.yaml
HYSTERESIS_S = 30.0            # T: the relay stays home this long after it came back
AFTER_S = 10.0                 # how long the output is watched after the crash


@pytest.fixture(scope="module")
def crash(tmp_path_factory):
    run_dir = str(tmp_path_factory.mktemp("crash_out"))
    model = paused_at_home_model(run_dir)
    got = os.path.join(run_dir, "relay_receipts.txt")
    with NamespaceBed(layout_with_cpu(0.0, 0.0)) as bed:
        session = TestbedSession(bed, run_dir)
        launch_relay_bed(bed, session, run_dir, model, got, HYSTERESIS_S)
        laptop, robot = bed.netns_link("laptop"), bed.netns_link("robot")
        out = wait_for(lambda: relay_in(laptop) and relay_in(robot)
                       and process_state(relay_in(robot)[0]) == "T", 60.0, 0.1)
        assert out, f"the relay never ran on the laptop with its robot instance paused: " \
                    f"laptop {relay_in(laptop)}, robot {relay_in(robot)}"
        paused = relay_in(robot)[0]
        time.sleep(2.0)                     # a few messages from the laptop's relay first
        crashed = relay_in(laptop)[0]
        os.kill(crashed, signal.SIGSEGV)
        at = time.time()
        time.sleep(AFTER_S)
        result = {"at": at, "paused": paused, "robot": relay_in(robot), "laptop": relay_in(laptop),
                  "robot_state": process_state(paused), "receipts": receipts(got)}
    return result


def test_the_relay_came_home_in_its_paused_instance_and_stayed(crash):
    assert crash["robot"] is not None and crash["robot"][0] == crash["paused"], crash["robot"]
    assert crash["robot_state"] != "T", "the robot's instance is still paused"
    assert crash["laptop"] is None, f"started again on the laptop: {crash['laptop']}"


def test_its_output_was_back_well_within_the_tolerance(crash):
    after = [t for t, who in crash["receipts"] if who == "/relay" and t > crash["at"]]
    assert after, "the robot's relay never published after the crash"
    back = after[0] - crash["at"]
    print(f"/chatter_relay back from the robot {back:.2f} s after the SIGSEGV")
    assert back <= RELAY_TOLERANCE_S / 2, back
    gaps = [b - a for a, b in zip(after, after[1:])]
    assert after[-1] > crash["at"] + AFTER_S - 1.0 and max(gaps, default=0.0) < 1.0
