"""The two-scale test bed on one Linux machine: network namespaces `robot` and `laptop` joined
by a veth pair, the link shaped with tc tbf and taken down/up, each scale's CPU held by a cgroup
v1 quota. Every command is an argv list (no shell); teardown is idempotent and leaves no
namespace, qdisc or cgroup behind.

iproute2 and the cgroup filesystem are driven directly rather than through a library: pyroute2
is not packaged for Debian's Python here, and these are a handful of well-known commands.
"""
from dataclasses import dataclass
import fcntl
import os
import signal
import subprocess
import time
from typing import Dict, List, Optional, Sequence

CGROUP_CPU_ROOT = "/sys/fs/cgroup/cpu"
CFS_PERIOD_US = 100_000


class TwoScaleError(RuntimeError):
    """A test-bed command failed; the message names the command and what it printed."""


@dataclass(frozen=True)
class ScaleEnd:
    scale: str             # robot, laptop
    namespace: str         # network namespace name
    interface: str         # its end of the veth pair
    address: str           # IPv4 address on the veth, without prefix
    cpu_cores: float       # cgroup quota in cores; 0 = no quota


@dataclass(frozen=True)
class TwoScaleLayout:
    robot: ScaleEnd = ScaleEnd("robot", "anyscale_robot", "asv_robot", "10.213.7.1", 0.0)
    laptop: ScaleEnd = ScaleEnd("laptop", "anyscale_laptop", "asv_laptop", "10.213.7.2", 0.0)
    prefix_len: int = 24

    @property
    def ends(self) -> Sequence[ScaleEnd]:
        return (self.robot, self.laptop)


def setup_commands(layout: TwoScaleLayout) -> List[List[str]]:
    r, l = layout.robot, layout.laptop
    cmds = [["ip", "netns", "add", r.namespace], ["ip", "netns", "add", l.namespace],
            ["ip", "link", "add", r.interface, "type", "veth", "peer", "name", l.interface],
            ["ip", "link", "set", r.interface, "netns", r.namespace],
            ["ip", "link", "set", l.interface, "netns", l.namespace]]
    for end in layout.ends:
        cmds += [["ip", "-n", end.namespace, "addr", "add",
                  f"{end.address}/{layout.prefix_len}", "dev", end.interface],
                 ["ip", "-n", end.namespace, "link", "set", "lo", "up"],
                 ["ip", "-n", end.namespace, "link", "set", end.interface, "up"]]
    return cmds


def shape_commands(layout: TwoScaleLayout, mbps: float,
                   burst_kbit: int = 32) -> List[List[str]]:
    """A token bucket of `mbps` on both ends (both directions); tbf needs a positive rate."""
    kbit = max(1, int(round(mbps * 1000)))
    return [["ip", "netns", "exec", end.namespace, "tc", "qdisc", "replace", "dev",
             end.interface, "root", "tbf", "rate", f"{kbit}kbit", "burst", f"{burst_kbit}kbit",
             "latency", "50ms"] for end in layout.ends]


def link_commands(layout: TwoScaleLayout, up: bool) -> List[List[str]]:
    return [["ip", "-n", end.namespace, "link", "set", end.interface, "up" if up else "down"]
            for end in layout.ends]


def run(argv: List[str], check: bool = True) -> subprocess.CompletedProcess:
    done = subprocess.run(argv, capture_output=True, text=True)
    if check and done.returncode != 0:
        raise TwoScaleError(f"`{' '.join(argv)}` failed ({done.returncode}): "
                           f"{(done.stderr or done.stdout).strip()}")
    return done


def namespace_exec(end: ScaleEnd, argv: List[str]) -> List[str]:
    """argv that runs a program inside the scale's network namespace. nsenter, not `ip netns
    exec`: the latter also remounts /sys for the namespace, which hides /sys/fs/cgroup from
    the program, and the agents read their CPU quota and usage there."""
    return ["nsenter", f"--net=/var/run/netns/{end.namespace}", "--"] + list(argv)


class CpuQuota:
    """A cgroup v1 CPU group holding a scale's processes at `cores` of CPU."""

    def __init__(self, name: str, cores: float, root: str = CGROUP_CPU_ROOT):
        self.path = os.path.join(root, name)
        self.cores = cores

    def create(self):
        os.makedirs(self.path, exist_ok=True)
        quota = int(self.cores * CFS_PERIOD_US) if self.cores > 0 else -1
        self._write("cpu.cfs_period_us", CFS_PERIOD_US)
        self._write("cpu.cfs_quota_us", quota)

    def add(self, pid: int):
        self._write("tasks", pid)

    def pids(self) -> List[int]:
        try:
            with open(os.path.join(self.path, "tasks")) as f:
                return [int(line) for line in f if line.strip()]
        except FileNotFoundError:
            return []

    def remove(self):
        """Moves leftover tasks to the parent group, then removes the group."""
        if not os.path.isdir(self.path):
            return
        parent_tasks = os.path.join(os.path.dirname(self.path), "tasks")
        for pid in self.pids():
            try:
                with open(parent_tasks, "w") as f:
                    f.write(str(pid))
            except OSError:
                pass        # already gone
        os.rmdir(self.path)

    def _write(self, name: str, value):
        with open(os.path.join(self.path, name), "w") as f:
            f.write(str(value))


def cgroup_available(root: str = CGROUP_CPU_ROOT) -> bool:
    return os.path.isfile(os.path.join(root, "cpu.cfs_quota_us")) and os.access(root, os.W_OK)


