"""`anyscale profile` and `anyscale thresholds` end to end on a live graph: a private roscore
on a free port (11511 when free) and two AnyScale agents on loopback (robot = master, laptop),
the stock-node relay model (test/config/relay_model.yaml), about 2.5 min in all.

- profile measures every node at home and the migratable relay on the laptop, writes the
  figures into the model (which `anyscale check` then accepts) and leaves nothing running;
- thresholds finds the rate and interruption limits of a probe with known limits
  (test/nodes/rate_probe.py: messages in the last 2 s) and restores the subscriber;
- bad input, each one line and exit status 2 with nothing left running: no master, an
  unknown connection, a probe that never passes, a node that fails to start, a decision
  node running, a model node started outside the agents.
The agents are given a model with one more node than the relay model, `broken` (topic_tools
relay without arguments, which aborts at once), so the failing start can be provoked; the other
tests use the relay model, whose nodes are a subset. Every process started here is ended by
process group."""
import json
import os
import re
import shutil
import subprocess
import sys

import psutil
import pytest
import rosgraph
import yaml

from anyscale_core.polling import wait_for

from private_roscore import Processes, free_port, private_master_env, stock_executable

HERE = os.path.dirname(os.path.abspath(__file__))
SCRIPT = os.path.join(HERE, "..", "scripts", "anyscale")
RELAY_MODEL = os.path.join(HERE, "config", "relay_model.yaml")
RATE_PROBE = os.path.join(HERE, "nodes", "rate_probe.py")
PREFERRED_PORT = 11511
MODEL_NODES = {"/talker", "/listener", "/relay", "/relay_listener", "/relay__laptop", "/broken"}
BROKEN = """  - name: broken
    launch: {package: topic_tools, type: relay}
    cpu_usage: {robot: 1}
    memory_mb: 10
"""


def agent_executable() -> str:
    import roslib.packages
    found = roslib.packages.find_node("anyscale_agent_cpp", "anyscale_agent")
    if not found:
        pytest.skip("anyscale_agent_cpp is not built")
    return found[0]


def with_broken_node(text: str) -> str:
    return text.replace("connections:\n", BROKEN + "connections:\n", 1)


class Graph(Processes):
    """The private master, the two agents and whatever a test starts itself."""

    def __init__(self, tmp):
        port = free_port(PREFERRED_PORT)
        super().__init__(tmp, private_master_env(port, tmp))
        self.agent_model = tmp / "agents_model.yaml"
        with open(RELAY_MODEL) as f:
            self.agent_model.write_text(with_broken_node(f.read()))
        self.master = rosgraph.Master("/characterise_test", master_uri=self.env["ROS_MASTER_URI"])
        self.start(["roscore", "-p", str(port)])
        assert wait_for(self.master_up, 20), "roscore did not come up"
        agent = agent_executable()
        self.agents = [
            self.start([agent, "__name:=anyscale_agent_robot", "_scale:=robot",
                        "_is_master:=true", f"_model:={self.agent_model}",
                        "_sigint_timeout_s:=3.0"]),
            self.start([agent, "__name:=anyscale_agent_laptop", "_scale:=laptop",
                        "_master_scale:=robot", f"_model:={self.agent_model}",
                        "_sigint_timeout_s:=3.0"])]
        assert wait_for(lambda: {"/anyscale_agent_robot", "/anyscale_agent_laptop"}
                        <= self.nodes(), 20), "the agents did not come up"

    def master_up(self) -> bool:
        try:
            self.master.getSystemState()
            return True
        except Exception:  # noqa: BLE001 - not up yet
            return False

    def nodes(self) -> set:
        pubs, subs, services = self.master.getSystemState()
        return {n for table in (pubs, subs, services) for _, names in table for n in names}

    def anyscale(self, *args, timeout=300, env=None):
        return subprocess.run([sys.executable, SCRIPT, *args], env=env or self.env,
                              capture_output=True, text=True, timeout=timeout)

    def assert_nothing_left(self):
        """No model node registered, no node process under either agent, no throttle or mux
        of thresholds."""
        assert wait_for(lambda: not (self.nodes() & MODEL_NODES), 10), self.nodes()
        for agent in self.agents:
            children = psutil.Process(agent.pid).children(recursive=True)
            assert children == [], [c.cmdline() for c in children]
        leftovers = [p.info["cmdline"] for p in psutil.process_iter(["cmdline"])
                     if any("anyscale_thresholds_" in a for a in (p.info["cmdline"] or []))]
        assert leftovers == []


