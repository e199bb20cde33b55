"""What the fault soak does on the running test bed (soak_run.py runs it): the census thread,
which samples /proc twice a second (every instance of every node and its scale, the
supervisors, the memory and file descriptors of the agents and the decision node, the CPU time
of every process of the ROS system), and the
injector, which strikes one fault of the schedule: the link through the link shaper's own
functions, signals to the supervisors and to a node, a roscore killed and started again."""
import os
import signal
import subprocess
import threading
import time
from typing import Dict, List, Optional, Tuple

from . import fault_schedule as fs
from .link_shaper import LinkSetting, apply_setting
from .proc_census import (cpu_usage, is_standby, master_processes, memory_and_fds,
                          processes_with_master)
from .soak_growth import ResourceSample
from .soak_invariants import CensusSample
from .testbed_monitor_ros import node_processes
from .two_scale_testbed import WORLD_NICE

# The supervised processes: the name roslaunch gives them -> their role.
ROLES = {"anyscale_agent_robot": "agent_robot", "anyscale_agent_laptop": "agent_laptop",
         "anyscale_decision": "decision"}
SAMPLE_PERIOD_S = 0.5
ROSCORE_UP_TIMEOUT_S = 15.0


class Sampler(threading.Thread):
    """Samples /proc every SAMPLE_PERIOD_S until stopped: the census (wall clock)."""

    def __init__(self, model, master_uri: str, netns_scale: Dict[str, str]):
        super().__init__(daemon=True)
        self.instance_of = {model.instance_name(n, s).lstrip("/"): n
                            for n in model.node_names for s in model.scale_names}
        self.master_uri = master_uri
        self.netns_scale = netns_scale
        self.census: List[CensusSample] = []
        self.resources: List[ResourceSample] = []
        self.stopped = threading.Event()
        self.lock = threading.Lock()

    def run(self):
        while not self.stopped.wait(SAMPLE_PERIOD_S):
            self.sample()

    def sample(self) -> CensusSample:
        now = time.time()
        # A paused instance (launch.pause_at_home) is no live one: the monitor's census.
        instances = {n: [self.scale_of(x) for x in netns]
                     for n, netns in node_processes(self.instance_of, self.master_uri).items()}
        pids: Dict[str, List[int]] = {}
        supervisors = {role: len(netns) for role, netns in
                       node_processes(ROLES, self.master_uri, pids=pids).items()}
        resources = []
        for role, role_pids in pids.items():
            for pid in role_pids:
                used = memory_and_fds(pid)
                if used is not None:
                    resources.append(ResourceSample(now, role, pid, *used))
        supervisors["master"] = len(master_processes(self.master_uri))
        system = processes_with_master(self.master_uri)
        cpu, standbys = [], []
        for pid in system:
            used = cpu_usage(pid)
            if used is not None:
                cpu.append((used[0], used[1], pid, used[2]))
                if is_standby(pid):
                    standbys.append(f"{used[0]} {used[1]}")     # its instance, its group
        sample = CensusSample(now, {n: sorted(s) for n, s in instances.items()}, supervisors,
                              len(system), cpu, sorted(standbys))
        with self.lock:
            self.census.append(sample)
            self.resources += resources
        return sample

    def scale_of(self, netns: str) -> str:
        return self.netns_scale.get(netns, netns)

    def latest(self) -> Optional[CensusSample]:
        with self.lock:
            return self.census[-1] if self.census else None

    def samples(self) -> List[CensusSample]:
        with self.lock:
            return list(self.census)


def describe_state(s: Optional[CensusSample]) -> str:
    """One line: where each node runs, and the supervisors that do not run exactly once."""
    if s is None:
        return "no census yet"
    where = []
    for node, scales in sorted(s.instances.items()):
        if scales != ["robot"]:
            where.append(f"{node}@{'+'.join(scales) or 'NONE'}")
    odd = [f"{r} x{n}" for r, n in sorted(s.supervisors.items()) if n != 1]
    return ("every node once, on the robot" if not where else "; ".join(where)) + \
        ("" if not odd else "; " + ", ".join(odd)) + f"; {s.processes} processes"


