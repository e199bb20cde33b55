"""The two-scale test bed for real (root, network namespaces, tc, cgroup v1): traffic crosses
the veth, tbf limits it, link down cuts it, the CPU quota holds a busy loop, and teardown
leaves nothing behind, also after an error, after Ctrl-C and with processes that linger."""
import os
import signal
import subprocess
import sys
import threading
import time

import pytest

from anyscale_testbed.system_test_gate import NOT_RUN
from anyscale_testbed.testbed_teardown import is_alive
from anyscale_testbed.two_scale_testbed import (ScaleEnd, TwoScaleError, TwoScaleLayout,
                                                TwoScaleTestbed, missing_capabilities, run,
                                                WORLD_NICE, shape_commands)

import tcp_byte_counter

MISSING = missing_capabilities()
needs_testbed = pytest.mark.skipif(bool(MISSING), reason=NOT_RUN + "this machine lacks " +
                                   "; ".join(MISSING))

LAYOUT = TwoScaleLayout(
    robot=ScaleEnd("robot", "anyscale_t_robot", "ast_robot", "10.213.9.1", 0.4),
    laptop=ScaleEnd("laptop", "anyscale_t_laptop", "ast_laptop", "10.213.9.2", 0.0))

PORT = 7700


def send_bytes(bed, size):
    """Sends size bytes laptop -> robot; returns (bytes the robot received, seconds)."""
    return tcp_byte_counter.send_bytes(bed.end("laptop").namespace, bed.end("robot").address,
                                       PORT, size)


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
        server = tcp_byte_counter.start_listener(bed, "robot", LAYOUT.robot.address, PORT,
                                                 tmp_path / "server.log")
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
def test_the_world_runs_outside_the_quota_above_the_scales_only_when_asked():
    with TwoScaleTestbed(LAYOUT, cgroup_prefix="anyscale_t") as bed:
        world = bed.start("robot", [sys.executable, "-c", "import time; time.sleep(30)"],
                          cpu_quota=False, nice=WORLD_NICE)
        outside = bed.start("laptop", [sys.executable, "-c", "import time; time.sleep(30)"],
                            cpu_quota=False)
        scale = bed.start("robot", [sys.executable, "-c", "import time; time.sleep(30)"])
        time.sleep(0.3)
        assert world.pid not in bed.quotas["robot"].pids()
        assert os.getpriority(os.PRIO_PROCESS, world.pid) == WORLD_NICE
        ours = os.getpriority(os.PRIO_PROCESS, 0)
        assert os.getpriority(os.PRIO_PROCESS, scale.pid) == ours
        assert os.getpriority(os.PRIO_PROCESS, outside.pid) == ours


# Ignores SIGINT, as does its `sleep` (an ignored signal stays ignored across exec); prints the
# sleep's pid and waits for it.
LINGERER = """
import signal, subprocess
signal.signal(signal.SIGINT, signal.SIG_IGN)
child = subprocess.Popen(["sleep", "120"])
print(child.pid, flush=True)
child.wait()
"""


def start_lingerer(start, *args, **kw):
    """A lingering process pair through `start`; returns (the python process, its sleep's pid)."""
    proc = start(*args, [sys.executable, "-c", LINGERER], stdout=subprocess.PIPE, **kw)
    return proc, int(proc.stdout.readline())


def nothing_left(pids=()):
    """What of the test bed is still there, in words (empty: nothing)."""
    left = [ns for ns in namespaces().split() if ns.startswith("anyscale_t_")]
    left += [f"veth {end.interface}" for end in LAYOUT.ends
             if run(["ip", "link", "show", end.interface], check=False).returncode == 0]
    left += [f"cgroup {d}" for d in os.listdir("/sys/fs/cgroup/cpu")
             if d.startswith("anyscale_t_")]
    left += [f"pid {pid}" for pid in pids if is_alive(pid)]
    return left


@needs_testbed
def test_teardown_after_an_error_leaves_nothing():
    with pytest.raises(RuntimeError, match="boom"):
        with TwoScaleTestbed(LAYOUT, cgroup_prefix="anyscale_t") as bed:
            child = bed.start("laptop", ["sleep", "60"])
            lingerer, its_sleep = start_lingerer(bed.start, "robot")
            raise RuntimeError("boom")
    assert child.poll() is not None
    assert nothing_left([lingerer.pid, its_sleep]) == []


@needs_testbed
def test_a_process_lingering_in_the_cgroup_is_killed_and_the_cgroup_removed():
    """Started by someone else, outside the namespaces, but in the robot's CPU group: the old
    teardown moved it to the parent group, where it ran on."""
    with TwoScaleTestbed(LAYOUT, cgroup_prefix="anyscale_t") as bed:
        quota = bed.quotas["robot"]
        lingerer, its_sleep = start_lingerer(
            subprocess.Popen, start_new_session=True, preexec_fn=lambda: quota.add(os.getpid()))
        assert {lingerer.pid, its_sleep} <= set(quota.pids())
    lingerer.wait(timeout=5)
    assert nothing_left([its_sleep]) == []


