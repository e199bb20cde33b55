"""The fault soak's schedule (tests/bench/bench_fault_soak.py), pure: which fault comes when,
drawn from a seed, so that a soak can be run again fault for fault.

Kinds (issue 15): link flaps of 1-5 s and bandwidth steps (the link shaper's settings), kill -9
of the laptop's and of the robot's agent, kill -9 of the decision node (roslaunch restarts it),
SIGSTOP/SIGCONT of the laptop's agent for 1-4 s, SIGSEGV of a managed node, and a restart of
roscore. Faults come one at a time: each is followed by a pause long enough for the system to
recover (SETTLE_S, measured on the test bed) plus a seeded jitter, so that a recovery time and
a violation belong to one fault."""
from dataclasses import dataclass
import random
from typing import Callable, Dict, List, Optional, Sequence

LINK_FLAP = "link_flap"
BANDWIDTH_STEP = "bandwidth_step"
KILL_LAPTOP_AGENT = "kill_laptop_agent"
KILL_ROBOT_AGENT = "kill_robot_agent"
KILL_DECISION = "kill_decision"
STOP_LAPTOP_AGENT = "stop_laptop_agent"
SEGV_NODE = "segv_node"
RESTART_ROSCORE = "restart_roscore"
KINDS = (LINK_FLAP, BANDWIDTH_STEP, KILL_LAPTOP_AGENT, KILL_ROBOT_AGENT, KILL_DECISION,
         STOP_LAPTOP_AGENT, SEGV_NODE, RESTART_ROSCORE)

FLAP_S = (1.0, 5.0)          # how long a link flap keeps the link down
STOP_S = (1.0, 4.0)          # how long the laptop's agent stays stopped
# The link shaper's rates a bandwidth step chooses from (802.11g's usable rates in the WiFi
# model): 27 and 12 carry AR's camera stream, 3 does not, so steps move AR as well.
LEVELS_MBPS = (27.0, 12.0, 6.0, 3.0)
START_MBPS = 27.0

# The pause after a fault before the next one, in s from the fault's end: what the test bed
# needs to get back to one instance of every node in its place. A killed robot agent's nodes
# run on and its successor adopts them (~nodes_outlive_agent), but the successor comes up
# under the robot's CPU quota and the pause is kept for a node the adoption drops; a roscore
# restart needs every registration and parameter back on the new master.
SETTLE_S: Dict[str, float] = {
    LINK_FLAP: 6.0, BANDWIDTH_STEP: 5.0, KILL_LAPTOP_AGENT: 8.0, KILL_ROBOT_AGENT: 20.0,
    KILL_DECISION: 6.0, STOP_LAPTOP_AGENT: 6.0, SEGV_NODE: 6.0, RESTART_ROSCORE: 20.0}
JITTER_S = 4.0               # up to this much more, seeded
# Before the first fault: the start's own settling, counted from the last change of placement
# once the soak's starting placement is reached (AMCL on the laptop). AMCL's move out is
# followed by AR's when the link carries it, and each moved node's connections are not judged
# for the decision node's startup_grace_s (robot.launch: 8 s).
START_SETTLE_S = 10.0
# How often each kind is drawn once every kind has had its turn: link faults are the
# everyday ones, process kills the rare ones.
WEIGHTS: Dict[str, float] = {
    LINK_FLAP: 4.0, BANDWIDTH_STEP: 3.0, KILL_LAPTOP_AGENT: 1.0, KILL_ROBOT_AGENT: 1.0,
    KILL_DECISION: 1.0, STOP_LAPTOP_AGENT: 2.0, SEGV_NODE: 2.0, RESTART_ROSCORE: 0.0}


@dataclass(frozen=True)
class Fault:
    t: float                # s after the soak's first fault
    kind: str
    hold_s: float = 0.0     # link flap: down for; stop: stopped for; else 0
    mbps: float = 0.0       # bandwidth step: the new rate; link flap: the rate it comes back at
    target: str = ""        # SIGSEGV: the model node hit

    @property
    def end(self) -> float:
        return self.t + self.hold_s

    def describe(self) -> str:
        if self.kind == LINK_FLAP:
            return f"link down for {self.hold_s:.1f} s"
        if self.kind == BANDWIDTH_STEP:
            return f"link to {self.mbps:g} Mbit/s"
        if self.kind == STOP_LAPTOP_AGENT:
            return f"SIGSTOP the laptop's agent for {self.hold_s:.1f} s"
        if self.kind == SEGV_NODE:
            return f"SIGSEGV {self.target}"
        return {KILL_LAPTOP_AGENT: "kill -9 the laptop's agent",
                KILL_ROBOT_AGENT: "kill -9 the robot's agent",
                KILL_DECISION: "kill -9 the decision node",
                RESTART_ROSCORE: "kill -9 roscore, start it again"}[self.kind]


