"""The stale-registration race, provoked on purpose on the two-scale test bed (issue: a dead
laptop instance's request, delivered by TCP once the link was back, took the node's name from
the live robot instance and silenced it for 11.6 s).

The stock relay runs on the laptop. The test freezes it (SIGSTOP), cuts the link so that the
relay comes home, restores the link within the lease (so the frozen instance is still alive),
lets it run again (SIGCONT) and replays what such an instance sends late: a registration with
its own name and API. The robot's relay must publish within the connection's tolerance of the
link loss, keep publishing, and the laptop instance must end (its lease) and leave no
registration behind."""
import os
import signal
import sys
import time

import pytest

from anyscale_core.polling import wait_for

from anyscale_testbed.testbed_session import NamespaceBed, TestbedSession, layout_with_cpu

from relay_bed import in_scale, launch_relay_bed, model_path, receipts, relay_in, relay_processes

RELAY_TOLERANCE_S = 2.0        # relay_model.yaml
LEASE_S = 3.0                  # the decision node's default
CUT_S = 2.0                    # shorter than the lease: the frozen instance survives the cut
AFTER_S = 12.0                 # how long the output is watched after the link returns

# What a frozen instance sends once it runs again and the link is back: a registration under
# its own name from its own API (rospy registers, and subscribes parameters, this way).
REPLAY = """
import sys, rosgraph
name, api = sys.argv[1], sys.argv[2]
rosgraph.Master(name).registerPublisher("/chatter_relay", "std_msgs/String", api)
"""

LOOKUP = "import sys, rosgraph; print(rosgraph.Master('/stale_test').lookupNode(sys.argv[1]))"


@pytest.fixture(scope="module")
def race(tmp_path_factory):
    run_dir = str(tmp_path_factory.mktemp("stale"))
    model = model_path()
    got = os.path.join(run_dir, "relay_receipts.txt")
    with NamespaceBed(layout_with_cpu(0.0, 0.0)) as bed:
        session = TestbedSession(bed, run_dir)
        launch_relay_bed(bed, session, run_dir, model, got, 30)
        laptop = bed.netns_link("laptop")
        # The relay moves out, and the robot's instance is stopped once the laptop's published.
        moved = wait_for(lambda: relay_in(laptop) and len(relay_processes()) == 1, 60.0, 0.1)
        assert moved, f"the relay never ran on the laptop alone: {relay_processes()}"
        pid, name = relay_in(laptop)
        api = in_scale(bed, session, "robot",
                       [sys.executable, "-c", LOOKUP, "/" + name]).stdout.strip()
        assert api.startswith("http://"), api
        os.kill(pid, signal.SIGSTOP)
        down = time.time()
        bed.set_link(False)
        time.sleep(CUT_S)
        bed.set_link(True)
        robot = bed.netns_link("robot")
        home = wait_for(lambda: relay_in(robot), 5.0, 0.1)
        os.kill(pid, signal.SIGCONT)
        up = time.time()
        replay = in_scale(bed, session, "laptop", [sys.executable, "-c", REPLAY, "/" + name, api])
        time.sleep(AFTER_S)
        laptop_left = relay_in(laptop)
        home_after = relay_in(robot)
        publishers = in_scale(bed, session, "robot", ["rostopic", "info", "/chatter_relay"]).stdout
    return {"down": down, "up": up, "name": name, "replay": replay, "receipts": receipts(got),
            "laptop_left": laptop_left, "publishers": publishers, "home": home,
            "home_after": home_after}


def test_the_laptop_instance_ran_under_its_own_name(race):
    assert race["name"] == "relay__laptop"


def test_the_replayed_late_registration_reached_the_master(race):
    assert race["replay"].returncode == 0, race["replay"].stderr


def test_the_robots_relay_publishes_within_the_tolerance_of_the_link_loss(race):
    robot = [t for t, who in race["receipts"] if who == "/relay" and t > race["down"]]
    assert robot, "the robot's relay never published after the link loss"
    assert robot[0] - race["down"] <= RELAY_TOLERANCE_S, robot[0] - race["down"]


def test_the_late_registration_does_not_end_the_robots_relay(race):
    assert race["home"], "no relay on the robot after the link loss"
    assert race["home_after"] == race["home"], (race["home"], race["home_after"])


def test_and_keeps_publishing_after_the_late_registration(race):
    times = [t for t, _ in race["receipts"] if t > race["down"]]
    points = [race["down"]] + times
    gaps = [b - a for a, b in zip(points, points[1:])]
    assert max(gaps) <= RELAY_TOLERANCE_S, max(gaps)
    assert times[-1] > race["up"] + AFTER_S - 1.0, "/chatter_relay went silent"


def test_the_frozen_instance_ends_and_leaves_no_registration(race):
    assert race["laptop_left"] is None, f"still running on the laptop: {race['laptop_left']}"
    publishers = race["publishers"].split("Subscribers:")[0]
    assert "/relay__laptop" not in publishers and "/relay " in publishers + " ", publishers
