#!/usr/bin/python3
"""Live migration on the two-scale test bed (root): per node, the gap on its output topic as
the robot's subscribers see it during a planned move out, a planned move back (the link
cannot carry it), and a link-loss move back, the reaction time from link down to the node
publishing on the robot again, and the decision node's CPU. Every column gives the median and
the worst move, and how many moves left the output silent longer than its tolerance (Table I:
AMCL 2 s, AR 1 s). Goals (issue 12): a planned move's gap <= one period of the node's
freq_min (AMCL 0.5 s, AR 1 s); every gap within the tolerance.

Links (--link):
  clean  the scripted cycle of the earlier bench: 27 Mbit/s (the nodes move out after T), then
         down. The navigation demo runs with the agents' warm standbys and without them (every
         start imports anew), and a stock topic_tools relay (roscpp: no standby); warm and cold
         share the machine's load of the moment, so their ratio is the figure to read.
  thin   the main job's conditions: per cycle 12 Mbit/s (both nodes move out), then 6 Mbit/s
         with AR's 6 Mbit/s camera stream on it (AR must come back, AMCL stays on the congested
         link: below robot.launch's weak_link_mbps it would come back too), then down.
  both   (default) all of the above.
Run with the workspace sourced:
    sudo -E /usr/bin/python3 tests/bench/bench_live_migration.py [--cycles 3] [--link thin]
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

try:
    from anyscale_testbed.testbed_figures import link_transitions, move_figures, reaction_s
    from anyscale_testbed.testbed_record import TestbedRecord
    from anyscale_testbed.testbed_session import NamespaceBed, TestbedSession, layout_with_cpu
    from anyscale_testbed.two_scale_testbed import missing_capabilities
except ImportError as e:
    sys.exit(f"{os.path.basename(__file__)}: {e}: source this workspace first "
             "(source devel/setup.bash; scripts/setup.sh installs and builds it)")

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
CLOCK_TICKS = os.sysconf("SC_CLK_TCK")


TOLERANCE_S = {"amcl": 2.0, "ar_recognition": 1.0, "relay": 2.0}


def cycle_schedule(cycles: int, up_s: float, down_s: float, thin: bool = False):
    """[[t, Mbit/s], ...]: per cycle up_s of good link (the second half at 6 Mbit/s when
    thin), then down_s of link down; and the run's duration."""
    steps, t = [], 0.0
    for _ in range(cycles):
        if thin:
            steps += [[t, 12], [t + up_s / 2, 6], [t + up_s, 0]]
        else:
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


def run_nav(cycles, up_s, down_s, out, warm, thin=False):
    steps, duration = cycle_schedule(cycles, up_s, down_s, thin)
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
            os.path.join(ROOT, "src", "anyscale_testbed", "test", "system", "relay_robot.launch"),
            f"model:={model}",
            f"schedule:={steps}", f"record_path:={record}", f"duration_s:={duration}",
            "hysteresis_s:=5.0", f"uplink_interface:={bed.uplink_interface('robot')}"],
            wait_for_master=False)
        session.roslaunch("laptop", "relay_laptop", [
            "anyscale_agent_cpp", "agent.launch", "scale:=laptop", "master_scale:=robot",
            f"model:={model}", "sample_rate_hz:=5.0", "sigint_timeout_s:=2.0"])
        robot.wait(timeout=duration + 60)
    return TestbedRecord.load(record)


def node_figures(rec: TestbedRecord, outputs):
    """{node: (planned gaps out, planned gaps back, link-loss gaps, reactions)} in seconds; a
    move the run did not see to its end, or whose window a silence it did not cause began
    before, is left out."""
    downs = [t for t, up in link_transitions(rec.bandwidth) if not up]
    out = {}
    for f in move_figures(rec, outputs):
        planned, back, lost, reaction = out.setdefault(f.event.node, ([], [], [], []))
        if math.isnan(f.output_gap_s):
            continue
        if f.event.kind == "migrate":
            planned.append(f.output_gap_s)
        elif not f.event.reason.startswith("link to"):
            back.append(f.output_gap_s)
        else:
            lost.append(f.output_gap_s)
            down = max((t for t in downs if t <= f.event.decided_t), default=None)
            if down is not None:
                reaction.append(reaction_s(rec.receipts[outputs[f.event.node]], down,
                                           f.event.decided_t))
    return out


