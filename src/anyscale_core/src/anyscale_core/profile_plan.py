"""`anyscale profile`, the pure part: which measurement windows to run, how long they will take,
what the agents' samples say about each node's CPU and memory, and the edits that write the
results into the model.

The plan follows the paper's characterisation (Table II: a node's CPU usage on each scale that
may run it). Window 1 runs every node where the paper starts it (its pinned scale, else the
master) and measures all of them there at once. Then each migratable node is moved, alone, to
each other scale that may run it (a `cpu_usage` key there, memory permitting; critical and
pinned nodes have one scale) while everything else stays home, and measured there. One node
moved at a time keeps each figure what the allocator assumes: that node's cost on that scale
with the rest of the system running as usual.

A figure is the mean of the agent's per-node CPU samples over the window (NodeProcess.cpu_percent:
utime+stime of the node's process group, % of one core) divided by the scale's capacity in
cores (its cgroup CPU quota where it has one, else its online cores): the model's `cpu_usage`
is "% of that scale's whole CPU", the unit of the agents' scale load, which the CPU constraint
adds it to. memory_mb is one number per node: the largest RSS seen on any scale, so the memory
constraint is never too optimistic. Nothing here talks to ROS (profile_ros.py does).

On a scale that runs at its quota's limit (the test bed's robot, by design: it sustains only the
minimum rates) a node's CPU is the share the scheduler gave it, and that share moves with
whatever else runs in the quota: with the agents' own work on the robot, AR got 6.8 % of a core
against 9.8 % in bench_cpu_calibration.py's agent-free set-up, and AMCL 6.1 against 5.2
(2026-11-27). The CPU per output message is the node's own cost and moves far less with the
split (the same runs: AMCL 25.1 against 24.8 ms, AR 13.3 against 12.6 ms per message). So every
figure says how busy its scale was and what one output message cost, and a saturated scale's is
named a share.
"""
import datetime
import math
import statistics
from dataclasses import dataclass, field
from typing import Dict, Iterable, List, Mapping, Optional, Sequence, Tuple

from .characterisation import characterise
# A scale busier than this over a window ran at its limit: its nodes' figures are shares (see
# above); the decision node's cost estimates judge a scale by the same rule.
from .constraints import SATURATED_PERCENT
from .model import ModelError, SystemModel
from .model_todos import home_mapping
from .model_update import CommentBlock, NumberEdit, node_paths

# Time assumed for one node's start up front (a rospy node registers in 1-3 s under the test
# bed's robot quota), and for a stop (the agent's SIGINT, then SIGKILL once it left the
# master). Only the prediction uses them; the run waits for the real events.
START_ESTIMATE_S = 3.0
STOP_ESTIMATE_S = 1.0
# Fewer samples than this in a window is no measurement (the agents sample at 2-5 Hz).
MIN_SAMPLES = 3


@dataclass(frozen=True)
class Window:
    """One measurement window: every node at home except `moved`, which runs on `scale`."""
    moved: Optional[str]                       # None: everything at home
    scale: Optional[str]
    measures: Tuple[Tuple[str, str], ...]      # (node, scale) this window gives figures for

    def describe(self) -> str:
        return "every node at home" if self.moved is None else f"{self.moved} on {self.scale}"


@dataclass(frozen=True)
class ProfilePlan:
    windows: Tuple[Window, ...]
    home: Mapping[str, str]                    # node -> where it starts
    skipped: Tuple[Tuple[str, str, str], ...]  # (node, scale, why) with a cpu_usage not measured

    @property
    def scales_needed(self) -> Tuple[str, ...]:
        seen = dict.fromkeys(self.home[n] for w in self.windows for n, _ in w.measures)
        seen.update(dict.fromkeys(w.scale for w in self.windows if w.scale))
        return tuple(seen)

    @property
    def moves(self) -> int:
        return sum(1 for w in self.windows if w.moved is not None)