def missing_capabilities(need_cgroups: bool = True) -> List[str]:
    """What the test bed needs and this machine lacks, in words (empty = all there)."""
    missing = []
    if os.geteuid() != 0:
        missing.append("root (network namespaces, tc and cgroups need it)")
    if run(["ip", "netns", "list"], check=False).returncode != 0:
        missing.append("`ip netns` (iproute2 with network-namespace support)")
    if need_cgroups and not cgroup_available():
        missing.append(f"a writable cgroup v1 CPU hierarchy at {CGROUP_CPU_ROOT}")
    return missing


def claim_layout(layout: TwoScaleLayout, lock_dir: str = "/run"):
    """An exclusive lock on the layout's namespace names, held while the bed exists: a second
    run would otherwise tear down the first one's namespaces as its leftovers."""
    path = os.path.join(lock_dir, f"anyscale_testbed_{layout.robot.namespace}.lock")
    f = open(path, "a+")
    try:
        fcntl.flock(f, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        f.close()
        raise TwoScaleError(f"another test bed is running with namespace "
                            f"{layout.robot.namespace} (lock {path}); wait for it to end") from None
    return f


class TwoScaleTestbed:
    """Context manager: builds the namespaces, link and quotas; tears all of it down on exit,
    also after an exception. Processes are started with `start(scale, argv, ...)` and ended
    (SIGINT, then SIGKILL) on teardown."""

    def __init__(self, layout: TwoScaleLayout = TwoScaleLayout(), cgroup_prefix: str = "anyscale"):
        self.layout = layout
        self.quotas: Dict[str, CpuQuota] = {
            end.scale: CpuQuota(f"{cgroup_prefix}_{end.scale}", end.cpu_cores)
            for end in layout.ends if end.cpu_cores > 0}
        self.processes: List[subprocess.Popen] = []

    def __enter__(self) -> "TwoScaleTestbed":
        self._lock = claim_layout(self.layout)
        self.teardown()     # leftovers of an earlier run that was killed
        try:
            for argv in setup_commands(self.layout):
                run(argv)
            for quota in self.quotas.values():
                quota.create()
        except BaseException:
            self.teardown()
            raise
        return self

    def __exit__(self, *exc):
        try:
            self.teardown()
        finally:
            self._lock.close()

    def end(self, scale: str) -> ScaleEnd:
        return next(e for e in self.layout.ends if e.scale == scale)

    def shape(self, mbps: float, burst_kbit: int = 32):
        for argv in shape_commands(self.layout, mbps, burst_kbit):
            run(argv)

    def set_link(self, up: bool):
        for argv in link_commands(self.layout, up):
            run(argv)

    def start(self, scale: str, argv: List[str], env: Optional[Dict[str, str]] = None,
              log_path: Optional[str] = None, cpu_quota: bool = True,
              stdout: Optional[int] = None) -> subprocess.Popen:
        """Starts argv inside the scale's namespace, in its own session, and in the scale's CPU
        group unless `cpu_quota` is False (the simulated world is not the robot's computer).
        Output goes to `log_path`, or to `stdout` (e.g. subprocess.PIPE), or nowhere."""
        quota = self.quotas.get(scale) if cpu_quota else None
        # The child joins the group before exec, so nothing it forks can escape the quota.
        join = (lambda: quota.add(os.getpid())) if quota else None
        proc = start_session(namespace_exec(self.end(scale), argv), env, log_path, stdout, join)
        self.processes.append(proc)
        return proc

    def teardown(self, grace_s: float = 5.0):
        self._stop_processes(grace_s)
        for end in self.layout.ends:
            # Whatever still runs in a namespace (started by others) ends with it.
            pids = run(["ip", "netns", "pids", end.namespace], check=False).stdout.split()
            for pid in pids:
                _signal_quietly(int(pid), signal.SIGKILL)
            run(["ip", "netns", "del", end.namespace], check=False)
        for quota in self.quotas.values():
            quota.remove()

    def _stop_processes(self, grace_s: float):
        stop_process_groups(self.processes, grace_s)
        self.processes.clear()


def start_session(argv: List[str], env: Optional[Dict[str, str]], log_path: Optional[str],
                  stdout: Optional[int] = None, preexec_fn=None) -> subprocess.Popen:
    """argv in a session of its own (signalled as a group), output to `log_path`, to `stdout`
    (e.g. subprocess.PIPE), or nowhere."""
    out = open(log_path, "ab") if log_path else (stdout or subprocess.DEVNULL)
    try:
        return subprocess.Popen(list(argv), env=env, stdout=out, stderr=subprocess.STDOUT,
                                start_new_session=True, preexec_fn=preexec_fn)
    finally:
        if log_path:
            out.close()


def stop_process_groups(processes: List[subprocess.Popen], grace_s: float):
    """SIGINT to every process group (roslaunch then stops its nodes), SIGKILL after grace_s."""
    for proc in processes:
        if proc.poll() is None:
            _signal_group(proc.pid, signal.SIGINT)
    deadline = time.monotonic() + grace_s
    for proc in processes:
        try:
            proc.wait(timeout=max(0.0, deadline - time.monotonic()))
        except subprocess.TimeoutExpired:
            _signal_group(proc.pid, signal.SIGKILL)
            proc.wait()


def _signal_group(pid: int, sig: int):
    try:
        os.killpg(pid, sig)
    except (ProcessLookupError, PermissionError):
        pass


def _signal_quietly(pid: int, sig: int):
    try:
        os.kill(pid, sig)
    except (ProcessLookupError, PermissionError):
        pass