def describe(values, tolerance=math.inf):
    if not values:
        return "-"
    over = sum(v > tolerance for v in values)
    return (f"{statistics.median(values):.2f} / {max(values):.2f} s (n={len(values)}"
            + (f", {over} > {tolerance:g} s" if over else "") + ")")


def ratio(cold, warm):
    if not cold or not warm:
        return "-"
    return f"{statistics.median(cold) / statistics.median(warm):.1f}x"


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--cycles", type=int, default=3, help="good-link/link-down cycles (3)")
    p.add_argument("--up", type=float, default=25.0, help="seconds of good link per cycle")
    p.add_argument("--down", type=float, default=8.0, help="seconds of link down per cycle")
    p.add_argument("--link", choices=("clean", "thin", "both"), default="both",
                   help="clean: 27 Mbit/s cycles (warm, cold, relay); thin: 12 then 6 Mbit/s "
                        "with AR's stream on it (warm); both (default)")
    args = p.parse_args(argv)
    missing = missing_capabilities()
    if missing:
        sys.exit("bench: the test bed needs " + "; ".join(missing))
    runs = ([("warm", "clean"), ("cold", "clean"), ("relay", "clean")]
            if args.link != "thin" else []) + ([("warm", "thin")] if args.link != "clean" else [])
    nav_outputs = {"amcl": "/amcl_pose", "ar_recognition": "/ar_markers"}
    rows, cpu = [], {}
    with tempfile.TemporaryDirectory(prefix="bench_live_") as out:
        for k, (kind, link) in enumerate(runs, 1):
            label = {"warm": "navigation demo with warm standbys", "cold": "navigation demo, "
                     "cold starts", "relay": "stock topic_tools relay"}[kind]
            print(f"[{k}/{len(runs)}] {label}, {link} link, {args.cycles} cycles ...", flush=True)
            where = os.path.join(out, f"{kind}_{link}")
            os.makedirs(where)
            if kind == "relay":
                figures = node_figures(run_relay(args.cycles, args.up, args.down, where),
                                       {"relay": "/chatter_relay"})
            else:
                rec, cpu[(kind, link)] = run_nav(args.cycles, args.up, args.down, where,
                                                 kind == "warm", link == "thin")
                figures = node_figures(rec, nav_outputs)
            rows += [(n, f"{kind}, {link}", f) for n, f in figures.items()]
    print("\nmedian / worst output gap per kind of move, and the reaction to a link loss")
    print(f"{'node':<16} {'run':<12} {'planned out':<26} {'planned back':<26} "
          f"{'link loss':<26} reaction")
    for node, run, (planned, back, lost, reaction) in rows:
        tol = TOLERANCE_S.get(node, math.inf)
        print(f"{node:<16} {run:<12} {describe(planned, tol):<26} {describe(back, tol):<26} "
              f"{describe(lost, tol):<26} {describe(reaction, tol)}")
    figures = {(n, r): f for n, r, f in rows}
    if ("warm", "clean") in cpu and ("cold", "clean") in cpu:
        print("\ncold / warm (medians, same machine, one after the other):")
        for node in nav_outputs:
            w, c = figures.get((node, "warm, clean")), figures.get((node, "cold, clean"))
            if w and c:
                print(f"  {node:<16} planned gap {ratio(c[0], w[0])}, link-loss gap "
                      f"{ratio(c[2], w[2])}, reaction {ratio(c[3], w[3])}")
    print("\ndecision node CPU: "
          + ", ".join(f"{v:.2f} % ({k[0]}, {k[1]})" for k, v in cpu.items()) + " of one core")
    print("goals: planned-move gap <= one period of freq_min (AMCL 0.5 s, AR 1 s); every gap "
          "within its tolerance (AMCL 2 s, AR 1 s)")


if __name__ == "__main__":
    main()
