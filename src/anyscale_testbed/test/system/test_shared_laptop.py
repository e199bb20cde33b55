"""Two robots share one laptop on the test bed (issue 39, item 2; docs/design/shared_scales.md):
both want it, there is room for one, and the laptop's capacity ledger never lets them
over-commit it.

Root: network namespaces, veths, a cgroup CPU quota (conftest.py skips without them). The suite
runs 6 rounds (about 2 min); the issue's 100 rounds take about 25 min:

    ANYSCALE_SHARED_LAPTOP_ROUNDS=100 sudo -E /usr/bin/python3 -m pytest -q -s \
        src/anyscale_testbed/test/system/test_shared_laptop.py

The bed: one process_layout bed per robot, each robot's namespace joined by a veth to a laptop
namespace. The laptop is one machine: both laptop namespaces' processes (each robot's laptop
agent, the nodes it starts, and a burner) run in one cgroup CPU quota of LAPTOP_CORES and share
one ledger file; only their network ends differ (a laptop with an interface toward each robot).
Each robot runs its own roscore, agent and decision node on the stock relay model with the
relay costing the laptop 52 % (learn_costs false): room for one robot's relay (two fill 104 %),
which goes out while the laptop's other load is at most 38 % (the paper allocator's 90 % fit).

Rounds: a seeded schedule of a burner in the laptop's quota (busy most of each 100 ms, for
4-6 s) that sends the laptop's relay home for CPU, then room (6-9 s) in which both robots'
decision nodes want the laptop at once. A sampler reads the ledger every 50 ms. Then the agent
restart and the robot that disappears: the laptop agent of the robot holding the laptop is
killed (roslaunch starts it again), and later the whole of the holding robot is killed.
"""
import math
import os
import random
import signal
import subprocess
import sys
import threading
import time

import pytest
import yaml

from anyscale_core.polling import wait_for

from anyscale_testbed.testbed_session import NamespaceBed, TestbedSession
from anyscale_testbed.two_scale_testbed import CpuQuota, process_layout

from relay_bed import PROBE, model_path, receipts

HERE = os.path.dirname(os.path.abspath(__file__))
# The suite's few rounds; the 100 (about 25 min): ANYSCALE_SHARED_LAPTOP_ROUNDS=100.
ROUNDS = int(os.environ.get("ANYSCALE_SHARED_LAPTOP_ROUNDS", "6"))
ROBOTS = ("robot_a", "robot_b")
LAPTOP_CORES = 1.0
RELAY_LAPTOP_PERCENT = 52.0
HYSTERESIS_S = 3.0
LEASE_S = 3.0                  # the decision node's default ~lease_s
RELAY_TOLERANCE_S = 2.0        # relay_model.yaml: /chatter_relay's Δ
SEED = 39
# Busy 85 of every 100 ms: the laptop at ~90 % of its quota, far above the 38 % that leaves
# room for the relay's 52 below 90 %.
BURN = """
import time
while True:
    end = time.monotonic() + 0.085
    while time.monotonic() < end:
        pass
    time.sleep(0.015)
"""
# Joins the cgroup (tasks file argv[1]) before it becomes argv[2:]: everything it starts stays in.
JOIN = "import os, sys; open(sys.argv[1], 'w').write(str(os.getpid())); " \
       "os.execvp(sys.argv[2], sys.argv[2:])"


def shared_model(run_dir):
    with open(model_path()) as f:
        model = yaml.safe_load(f)
    for node in model["nodes"]:
        if node["name"] == "relay":
            node["cpu_usage"]["laptop"] = RELAY_LAPTOP_PERCENT
    path = os.path.join(run_dir, "shared_laptop_model.yaml")
    with open(path, "w") as f:
        yaml.safe_dump(model, f)
    return path


def held(ledger):
    """robot -> CPU % its unexpired entries hold ({} while the file is not there yet). The
    agents' lease clock is CLOCK_MONOTONIC, time.monotonic() here, in every namespace."""
    try:
        with open(ledger) as f:
            text = f.read()
    except FileNotFoundError:
        return {}
    now = time.monotonic()
    out = {}
    for e in yaml.safe_load(text)["entries"]:
        if e["lease_end_s"] > now:
            out[e["robot"]] = out.get(e["robot"], 0.0) + e["cpu_percent"]
    return out


