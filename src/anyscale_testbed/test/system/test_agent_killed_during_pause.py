"""The robot's agent killed while a node moves out, provoked on purpose on the two-scale test
bed (issue 15: in a fault soak the pause of AMCL's robot instance got "connection refused",
the agent's successor adopted that instance as running, and it published beside the laptop's
for 17.8 s; at home no lease ends an instance).

The stock relay (declared launch.pause_at_home) moves to the laptop. As soon as its laptop
instance exists, the test freezes the robot's agent (SIGSTOP), so the pause that follows the
laptop instance's first output cannot be answered, then kills it (SIGKILL). roslaunch starts
the agent again; it adopts the robot's relay, still running. The laptop's agent probes the
link through the robot's agent: here it waits longer than the agent is gone before it calls
the link lost, as it would for a robot agent killed alone (the soak's case), not frozen. The
decision node must pause it within a period or two of the successor's first status, and the
laptop's relay keeps the output."""
import os
import signal
import time

import pytest

from anyscale_core.polling import wait_for

from anyscale_testbed.testbed_session import NamespaceBed, TestbedSession, layout_with_cpu

from relay_bed import (launch_relay_bed, paused_at_home_model, process_state, processes_named,
                       receipts, relay_in)

RELAY_TOLERANCE_S = 2.0        # relay_model.yaml
HYSTERESIS_S = 30.0            # T: nothing moves back and forth meanwhile
PAUSE_CALL_S = 1.0             # how long the pause call hangs on the frozen agent
AFTER_S = 12.0                 # how long the outcome is watched after the kill
# The laptop agent's link timeout: longer than the robot's agent is frozen and dead here.
LINK_TIMEOUT_S = 8.0


def robot_agent():
    pids = list(processes_named("anyscale_agent_robot"))
    return pids[0] if len(pids) == 1 else None


@pytest.fixture(scope="module")
def kill(tmp_path_factory):
    run_dir = str(tmp_path_factory.mktemp("agent_killed"))
    model = paused_at_home_model(run_dir)
    got = os.path.join(run_dir, "relay_receipts.txt")
    with NamespaceBed(layout_with_cpu(0.0, 0.0)) as bed:
        session = TestbedSession(bed, run_dir)
        launch_relay_bed(bed, session, run_dir, model, got, HYSTERESIS_S, agent_respawn=True,
                         laptop_args=[f"link_timeout_s:={LINK_TIMEOUT_S}"])
        laptop, robot = bed.netns_link("laptop"), bed.netns_link("robot")
        assert wait_for(lambda: robot_agent() and relay_in(robot), 60.0, 0.1), \
            f"no robot agent and relay: {robot_agent()}, {relay_in(robot)}"
        agent = robot_agent()
        # The laptop instance exists before it publishes (its process starts first).
        assert wait_for(lambda: relay_in(laptop), 60.0, 0.02), "the relay never moved out"
        os.kill(agent, signal.SIGSTOP)
        frozen = time.time()
        published = wait_for(lambda: any(who == "/relay__laptop" for _, who in receipts(got)),
                             15.0, 0.05)
        time.sleep(PAUSE_CALL_S)
        robot_relay = relay_in(robot)
        state_at_kill = process_state(robot_relay[0]) if robot_relay else "-"
        os.kill(agent, signal.SIGKILL)
        killed = time.time()
        successor = wait_for(lambda: robot_agent() not in (None, agent) and robot_agent(),
                             10.0, 0.05)
        successor_at = time.time()
        time.sleep(AFTER_S)
        result = {"frozen": frozen, "published": published, "robot_relay": robot_relay,
                  "state_at_kill": state_at_kill, "killed": killed, "successor": successor,
                  "successor_at": successor_at, "robot_after": relay_in(robot),
                  "laptop_after": relay_in(laptop), "receipts": receipts(got)}
        result["robot_state_after"] = process_state(result["robot_after"][0]) \
            if result["robot_after"] else "-"
    return result


def test_the_race_was_provoked(kill):
    assert kill["published"], "the laptop's relay never published while the agent was frozen"
    assert kill["robot_relay"] is not None, "no relay on the robot when the agent was killed"
    assert kill["state_at_kill"] != "T", "the robot's relay was paused before the agent died"
    assert kill["successor"], "roslaunch did not start the robot's agent again"


def test_the_robots_instance_is_paused_again_soon_after_the_successor_came(kill):
    assert kill["robot_after"] is not None and \
        kill["robot_after"][0] == kill["robot_relay"][0], kill["robot_after"]
    assert kill["robot_state_after"] == "T", "the robot's relay still runs beside the laptop's"
    late = [t for t, who in kill["receipts"] if who == "/relay" and t > kill["killed"]]
    last = max(late, default=kill["killed"])
    print(f"the robot's relay published until {last - kill['successor_at']:.2f} s after the "
          f"successor agent came ({last - kill['killed']:.2f} s after the kill)")
    assert last - kill["successor_at"] <= RELAY_TOLERANCE_S, last - kill["successor_at"]


def test_the_laptops_relay_kept_the_output(kill):
    assert kill["laptop_after"] is not None, "the relay no longer runs on the laptop"
    after = [t for t, who in kill["receipts"] if who == "/relay__laptop" and t > kill["killed"]]
    assert after and after[-1] > kill["killed"] + AFTER_S - 1.0, "/chatter_relay went silent"
    points = [kill["killed"]] + after
    assert max(b - a for a, b in zip(points, points[1:])) <= RELAY_TOLERANCE_S
