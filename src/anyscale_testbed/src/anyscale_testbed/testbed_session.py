"""roslaunch files run on the two scales of the test bed: in the network namespaces with the
robot's master reached over the veth (TwoScaleTestbed), or, where root, namespaces or cgroups
are missing, both on this machine's loopback, unshaped (LoopbackBed). One interface for both,
so the demo script and the system tests start the same launch files either way."""
import os
import subprocess
import threading
from typing import Callable, Dict, IO, List, Optional

from .testbed_teardown import signals_deferred, stop_process_groups
from .two_scale_testbed import (ScaleEnd, TwoScaleLayout, TwoScaleTestbed, report_leftovers,
                                start_session)

MASTER_PORT = 11311


def agent_binary() -> Optional[str]:
    """The built anyscale_agent of the sourced workspace, or None (not built, not sourced)."""
    try:
        from catkin.find_in_workspaces import find_in_workspaces
    except ImportError:
        return None
    found = find_in_workspaces(["libexec"], project="anyscale_agent_cpp", path="anyscale_agent",
                               first_matching_workspace_only=True)
    return found[0] if found else None


def ros_env(base: Dict[str, str], master_address: str, own_address: Optional[str],
            port: int, log_dir: str) -> Dict[str, str]:
    """The environment of a scale's processes: the robot's master, this scale's own address
    (what other scales connect back to), and the run's log directory."""
    env = dict(base)
    env["ROS_MASTER_URI"] = f"http://{master_address}:{port}"
    env.pop("ROS_HOSTNAME", None)
    env.pop("ROS_IP", None)
    if own_address == "localhost":
        env["ROS_HOSTNAME"] = "localhost"
    elif own_address:
        env["ROS_IP"] = own_address
    env["ROS_LOG_DIR"] = log_dir
    # Nodes with a ROS_HOME of their own keep the user's ~/.ros untouched by test-bed runs.
    env["ROS_HOME"] = os.path.dirname(log_dir.rstrip("/")) or log_dir
    return env


class LoopbackBed:
    """Both scales as plain processes on this machine: no namespaces, no shaping, no quotas.
    The link cannot be shaped or cut here; callers must say so rather than pretend."""

    shaped = False

    def __init__(self):
        self.processes: List[subprocess.Popen] = []

    def __enter__(self):
        return self

    def __exit__(self, exc_type, exc, tb):
        report_leftovers(self.teardown(), block_failed=exc_type is not None)
        return False

    def address(self, scale: str) -> str:
        return "localhost"

    def uplink_interface(self, scale: str) -> str:
        return ""               # loopback: no interface of the link to watch

    def start(self, scale, argv, env=None, log_path=None, cpu_quota=True, stdout=None, nice=0):
        # Loopback runs as the user, who may not raise a priority: `nice` is left out here.
        proc = start_session(argv, env, log_path, stdout)
        self.processes.append(proc)
        return proc

    def teardown(self, grace_s: float = 10.0) -> List[str]:
        """Ends every process; returns those that did not end, in words (never raises)."""
        with signals_deferred():
            left = stop_process_groups(self.processes, grace_s)
            self.processes.clear()
        return left


class NamespaceBed(TwoScaleTestbed):
    shaped = True

    def address(self, scale: str) -> str:
        return self.end(scale).address

    def uplink_interface(self, scale: str) -> str:
        """The scale's end of the veth: its carrier goes when the link is taken down."""
        return self.end(scale).interface

    def netns_link(self, scale: str) -> str:
        """What /proc/PID/ns/net reads for the scale's processes: the inode `ip netns` keeps.
        All scales share one PID namespace, so a process's scale can be told from /proc."""
        return f"net:[{os.stat('/var/run/netns/' + self.end(scale).namespace).st_ino}]"


def layout_with_cpu(robot_cores: float, laptop_cores: float,
                    base: TwoScaleLayout = TwoScaleLayout()) -> TwoScaleLayout:
    def with_cores(end: ScaleEnd, cores: float) -> ScaleEnd:
        return ScaleEnd(end.scale, end.namespace, end.interface, end.address, cores)
    return TwoScaleLayout(with_cores(base.robot, robot_cores),
                          with_cores(base.laptop, laptop_cores), base.prefix_len)


class TestbedSession:
    """Starts roslaunch files on the scales of a bed and keeps their logs in run_dir/logs."""

    __test__ = False    # not a pytest class, whatever its name says

    def __init__(self, bed, run_dir: str, port: int = MASTER_PORT):
        self.bed = bed
        self.run_dir = run_dir
        self.log_dir = os.path.join(run_dir, "logs")
        self.port = port
        os.makedirs(self.log_dir, exist_ok=True)

    def env(self, scale: str) -> Dict[str, str]:
        return ros_env(os.environ, self.bed.address("robot"), self.bed.address(scale),
                       self.port, self.log_dir)

    def roslaunch(self, scale: str, name: str, launch_args: List[str], cpu_quota: bool = True,
                  wait_for_master: bool = True, echo: Optional[Callable[[str], None]] = None,
                  nice: int = 0) -> subprocess.Popen:
        """`roslaunch` on a scale; the first one (wait_for_master=False) brings up the master.
        Output goes to logs/NAME.log; with `echo`, each line is also handed to it."""
        # The port comes from ROS_MASTER_URI: `-p` would make roslaunch put the master on this
        # scale's own address.
        argv = (["roslaunch", "--wait"] if wait_for_master else ["roslaunch"]) + list(launch_args)
        log_path = os.path.join(self.log_dir, f"{name}.log")
        if echo is None:
            return self.bed.start(scale, argv, self.env(scale), log_path, cpu_quota, nice=nice)
        proc = self.bed.start(scale, argv, self.env(scale), None, cpu_quota,
                              stdout=subprocess.PIPE, nice=nice)
        threading.Thread(target=copy_lines, args=(proc.stdout, log_path, echo),
                         daemon=True).start()
        return proc


def copy_lines(stream: IO[bytes], log_path: str, echo: Callable[[str], None]):
    with open(log_path, "ab") as log:
        for raw in iter(stream.readline, b""):
            log.write(raw)
            log.flush()
            echo(raw.decode(errors="replace").rstrip("\n"))
