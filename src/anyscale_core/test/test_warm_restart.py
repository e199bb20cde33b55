"""warm_restart.become_node (a killed node forked again from the process that holds its
imports) and the decision node's --warm-restart, with small Python scripts as the node: no ROS.

Each script runs in a process of its own (become_node forks its caller) and writes a line per
import of its module and per node process to a log, so that a test can tell a node forked
from its standby (no new import) from a process started again."""
import os
import signal
import subprocess
import sys
import time

import pytest

HERE = os.path.dirname(os.path.abspath(__file__))
DECISION_NODE = os.path.join(HERE, "..", "nodes", "decision_node")

NODE = """
import os, sys, time
sys.path[:0] = {path!r}
with open({log!r}, "a") as f:
    f.write("imported\\n")
from anyscale_core.restart_backoff import BackoffParams
from anyscale_core.warm_restart import become_node
become_node(BackoffParams({first_delay_s}, 30.0, 30.0))
with open({log!r}, "a") as f:
    f.write(f"node {{os.getpid()}} {{os.getppid()}}\\n")
if os.environ.get("NODE_EXIT"):
    sys.exit(int(os.environ["NODE_EXIT"]))
try:
    while True:
        time.sleep(0.02)
except KeyboardInterrupt:
    sys.exit(0)
"""


def sigint_as_in_a_terminal():
    """A node started by roslaunch from a terminal gets SIGINT's default action; a test run in
    the background (nohup ... &, as CI may be) would hand its children SIGINT ignored, and a
    Python process that starts with SIGINT ignored never raises KeyboardInterrupt."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def start(tmp_path, first_delay_s=1.0, **env):
    log = tmp_path / "node.log"
    script = tmp_path / "node.py"
    script.write_text(NODE.format(path=sys.path, log=str(log), first_delay_s=first_delay_s))
    proc = subprocess.Popen([sys.executable, str(script)], env={**os.environ, **env},
                            stderr=subprocess.PIPE, text=True,
                            preexec_fn=sigint_as_in_a_terminal)
    return proc, log


def nodes(log):
    """(pid, parent pid) of each node process so far, and how many times the module loaded."""
    lines = log.read_text().splitlines() if log.exists() else []
    found = [tuple(int(x) for x in line.split()[1:3]) for line in lines
             if line.startswith("node")]
    return found, lines.count("imported")


def wait_for_nodes(log, count, timeout_s=10.0):
    end = time.monotonic() + timeout_s
    while time.monotonic() < end:
        found, _ = nodes(log)
        if len(found) >= count:
            return found
        time.sleep(0.01)
    raise AssertionError(f"{count} node processes expected, found {nodes(log)[0]}")


def comm(pid):
    with open(f"/proc/{pid}/comm") as f:
        return f.read().strip()


def gone(pid, timeout_s=5.0):
    end = time.monotonic() + timeout_s
    while time.monotonic() < end:
        try:
            with open(f"/proc/{pid}/stat") as f:
                if f.read().rsplit(")", 1)[1].split()[0] == "Z":
                    return True
        except FileNotFoundError:
            return True
        time.sleep(0.01)
    return False


@pytest.fixture
def cleanup():
    procs = []
    yield procs
    for p in procs:
        if p.poll() is None:
            p.kill()
            p.wait()


def test_a_killed_node_is_forked_again_at_once_from_its_standby(tmp_path, cleanup):
    proc, log = start(tmp_path)
    cleanup.append(proc)
    [(node, parent)] = wait_for_nodes(log, 1)
    assert parent == proc.pid and node != proc.pid
    # The standby is no node to tools that skip standbys (the soak's census, as for the agents'
    # python_standby); the node has the name a process of the script has.
    assert comm(proc.pid).startswith("standby:")
    assert comm(node) == os.path.basename(sys.executable)[:15]
    killed = time.monotonic()
    os.kill(node, signal.SIGKILL)
    found = wait_for_nodes(log, 2)
    assert time.monotonic() - killed < 1.0
    assert found[1][1] == proc.pid
    assert nodes(log)[1] == 1                     # forked: the imports were not done again
    os.kill(proc.pid, signal.SIGINT)              # roslaunch's stop: passed on, no restart
    assert proc.wait(timeout=10) == 0
    assert gone(found[1][0]) and len(nodes(log)[0]) == 2
    assert "killed (SIGKILL); started again from its warm standby" in proc.stderr.read()


def test_restarts_in_a_row_back_off(tmp_path, cleanup):
    proc, log = start(tmp_path, first_delay_s=0.6)
    cleanup.append(proc)
    [(first, _)] = wait_for_nodes(log, 1)
    os.kill(first, signal.SIGSEGV)
    second = wait_for_nodes(log, 2)[1][0]
    killed = time.monotonic()
    os.kill(second, signal.SIGKILL)
    wait_for_nodes(log, 3)
    assert time.monotonic() - killed >= 0.55      # the second restart in a row waits
    proc.send_signal(signal.SIGINT)
    assert proc.wait(timeout=10) == 0


def test_a_node_that_exits_by_itself_ends_its_standby_with_its_status(tmp_path, cleanup):
    proc, log = start(tmp_path, NODE_EXIT="3")
    cleanup.append(proc)
    assert proc.wait(timeout=10) == 3             # roslaunch's respawn or required decides
    assert len(nodes(log)[0]) == 1


def test_sigterm_ends_the_node_and_the_standby_as_it_ended_the_node(tmp_path, cleanup):
    proc, log = start(tmp_path)
    cleanup.append(proc)
    [(node, _)] = wait_for_nodes(log, 1)
    proc.send_signal(signal.SIGTERM)
    assert proc.wait(timeout=10) == -signal.SIGTERM
    assert gone(node) and len(nodes(log)[0]) == 1


def test_the_node_does_not_outlive_its_standby(tmp_path, cleanup):
    proc, log = start(tmp_path)
    cleanup.append(proc)
    [(node, _)] = wait_for_nodes(log, 1)
    proc.kill()                                   # roslaunch's last escalation
    proc.wait()
    assert gone(node)


FAKE_DECISION = """
import os, sys, time, types, runpy
sys.path[:0] = {path!r}
fake = types.ModuleType("anyscale_core.decision_ros")
def main():
    with open({log!r}, "a") as f:
        f.write(f"node {{os.getpid()}} {{os.getppid()}} {{' '.join(sys.argv[1:])}} "
                f"{{os.environ.get('OPENBLAS_NUM_THREADS')}}\\n")
    try:
        while True:
            time.sleep(0.02)
    except KeyboardInterrupt:
        return 0