@pytest.fixture(scope="module")
def graph(tmp_path_factory):
    stock_executable("topic_tools", "relay")
    stock_executable("topic_tools", "throttle")
    g = Graph(tmp_path_factory.mktemp("characterise"))
    yield g
    g.close()


@pytest.fixture
def relay_model(tmp_path):
    path = tmp_path / "relay_model.yaml"
    shutil.copy(RELAY_MODEL, path)
    return path


def one_error_line(run, *needles, alone=True):
    """Exit status 2 and one error line, no traceback. alone: nothing else on standard error
    (input refused before anything ran); else the error ends what the run printed so far (its
    plan and steps)."""
    assert run.returncode == 2, (run.stdout, run.stderr)
    lines = run.stderr.strip().splitlines()
    assert "Traceback" not in run.stderr, run.stderr
    assert len([x for x in lines if ": error: " in x]) == 1, run.stderr
    assert len(lines) == 1 if alone else lines[-1].startswith("anyscale "), run.stderr
    for needle in needles:
        assert needle in lines[-1], lines[-1]
    return lines[-1]


def test_profile_writes_figures_into_the_model_and_leaves_nothing_running(graph, relay_model):
    before = relay_model.read_text()
    run = graph.anyscale("profile", str(relay_model), "--warmup", "1", "--window", "3",
                         "--json")
    assert run.returncode == 0, run.stderr
    assert "predicted" in run.stderr
    result = json.loads(run.stdout)
    measured = {(m["node"], m["scale"]): m for m in result["measurements"]}
    assert set(measured) == {("talker", "robot"), ("listener", "robot"), ("relay", "robot"),
                             ("relay_listener", "robot"), ("relay", "laptop")}
    for m in measured.values():
        assert m["samples"] >= 3 and 0 <= m["cpu_usage"] <= 100 and m["rss_mb"] > 1
        assert m["capacity_cores"] == psutil.cpu_count() and m["quota"] is False
        # The agents say how busy the scale was: a relay on an idle machine is no share.
        assert 0 <= m["scale_busy_percent"] <= 100 and m["saturated"] is (
            m["scale_busy_percent"] >= 90)
    # The relay forwards the talker's 10 Hz on both scales: it ran, and ran fully, there.
    for scale in ("robot", "laptop"):
        assert 8 <= measured[("relay", scale)]["output_rates_hz"]["/chatter_relay"] <= 11
        assert set(measured[("relay", scale)]["cpu_ms_per_message"]) == {"/chatter_relay"}
    assert result["written"] is True
    tree = yaml.safe_load(relay_model.read_text())
    relay = next(n for n in tree["nodes"] if n["name"] == "relay")
    assert relay["cpu_usage"] == {"robot": measured[("relay", "robot")]["cpu_usage"],
                                  "laptop": measured[("relay", "laptop")]["cpu_usage"]}
    assert relay["memory_mb"] == result["memory_mb"]["relay"]
    text = relay_model.read_text()
    assert text.count("# profile: ") >= 8 and "# Small on the laptop so that" in text
    assert before.splitlines()[0] in text
    check = graph.anyscale("check", str(relay_model))
    assert check.returncode == 0, check.stderr
    graph.assert_nothing_left()


def test_thresholds_finds_a_probes_limits_and_restores_the_subscriber(graph, relay_model):
    probe = graph.start([sys.executable, RATE_PROBE, "input:=/chatter_relay",
                         "rate:=/relay_rate", "_window_s:=2.0"])
    try:
        run = graph.anyscale(
            "thresholds", str(relay_model), "--connection", "talker:relay:/chatter",
            "--probe", "/relay_rate", "--condition", "m.data >= 6", "--value", "20 - m.data",
            "--rates", "10,5,2", "--outages", "0.5,1,2", "--settle", "3", "--step", "4",
            "--json")
    finally:
        graph.stop(probe)
    assert run.returncode == 0, run.stderr
    result = json.loads(run.stdout)
    steps = [(s["rate_hz"], s["outage_s"], s["correct"]) for s in result["steps"]]
    # 10 and 5 Hz keep >= 6 messages in 2 s, 2 Hz does not; a 1 s cut keeps >= 6, 2 s not.
    assert steps == [(10, 0, True), (5, 0, True), (2, 0, False), (10, 0.5, True),
                     (10, 1, True), (10, 2, False)], result["steps"]
    assert (result["freq_min"], result["freq_opt"], result["tolerance"]) == (5, 10, 1)
    connection = next(c for c in yaml.safe_load(relay_model.read_text())["connections"]
                      if c["subscriber"] == "relay")
    assert (connection["freq_min"], connection["freq_opt"], connection["tolerance"]) == (5, 10, 1)
    assert "# thresholds: " in relay_model.read_text()
    graph.assert_nothing_left()


