"""`anyscale model draft` end to end on a live graph: a private roscore on a free port (11498
if free) in the root namespace, Debian's stock `rostopic pub -r 10`, `topic_tools relay` and
`rostopic echo`; the draft, filled in, passes `anyscale check` and `plan`. Also: no master
running is one line and exit 2. Everything started here is killed by process group."""
import os
import subprocess
import sys

import pytest
import yaml

from anyscale_core.polling import wait_for

from core_test_data import filled_draft
from private_roscore import Processes, free_port, private_master_env, stock_executable

SCRIPT = os.path.join(os.path.dirname(__file__), "..", "scripts", "anyscale")
PREFERRED_PORT = 11498


@pytest.fixture
def ros_env(tmp_path):
    return private_master_env(free_port(PREFERRED_PORT), tmp_path)


@pytest.fixture
def started(tmp_path, ros_env):
    """start(argv): a process with ros_env in its own session; all are ended (SIGINT, then
    SIGKILL) and reaped after the test."""
    procs = Processes(tmp_path, ros_env)
    yield procs.start
    procs.close()


def graph(env) -> dict:
    """topic -> (publishers, subscribers) of the master at env's ROS_MASTER_URI."""
    code = ("import rosgraph, json; p, s, _ = rosgraph.Master('/draft_test').getSystemState(); "
            "d = {}; [d.setdefault(t, [[], []])[0].extend(n) for t, n in p]; "
            "[d.setdefault(t, [[], []])[1].extend(n) for t, n in s]; print(json.dumps(d))")
    run = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True)
    return yaml.safe_load(run.stdout) if run.returncode == 0 else {}


def draft(env, *args):
    return subprocess.run([sys.executable, SCRIPT, "model", "draft", *args], env=env,
                          capture_output=True, text=True, timeout=60)


def test_draft_of_a_live_graph_passes_check_and_plan(ros_env, started, tmp_path):
    port = ros_env["ROS_MASTER_URI"].rsplit(":", 1)[1]
    relay = stock_executable("topic_tools", "relay")
    started(["roscore", "-p", port])
    assert wait_for(lambda: graph(ros_env), 20), "roscore did not come up"
    started(["rostopic", "pub", "-r", "10", "/chatter", "std_msgs/String", "data: hi",
             "__name:=talker"])
    started([relay, "chatter", "/chatter_relay", "chatter:=/chatter", "__name:=relay"])
    started(["rostopic", "echo", "/chatter_relay", "__name:=echo"])
    ready = wait_for(lambda: "/echo" in graph(ros_env).get("/chatter_relay", [[], []])[1]
                     and "/relay" in graph(ros_env).get("/chatter", [[], []])[1], 20)
    assert ready, f"the stock nodes did not come up: {graph(ros_env)}"

    out = tmp_path / "drafted.yaml"
    run = draft(ros_env, str(out), "--seconds", "3")
    assert run.returncode == 0, run.stderr
    assert "Traceback" not in run.stderr
    model = yaml.safe_load(out.read_text())
    nodes = {n["name"]: n for n in model["nodes"]}
    assert set(nodes) == {"talker", "relay", "echo"}           # no rosout, not the drafter
    assert nodes["relay"]["launch"] == {"package": "topic_tools", "type": "relay",
                                        "args": ["chatter", "/chatter_relay"],
                                        "remaps": {"chatter": "/chatter"}}
    assert nodes["talker"]["launch"]["package"] == "rostopic"
    assert nodes["talker"]["launch"]["args"] == ["pub", "-r", "10", "/chatter",
                                                 "std_msgs/String", "data: hi"]
    assert nodes["talker"]["pinned"] == "TODO" and nodes["relay"]["memory_mb"] > 0
    connections = {(c["publisher"], c["subscriber"], c["topic"]): c
                   for c in model["connections"]}
    assert set(connections) == {("talker", "relay", "/chatter"),
                                ("relay", "echo", "/chatter_relay")}
    for c in connections.values():
        assert 8 <= c["freq_opt"] <= 11, c
        assert c["bandwidth_mbps"] > 0 and c["freq_min"] == "TODO"
    assert "std_msgs/String" in out.read_text()

    again = draft(ros_env, str(out), "--seconds", "1")
    assert again.returncode == 2 and "exists; give --force" in again.stderr

    filled = tmp_path / "filled.yaml"
    filled.write_text(yaml.safe_dump(filled_draft(model, critical_topics={"/chatter_relay"})))
    check = subprocess.run([sys.executable, SCRIPT, "check", str(filled)], env=ros_env,
                           capture_output=True, text=True)
    assert check.returncode == 0, check.stderr
    assert "critical nodes (2, pinned to robot): echo, relay" in check.stdout
    plan = subprocess.run([sys.executable, SCRIPT, "plan", str(filled), "--json"], env=ros_env,
                          capture_output=True, text=True)
    assert plan.returncode == 0, plan.stderr
    assert yaml.safe_load(plan.stdout)["feasible"] is True


def test_no_master_is_one_line_and_exit_2(ros_env, tmp_path):
    out = tmp_path / "never.yaml"
    run = draft(ros_env, str(out))
    assert run.returncode == 2
    lines = run.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in run.stderr
    assert lines[0].startswith(f"anyscale model draft: error: ROS_MASTER_URI="
                               f"{ros_env['ROS_MASTER_URI']}: no ROS master there")
    assert not out.exists()
