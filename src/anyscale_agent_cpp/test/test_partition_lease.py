"""pytest: a lease ends a remote node while the link to the master is down (network partition
between two network namespaces joined by a veth pair). Needs root for `ip netns`; skips with
the reason otherwise. Needs the workspace built and its devel/setup.bash sourced."""
import os
import shutil
import subprocess
import time

import psutil
import pytest

NS_MASTER = "asagt%d_m" % os.getpid()
NS_REMOTE = "asagt%d_r" % os.getpid()
VETH_M, VETH_R = "asm%d" % os.getpid(), "asr%d" % os.getpid()
IP_M, IP_R = "10.213.77.1", "10.213.77.2"
MASTER_URI = "http://%s:11311" % IP_M
HERE = os.path.dirname(os.path.abspath(__file__))
MODEL = os.path.join(HERE, "config", "test_model.yaml")


def _agent_binary():
    try:
        from catkin.find_in_workspaces import find_in_workspaces
    except ImportError:
        return None
    found = find_in_workspaces(["libexec"], project="anyscale_agent_cpp", path="anyscale_agent",
                               first_matching_workspace_only=True)
    return found[0] if found else None


def _why_skip():
    if os.geteuid() != 0:
        return "needs root to create network namespaces (ip netns)"
    if not shutil.which("ip"):
        return "needs iproute2 (ip)"
    if not _agent_binary():
        return "anyscale_agent is not built or the workspace is not sourced"
    return None


def sh(*args):
    subprocess.run(args, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)


def in_ns(ns, ip, argv, **kw):
    env = dict(os.environ, ROS_MASTER_URI=MASTER_URI, ROS_IP=ip, ROS_HOME="/tmp/%s_home" % ns)
    env.pop("ROS_HOSTNAME", None)
    return subprocess.Popen(["ip", "netns", "exec", ns] + argv, env=env, **kw)


def call(service, srv_type, request, timeout=20):
    """rosservice call from the master's namespace; returns its YAML output."""
    out = in_ns(NS_MASTER, IP_M, ["rosservice", "call", "--wait", service, request],
                stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    text, _ = out.communicate(timeout=timeout)
    return text


@pytest.fixture
def two_namespaces():
    why = _why_skip()
    if why:
        pytest.skip(why)
    procs = []
    try:
        sh("ip", "netns", "add", NS_MASTER)
        sh("ip", "netns", "add", NS_REMOTE)
        sh("ip", "link", "add", VETH_M, "type", "veth", "peer", "name", VETH_R)
        sh("ip", "link", "set", VETH_M, "netns", NS_MASTER)
        sh("ip", "link", "set", VETH_R, "netns", NS_REMOTE)
        for ns, dev, ip in ((NS_MASTER, VETH_M, IP_M), (NS_REMOTE, VETH_R, IP_R)):
            sh("ip", "-n", ns, "addr", "add", ip + "/24", "dev", dev)
            sh("ip", "-n", ns, "link", "set", dev, "up")
            sh("ip", "-n", ns, "link", "set", "lo", "up")
        devnull = subprocess.DEVNULL
        procs.append(in_ns(NS_MASTER, IP_M, ["roscore"], stdout=devnull, stderr=devnull))
        check = ["/usr/bin/python3", "-c", "import rosgraph, sys; sys.exit(not rosgraph.is_master_online())"]
        deadline = time.monotonic() + 30.0
        while in_ns(NS_MASTER, IP_M, check).wait() != 0:
            assert time.monotonic() < deadline, "roscore did not come up in the master namespace"
            time.sleep(0.3)
        procs.append(in_ns(NS_REMOTE, IP_R, [_agent_binary(), "__name:=anyscale_agent_laptop", "_scale:=laptop",
                                             "_master_scale:=robot", "_model:=" + MODEL,
                                             "_sigint_timeout_s:=2.0"], stdout=devnull, stderr=devnull))
        yield procs
    finally:
        for p in reversed(procs):
            if p.poll() is None:
                p.send_signal(2)
                try:
                    p.wait(timeout=20)
                except subprocess.TimeoutExpired:
                    p.kill()
                    p.wait()
        subprocess.run(["ip", "netns", "del", NS_MASTER], stderr=subprocess.DEVNULL)
        subprocess.run(["ip", "netns", "del", NS_REMOTE], stderr=subprocess.DEVNULL)
        for ns in (NS_MASTER, NS_REMOTE):
            shutil.rmtree("/tmp/%s_home" % ns, ignore_errors=True)


def alive(pid):
    try:
        return psutil.Process(pid).status() != psutil.STATUS_ZOMBIE
    except psutil.NoSuchProcess:
        return False


def test_lease_stops_node_during_partition(two_namespaces):
    agent = two_namespaces[1]
    reply = call("/anyscale/laptop/start_node", "anyscale_msgs/StartNode",
                 "{node: talker_cpp, param_overrides: [], lease_s: 4.0}", timeout=60)
    assert "success: True" in reply, reply
    pid = int(reply.split("pid:")[1].split()[0])
    assert alive(pid)
    # Partition: the remote scale can no longer reach the master (nor be reached).
    sh("ip", "-n", NS_REMOTE, "link", "set", VETH_R, "down")
    t0 = time.monotonic()
    while alive(pid) and time.monotonic() - t0 < 15.0:
        time.sleep(0.05)
    took = time.monotonic() - t0
    assert not alive(pid), "node still running %.1f s into the partition" % took
    assert took < 4.0 + 2.0 + 2.0, took  # lease, then at most SIGINT timeout + margin
    assert agent.poll() is None, "the agent itself must survive the partition"
    sh("ip", "-n", NS_REMOTE, "link", "set", VETH_R, "up")
    listed = call("/anyscale/laptop/list_nodes", "anyscale_msgs/ListNodes", "{}", timeout=60)
    assert "state: 5" in listed, listed  # LEASE_EXPIRED
