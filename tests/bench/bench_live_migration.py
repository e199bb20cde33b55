#!/usr/bin/python3
"""Live migration on the two-scale test bed (root): per node, the gap on its output topic as
the robot's subscribers see it during a planned move and during a link-loss move back, the
reaction time from link down to the node publishing on the robot again, and the decision
node's CPU. Goals (issue 5): planned-move gap <= 1.0 s, reaction <= 1.0 s, decision node
<= 3 % of a core.

The navigation demo (AMCL, AR recognition) runs twice, with the agents' warm standbys of the
rospy nodes and without them (every start imports anew), and a stock topic_tools relay
(roscpp: no standby) once, each with a link schedule that repeats: good link (the nodes move
out after T), link down (they come back). Warm and cold runs share the machine's load of the
moment, so their ratio is the figure to read. Run with the workspace sourced:
    sudo -E /usr/bin/python3 tests/bench/bench_live_migration.py [--cycles 3]
"""
import argparse
import glob
import math
import os
import statistics
import subprocess
import sys
import tempfile
import threading
import time

from anyscale_core.testbed_record import (TestbedRecord, link_transitions, move_figures,
                                          reaction_s)
from anyscale_core.testbed_session import NamespaceBed, TestbedSession, layout_with_cpu
from anyscale_core.two_scale_testbed import missing_capabilities

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
CLOCK_TICKS = os.sysconf("SC_CLK_TCK")


def cycle_schedule(cycles: int, up_s: float, down_s: float):
    steps, t = [], 0.0
    for _ in range(cycles):
        steps += [[t, 27], [t + up_s, 0]]
        t += up_s + down_s
    steps.append([t, 27])
    return steps, t + 20.0          # the last move out (after T) is seen to its end


class ProcessCpu(threading.Thread):
    """CPU share of the process named `__name:=NAME` from /proc, over its whole life here."""

    def __init__(self, name: str):
        super().__init__(daemon=True)
        self.tag = f"__name:={name}".encode()
        self.first = self.last = None
        self.stop = threading.Event()

    def sample(self):
        for pid in filter(str.isdigit, os.listdir("/proc")):
            try:
                with open(f"/proc/{pid}/cmdline", "rb") as f:
                    if self.tag not in f.read().split(b"\0"):
                        continue
                with open(f"/proc/{pid}/stat", "rb") as f:
                    fields = f.read().rsplit(b")", 1)[1].split()
                return int(pid), (int(fields[11]) + int(fields[12])) / CLOCK_TICKS
            except (OSError, IndexError, ValueError):
                continue
        return None

    def run(self):
        while not self.stop.is_set():
            s = self.sample()
            if s is not None:
                now = time.monotonic()
                if self.first is None or self.first[0] != s[0]:
                    self.first = (s[0], s[1], now)
                self.last = (s[0], s[1], now)
            self.stop.wait(0.5)

    def percent(self) -> float:
        if not self.first or not self.last or self.last[2] - self.first[2] < 5.0:
            return float("nan")
        return 100.0 * (self.last[1] - self.first[1]) / (self.last[2] - self.first[2])


def run_nav(cycles, up_s, down_s, out, warm):
    steps, duration = cycle_schedule(cycles, up_s, down_s)
    cpu = ProcessCpu("anyscale_decision")
    cpu.start()
    done = subprocess.run(
        [sys.executable, os.path.join(ROOT, "scripts", "run_testbed.py"), "--world",
         "small_loop", "--link", "schedule", "--schedule", str(steps), "--duration",
         str(duration), "--hysteresis", "5", "--out", out] + ([] if warm else ["--cold-start"]),
        capture_output=True, text=True)
    cpu.stop.set()
    records = glob.glob(os.path.join(out, "*", "record.json"))
    if done.returncode != 0 or not records:
        sys.exit("bench: the nav test-bed run failed:\n" + done.stdout[-2000:] + done.stderr)
    return TestbedRecord.load(records[0]), cpu.percent()


