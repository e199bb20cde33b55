"""Scale-agnostic means any node: a stock Debian node (topic_tools' relay, C++), declared in a
small model, migrates over the two-scale test bed's veth, comes back when the link drops and
goes out again after T, with one live instance at a time while both scales can talk (two only
during a planned move's overlap: make before break)."""
import os
import subprocess

import pytest

from anyscale_testbed.testbed_figures import (duplicate_instances, first_after, handover_windows,
                                              link_transitions, longest_gap)
from anyscale_testbed.testbed_record import TestbedRecord, mapping_at
from anyscale_testbed.testbed_session import NamespaceBed, TestbedSession, layout_with_cpu

HERE = os.path.dirname(os.path.abspath(__file__))

SCHEDULE = "[[0, 27], [15, 0], [21, 27]]"
HYSTERESIS_S = 5.0
DURATION_S = 35.0
RELAY_TOLERANCE_S = 2.0        # relay_model.yaml


def model_path():
    pkg = subprocess.run(["rospack", "find", "anyscale_core"], capture_output=True, text=True)
    return os.path.join(pkg.stdout.strip(), "test", "config", "relay_model.yaml")


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    run_dir = str(tmp_path_factory.mktemp("relay"))
    record = os.path.join(run_dir, "record.json")
    model = model_path()
    with NamespaceBed(layout_with_cpu(0.0, 0.0)) as bed:
        session = TestbedSession(bed, run_dir)
        robot = session.roslaunch("robot", "robot", [
            os.path.join(HERE, "relay_robot.launch"), f"model:={model}",
            f"schedule:={SCHEDULE}", f"record_path:={record}", f"duration_s:={DURATION_S}",
            f"hysteresis_s:={HYSTERESIS_S}",
            f"uplink_interface:={bed.uplink_interface('robot')}"], wait_for_master=False)
        session.roslaunch("laptop", "laptop", [
            "anyscale_agent_cpp", "agent.launch", "scale:=laptop", "master_scale:=robot",
            f"model:={model}", "sample_rate_hz:=5.0", "sigint_timeout_s:=2.0"])
        code = robot.wait(timeout=DURATION_S + 60)
    assert code == 0 and os.path.exists(record), open(
        os.path.join(run_dir, "logs", "robot.log")).read()[-3000:]
    return TestbedRecord.load(record)


@pytest.fixture(scope="module")
def link_times(run):
    """(down, up) on the record's clock: the schedule shifted by when the shaper started."""
    transitions = link_transitions(run.bandwidth)
    assert [up for _, up in transitions] == [False, True], transitions
    return transitions[0][0], transitions[1][0]


def test_the_relay_moves_out_comes_back_on_link_loss_and_goes_out_after_t(run, link_times):
    down_at, up_at = link_times
    relay = [e for e in run.events if e.node == "relay" and e.success]
    kinds = [(e.kind, e.to_scale) for e in relay if e.kind != "start"]
    assert kinds[:3] == [("migrate", "laptop"), ("migrate_back", "robot"),
                         ("migrate", "laptop")], kinds
    out, back, again = relay[1:4] if relay[0].kind == "start" else relay[:3]
    assert out.decided_t < down_at and down_at <= back.decided_t < up_at
    assert "down" in back.reason
    assert back.decided_t - down_at < 0.5          # the veth's carrier, not a status timeout
    assert again.decided_t >= max(up_at, back.decided_t + HYSTERESIS_S) - 0.01
    assert mapping_at(run, down_at - 1.0)["relay"] == "laptop"
    # Where it ran is where its process was: the robot and laptop namespaces differ.
    spaces = {ns for s in run.processes for ns in s.instances["relay"]}
    assert len(spaces) == 2


def test_the_relays_output_never_goes_silent_longer_than_its_tolerance(run, link_times):
    down_at = link_times[0]
    times = run.receipts["/chatter_relay"]
    assert times, "no /chatter_relay received on the robot"
    assert longest_gap(times, times[0], run.finished_t) <= RELAY_TOLERANCE_S
    assert first_after(times, down_at) < RELAY_TOLERANCE_S


def test_one_relay_instance_while_the_link_is_up_also_after_the_partition_heals(run, link_times):
    up_at = link_times[1]
    assert duplicate_instances(run.processes, ["relay"], run.events) == []
    healed = [s for s in run.processes if s.t > up_at]
    assert healed and duplicate_instances(healed, ["relay"], run.events) == []
    assert len(healed[-1].instances["relay"]) == 1
    overlaps = handover_windows(run.events).get("relay", [])
    for t, publishers in run.master_publishers:
        if not any(a <= t <= b for a, b in overlaps):
            assert len(publishers.get("/chatter_relay", [])) <= 1, (t, publishers)
