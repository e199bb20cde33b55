"""The two-scale test bed on one Linux machine: network namespaces `robot` and `laptop` joined
by a veth pair, the link shaped with tc tbf and taken down/up, each scale's CPU held by a cgroup
v1 quota. Every command is an argv list (no shell); teardown is idempotent, never raises, and
leaves no namespace, veth, cgroup or process behind, or names in one line what it could not remove.
TwoScaleTestbed sets up the three-scale layout too (access_point_layout.py: robot, laptop and
server behind an access point): a layout gives it its ends, namespaces, interfaces, WiFi link
and setup commands.

iproute2 and the cgroup filesystem are driven directly rather than through a library: pyroute2
is not packaged for Debian's Python here, and these are a handful of well-known commands.
"""
from dataclasses import dataclass
import errno
import fcntl
import os
import signal
import subprocess
import sys
import time
from typing import Dict, List, Optional, Sequence

from .testbed_teardown import (attempt, remove_namespace, remove_veths, signal_quietly,
                               signals_deferred, stop_process_groups)

CGROUP_CPU_ROOT = "/sys/fs/cgroup/cpu"
# The kernel's default CFS period. Within a period a group that has used its quota waits for the
# next one (at 0.3 cores of 100 ms, up to 70-85 ms), a stall no slow CPU has; a shorter period
# (run_testbed.py --cfs-period-ms) was tried and made it worse: at 10 ms, /joint_states' longest
# gap went from 0.12 s to 0.27-0.29 s and AMCL's from 0.8-1.0 s to 1.5-1.8 s with every node on
# the robot (bench_premise.py, 0.30 cores, 2 runs each, interleaved). The kernel hands a group's
# quota to a CPU in slices of sched_cfs_bandwidth_slice_us (5 ms here): a 3 ms quota is one
# slice on one CPU, and the group's threads on the other wait out the period.
CFS_PERIOD_US = 100_000
# The niceness of the world's launch (simulator, link shaper, monitor, and the master it
# brings up), outside the quotas: above the scales, as a robot's sensors do not wait for its
# computers. At equal weight they shared the 2-core host with the laptop's 0.9 cores, and a
# fault soak in CI judged /joint_states (critical, 40 Hz) silent 0.204 s > its 0.2 s limit
# with nothing on its path moving.
WORLD_NICE = -10


class TwoScaleError(RuntimeError):
    """A test-bed command failed; the message names the command and what it printed."""


@dataclass(frozen=True)
class ScaleEnd:
    scale: str             # robot, laptop
    namespace: str         # network namespace name
    interface: str         # its end of the veth pair
    address: str           # IPv4 address on the veth, without prefix
    cpu_cores: float       # cgroup quota in cores; 0 = no quota


# The default beds' namespaces, two scales and three (access_point_layout.py): both take the
# robot's lock (claim_layout), so a run of either removes what a killed run of the other left.
DEFAULT_ROBOT_NAMESPACE = "anyscale_robot"
DEFAULT_AP_NAMESPACE, DEFAULT_SERVER_NAMESPACE = "anyscale_ap", "anyscale_server"
DEFAULT_BED_NAMESPACES = (DEFAULT_ROBOT_NAMESPACE, "anyscale_laptop", DEFAULT_AP_NAMESPACE,
                          DEFAULT_SERVER_NAMESPACE)


@dataclass(frozen=True)
class TwoScaleLayout:
    robot: ScaleEnd = ScaleEnd("robot", DEFAULT_ROBOT_NAMESPACE, "asv_robot", "10.213.7.1", 0.0)
    laptop: ScaleEnd = ScaleEnd("laptop", "anyscale_laptop", "asv_laptop", "10.213.7.2", 0.0)
    prefix_len: int = 24

    @property
    def ends(self) -> Sequence[ScaleEnd]:
        return (self.robot, self.laptop)

    @property
    def namespaces(self) -> Sequence[str]:
        return tuple(end.namespace for end in self.ends)

    @property
    def interfaces(self) -> Sequence[str]:
        return tuple(end.interface for end in self.ends)

    @property
    def wifi_link(self) -> "TwoScaleLayout":
        """The link the WiFi model shapes: here the one veth, both of its ends."""
        return self

    def setup_commands(self) -> List[List[str]]:
        return setup_commands(self)