def run_relay(cycles, up_s, down_s, out):
    steps, duration = cycle_schedule(cycles, up_s, down_s)
    model = subprocess.run(["rospack", "find", "anyscale_core"], capture_output=True,
                           text=True).stdout.strip() + "/test/config/relay_model.yaml"
    record = os.path.join(out, "relay.json")
    with NamespaceBed(layout_with_cpu(0.0, 0.0)) as bed:
        session = TestbedSession(bed, out)
        robot = session.roslaunch("robot", "relay_robot", [
            os.path.join(ROOT, "tests", "system", "relay_robot.launch"), f"model:={model}",
            f"schedule:={steps}", f"record_path:={record}", f"duration_s:={duration}",
            "hysteresis_s:=5.0", f"uplink_interface:={bed.uplink_interface('robot')}"],
            wait_for_master=False)
        session.roslaunch("laptop", "relay_laptop", [
            "anyscale_agent_cpp", "agent.launch", "scale:=laptop", "master_scale:=robot",
            f"model:={model}", "sample_rate_hz:=5.0", "sigint_timeout_s:=2.0"])
        robot.wait(timeout=duration + 60)
    return TestbedRecord.load(record)


def node_figures(rec: TestbedRecord, outputs):
    """{node: (planned gaps, link-loss gaps, reactions)} in seconds; a move the run did not see
    to its end is left out."""
    downs = [t for t, up in link_transitions(rec.bandwidth) if not up]
    out = {}
    for f in move_figures(rec, outputs):
        planned, lost, reaction = out.setdefault(f.event.node, ([], [], []))
        if math.isnan(f.output_gap_s):
            continue
        if f.event.kind == "migrate":
            planned.append(f.output_gap_s)
        elif "down" in f.event.reason:
            lost.append(f.output_gap_s)
            down = max((t for t in downs if t <= f.event.decided_t), default=None)
            if down is not None:
                reaction.append(reaction_s(rec.receipts[outputs[f.event.node]], down,
                                           f.event.decided_t))
    return out


def describe(values):
    if not values:
        return "-"
    return (f"median {statistics.median(values):.2f} s, max {max(values):.2f} s "
            f"(n={len(values)})")


def ratio(cold, warm):
    if not cold or not warm:
        return "-"
    return f"{statistics.median(cold) / statistics.median(warm):.1f}x"


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--cycles", type=int, default=3, help="good-link/link-down cycles (3)")
    p.add_argument("--up", type=float, default=25.0, help="seconds of good link per cycle")
    p.add_argument("--down", type=float, default=8.0, help="seconds of link down per cycle")
    args = p.parse_args(argv)
    missing = missing_capabilities()
    if missing:
        sys.exit("bench: the test bed needs " + "; ".join(missing))
    with tempfile.TemporaryDirectory(prefix="bench_live_") as out:
        print(f"[1/3] navigation demo with warm standbys, {args.cycles} cycles ...", flush=True)
        warm, warm_cpu = run_nav(args.cycles, args.up, args.down, os.path.join(out, "warm"), True)
        print(f"[2/3] navigation demo, cold starts, {args.cycles} cycles ...", flush=True)
        cold, cold_cpu = run_nav(args.cycles, args.up, args.down, os.path.join(out, "cold"), False)
        print(f"[3/3] stock topic_tools relay, {args.cycles} cycles ...", flush=True)
        os.makedirs(os.path.join(out, "relay"))
        relay = run_relay(args.cycles, args.up, args.down, os.path.join(out, "relay"))
    nav_outputs = {"amcl": "/amcl_pose", "ar_recognition": "/ar_markers"}
    rows = [(f"{n} (warm)", f) for n, f in node_figures(warm, nav_outputs).items()]
    rows += [(f"{n} (cold)", f) for n, f in node_figures(cold, nav_outputs).items()]
    rows += list(node_figures(relay, {"relay": "/chatter_relay"}).items())
    print("\nnode                   planned move: output gap          link loss: output gap"
          "             reaction (link down -> output on the robot)")
    for node, (planned, lost, reaction) in rows:
        print(f"{node:<22} {describe(planned):<34} {describe(lost):<34} {describe(reaction)}")
    figures = {name: f for name, f in rows}
    print("\ncold / warm (medians, same machine, one after the other):")
    for node in nav_outputs:
        w, c = figures.get(f"{node} (warm)"), figures.get(f"{node} (cold)")
        if w and c:
            print(f"  {node:<16} planned gap {ratio(c[0], w[0])}, link-loss gap "
                  f"{ratio(c[1], w[1])}, reaction {ratio(c[2], w[2])}")
    print(f"\ndecision node CPU: {warm_cpu:.2f} % (warm run), {cold_cpu:.2f} % (cold run) of "
          "one core (goal <= 3 %)")
    print("goals: planned-move gap <= 1.0 s, reaction <= 1.0 s")


if __name__ == "__main__":
    main()
