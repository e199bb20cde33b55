"""The fault soak's run (tests/bench/bench_fault_soak.py, root): the navigation demo on the
small loop, on the two-scale test bed, with AnyScale deciding, while a seeded schedule
(fault_schedule.py) injects faults one at a time (soak_bed.py); then the verdicts
(soak_invariants.py), the table per fault kind and its CSV and Markdown copies (soak_report.py).

The master runs as a roscore of its own (so that it can be killed and started again without
ending the world launch; robot.launch's master keeper gives the new one what the old one
held), and roslaunch restarts the agents when they are killed (respawn:=true), as it would for
a user who asks it to; with it, robot.launch gives the decision node a warm standby of itself
that forks it again at once (decision_node --warm-restart). The link is set through the
link shaper's own functions (link_shaper.apply_setting), at the moment of each fault. While it
runs, a thread samples /proc twice a second (soak_bed.Sampler). The monitor node records the
outputs, the mapping, the events and the master's publishers as in every test-bed run, and the
critical connections' topics too (record_critical)."""
import datetime
import json
import math
import os
import subprocess
import time
from dataclasses import asdict
from typing import Dict, List, Optional, Tuple

from anyscale_core.characterisation import critical_node_names
from anyscale_core.cli_common import OneLineParser
from anyscale_core.model import ModelError
from anyscale_core.model_loader import load_model

from . import fault_schedule as fs
from .bench_runs import interrupt_then_kill, start_on_the_testbed
from .calibration_file import nav_demo_path, quota_cores
from .demo_run import launch_demo, read_calibration, world_start
from .demo_run import parse_args as demo_args
from .link_shaper import apply_setting
from .proc_census import processes_with_master
from .slow_host import check_factor, describe, emulated_host, slow_day_mode
from .soak_bed import Injector, Sampler, describe_state
from .soak_growth import ResourceSample, growth, unjudged_growth
from .soak_cpu import cpu_during, describe_cpu
from .soak_invariants import CensusSample, InjectedFault, SoakModel, judge_faults, process_leak
from .soak_silences import silence_violations, startup_silences, unchecked
from .soak_report import format_markdown, format_table, verdict_ok, write_csv
from .testbed_record import TestbedRecord
from .testbed_session import NamespaceBed, TestbedSession, layout_with_cpu
from .two_scale_testbed import CFS_PERIOD_US, CGROUP_CPU_ROOT, TwoScaleError, run

WORLD = "small_loop"
LEASE_S = 3.0               # robot.launch's lease_s, which the soak leaves as it is
# Before the first fault: the robot's node set takes 15-17 s to come up under its quota, and
# AMCL goes out once the link has held for bandwidth_hold_s; faults wait for both and the
# start's settling (fault_schedule.START_SETTLE_S), this long at most.
SETUP_TIMEOUT_S = 90.0
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
    p.add_argument("--cfs-period-ms", type=float, default=CFS_PERIOD_US / 1000, metavar="MS",
                   help="the CPU quotas' CFS period, 1-1000 ms (default: the kernel's 100); see "
                        "run_testbed.py --help")
    p.add_argument("--hysteresis", type=float, default=10.0, help="the paper's T in s (10)")
    p.add_argument("--host-factor", type=float, default=1.0, metavar="F",
                   help="the system tests' slow-day mode for a host F times slower than the "
                        "reference day (run_testbed.py --help; default 1: none)")
    p.add_argument("--emulate-slow-host", type=float, default=1.0, metavar="E",
                   help="test bed only: EMULATE a host E times slower than this one "
                        "(run_testbed.py --help; default 1: none)")
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
    if not 1 <= args.cfs_period_ms <= 1000:
        p.error("--cfs-period-ms: expected 1 to 1000 ms (the kernel's limits), got "
                f"{args.cfs_period_ms:g}")
    if not (math.isfinite(args.hysteresis) and args.hysteresis >= 0):
        p.error(f"--hysteresis: expected seconds >= 0, got {args.hysteresis:g}")
    for option, value in (("--host-factor", args.host_factor),
                          ("--emulate-slow-host", args.emulate_slow_host)):
        try:
            check_factor(value, option)
        except ValueError as e:
            p.error(str(e))
    return args


def soak_model(model) -> SoakModel:
    fixed = set(critical_node_names(model)) | {n.name for n in model.nodes
                                               if n.pinned is not None}
    return SoakModel(model.master.name, list(model.node_names), fixed,
                     {(n, s): model.instance_name(n, s) for n in model.node_names
                      for s in model.scale_names}, LEASE_S)


def migratable(model, soak: SoakModel) -> List[str]:
    return [n for n in model.node_names if n not in soak.fixed]


