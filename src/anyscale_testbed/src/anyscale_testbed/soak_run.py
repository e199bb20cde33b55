"""The fault soak's run (tests/bench/bench_fault_soak.py, root): the navigation demo on the
small loop, on the two-scale test bed, with AnyScale deciding, while a seeded schedule
(fault_schedule.py) injects faults one at a time; then the verdicts (soak_invariants.py), the
table per fault kind and its CSV and Markdown copies.

The master runs as a roscore of its own (so that it can be killed and started again without
ending the world launch), and roslaunch restarts the agents and the decision node when they
are killed (respawn:=true), as it would for a user who asks it to. The link is set through the
link shaper's own functions (link_shaper.apply_setting), at the moment of each fault. While it
runs, a thread samples /proc twice a second: every instance of every node and its scale, the
supervisors (agents, decision node, master), and the memory and file descriptors of the
agents and the decision node. The monitor node records the outputs, the mapping, the events
and the master's publishers as in every test-bed run."""
import datetime
import json
import math
import os
import signal
import subprocess
import threading
import time
from dataclasses import asdict
from typing import Dict, List, Optional, Tuple

from anyscale_core.characterisation import critical_node_names
from anyscale_core.cli_common import OneLineParser
from anyscale_core.model import ModelError
from anyscale_core.model_loader import load_model

from . import fault_schedule as fs
from .bench_runs import interrupt_then_kill, start_on_the_testbed
from .demo_run import launch_demo, nav_demo_path, quota_cores, world_start
from .demo_run import parse_args as demo_args
from .link_shaper import LinkSetting, apply_setting
from .proc_census import master_processes, memory_and_fds, processes_with_master
from .soak_invariants import (CensusSample, InjectedFault, ResourceSample, SoakModel,
                              format_markdown, format_table, growth, judge_faults, process_leak,
                              verdict_ok, write_csv)
from .testbed_monitor_ros import node_processes
from .testbed_record import TestbedRecord
from .testbed_session import NamespaceBed, TestbedSession, layout_with_cpu
from .two_scale_testbed import TwoScaleError, run

WORLD = "small_loop"
# The supervised processes: the name roslaunch gives them -> their role.
ROLES = {"anyscale_agent_robot": "agent_robot", "anyscale_agent_laptop": "agent_laptop",
         "anyscale_decision": "decision"}
LEASE_S = 3.0               # robot.launch's lease_s, which the soak leaves as it is
SAMPLE_PERIOD_S = 0.5
# Before the first fault: the robot's node set takes 15-17 s to come up under its quota, and
# AMCL goes out once the link has held for bandwidth_hold_s; faults wait for both, this long
# at most.
SETUP_TIMEOUT_S = 90.0
ROSCORE_UP_TIMEOUT_S = 15.0
LOOP_S = 40.0               # the small loop takes longer than this at the robot's top speed