fake.main = main
sys.modules["anyscale_core.decision_ros"] = fake
sys.argv = [{script!r}] + sys.argv[1:]
runpy.run_path({script!r}, run_name="__main__")
"""


@pytest.mark.parametrize("flag", [["--warm-restart"], []])
def test_the_decision_node_keeps_a_warm_standby_when_asked(tmp_path, cleanup, flag):
    """The decision node's script with the flag robot.launch gives it when respawn:=true (its
    rospy part replaced: what is tested is the script's use of the flag)."""
    log = tmp_path / "node.log"
    wrapper = tmp_path / "decision.py"
    wrapper.write_text(FAKE_DECISION.format(path=sys.path, log=str(log),
                                            script=os.path.abspath(DECISION_NODE)))
    env = {k: v for k, v in os.environ.items() if k != "OPENBLAS_NUM_THREADS"}
    proc = subprocess.Popen([sys.executable, str(wrapper), "__name:=anyscale_decision"] + flag,
                            env=env, preexec_fn=sigint_as_in_a_terminal)
    cleanup.append(proc)
    line = wait_for_nodes(log, 1)
    text = log.read_text().split()
    assert text[3:] == ["__name:=anyscale_decision", "1" if flag else "None"]
    node = line[0][0]
    if not flag:                                  # as before: the node is the process itself
        assert node == proc.pid
        proc.send_signal(signal.SIGINT)
        assert proc.wait(timeout=10) == 0
        return
    assert node != proc.pid
    os.kill(node, signal.SIGKILL)
    assert wait_for_nodes(log, 2)[1][1] == proc.pid
    proc.send_signal(signal.SIGINT)
    assert proc.wait(timeout=10) == 0