class LedgerSampler(threading.Thread):
    """(time.monotonic(), robot -> CPU % held) every 50 ms."""

    def __init__(self, ledger):
        super().__init__(daemon=True)
        self.ledger, self.samples, self.running = ledger, [], True

    def run(self):
        while self.running:
            self.samples.append((time.monotonic(), held(self.ledger)))
            time.sleep(0.05)

    def holder(self):
        last = self.samples[-1][1] if self.samples else {}
        return next(iter(last), None) if len(last) == 1 else None


def pids_with(*words):
    """The live processes whose command line holds every word."""
    found = []
    for pid in filter(str.isdigit, os.listdir("/proc")):
        try:
            with open(f"/proc/{pid}/cmdline", "rb") as f:
                args = f.read().decode(errors="replace").split("\0")
        except OSError:
            continue
        if all(w in args for w in words):
            found.append(int(pid))
    return found


def kill_namespace(bed):
    """SIGKILL to every process of a robot's own (its network namespace): its roscore, agent,
    decision node and nodes."""
    listed = subprocess.run(["ip", "netns", "pids", bed.end("robot").namespace],
                            capture_output=True, text=True).stdout.split()
    for pid in map(int, filter(str.isdigit, listed)):
        try:
            os.kill(pid, signal.SIGKILL)
        except ProcessLookupError:
            pass


def laptop_agent(robot):
    pids = pids_with(f"_robot:={robot}", "__name:=anyscale_agent_laptop")
    agents = {pid: open(f"/proc/{pid}/cmdline").read().replace("\0", " ")
              for pid in pids_with("__name:=anyscale_agent_laptop")}
    assert len(pids) == 1, f"{robot}'s laptop agent: {pids} of {agents}"
    return pids[0]


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    run_dir = str(tmp_path_factory.mktemp("shared_laptop"))
    model = shared_model(run_dir)
    ledger = os.path.join(run_dir, "ledger", "laptop.yaml")
    quota = CpuQuota(f"asshl{os.getpid()}", LAPTOP_CORES)
    rng = random.Random(SEED)
    out = {"rounds": [], "receipts": {}, "ledger": ledger, "run_dir": run_dir}
    with NamespaceBed(process_layout("shla", "10.213.91")) as bed_a, \
            NamespaceBed(process_layout("shlb", "10.213.92")) as bed_b:
        quota.create()
        beds = dict(zip(ROBOTS, (bed_a, bed_b)))
        sessions, robots, burner = {}, {}, None
        try:
            for name, bed in beds.items():
                session = sessions[name] = TestbedSession(bed, os.path.join(run_dir, name))
                robots[name] = session.roslaunch("robot", "robot", [
                    os.path.join(HERE, "shared_laptop_robot.launch"), f"model:={model}",
                    f"hysteresis_s:={HYSTERESIS_S}",
                    f"uplink_interface:={bed.uplink_interface('robot')}"],
                    wait_for_master=False)
                bed.start("laptop", [sys.executable, "-c", JOIN, os.path.join(quota.path, "tasks"),
                                     "roslaunch", "--wait", "anyscale_agent_cpp", "agent.launch",
                                     "scale:=laptop", "master_scale:=robot", f"model:={model}",
                                     "sample_rate_hz:=5.0", "sigint_timeout_s:=2.0",
                                     f"robot:={name}", f"ledger_file:={ledger}", "respawn:=true"],
                          session.env("laptop"), os.path.join(session.log_dir, "laptop.log"),
                          cpu_quota=False)
                out["receipts"][name] = os.path.join(run_dir, name, "receipts.txt")
                bed.start("robot", [sys.executable, "-c", PROBE, out["receipts"][name]],
                          session.env("robot"), os.path.join(session.log_dir, "probe.log"),
                          cpu_quota=False)
            sampler = LedgerSampler(ledger)
            sampler.start()
            assert wait_for(lambda: sampler.holder() is not None, 90.0, 0.2), \
                "neither robot's relay went to the laptop"
            out["began"] = time.monotonic()
            for _ in range(ROUNDS):
                burn_s, room_s = rng.uniform(4.0, 6.0), rng.uniform(6.0, 9.0)
                burner = subprocess.Popen([sys.executable, "-c", BURN], start_new_session=True,
                                          preexec_fn=lambda: quota.add(os.getpid()))
                started = time.monotonic()
                time.sleep(burn_s)
                burner.kill()
                burner.wait()
                freed = time.monotonic()
                time.sleep(room_s)
                out["rounds"].append((started, freed, time.monotonic()))
            out["rounds_ended"] = time.monotonic()
            # An agent restart: the laptop agent of the robot holding the laptop is killed.
            out["restart"] = end_phase(sampler, lambda robot: os.kill(laptop_agent(robot),
                                                                      signal.SIGKILL))
            # A robot that disappears: everything in the holding robot's namespace is killed.
            out["gone"] = end_phase(sampler, lambda robot: kill_namespace(beds[robot]))
            sampler.running = False
            sampler.join()
            out["samples"] = sampler.samples
        finally:
            if burner is not None and burner.poll() is None:
                burner.kill()
            for bed in (bed_b, bed_a):
                bed.teardown()
            left = quota.remove()
            if left:
                print(f"test bed: teardown left behind {left}", file=sys.stderr)
    for name in ROBOTS:
        out["receipts"][name] = receipts(out["receipts"][name])
    return out