def process_layout(tag: str, subnet: str, pid: Optional[int] = None) -> TwoScaleLayout:
    """A layout no other test bed on the machine uses, for a test or bench that may run beside
    one: namespaces and interfaces named by `tag` and the process id, addresses .1 (robot) and
    .2 (laptop) of its own /24 `subnet` (e.g. "10.213.77"). Interface names stay within
    IFNAMSIZ for a tag of up to 6 characters."""
    pid = os.getpid() if pid is None else pid
    return TwoScaleLayout(
        robot=ScaleEnd("robot", f"{tag}{pid}_m", f"{tag}{pid}m", f"{subnet}.1", 0.0),
        laptop=ScaleEnd("laptop", f"{tag}{pid}_r", f"{tag}{pid}r", f"{subnet}.2", 0.0))


def setup_commands(layout: TwoScaleLayout) -> List[List[str]]:
    robot, laptop = layout.robot, layout.laptop
    cmds = [["ip", "netns", "add", robot.namespace], ["ip", "netns", "add", laptop.namespace],
            ["ip", "link", "add", robot.interface, "type", "veth", "peer", "name",
             laptop.interface],
            ["ip", "link", "set", robot.interface, "netns", robot.namespace],
            ["ip", "link", "set", laptop.interface, "netns", laptop.namespace]]
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


def quota_us(cores: float, period_us: int = CFS_PERIOD_US) -> int:
    """cpu.cfs_quota_us for `cores` per `period_us`; -1 (no limit) for 0 cores."""
    return int(cores * period_us) if cores > 0 else -1