def parse_args(argv):
    p = OneLineParser(prog="bench_fault_soak",
                      description="The fault soak on the two-scale test bed (root): the "
                                  "navigation demo on the small loop while a seeded schedule "
                                  "injects faults; a table per fault kind at the end.",
                      epilog="Example: sudo -E /usr/bin/python3 tests/bench/bench_fault_soak.py "
                             "--minutes 10 --seed 1")
    p.add_argument("--minutes", type=float, default=None,
                   help="how long the faults go on (the set-up before and the teardown after "
                        "come on top)")
    p.add_argument("--seed", type=int, default=None, help="the schedule's seed (>= 0)")
    p.add_argument("--out", default=None,
                   help="results directory (default: results/bench_fault_soak/<date-time>)")
    p.add_argument("--roscore-restarts", type=int, default=1, metavar="N",
                   help="roscore restarts, at the end of the schedule (default 1)")
    p.add_argument("--robot-cpu", type=float, default=None, metavar="CORES",
                   help="robot CPU quota (default: the calibration file's)")
    p.add_argument("--laptop-cpu", type=float, default=None, metavar="CORES",
                   help="laptop CPU quota (default: the calibration file's)")
    p.add_argument("--hysteresis", type=float, default=10.0, help="the paper's T in s (10)")
    p.add_argument("--dry-run", action="store_true",
                   help="print the schedule and exit (no root needed)")
    p.add_argument("--judge", metavar="DIR", default=None,
                   help="judge a soak that ran again, from DIR/soak.json and DIR/run/record.json "
                        "(no root needed; --minutes and --seed are then not needed)")
    args = p.parse_args(argv)
    if args.judge is not None:
        return args
    if args.minutes is None or args.seed is None:
        p.error("--minutes and --seed are required")
    if not (math.isfinite(args.minutes) and 0 < args.minutes <= 24 * 60):
        p.error(f"--minutes: expected a number of minutes in (0, 1440], got {args.minutes:g}")
    if args.seed < 0:
        p.error(f"--seed: expected an integer >= 0, got {args.seed}")
    if args.roscore_restarts < 0:
        p.error(f"--roscore-restarts: expected >= 0, got {args.roscore_restarts}")
    for name in ("robot_cpu", "laptop_cpu"):
        cores = getattr(args, name)
        if cores is not None and not (math.isfinite(cores) and cores > 0):
            p.error(f"--{name.replace('_', '-')}: expected cores > 0, got {cores:g}")
    if not (math.isfinite(args.hysteresis) and args.hysteresis >= 0):
        p.error(f"--hysteresis: expected seconds >= 0, got {args.hysteresis:g}")
    return args


def soak_model(model) -> SoakModel:
    fixed = set(critical_node_names(model)) | {n.name for n in model.nodes
                                                if n.pinned is not None}
    return SoakModel(model.master.name, list(model.node_names), fixed,
                     {(n, s): model.instance_name(n, s) for n in model.node_names
                      for s in model.scale_names}, LEASE_S)


def migratable(model, soak: SoakModel) -> List[str]:
    return [n for n in model.node_names if n not in soak.fixed]


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
                    resources.append(ResourceSample(now, role, pid, used[0], used[1]))
        supervisors["master"] = len(master_processes(self.master_uri))
        sample = CensusSample(now, {n: sorted(s) for n, s in instances.items()}, supervisors,
                              len(processes_with_master(self.master_uri)))
        with self.lock:
            self.census.append(sample)
            self.resources += resources
        return sample

    def scale_of(self, netns: str) -> str:
        return self.netns_scale.get(netns, netns)

    def latest(self) -> Optional[CensusSample]:
        with self.lock:
            return self.census[-1] if self.census else None


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
                                      os.path.join(self.log_dir, "roscore.log"), cpu_quota=False)

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


def leftovers(bed, master_uri: str) -> List[str]:
    """What the test bed left on the machine after its teardown, in words."""
    left = []
    listed = run(["ip", "netns", "list"], check=False).stdout.split()
    for end in bed.layout.ends:
        if end.namespace in listed:
            left.append(f"namespace {end.namespace}")
        if run(["ip", "link", "show", end.interface], check=False).returncode == 0:
            left.append(f"veth {end.interface}")
    for quota in bed.quotas.values():
        if os.path.isdir(quota.path):
            left.append(f"cgroup {quota.path}")
    left += [f"process {pid} ({_cmdline(pid)})" for pid in processes_with_master(master_uri)]
    return left


def _cmdline(pid: int) -> str:
    try:
        with open(f"/proc/{pid}/cmdline", "rb") as f:
            return f.read().replace(b"\0", b" ").decode(errors="replace").strip()[:80]
    except OSError:
        return "?"


def say(line: str):
    print(line, flush=True)


def quiet_world(line: str):
    """The world launch's lines go to its log; only fatal ones reach the soak's console."""
    if "[FATAL]" in line or "REQUIRED process" in line:
        say("  world: " + line.strip())