def plan_profile(model: SystemModel, nodes: Optional[Sequence[str]] = None) -> ProfilePlan:
    """The windows for `nodes` (default: every node of the model). A node not in the model is
    a ModelError naming the known ones."""
    ch = characterise(model)
    selected = list(nodes) if nodes else list(model.node_names)
    unknown = [n for n in selected if n not in model.node_names]
    if unknown:
        raise ModelError("--nodes", "", f"not in {model.source}: {', '.join(unknown)} "
                                        f"(nodes: {', '.join(model.node_names)})")
    home = home_mapping(model)
    windows = [Window(None, None, tuple((n, home[n]) for n in selected))]
    skipped = []
    for name in selected:
        i = ch.node_index(name)
        for scale in model.node(name).cpu_usage:
            if scale == home[name]:
                continue
            if ch.allowed[i, ch.scale_index(scale)]:
                windows.append(Window(name, scale, ((name, scale),)))
            else:
                why = ("critical: runs only on the master" if ch.critical[i] else
                       f"pinned to {model.node(name).pinned}" if model.node(name).pinned else
                       "does not fit the scale's memory")
                skipped.append((name, scale, why))
    return ProfilePlan(tuple(windows), home, tuple(skipped))


def predict_seconds(plan: ProfilePlan, warmup_s: float, window_s: float,
                    nodes_to_start: int) -> float:
    """The whole run: starting what is not running (the agents start nodes one by one), each
    window's warm-up and measurement, each move there and back, and the final stops."""
    starts = nodes_to_start * START_ESTIMATE_S
    per_window = len(plan.windows) * (warmup_s + window_s)
    moves = plan.moves * 2 * (START_ESTIMATE_S + STOP_ESTIMATE_S)
    return starts + per_window + moves + nodes_to_start * STOP_ESTIMATE_S


def format_duration(seconds: float) -> str:
    seconds = int(round(seconds))
    if seconds < 60:
        return f"{seconds} s"
    minutes, s = divmod(seconds, 60)
    if minutes < 60:
        return f"{minutes} min {s} s"
    hours, minutes = divmod(minutes, 60)
    return f"{hours} h {minutes} min"


@dataclass(frozen=True)
class CpuSample:
    """One agent sample of one running node."""
    t: float                 # when it was received (monotonic s)
    scale: str
    node: str                # model name, no slash
    cpu_percent: float       # % of one core over the agent's sample period
    rss_bytes: int
    capacity_cores: float    # the scale's quota in cores, else its online cores
    quota: bool              # capacity_cores is a cgroup quota
    scale_busy: float = math.nan   # the scale's whole CPU then, % of capacity_cores


@dataclass(frozen=True)
class Measurement:
    node: str
    scale: str
    cpu_usage: float         # % of the scale's capacity (the model's unit)
    cpu_one_core: float      # mean % of one core
    cpu_sd: float            # standard deviation of the samples, % of one core
    samples: int
    capacity_cores: float
    quota: bool
    rss_mb: float            # largest RSS in the window
    window_s: float
    output_rates: Mapping[str, float] = field(default_factory=dict)   # topic -> Hz
    scale_busy: float = math.nan   # mean % of the scale's capacity in use over the window

    @property
    def saturated(self) -> bool:
        return self.scale_busy >= SATURATED_PERCENT

    @property
    def cpu_ms_per_message(self) -> Dict[str, float]:
        """topic -> ms of one core per message, for each output that published."""
        return {t: self.cpu_one_core * 10.0 / hz for t, hz in self.output_rates.items()
                if hz > 0}


def summarise(samples: Iterable[CpuSample], node: str, scale: str, start: float, end: float,
              output_rates: Optional[Mapping[str, float]] = None) -> Measurement:
    """The figures of `node` on `scale` from the samples received in [start, end]; ModelError
    (one line for the user) when there are too few."""
    mine = [s for s in samples if s.node == node and s.scale == scale and start <= s.t <= end]
    if len(mine) < MIN_SAMPLES:
        raise ModelError(f"{node} on {scale}", "", f"{len(mine)} CPU samples in the "
                         f"{end - start:.0f} s window (at least {MIN_SAMPLES} needed): is the "
                         f"agent of {scale} publishing /anyscale/status?")
    cpu = [s.cpu_percent for s in mine]
    mean = statistics.fmean(cpu)
    capacity = statistics.median(s.capacity_cores for s in mine)
    busy = [s.scale_busy for s in mine if math.isfinite(s.scale_busy)]
    return Measurement(node, scale, round(mean / capacity, 1), mean,
                       statistics.pstdev(cpu), len(mine), capacity, mine[-1].quota,
                       max(s.rss_bytes for s in mine) / 2 ** 20, end - start,
                       dict(output_rates or {}),
                       statistics.fmean(busy) if busy else math.nan)