def leftovers(bed, master_uri: str) -> List[str]:
    """What the test bed left on the machine after its teardown, in words."""
    left = []
    listed = run(["ip", "netns", "list"], check=False).stdout.split()
    for end in bed.layout.ends:
        if end.namespace in listed:
            left.append(f"namespace {end.namespace}")
        if run(["ip", "link", "show", end.interface], check=False).returncode == 0:
            left.append(f"veth {end.interface}")
    for quota in bed.cpu_groups():
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
    mode = None
    if args.host_factor > 1:
        mode = slow_day_mode(args.host_factor, robot_cpu, laptop_cpu, read_calibration())
        robot_cpu, laptop_cpu = mode.robot_cores, mode.laptop_cores
        say("bench_fault_soak: " + describe(mode))
    emulated = emulated_host(args.emulate_slow_host, robot_cpu, laptop_cpu, os.cpu_count())
    if args.emulate_slow_host > 1:
        robot_cpu, laptop_cpu = emulated.robot_cores, emulated.laptop_cores
        say(f"bench_fault_soak: EMULATING a host {emulated.slowdown:g} x slower than this one: "
            f"the quotas divided by {emulated.slowdown:g}, the world in "
            f"{emulated.world_cores:.3f} cores")
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
    say(f"bench_fault_soak: CPU quota robot {robot_cpu:g} / laptop {laptop_cpu:g} cores per "
        f"{args.cfs_period_ms:g} ms period; logs and record in {run_dir}")

    bed = NamespaceBed(layout_with_cpu(robot_cpu, laptop_cpu),
                       cfs_period_us=int(args.cfs_period_ms * 1000),
                       world_cores=emulated.world_cores if args.emulate_slow_host > 1 else 0.0)
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
                                echo=quiet_world, record_critical=True, mode=mode)
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
    quotas = {"/" + os.path.relpath(q.path, CGROUP_CPU_ROOT): (scale, q.cores)
              for scale, q in list(bed.quotas.items())
              + ([("world", bed.world_quota)] if bed.world_quota else [])}
    return report(out, args, schedule, injected, sampler, record_path, soak, left, quotas)


def run_schedule(schedule, sampler: Sampler, injector: Injector, world: subprocess.Popen,
                 injected: List[InjectedFault]):
    """Waits for the initial configuration, then injects each fault at its time, adding it to
    `injected` (wall clock) as it goes, so that an interrupted soak keeps what it did. Stops
    early if the world launch ends."""
    began = time.time()
    say(f"bench_fault_soak: waiting for every node to run once and AMCL to be on the laptop, "
        f"then {fs.START_SETTLE_S:g} s with nothing moving")
    while time.time() - began < SETUP_TIMEOUT_S and world.poll() is None:
        if fs.first_fault_at(sampler.samples(), set_up) is not None:
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


def set_up(s: CensusSample) -> bool:
    """The soak's starting placement: every node once, AMCL on the laptop."""
    return all(len(v) == 1 for v in s.instances.values()) and s.instances.get("amcl") == ["laptop"]


def report(out: str, args, schedule, injected: List[InjectedFault], sampler: Sampler,
           record_path: str, soak: SoakModel, left: List[str], quotas: Dict[str, Tuple]) -> int:
    """Moves the soak's samples to the record's clock, keeps them in OUT/soak.json (for
    --judge) and judges them. `quotas`: CPU cgroup -> (scale, cores)."""
    rec = TestbedRecord.load(record_path)
    zero = rec.started_wall
    data = {"seed": args.seed, "minutes": args.minutes, "record_started_wall": zero,
            "schedule": [asdict(x) for x in schedule],
            "injected": [dict(asdict(f), t=f.t - zero, end=f.end - zero) for f in injected],
            "census": [dict(asdict(c), t=c.t - zero) for c in sampler.census],
            "resources": [dict(asdict(r), t=r.t - zero) for r in sampler.resources],
            "leaks": left, "quotas": quotas}
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
    first_fault_t = min((f.t for f in faults), default=0.0)
    left = list(data["leaks"]) + process_leak(census, rec, soak, first_fault_t)
    growths = growth(resources)
    missed = unchecked(rec) + startup_silences(faults, rec) + unjudged_growth(resources)
    quotas = {group: tuple(q) for group, q in data.get("quotas", {}).items()}
    cpu = [f"CPU while {text}: {describe_cpu(*cpu_during(census, v.start_t, v.end_t), quotas)}"
           for v, text in silence_violations(rec)]
    title = (f"Fault soak: seed {data['seed']}, {data['minutes']:g} min, {len(faults)} of "
             f"{len(data['schedule'])} faults injected, {WORLD}")
    say(title)
    say(format_table(outcomes, left, growths, missed, cpu))
    write_csv(os.path.join(out, "fault_soak.csv"), outcomes)
    with open(os.path.join(out, "fault_soak.md"), "w") as f:
        f.write(format_markdown(outcomes, left, growths, title, missed, cpu))
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