def main(root: str, argv=None) -> int:
    args = parse_args(argv)
    try:
        model_path = nav_demo_path("config", "testbed.yaml")
        model = load_model(model_path)
    except ModelError as e:
        say(f"bench_fault_soak: {e}")
        return 2
    soak = soak_model(model)
    if args.judge is not None:
        return judge_again(os.path.abspath(args.judge), soak)
    schedule = fs.make_schedule(args.seed, args.minutes * 60.0, migratable(model, soak),
                                args.roscore_restarts)
    say(f"bench_fault_soak: seed {args.seed}, {args.minutes:g} min: {len(schedule)} faults "
        f"over {fs.schedule_length_s(schedule):.0f} s")
    if args.dry_run:
        for i, f in enumerate(schedule, 1):
            say(f"  [{i:2d}] t={f.t:6.1f} s  {f.kind:<18} {f.describe()}")
        return 0
    start_on_the_testbed("bench_fault_soak")
    robot_cpu, laptop_cpu = quota_cores(args.robot_cpu, args.laptop_cpu)
    stamp = datetime.datetime.now().strftime("%Y%m%d-%H%M%S")
    out = os.path.abspath(args.out or os.path.join(root, "results", "bench_fault_soak", stamp))
    run_dir = os.path.join(out, "run")
    record_path = os.path.join(run_dir, "record.json")
    os.makedirs(run_dir, exist_ok=True)
    total_s = SETUP_TIMEOUT_S + fs.schedule_length_s(schedule) + 60.0
    start, loop = world_start(WORLD, 0)
    goals = loop * max(2, math.ceil(total_s / LOOP_S))
    demo = demo_args(["--world", WORLD, "--link", "unshaped", "--hysteresis",
                      str(args.hysteresis)], out)
    say(f"bench_fault_soak: CPU quota robot {robot_cpu:g} / laptop {laptop_cpu:g} cores; "
        f"logs and record in {run_dir}")

    bed = NamespaceBed(layout_with_cpu(robot_cpu, laptop_cpu))
    injected: List[InjectedFault] = []
    sampler: Optional[Sampler] = None
    teardown_left: List[str] = []
    master_uri = ""
    try:
        with bed:
            session = TestbedSession(bed, run_dir)
            master_uri = session.env("robot")["ROS_MASTER_URI"]
            sampler = Sampler(model, master_uri,
                              {bed.netns_link(s): s for s in model.scale_names})
            injector = Injector(bed, session, master_uri, sampler, session.log_dir)
            apply_setting(bed.layout, None, injector.link)
            injector.start_roscore()
            world = launch_demo(session, bed, demo, model_path, start, goals, record_path,
                                run_dir, "unshaped", master_running=True, respawn=True,
                                echo=quiet_world)
            sampler.start()
            try:
                run_schedule(schedule, sampler, injector, world, injected)
            finally:
                injector.resume_stopped()
                sampler.stopped.set()
                sampler.join(5.0)
                say("bench_fault_soak: ending the run (the monitor saves its record)")
                interrupt_then_kill(world, 30.0)
    except TwoScaleError as e:
        teardown_left.append(str(e))
    except KeyboardInterrupt:
        say("bench_fault_soak: interrupted; judging the faults injected so far")
    if sampler is None or not os.path.exists(record_path):
        say(f"bench_fault_soak: no record at {record_path}; nothing to judge")
        return 1
    left = teardown_left + leftovers(bed, master_uri)
    return report(out, args, schedule, injected, sampler, record_path, soak, left)