def memory_figures(measurements: Sequence[Measurement]) -> Dict[str, float]:
    """node -> memory_mb to write: the largest RSS on any scale, rounded up to a MB."""
    out: Dict[str, float] = {}
    for m in measurements:
        out[m.node] = max(out.get(m.node, 0.0), float(math.ceil(m.rss_mb)))
    return out


def describe_measurement(m: Measurement) -> str:
    capacity = (f"{m.capacity_cores:g} cores, its CPU quota" if m.quota
                else f"{m.capacity_cores:g} cores")
    per_message = m.cpu_ms_per_message
    rates = "".join(f"; {topic} {hz:.1f} Hz"
                    + (f", {per_message[topic]:.1f} ms of CPU per message" if topic in per_message
                       else "")
                    for topic, hz in sorted(m.output_rates.items()))
    limit = ", at its limit: the figure is the share the node got" if m.saturated else ""
    busy = (f"; the scale {m.scale_busy:.0f} % busy{limit}" if math.isfinite(m.scale_busy)
            else "")
    return (f"{m.scale} {m.cpu_usage:g} % ({m.cpu_one_core:.1f} % of one core, sd "
            f"{m.cpu_sd:.1f}, {m.samples} samples; scale capacity {capacity}){rates}{busy}")


def profile_edits(tree: Mapping, measurements: Sequence[Measurement], when: datetime.datetime,
                  warmup_s: float, window_s: float
                  ) -> Tuple[List[NumberEdit], List[CommentBlock]]:
    """The numbers and comment blocks that write `measurements` into the model whose YAML tree
    (yaml.safe_load) is `tree`."""
    index = node_paths(tree)
    numbers, comments = [], []
    memory = memory_figures(measurements)
    by_node: Dict[str, List[Measurement]] = {}
    for m in measurements:
        by_node.setdefault(m.node, []).append(m)
    for node, ms in by_node.items():
        i = index[node]
        for m in ms:
            numbers.append(NumberEdit(("nodes", i, "cpu_usage", m.scale), m.cpu_usage))
        numbers.append(NumberEdit(("nodes", i, "memory_mb"), memory[node]))
        lines = [f"{when:%Y-%m-%d %H:%M} by `anyscale profile`: the agents' /proc samples over "
                 f"{window_s:g} s after {warmup_s:g} s of warm-up; at home with every node at "
                 "home, elsewhere moved there alone"]
        lines += [f"cpu_usage {describe_measurement(m)}" for m in ms]
        rss = ", ".join(f"{m.scale} {m.rss_mb:.1f} MB" for m in ms)
        lines.append(f"memory_mb {memory[node]:g}: the largest RSS seen ({rss})")
        comments.append(CommentBlock(("nodes", i), PROFILE_PREFIX, tuple(lines)))
    return numbers, comments


PROFILE_PREFIX = "profile: "


def measurements_json(measurements: Sequence[Measurement]) -> List[Dict]:
    return [{"node": m.node, "scale": m.scale, "cpu_usage": m.cpu_usage,
             "cpu_percent_of_one_core": round(m.cpu_one_core, 2), "cpu_sd": round(m.cpu_sd, 2),
             "samples": m.samples, "capacity_cores": m.capacity_cores, "quota": m.quota,
             "rss_mb": round(m.rss_mb, 1), "window_s": round(m.window_s, 2),
             "output_rates_hz": {t: round(hz, 2) for t, hz in m.output_rates.items()},
             "cpu_ms_per_message": {t: round(ms, 2) for t, ms in m.cpu_ms_per_message.items()},
             "scale_busy_percent": (round(m.scale_busy, 1) if math.isfinite(m.scale_busy)
                                    else None),
             "saturated": m.saturated}
            for m in measurements]
