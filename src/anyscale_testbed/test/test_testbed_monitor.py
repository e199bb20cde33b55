"""The test-bed monitor's /proc census: a node's live processes of this ROS system only, and a
warm standby is no instance until it is started; a raw message's header stamp."""
import io
import os
import signal
import subprocess
import sys

from anyscale_core.polling import wait_for

import rospy
from sensor_msgs.msg import JointState

from anyscale_testbed.testbed_monitor_ros import header_stamp, node_processes

STANDBY = os.path.join(os.path.dirname(__file__), "..", "..", "anyscale_agent_cpp", "scripts",
                       "python_standby")
MASTER = "http://census-test-%d:11311" % os.getpid()
# census_node on the master scale, census_node__laptop on a remote one: one node.
NODE = {"census_node": "census_node", "census_node__laptop": "census_node"}


def spawn(args, master=MASTER, **kw):
    return subprocess.Popen(args, env=dict(os.environ, ROS_MASTER_URI=master),
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, **kw)


def test_counts_processes_of_this_master_by_their_node_name(tmp_path):
    sleeper = [sys.executable, "-c", "import time; time.sleep(30)"]
    ours = spawn(sleeper + ["__name:=census_node"])
    remote = spawn(sleeper + ["__name:=census_node__laptop"])
    other_system = spawn(sleeper + ["__name:=census_node"], master="http://elsewhere:11311")
    try:
        assert wait_for(lambda: len(node_processes(NODE, MASTER)["census_node"]) == 2)
        assert node_processes(NODE, MASTER)["census_node"] == \
            [os.readlink(f"/proc/{p.pid}/ns/net") for p in (ours, remote)]
        assert node_processes({"other": "other"}, MASTER) == {"other": []}
    finally:
        for p in (ours, remote, other_system):
            p.kill()
            p.wait()
    assert node_processes(NODE, MASTER)["census_node"] == []


FORKER = """
import ctypes, os, sys, time
if os.fork() != 0 and sys.argv[1] == "standby":
    ctypes.CDLL(None).prctl(15, ctypes.c_char_p(b"standby:census"), 0, 0, 0)
time.sleep(30)
"""


def forked(kind):
    """A process of census_node that forks once: `copy` as an agent does before its exec, or
    `standby` as warm_restart does (the parent renames itself, the child is the node). Returns
    (parent, child pid)."""
    parent = spawn([sys.executable, "-c", FORKER, kind, "__name:=census_node"])
    assert wait_for(lambda: len(children(parent.pid)) == 1)
    return parent, children(parent.pid)[0]


def net(pid):
    return os.readlink(f"/proc/{pid}/ns/net")


def test_a_fork_not_yet_execd_is_no_second_instance_but_a_standbys_node_is_one():
    for kind in ("copy", "standby"):
        parent, child = forked(kind)
        try:
            if kind == "standby":
                assert wait_for(lambda: open(f"/proc/{parent.pid}/comm").read().startswith(
                    "standby:"))
            pids = {}
            assert node_processes(NODE, MASTER, pids=pids)["census_node"] == [net(parent.pid)]
            assert pids["census_node"] == [parent.pid if kind == "copy" else child], kind
        finally:
            os.kill(child, signal.SIGKILL)
            parent.kill()
            parent.wait()


def children(pid):
    with open(f"/proc/{pid}/task/{pid}/children") as f:
        return [int(c) for c in f.read().split()]


def test_a_warm_standby_counts_once_started(tmp_path):
    script = tmp_path / "node"
    script.write_text("#!/usr/bin/python3\nimport time\ntime.sleep(30)\n")
    # Exec'd like the agent does it (the script itself, not python3 SCRIPT): from the first
    # instant its comm is the standby's file name.
    standby = spawn([STANDBY, str(script), "__name:=census_warm"], stdin=subprocess.PIPE)
    try:
        assert node_processes({"census_warm": "census_warm"}, MASTER)["census_warm"] == []
        assert wait_for(lambda: open(f"/proc/{standby.pid}/comm").read().startswith("standby:"))
        assert node_processes({"census_warm": "census_warm"}, MASTER)["census_warm"] == []
        standby.stdin.write(b"start\n")
        standby.stdin.close()
        assert wait_for(lambda: len(node_processes({"census_warm": "census_warm"},
                                                   MASTER)["census_warm"]) == 1)
    finally:
        standby.kill()
        standby.wait()


def test_a_paused_process_is_no_live_instance_and_is_reported_paused():
    node = spawn([sys.executable, "-c", "import time; time.sleep(30)", "__name:=census_paused"])
    names = {"census_paused": "census_paused"}
    try:
        assert wait_for(lambda: len(node_processes(names, MASTER)["census_paused"]) == 1)
        node.send_signal(signal.SIGSTOP)
        paused = set()
        assert wait_for(lambda: node_processes(names, MASTER, paused)["census_paused"] == [])
        assert paused == {"census_paused"}
        node.send_signal(signal.SIGCONT)
        assert wait_for(lambda: len(node_processes(names, MASTER)["census_paused"]) == 1)
    finally:
        node.kill()
        node.wait()


def census_pids():
    pids = {}
    return node_processes(NODE, MASTER, pids=pids)["census_node"], pids


def test_pids_are_given_in_the_order_of_the_namespaces_and_a_paused_one_has_none():
    sleeper = [sys.executable, "-c", "import time; time.sleep(30)"]
    ours = spawn(sleeper + ["__name:=census_node"])
    remote = spawn(sleeper + ["__name:=census_node__laptop"])
    try:
        assert wait_for(lambda: len(census_pids()[0]) == 2)
        assert census_pids()[1] == {"census_node": [ours.pid, remote.pid]}
        remote.send_signal(signal.SIGSTOP)
        assert wait_for(lambda: len(census_pids()[0]) == 1)
        assert census_pids() == ([os.readlink(f"/proc/{ours.pid}/ns/net")],
                                 {"census_node": [ours.pid]})
    finally:
        for p in (ours, remote):
            p.kill()
            p.wait()


def test_reads_the_header_stamp_of_a_serialised_message():
    msg = JointState(name=["left"], position=[1.0])
    msg.header.seq, msg.header.stamp = 7, rospy.Time(1796187326, 250000000)
    buff = io.BytesIO()
    msg.serialize(buff)
    assert header_stamp(buff.getvalue()) == 1796187326.25
    assert header_stamp(b"\0" * 8) is None