def end_phase(sampler, kill):
    """Kills (with `kill`) what of the robot holding the laptop the phase is about; the robot,
    when, and when the other robot held the laptop after it (None: not within 60 s)."""
    assert wait_for(lambda: sampler.holder() is not None, 60.0, 0.1), "nobody holds the laptop"
    robot = sampler.holder()
    killed = time.monotonic()
    kill(robot)
    other = next(r for r in ROBOTS if r != robot)
    taken = wait_for(lambda: sampler.holder() == other, 60.0, 0.1)
    return robot, killed, time.monotonic() if taken else None


def test_the_laptops_admitted_cpu_never_exceeds_its_capacity(run):
    assert len(run["rounds"]) == ROUNDS
    most = max(sum(h.values()) for _, h in run["samples"])
    both = [t for t, h in run["samples"] if len(h) > 1]
    print(f"{len(run['samples'])} ledger samples: at most {most:g} % held; "
          f"{len(both)} with both robots holding")
    assert most <= 100.0
    assert not both, \
        f"both relays ({RELAY_LAPTOP_PERCENT:g} % each) were held on the laptop at once"


def test_both_robots_wanted_the_laptop_and_took_it_in_turn(run):
    holders, taken = set(), 0
    for started, freed, ended in run["rounds"]:
        after = [h for t, h in run["samples"] if freed <= t < ended and h]
        if after:
            taken += 1
            holders.update(after[-1])
    print(f"{taken} of {len(run['rounds'])} rounds: the laptop was taken once room came back; "
          f"holders {sorted(holders)}")
    assert taken >= 0.8 * len(run["rounds"])
    assert holders == set(ROBOTS), "one robot never got the laptop"
    refusals = {}
    for name in ROBOTS:
        with open(os.path.join(run["run_dir"], name, "logs", "robot.log"),
                  errors="replace") as f:
            refusals[name] = sum("laptop full:" in line for line in f)
    print(f"starts refused for capacity (decision nodes' log lines): {refusals}")


def test_no_robots_tolerance_was_broken_during_the_rounds(run):
    for name in ROBOTS:
        times = [t for t, _ in run["receipts"][name]]
        assert times, f"{name}: /chatter_relay never arrived"
        # Wall-clock receipts against the monotonic rounds: both clocks advance together.
        offset = time.time() - time.monotonic()
        begin, end = run["began"] + offset, run["rounds_ended"] + offset
        during = [t for t in times if begin <= t <= end]
        gaps = [b - a for a, b in zip([begin] + during, during + [end])]
        print(f"{name}: {len(during)} /chatter_relay messages in the rounds, longest gap "
              f"{max(gaps):.2f} s (Δ {RELAY_TOLERANCE_S:g} s)")
        assert max(gaps) <= RELAY_TOLERANCE_S, name


@pytest.mark.parametrize("phase", ["restart", "gone"])
def test_what_a_killed_agent_or_a_gone_robot_held_is_free_once_its_leases_end(run, phase):
    robot, killed, taken = run[phase]
    # Until the first sample without it: the robot may take the laptop again later, by rule.
    freed = next((t - killed for t, h in run["samples"] if t >= killed and robot not in h), None)
    print(f"{phase}: {robot}'s capacity held {freed if freed is not None else math.inf:.2f} s "
          f"after the kill; the other robot took the laptop {(taken or killed) - killed:.1f} s "
          "after it")
    assert freed is not None and freed <= LEASE_S + 0.5
    assert taken is not None, "the other robot never took the laptop"