def run_schedule(schedule, sampler: Sampler, injector: Injector, world: subprocess.Popen,
                 injected: List[InjectedFault]):
    """Waits for the initial configuration, then injects each fault at its time, adding it to
    `injected` (wall clock) as it goes, so that an interrupted soak keeps what it did. Stops
    early if the world launch ends."""
    began = time.time()
    say("bench_fault_soak: waiting for every node to run once and AMCL to be on the laptop")
    while time.time() - began < SETUP_TIMEOUT_S and world.poll() is None:
        s = sampler.latest()
        if s and all(len(v) == 1 for v in s.instances.values()) and \
                s.instances.get("amcl") == ["laptop"]:
            break
        time.sleep(0.5)
    say(f"bench_fault_soak: set up after {time.time() - began:.0f} s: "
        f"{describe_state(sampler.latest())}")
    t0 = time.time()
    for i, fault in enumerate(schedule, 1):
        while time.time() < t0 + fault.t and world.poll() is None:
            time.sleep(0.1)
        if world.poll() is not None:
            say(f"bench_fault_soak: the world launch ended (exit {world.returncode}); "
                f"no more faults")
            break
        say(f"[{i:2d}/{len(schedule)}] t={time.time() - t0:6.1f} s  before: "
            f"{describe_state(sampler.latest())}")
        struck = time.time()
        try:
            detail, error = injector.inject(fault)
        except TwoScaleError as e:
            detail, error = "", str(e)
        ended = time.time() if fault.hold_s or fault.kind == fs.RESTART_ROSCORE else struck
        injected.append(InjectedFault(fault, struck, ended, detail, error))
        say(f"[{i:2d}/{len(schedule)}] t={struck - t0:6.1f} s  {fault.kind}: "
            f"{fault.describe()}" + (f" ({detail})" if detail else "")
            + (f"  NOT INJECTED: {error}" if error else ""))
    if injected:
        last = schedule[len(injected) - 1]
        settle_until = injected[-1].end + fs.SETTLE_S[last.kind]
        while time.time() < settle_until and world.poll() is None:
            time.sleep(0.2)
        say(f"bench_fault_soak: after the last fault: {describe_state(sampler.latest())}")


def report(out: str, args, schedule, injected: List[InjectedFault], sampler: Sampler,
           record_path: str, soak: SoakModel, left: List[str]) -> int:
    """Moves the soak's samples to the record's clock, keeps them in OUT/soak.json (for
    --judge) and judges them."""
    rec = TestbedRecord.load(record_path)
    zero = rec.started_wall
    data = {"seed": args.seed, "minutes": args.minutes, "record_started_wall": zero,
            "schedule": [asdict(x) for x in schedule],
            "injected": [dict(asdict(f), t=f.t - zero, end=f.end - zero) for f in injected],
            "census": [dict(asdict(c), t=c.t - zero) for c in sampler.census],
            "resources": [dict(asdict(r), t=r.t - zero) for r in sampler.resources],
            "leaks": left}
    with open(os.path.join(out, "soak.json"), "w") as f:
        json.dump(data, f)
    return judge(out, data, rec, soak)


def judge(out: str, data: dict, rec: TestbedRecord, soak: SoakModel) -> int:
    """The verdicts of a soak (soak.json's data, on the record's clock): the table on the
    console, OUT/fault_soak.csv and OUT/fault_soak.md. 0 if every invariant held."""
    census = [CensusSample(**c) for c in data["census"]]
    resources = [ResourceSample(**r) for r in data["resources"]]
    faults = [InjectedFault(**dict(f, fault=fs.Fault(**f["fault"]))) for f in data["injected"]]
    end_t = census[-1].t if census else 0.0
    outcomes = judge_faults(faults, census, rec, soak, end_t)
    left = list(data["leaks"]) + process_leak(census, rec, soak)
    growths = growth(resources)
    title = (f"Fault soak: seed {data['seed']}, {data['minutes']:g} min, {len(faults)} of "
             f"{len(data['schedule'])} faults injected, {WORLD}")
    say(title)
    say(format_table(outcomes, left, growths))
    write_csv(os.path.join(out, "fault_soak.csv"), outcomes)
    with open(os.path.join(out, "fault_soak.md"), "w") as f:
        f.write(format_markdown(outcomes, left, growths, title))
    say(f"bench_fault_soak: {out}/fault_soak.csv, fault_soak.md, soak.json")
    return 0 if verdict_ok(outcomes, left, growths) else 1


def judge_again(out: str, soak: SoakModel) -> int:
    """--judge OUT: the verdicts of a soak that ran, from OUT/soak.json and its record."""
    try:
        with open(os.path.join(out, "soak.json")) as f:
            data = json.load(f)
        rec = TestbedRecord.load(os.path.join(out, "run", "record.json"))
    except (OSError, ValueError, KeyError, TypeError) as e:
        say(f"bench_fault_soak: --judge {out}: not a soak's results ({e})")
        return 2
    return judge(out, data, rec, soak)
