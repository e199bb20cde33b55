"""pytest: a lease ends a remote node while the link to the master is down (network partition
between two network namespaces joined by a veth pair). Needs root for `ip netns`; skips with
the reason otherwise. Needs the workspace built and its devel/setup.bash sourced."""
import os
import shutil
import subprocess
import time

import psutil
import pytest

from anyscale_testbed.system_test_gate import NOT_RUN
from anyscale_testbed.testbed_session import agent_binary
from anyscale_testbed.two_scale_testbed import (TwoScaleTestbed, missing_capabilities,
                                                namespace_exec, process_layout)

PID = os.getpid()
LAYOUT = process_layout("asagt", "10.213.77", PID)
MASTER_URI = "http://%s:11311" % LAYOUT.robot.address
HERE = os.path.dirname(os.path.abspath(__file__))
# the agent package's own test model (this test moved here from anyscale_agent_cpp/test)
MODEL = os.path.join(HERE, "..", "..", "..", "anyscale_agent_cpp", "test", "config",
                     "test_model.yaml")


def _why_skip():
    missing = missing_capabilities(need_cgroups=False)
    if missing:
        return NOT_RUN + "this machine lacks " + "; ".join(missing)
    if not agent_binary():
        return NOT_RUN + "anyscale_agent is not built or the workspace is not sourced"
    return None


def ros_env(end):
    env = dict(os.environ, ROS_MASTER_URI=MASTER_URI, ROS_IP=end.address,
               ROS_HOME="/tmp/%s_home" % end.namespace)
    env.pop("ROS_HOSTNAME", None)
    return env


def call(service, srv_type, request, timeout=20):
    """rosservice call from the master's namespace; returns its YAML output."""
    out = subprocess.run(namespace_exec(LAYOUT.robot, ["rosservice", "call", "--wait", service,
                                                       request]),
                         env=ros_env(LAYOUT.robot), capture_output=True, text=True,
                         timeout=timeout)
    return out.stdout + out.stderr


@pytest.fixture
def two_namespaces():
    why = _why_skip()
    if why:
        pytest.skip(why)
    # The shared test bed builds the namespaces and veth and tears everything down, processes
    # included, whatever happens in the test.
    with TwoScaleTestbed(LAYOUT, cgroup_prefix="asagt%d" % PID) as bed:
        bed.start("robot", ["roscore"], env=ros_env(LAYOUT.robot))
        check = ["/usr/bin/python3", "-c",
                 "import rosgraph, sys; sys.exit(not rosgraph.is_master_online())"]
        deadline = time.monotonic() + 30.0
        while subprocess.run(namespace_exec(LAYOUT.robot, check),
                             env=ros_env(LAYOUT.robot)).returncode != 0:
            assert time.monotonic() < deadline, "roscore did not come up in the master namespace"
            time.sleep(0.3)
        agent = bed.start("laptop", [agent_binary(), "__name:=anyscale_agent_laptop",
                                     "_scale:=laptop", "_master_scale:=robot", "_model:=" + MODEL,
                                     "_sigint_timeout_s:=2.0"], env=ros_env(LAYOUT.laptop))
        yield bed, agent
    for end in LAYOUT.ends:
        shutil.rmtree("/tmp/%s_home" % end.namespace, ignore_errors=True)


def alive(pid):
    try:
        return psutil.Process(pid).status() != psutil.STATUS_ZOMBIE
    except psutil.NoSuchProcess:
        return False


def test_lease_stops_node_during_partition(two_namespaces):
    bed, agent = two_namespaces
    reply = call("/anyscale/laptop/start_node", "anyscale_msgs/StartNode",
                 "{node: talker_cpp, param_overrides: [], lease_s: 4.0}", timeout=60)
    assert "success: True" in reply, reply
    pid = int(reply.split("pid:")[1].split()[0])
    assert alive(pid)
    # Partition: the remote scale can no longer reach the master (nor be reached).
    bed.set_link(False)
    t0 = time.monotonic()
    while alive(pid) and time.monotonic() - t0 < 15.0:
        time.sleep(0.05)
    took = time.monotonic() - t0
    assert not alive(pid), "node still running %.1f s into the partition" % took
    assert took < 4.0 + 2.0 + 2.0, took  # lease, then at most SIGINT timeout + margin
    assert agent.poll() is None, "the agent itself must survive the partition"
    bed.set_link(True)
    listed = call("/anyscale/laptop/list_nodes", "anyscale_msgs/ListNodes", "{}", timeout=60)
    assert "state: 5" in listed, listed  # LEASE_EXPIRED