class ScheduleError(ValueError):
    """Arguments no schedule can be made from; the message says which and why."""


def make_schedule(seed: int, duration_s: float, segv_targets: Sequence[str],
                  roscore_restarts: int = 1,
                  weights: Optional[Dict[str, float]] = None) -> List[Fault]:
    """The faults of a soak of about `duration_s` seconds, the same for the same seed.

    Every kind but the roscore restart comes once first, in a seeded order, so that even a
    short soak meets each; then kinds are drawn by `weights` while the time lasts. The
    `roscore_restarts` come last: ROS 1 keeps the parameters and registrations in the master
    only, and whatever a restarted master did not get back (robot.launch's master keeper gives
    it what the old one held) would be charged to every later fault."""
    if not duration_s > 0:
        raise ScheduleError(f"duration: expected > 0 s, got {duration_s}")
    if not segv_targets:
        raise ScheduleError("no node to send SIGSEGV to")
    if roscore_restarts < 0:
        raise ScheduleError(f"roscore restarts: expected >= 0, got {roscore_restarts}")
    weights = dict(WEIGHTS if weights is None else weights)
    unknown = set(weights) - set(KINDS)
    if unknown:
        raise ScheduleError(f"unknown fault kinds: {', '.join(sorted(unknown))}")
    rng = random.Random(seed)
    drawable = [k for k in KINDS if k != RESTART_ROSCORE and weights.get(k, 0.0) > 0]
    first = [k for k in KINDS if k != RESTART_ROSCORE]
    rng.shuffle(first)
    tail = [RESTART_ROSCORE] * roscore_restarts
    reserved = sum(SETTLE_S[k] + JITTER_S / 2 for k in tail)
    faults: List[Fault] = []
    t, mbps = 0.0, START_MBPS
    kinds = iter(first)
    while True:
        kind = next(kinds, None)
        if kind is None:
            if not drawable or t + reserved >= duration_s:
                break
            kind = rng.choices(drawable, [weights[k] for k in drawable])[0]
        fault, mbps = _draw(rng, t, kind, mbps, segv_targets)
        faults.append(fault)
        t = fault.end + SETTLE_S[kind] + rng.uniform(0.0, JITTER_S)
    for kind in tail:
        fault, mbps = _draw(rng, t, kind, mbps, segv_targets)
        faults.append(fault)
        t = fault.end + SETTLE_S[kind] + rng.uniform(0.0, JITTER_S)
    return faults


def _draw(rng: random.Random, t: float, kind: str, mbps: float, segv_targets: Sequence[str]):
    """One fault of `kind` at `t` while the link runs at `mbps`; and the rate after it."""
    if kind == LINK_FLAP:
        return Fault(round(t, 2), kind, hold_s=round(rng.uniform(*FLAP_S), 2), mbps=mbps), mbps
    if kind == BANDWIDTH_STEP:
        new = rng.choice([m for m in LEVELS_MBPS if m != mbps])
        return Fault(round(t, 2), kind, mbps=new), new
    if kind == STOP_LAPTOP_AGENT:
        return Fault(round(t, 2), kind, hold_s=round(rng.uniform(*STOP_S), 2)), mbps
    if kind == SEGV_NODE:
        return Fault(round(t, 2), kind, target=rng.choice(list(segv_targets))), mbps
    return Fault(round(t, 2), kind), mbps


def first_fault_at(samples: Sequence, ready: Callable[[object], bool]) -> Optional[float]:
    """When the first fault may strike: START_SETTLE_S after the last change of placement (a
    sample's `instances`), once every sample since has been `ready`; None while that has not
    been so for START_SETTLE_S. `samples` in time order, each with .t and .instances."""
    since = None
    for before, s in zip([None] + list(samples[:-1]), samples):
        if not ready(s):
            since = None
        elif since is None or before.instances != s.instances:
            since = s.t
    if since is None or samples[-1].t < since + START_SETTLE_S:
        return None
    return since + START_SETTLE_S


def schedule_length_s(faults: Sequence[Fault]) -> float:
    """From the first fault to the end of the last one's settling pause."""
    return max((f.end + SETTLE_S[f.kind] for f in faults), default=0.0)