class Injector:
    """Injects one fault on the running bed; returns (detail, error) in words."""

    def __init__(self, bed, session, master_uri: str, sampler: Sampler, log_dir: str):
        self.bed = bed
        self.session = session
        self.master_uri = master_uri
        self.sampler = sampler
        self.log_dir = log_dir
        self.link = LinkSetting(True, fs.START_MBPS)
        self.roscore: Optional[subprocess.Popen] = None
        self.stopped_pids: List[int] = []

    def set_link(self, setting: LinkSetting):
        apply_setting(self.bed.layout, self.link, setting)
        self.link = setting

    def start_roscore(self):
        self.roscore = self.bed.start("robot", ["roscore"], self.session.env("robot"),
                                      os.path.join(self.log_dir, "roscore.log"), cpu_quota=False,
                                      nice=WORLD_NICE)

    def pids_of(self, role: str) -> List[int]:
        pids: Dict[str, List[int]] = {}
        node_processes({n: r for n, r in ROLES.items() if r == role}, self.master_uri,
                       pids=pids)
        return pids.get(role, [])

    def inject(self, fault: fs.Fault) -> Tuple[str, str]:
        kind = fault.kind
        if kind == fs.LINK_FLAP:
            self.set_link(LinkSetting(False))
            time.sleep(fault.hold_s)
            self.set_link(LinkSetting(True, fault.mbps))
            return f"down {fault.hold_s:.1f} s, back at {fault.mbps:g} Mbit/s", ""
        if kind == fs.BANDWIDTH_STEP:
            before = self.link.describe()
            self.set_link(LinkSetting(True, fault.mbps))
            return f"{before} -> {fault.mbps:g} Mbit/s", ""
        if kind in (fs.KILL_LAPTOP_AGENT, fs.KILL_ROBOT_AGENT, fs.KILL_DECISION):
            role = {fs.KILL_LAPTOP_AGENT: "agent_laptop", fs.KILL_ROBOT_AGENT: "agent_robot",
                    fs.KILL_DECISION: "decision"}[kind]
            return self.signal_role(role, signal.SIGKILL)
        if kind == fs.STOP_LAPTOP_AGENT:
            # Signalled, the stopped agent is no live process for the census: keep its pids.
            self.stopped_pids = self.pids_of("agent_laptop")
            detail, error = self.signal_role("agent_laptop", signal.SIGSTOP, self.stopped_pids)
            if error:
                return detail, error
            try:
                time.sleep(fault.hold_s)
            finally:
                self.resume_stopped()
            return detail + f", SIGCONT after {fault.hold_s:.1f} s", ""
        if kind == fs.SEGV_NODE:
            return self.segv(fault.target)
        if kind == fs.RESTART_ROSCORE:
            return self.restart_roscore()
        return "", f"unknown fault kind {kind}"

    def resume_stopped(self):
        for pid in self.stopped_pids:
            try:
                os.kill(pid, signal.SIGCONT)
            except ProcessLookupError:
                pass
        self.stopped_pids = []

    def signal_role(self, role: str, sig: int, pids: Optional[List[int]] = None):
        pids = self.pids_of(role) if pids is None else pids
        if not pids:
            return "", f"no {role} process to signal"
        for pid in pids:
            try:
                os.kill(pid, sig)
            except ProcessLookupError:
                pass
        return f"{signal.Signals(sig).name} to {role} pid {' '.join(map(str, pids))}", ""

    def segv(self, node: str):
        pids: Dict[str, List[int]] = {}
        netns = node_processes(self.sampler.instance_of, self.master_uri, pids=pids).get(node)
        if not netns:
            return "", f"no live instance of {node}"
        os.kill(pids[node][0], signal.SIGSEGV)
        return f"{node} pid {pids[node][0]} on {self.sampler.scale_of(netns[0])}", ""

    def restart_roscore(self):
        """kill -9 of roscore's launcher, its master and its rosout, then roscore again."""
        victims = set(master_processes(self.master_uri))
        if self.roscore is not None and self.roscore.poll() is None:
            victims.add(self.roscore.pid)
            victims |= set(children_of(self.roscore.pid))
        if not victims:
            return "", "no roscore process to kill"
        for pid in victims:
            try:
                os.kill(pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
        if self.roscore is not None:
            self.roscore.wait()
        self.start_roscore()
        deadline = time.monotonic() + ROSCORE_UP_TIMEOUT_S
        while not master_processes(self.master_uri) and time.monotonic() < deadline:
            time.sleep(0.1)
        if not master_processes(self.master_uri):
            return "", f"roscore did not start again within {ROSCORE_UP_TIMEOUT_S:g} s"
        return f"killed pids {' '.join(map(str, sorted(victims)))}, roscore pid " \
               f"{self.roscore.pid}", ""


def children_of(pid: int) -> List[int]:
    """Every descendant of pid (from /proc's parent links)."""
    parent = {}
    for p in filter(str.isdigit, os.listdir("/proc")):
        try:
            with open(f"/proc/{p}/stat", "rb") as f:
                parent[int(p)] = int(f.read().rsplit(b")", 1)[1].split()[1])
        except (OSError, IndexError, ValueError):
            continue
    found, frontier = [], [pid]
    while frontier:
        kids = [c for c, pp in parent.items() if pp in frontier]
        found += kids
        frontier = kids
    return found