class CpuQuota:
    """A cgroup v1 CPU group holding a scale's processes at `cores` of CPU."""

    def __init__(self, name: str, cores: float, root: str = CGROUP_CPU_ROOT,
                 period_us: int = CFS_PERIOD_US):
        self.path = os.path.join(root, name)
        self.cores = cores
        self.period_us = period_us

    def create(self):
        os.makedirs(self.path, exist_ok=True)
        self._write("cpu.cfs_period_us", self.period_us)
        self._write("cpu.cfs_quota_us", quota_us(self.cores, self.period_us))

    def set_cores(self, cores: float):
        """Changes the quota of the existing group in place (only cpu.cfs_quota_us is written;
        its processes stay in it): host_speed.CpuNormaliser follows the host's speed with it."""
        self._write("cpu.cfs_quota_us", quota_us(cores, self.period_us))
        self.cores = cores

    def add(self, pid: int):
        self._write("tasks", pid)

    def pids(self) -> List[int]:
        """Every process and thread in the group (cgroup.procs and tasks)."""
        found = set()
        for name in ("cgroup.procs", "tasks"):
            try:
                with open(os.path.join(self.path, name)) as f:
                    found.update(int(line) for line in f if line.strip())
            except OSError:
                pass            # the group is gone
        return sorted(found)

    def remove(self, leave_s: float = 1.0, deadline_s: float = 5.0,
               poll_s: float = 0.05) -> Optional[str]:
        """Removes the group; returns None, or what stopped it, in words (never raises).
        Processes get `leave_s` to leave (the teardown has already asked them to end), then
        the ones that linger are killed. rmdir is retried until `deadline_s`: a killed process
        keeps the group busy (EBUSY) for a moment after it left `tasks`."""
        start = time.monotonic()
        pids: List[int] = []
        while True:
            if not os.path.isdir(self.path):
                return None
            pids = self.pids()
            if pids and time.monotonic() - start >= leave_s:
                for pid in pids:
                    signal_quietly(pid, signal.SIGKILL)
            if not pids:
                try:
                    os.rmdir(self.path)
                    return None
                except FileNotFoundError:
                    return None
                except OSError as e:
                    if e.errno != errno.EBUSY:
                        return f"cgroup {self.path} ({e.strerror})"
            if time.monotonic() - start >= deadline_s:
                held = f"processes {' '.join(map(str, pids))} still in it" if pids else "busy"
                return f"cgroup {self.path} ({held} after {deadline_s:g} s)"
            time.sleep(poll_s)

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
    (SIGINT, then SIGKILL) on teardown.

    `world_cores` (an emulated slower host, slow_host.py): the processes started outside the
    scales' quotas go into a CPU group `PREFIX_world` of that many cores instead.

    `layout`: a TwoScaleLayout, or access_point_layout.AccessPointLayout (three scales)."""

    def __init__(self, layout: TwoScaleLayout = TwoScaleLayout(), cgroup_prefix: str = "anyscale",
                 cfs_period_us: int = CFS_PERIOD_US, world_cores: float = 0.0):
        self.layout = layout
        self.quotas: Dict[str, CpuQuota] = {
            end.scale: CpuQuota(f"{cgroup_prefix}_{end.scale}", end.cpu_cores,
                                period_us=cfs_period_us)
            for end in layout.ends if end.cpu_cores > 0}
        self.world_quota = CpuQuota(f"{cgroup_prefix}_world", world_cores,
                                    period_us=cfs_period_us) if world_cores > 0 else None
        self.processes: List[subprocess.Popen] = []

    def cpu_groups(self) -> List[CpuQuota]:
        """Every CPU group of the bed."""
        return list(self.quotas.values()) + ([self.world_quota] if self.world_quota else [])

    def __enter__(self) -> "TwoScaleTestbed":
        self._lock = claim_layout(self.layout)
        left = self.teardown(stale=leftover_namespaces(self.layout))  # of a run killed earlier
        if left:
            self._lock.close()
            raise TwoScaleError("cannot set up: an earlier run left " + "; ".join(left))
        try:
            for argv in self.layout.setup_commands():
                run(argv)
            for quota in self.cpu_groups():
                quota.create()
        except BaseException:
            self.teardown()
            self._lock.close()
            raise
        return self

    def __exit__(self, exc_type, exc, tb):
        try:
            left = self.teardown()
        finally:
            self._lock.close()
        report_leftovers(left, block_failed=exc_type is not None)
        return False

    def end(self, scale: str) -> ScaleEnd:
        return next(e for e in self.layout.ends if e.scale == scale)

    def shape(self, mbps: float, burst_kbit: int = 32):
        """The WiFi link's rate (the veth; on three scales the robot's hop to the AP)."""
        for argv in shape_commands(self.layout.wifi_link, mbps, burst_kbit):
            run(argv)

    def set_link(self, up: bool):
        for argv in link_commands(self.layout.wifi_link, up):
            run(argv)

    def start(self, scale: str, argv: List[str], env: Optional[Dict[str, str]] = None,
              log_path: Optional[str] = None, cpu_quota: bool = True,
              stdout: Optional[int] = None, nice: int = 0) -> subprocess.Popen:
        """Starts argv inside the scale's namespace, in its own session, and in the scale's CPU
        group unless `cpu_quota` is False (the simulated world is not the robot's computer;
        with `world_cores`, it goes into the world's group instead), at
        niceness `nice` (WORLD_NICE for the world). Output goes to `log_path`, or to `stdout`
        (e.g. subprocess.PIPE), or nowhere."""
        quota = self.quotas.get(scale) if cpu_quota else self.world_quota

        def before_exec():
            # The child joins the group before exec, so nothing it forks can escape the quota.
            if quota:
                quota.add(os.getpid())
            if nice:
                os.nice(nice)
        proc = start_session(namespace_exec(self.end(scale), argv), env, log_path, stdout,
                             before_exec if quota or nice else None)
        self.processes.append(proc)
        return proc

    def teardown(self, grace_s: float = 5.0, stale: Sequence[str] = ()) -> List[str]:
        """Ends every process, then removes the namespaces (the layout's and `stale`), the veth
        and the CPU groups. Never raises: returns what it could not remove, in words (empty
        when nothing is left). Safe to call again."""
        left: List[str] = []
        with signals_deferred():
            attempt(left, "stopping processes",
                    lambda: left.extend(stop_process_groups(self.processes, grace_s)))
            self.processes.clear()
            for namespace in dict.fromkeys(tuple(self.layout.namespaces) + tuple(stale)):
                attempt(left, f"namespace {namespace}",
                        lambda ns=namespace: left.extend(remove_namespace(ns)))
            # A setup that failed before moving the veth's ends leaves them here, outside the
            # namespaces, where deleting those does not remove them.
            attempt(left, "veth", lambda: left.extend(remove_veths(list(self.layout.interfaces))))
            for quota in self.cpu_groups():
                attempt(left, f"cgroup {quota.path}",
                        lambda quota=quota: left.extend(filter(None, [quota.remove()])))
        return left


def leftover_namespaces(layout) -> Sequence[str]:
    """What a bed removes before it sets up besides its own namespaces: on the default robot
    namespace, every default bed's (a killed three-scale run leaves its access point and
    server); none for a layout of its own (process_layout)."""
    return DEFAULT_BED_NAMESPACES if layout.robot.namespace == DEFAULT_ROBOT_NAMESPACE else ()


def report_leftovers(left: List[str], block_failed: bool):
    """What a teardown could not remove, as one line: a TwoScaleError after a block that went
    well; after one that failed, a line on stderr, since raising would hide the block's error."""
    if not left:
        return
    message = "teardown left behind: " + "; ".join(left)
    if not block_failed:
        raise TwoScaleError(message)
    print(f"test bed: {message}", file=sys.stderr, flush=True)


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