@needs_testbed
def test_a_cgroup_busy_for_a_moment_is_removed_once_it_is_free():
    """rmdir fails with EBUSY while the group is held (here by a child group, as by a process
    still exiting after SIGKILL); the teardown retries instead of raising OSError."""
    with TwoScaleTestbed(LAYOUT, cgroup_prefix="anyscale_t") as bed:
        holder = os.path.join(bed.quotas["robot"].path, "held")
        os.mkdir(holder)
        threading.Timer(1.0, os.rmdir, args=[holder]).start()
    assert nothing_left() == []


@needs_testbed
def test_what_teardown_cannot_remove_is_one_clear_line():
    holder = None
    try:
        with pytest.raises(TwoScaleError) as raised:
            with TwoScaleTestbed(LAYOUT, cgroup_prefix="anyscale_t") as bed:
                holder = os.path.join(bed.quotas["robot"].path, "held")
                os.mkdir(holder)        # never freed during the teardown
        message = str(raised.value)
        assert message.startswith("teardown left behind: cgroup ")
        assert "anyscale_t_robot" in message and "\n" not in message
        assert "anyscale_t_" not in namespaces()
    finally:
        if holder:
            os.rmdir(holder)
            os.rmdir(os.path.dirname(holder))


@needs_testbed
def test_teardown_twice_is_fine():
    with TwoScaleTestbed(LAYOUT, cgroup_prefix="anyscale_t") as bed:
        bed.start("laptop", ["sleep", "60"])
        assert bed.teardown() == []
        assert bed.teardown() == []
    assert bed.teardown() == []
    assert nothing_left() == []


# A script that holds a test bed until it is interrupted, as scripts/run_testbed.py does.
HOLDER = f"""
import subprocess, sys, time
from anyscale_testbed.two_scale_testbed import ScaleEnd, TwoScaleLayout, TwoScaleTestbed
LAYOUT = {LAYOUT!r}
try:
    with TwoScaleTestbed(LAYOUT, cgroup_prefix="anyscale_t") as bed:
        bed.start("laptop", ["sleep", "120"])
        proc = bed.start("robot", [sys.executable, "-c", {LINGERER!r}], stdout=subprocess.PIPE)
        print(proc.pid, int(proc.stdout.readline()), flush=True)
        time.sleep(120)
except KeyboardInterrupt:
    print("interrupted", flush=True)
    sys.exit(130)
"""


@needs_testbed
@pytest.mark.parametrize("interrupts", [1, 2], ids=["ctrl-c", "ctrl-c-again-during-teardown"])
def test_ctrl_c_leaves_nothing_behind(interrupts):
    # SIGINT as a terminal gives it, to the script and the processes it starts: a test run
    # started in the background of a shell ignores SIGINT, and they would inherit that.
    script = subprocess.Popen([sys.executable, "-c", HOLDER], stdout=subprocess.PIPE,
                              stderr=subprocess.PIPE, text=True,
                              env=dict(os.environ, PYTHONPATH=os.pathsep.join(sys.path)),
                              preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    try:
        pids = [int(p) for p in script.stdout.readline().split()]
        assert len(pids) == 2, script.stderr.read()
        script.send_signal(signal.SIGINT)
        if interrupts == 2:
            time.sleep(1.0)     # the lingerer ignores SIGINT: the teardown waits out its grace
            script.send_signal(signal.SIGINT)
        out, err = script.communicate(timeout=30)
    finally:
        script.kill()
    assert script.returncode == 130 and "interrupted" in out
    assert "Traceback" not in err, err
    assert nothing_left(pids) == []


@needs_testbed
def test_a_second_setup_cleans_leftovers_of_a_killed_run():
    run(["ip", "netns", "add", LAYOUT.robot.namespace])          # a leftover namespace
    with TwoScaleTestbed(LAYOUT, cgroup_prefix="anyscale_t"):
        assert LAYOUT.laptop.namespace in namespaces()
    assert "anyscale_t_" not in namespaces()


@needs_testbed
def test_a_veth_left_outside_the_namespaces_is_removed():
    """A setup that failed before moving the veth's ends into the namespaces left them here."""
    run(["ip", "link", "add", LAYOUT.robot.interface, "type", "veth", "peer", "name",
         LAYOUT.laptop.interface])
    with TwoScaleTestbed(LAYOUT, cgroup_prefix="anyscale_t"):
        pass
    assert nothing_left() == []