def test_a_probe_that_never_passes(graph, relay_model):
    probe = graph.start([sys.executable, RATE_PROBE, "input:=/chatter_relay",
                         "rate:=/relay_rate"])
    try:
        run = graph.anyscale("thresholds", str(relay_model), "--connection",
                             "talker:relay:/chatter", "--probe", "/relay_rate", "--condition",
                             "m.data > 1000", "--settle", "1", "--step", "2")
    finally:
        graph.stop(probe)
    # The full rate is the source's measured rate: 10 Hz nominal, 9.99 Hz on a busy host.
    line = one_error_line(run, "anyscale thresholds: error: probe: never passed at the source's "
                               "full rate ", " Hz (0 of ", alone=False)
    assert abs(float(re.search(r"full rate ([0-9.]+) Hz", line).group(1)) - 10) < 0.5, line
    assert yaml.safe_load(relay_model.read_text()) == yaml.safe_load(open(RELAY_MODEL))
    graph.assert_nothing_left()


def test_a_probe_script_that_breaks(graph, relay_model, tmp_path):
    script = tmp_path / "probe.sh"
    script.write_text("#!/bin/sh\necho 'cannot reach the robot' >&2\nexit 3\n")
    script.chmod(0o755)
    run = graph.anyscale("thresholds", str(relay_model), "--connection",
                         "talker:relay:/chatter", "--probe-script", str(script), "--settle", "1",
                         "--step", "2")
    one_error_line(run, f"--probe-script: {script}: exit status 3", "cannot reach the robot",
                   alone=False)
    graph.assert_nothing_left()


def test_a_node_that_fails_to_start(graph):
    for command in (["profile", "--window", "2"],
                    ["thresholds", "--connection", "talker:relay:/chatter", "--probe-script",
                     "true"]):
        run = graph.anyscale(command[0], str(graph.agent_model), *command[1:])
        one_error_line(run, f"anyscale {command[0]}: error: broken on robot: failed to start: "
                            "it ended with ", "log ", alone=False)
        graph.assert_nothing_left()


def test_an_unknown_connection(graph, relay_model):
    run = graph.anyscale("thresholds", str(relay_model), "--connection", "talker:nope:/chatter",
                         "--probe-script", "true")
    one_error_line(run, "--connection: no connection talker:nope:/chatter in ",
                   "talker:relay:/chatter")


def test_no_master_running(relay_model):
    env = {**os.environ, "ROS_MASTER_URI": f"http://localhost:{free_port(11599)}",
           "PYTHONPATH": os.pathsep.join(sys.path)}
    for command in (["profile"], ["thresholds", "--connection", "talker:relay:/chatter",
                                  "--probe-script", "true"]):
        run = subprocess.run([sys.executable, SCRIPT, command[0], str(relay_model),
                              *command[1:]], env=env, capture_output=True, text=True,
                             timeout=60)
        one_error_line(run, f"anyscale {command[0]}: error: ROS_MASTER_URI=", "no ROS master "
                                                                              "there")


def test_refused_while_a_decision_node_or_a_foreign_node_runs(graph, relay_model):
    mapping = graph.start(["rostopic", "pub", "/anyscale/mapping", "anyscale_msgs/Mapping",
                           "{}", "__name:=fake_decision"])
    assert wait_for(lambda: "/fake_decision" in graph.nodes(), 20)
    try:
        run = graph.anyscale("profile", str(relay_model))
        one_error_line(run, "a decision node runs (/fake_decision)", "decision:=false")
    finally:
        graph.stop(mapping)
    relay = graph.start([stock_executable("topic_tools", "relay"), "/chatter", "/chatter_relay",
                         "__name:=relay"])
    assert wait_for(lambda: "/relay" in graph.nodes(), 20)
    try:
        run = graph.anyscale("profile", str(relay_model))
        one_error_line(run, "relay: /relay is registered with the master but no agent "
                            "supervises it")
    finally:
        graph.stop(relay)
    graph.assert_nothing_left()
