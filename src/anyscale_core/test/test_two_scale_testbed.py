"""The two-scale test bed for real (root, network namespaces, tc, cgroup v1): traffic crosses
the veth, tbf limits it, link down cuts it, the CPU quota holds a busy loop, and teardown
leaves nothing behind, also after an error."""
import os
import subprocess
import sys
import time

import pytest

from anyscale_core.two_scale_testbed import (ScaleEnd, TwoScaleLayout, TwoScaleTestbed,
                                             missing_capabilities, run, shape_commands)

MISSING = missing_capabilities()
needs_testbed = pytest.mark.skipif(bool(MISSING), reason="the test bed needs " +
                                   "; ".join(MISSING))

LAYOUT = TwoScaleLayout(
    robot=ScaleEnd("robot", "anyscale_t_robot", "ast_robot", "10.213.9.1", 0.4),
    laptop=ScaleEnd("laptop", "anyscale_t_laptop", "ast_laptop", "10.213.9.2", 0.0))

SERVER = """
import socket, sys
s = socket.socket(); s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
s.bind((sys.argv[1], 7700)); s.listen(4); print("ready", flush=True)
while True:
    c, _ = s.accept(); n = 0
    while True:
        b = c.recv(65536)
        if not b: break
        n += len(b)
    c.sendall(str(n).encode()); c.close()
"""

CLIENT = """
import socket, sys, time
t = time.monotonic(); s = socket.create_connection((sys.argv[1], 7700), timeout=30)
s.sendall(b"x" * int(sys.argv[2])); s.shutdown(socket.SHUT_WR)
print(s.recv(64).decode(), time.monotonic() - t)
"""


def send_bytes(bed, size):
    """Sends size bytes laptop -> robot; returns (bytes the robot received, seconds)."""
    done = run(["ip", "netns", "exec", bed.end("laptop").namespace, sys.executable, "-c", CLIENT,
                bed.end("robot").address, str(size)], check=False)
    if done.returncode != 0:
        return None, None
    received, seconds = done.stdout.split()
    return int(received), float(seconds)


def namespaces():
    return run(["ip", "netns", "list"]).stdout


def test_shape_commands_are_argv_lists():
    cmds = shape_commands(LAYOUT, 2.5)
    assert cmds[0][-8:] == ["root", "tbf", "rate", "2500kbit", "burst", "32kbit", "latency",
                            "50ms"]
    assert all(isinstance(a, str) for cmd in cmds for a in cmd)


@needs_testbed
def test_traffic_crosses_a_shaped_link_and_stops_when_it_is_down(tmp_path):
    with TwoScaleTestbed(LAYOUT, cgroup_prefix="anyscale_t") as bed:
        server = bed.start("robot", [sys.executable, "-u", "-c", SERVER, LAYOUT.robot.address],
                           log_path=str(tmp_path / "server.log"))
        for _ in range(50):
            if "ready" in (tmp_path / "server.log").read_text():
                break
            time.sleep(0.1)
        assert send_bytes(bed, 100_000)[0] == 100_000
        bed.shape(1.0)
        received, seconds = send_bytes(bed, 500_000)        # 4 Mbit at 1 Mbit/s
        assert received == 500_000 and seconds > 2.0
        bed.set_link(False)
        assert send_bytes(bed, 1000) == (None, None)
        bed.set_link(True)
        bed.shape(50.0)
        assert send_bytes(bed, 1000)[0] == 1000
        assert server.poll() is None
    assert "anyscale_t_" not in namespaces()
    assert server.poll() is not None


@needs_testbed
def test_cpu_quota_holds_a_busy_loop():
    with TwoScaleTestbed(LAYOUT, cgroup_prefix="anyscale_t") as bed:
        busy = bed.start("robot", [sys.executable, "-c", "while True: pass"])
        quota_dir = bed.quotas["robot"].path
        assert busy.pid in bed.quotas["robot"].pids()
        ticks = os.sysconf("SC_CLK_TCK")

        def cpu_seconds():
            fields = open(f"/proc/{busy.pid}/stat").read().rsplit(")", 1)[1].split()
            return (int(fields[11]) + int(fields[12])) / ticks

        time.sleep(0.5)
        c0, t0 = cpu_seconds(), time.monotonic()
        time.sleep(2.0)
        share = (cpu_seconds() - c0) / (time.monotonic() - t0)
        assert share < 0.6                                   # held near 0.4 of a core
    assert not os.path.exists(quota_dir)
    assert busy.poll() is not None


@needs_testbed
def test_teardown_after_an_error_leaves_nothing():
    with pytest.raises(RuntimeError, match="boom"):
        with TwoScaleTestbed(LAYOUT, cgroup_prefix="anyscale_t") as bed:
            child = bed.start("laptop", ["sleep", "60"])
            raise RuntimeError("boom")
    assert "anyscale_t_" not in namespaces()
    assert child.poll() is not None
    assert not os.path.exists(bed.quotas["robot"].path)


@needs_testbed
def test_a_second_setup_cleans_leftovers_of_a_killed_run():
    run(["ip", "netns", "add", LAYOUT.robot.namespace])          # a leftover namespace
    with TwoScaleTestbed(LAYOUT, cgroup_prefix="anyscale_t"):
        assert LAYOUT.laptop.namespace in namespaces()
    assert "anyscale_t_" not in namespaces()
