"""The fault soak's verdicts, pure (no ROS): from what the soak sampled (its /proc census of
instances and supervisors, the memory and file descriptors of the agents and the decision
node, the faults as injected) and the monitor's record of the run, per fault its recovery
time and the invariants it broke, and the growth of memory and file descriptors.
soak_report.py makes the table of them that tests/bench/bench_fault_soak.py prints and writes.

Every time here is on the record's clock (s since the monitor started).

The invariants (issue 15):
- exactly one instance of each node: two live instances (or one on a scale the mapping does
  not place it on) for longer than a lease plus LEASE_GRACE_S, outside a planned move's
  make-before-break overlap, is a violation: an instance cut off from the robot ends only when
  its lease runs out, so that long is allowed;
- no publisher of a recorded topic on a scale the mapping does not place its node on, in the
  master's lists, for longer than that (a registration can outlive its process);
- nodes that may not move (critical or pinned) never leave the master scale: not in the
  mapping, not in an event, not as a process elsewhere;
- every connection's tolerance Δ: an output silent longer than Δ, charged to the last fault
  that struck before the silence became a violation (one already too long then is no doing of
  that fault; one before the first fault is named as the start-up's); a critical
  connection's (Δ 0) topic silent for longer than a period at its freq_min (plus
  CRITICAL_SLACK_S), likewise (the silences themselves: soak_silences.py);
- the fault is recovered from before the next one: every supervisor (both agents, the
  decision node, the master) runs once, every node runs once where the mapping places it,
  every output has spoken since the fault ended, and the master lists a publisher for it;
- nothing left behind at the end (and no growth of memory or file descriptors: soak_growth.py)."""
from dataclasses import dataclass, field
import math
from typing import Dict, List, Optional, Sequence, Set, Tuple

from .fault_schedule import Fault
from .soak_silences import charged_to, silence_violations, worst_silence
from .testbed_figures import handover_windows
from .testbed_record import TestbedRecord, mapping_at

# An instance cut off from the robot runs until its lease ends; its agent checks leases about
# once a second and the census samples twice a second: this long on top of the lease.
LEASE_GRACE_S = 2.0
# A stretch of two instances or of a misplaced publisher that began this long before a fault
# is the fault's, and so is the output silence reported as its worst: one period of AR's 1 Hz
# minimum. (A silence's violation goes by its own limit: soak_silences.charged_to.)
FAULT_LEAD_S = 1.0
SUPERVISORS = ("agent_robot", "agent_laptop", "decision", "master")


@dataclass
class CensusSample:
    t: float
    instances: Dict[str, List[str]]      # node -> the scale of each live instance
    supervisors: Dict[str, int]          # role (SUPERVISORS) -> live processes
    processes: int = 0                   # every live process of this ROS system
    cpu: List[Tuple[str, str, int, float]] = field(default_factory=list)   # soak_cpu.py
    # "<instance name> <CPU group>" of each warm standby among `processes`; None: not recorded
    # (soaks before 2026-11-27)
    standbys: Optional[List[str]] = None


@dataclass
class InjectedFault:
    fault: Fault            # as scheduled
    t: float                # when it struck
    end: float              # when it ended (link back, SIGCONT); = t if instantaneous
    detail: str = ""        # what was hit, e.g. "pid 4711 on laptop"
    error: str = ""         # why it could not be injected (then it is not judged)


@dataclass
class SoakModel:
    """What the checks need of the system model and the decision node's settings."""
    master: str                                  # the master scale
    nodes: Sequence[str]
    fixed: Set[str]                              # critical or pinned: never leave the master
    instance_names: Dict[Tuple[str, str], str]   # (node, scale) -> its name on the master
    lease_s: float


@dataclass
class FaultOutcome:
    index: int              # 1-based, in the order injected
    injected: InjectedFault
    window_end: float       # the next fault's start, or the soak's end
    recovery_s: float       # fault start -> recovered; inf if it was not before window_end
    worst_silence: Tuple[str, float, float] = ("", 0.0, 0.0)   # topic, silence, its Δ
    violations: List[str] = field(default_factory=list)

    @property
    def kind(self) -> str:
        return self.injected.fault.kind


# --- per fault ----------------------------------------------------------------------------------
def judge_faults(faults: Sequence[InjectedFault], census: Sequence[CensusSample],
                 rec: TestbedRecord, model: SoakModel, end_t: float) -> List[FaultOutcome]:
    """Each injected fault's recovery and violations, its window reaching to the next fault."""
    ordered = sorted(faults, key=lambda f: f.t)
    outcomes = []
    for i, f in enumerate(ordered):
        window_end = ordered[i + 1].t if i + 1 < len(ordered) else end_t
        outcomes.append(FaultOutcome(i + 1, f, window_end, math.inf))
    judged = [o for o in outcomes if not o.injected.error]
    for o in judged:
        o.recovery_s = recovery_s(o.injected, o.window_end, census, rec, model)
        if not math.isfinite(o.recovery_s):
            why = unhealthy_reason(census, rec, model, o.injected.end, o.window_end)
            o.violations.append(f"not recovered within {o.window_end - o.injected.t:.1f} s: {why}")
    for t, text in instance_violations(census, rec, model):
        _charge(judged, t, text)
    for t, text in fixed_node_violations(census, rec, model):
        _charge(judged, t, text)
    for t, text in publisher_violations(rec, model):
        _charge(judged, t, text)
    for v, text in silence_violations(rec):
        i = charged_to([o.injected.t for o in judged], v)
        if i is not None:
            lag = v.start_t - judged[i].injected.t
            judged[i].violations.append(f"{text} (began {abs(lag):.2f} s "
                                        f"{'after' if lag >= 0 else 'before'} the fault struck)")
    for o in judged:
        o.worst_silence = worst_silence(rec, o.injected.t - FAULT_LEAD_S, o.window_end)
    return outcomes


def _charge(outcomes: Sequence[FaultOutcome], t: float, text: str):
    """A violation found at `t` goes to the fault in whose window it began (a violation before
    the first fault is the start-up's, not a fault's, and is not charged)."""
    owner = None
    for o in outcomes:
        if o.injected.t - FAULT_LEAD_S <= t:
            owner = o
    if owner is not None and text not in owner.violations:
        owner.violations.append(text)


def healthy(sample: CensusSample, mapping: Dict[str, str], model: SoakModel) -> Optional[str]:
    """None if the sample is healthy, else why not, in words."""
    down = [r for r in SUPERVISORS if sample.supervisors.get(r, 0) != 1]
    if down:
        return ", ".join(f"{r} x{sample.supervisors.get(r, 0)}" for r in down)
    for node in model.nodes:
        scales = sample.instances.get(node, [])
        where = mapping.get(node, model.master)
        if scales != [where]:
            return f"{node} on [{', '.join(scales)}], mapped to {where}"
    return None


def recovery_s(f: InjectedFault, window_end: float, census: Sequence[CensusSample],
               rec: TestbedRecord, model: SoakModel) -> float:
    """From the fault's start to the first census sample after its end at which the system is
    whole again (see the module's docstring); inf if none came before `window_end`."""
    for s in census:
        if s.t < f.end or s.t > window_end:
            continue
        if healthy(s, mapping_at(rec, s.t), model) is None and \
                outputs_spoke(rec, f.end, s.t) and publishers_listed(rec, model, f.end, s.t):
            return s.t - f.t
    return math.inf


def unhealthy_reason(census: Sequence[CensusSample], rec: TestbedRecord, model: SoakModel,
                     since: float, until: float) -> str:
    """Why the system was not whole at the end of a window, in words, for the report."""
    inside = [s for s in census if since <= s.t <= until]
    if not inside:
        return "no census sample in the window"
    last = inside[-1]
    why = healthy(last, mapping_at(rec, last.t), model)
    if why:
        return f"at t={last.t:.1f} s: {why}"
    silent = [t for t in sorted(rec.tolerances)
              if not any(since < x <= last.t for x in rec.receipts.get(t, []))]
    if silent:
        return f"no message on {', '.join(silent)} since the fault ended"
    missing = unlisted_publishers(rec, model, since, last.t)
    return (f"the master lists no publisher {missing}" if missing
            else "the master could not be asked since the fault ended")


def outputs_spoke(rec: TestbedRecord, since: float, until: float) -> bool:
    """Every output with a tolerance has had a message in (since, until]."""
    return all(any(since < t <= until for t in rec.receipts.get(topic, []))
               for topic in rec.tolerances)


def publishers_listed(rec: TestbedRecord, model: SoakModel, since: float,
                      until: float) -> bool:
    """At a master poll in (since, until], each output's node was registered as its publisher
    under the instance name of the scale the mapping places it on."""
    return any(not _unlisted(publishers, mapping_at(rec, t), rec, model)
               for t, publishers in rec.master_publishers if since < t <= until)


def unlisted_publishers(rec: TestbedRecord, model: SoakModel, since: float,
                        until: float) -> str:
    polls = [(t, p) for t, p in rec.master_publishers if since < t <= until]
    if not polls:
        return ""
    t, publishers = polls[-1]
    return ", ".join(_unlisted(publishers, mapping_at(rec, t), rec, model))


def _unlisted(publishers: Dict[str, List[str]], mapping: Dict[str, str], rec: TestbedRecord,
              model: SoakModel) -> List[str]:
    out = []
    for node, topic in sorted(rec.outputs.items()):
        name = model.instance_names.get((node, mapping.get(node, model.master)))
        if name is not None and name not in publishers.get(topic, []):
            out.append(f"{name} of {topic}")
    return out


def instance_violations(census: Sequence[CensusSample], rec: TestbedRecord,
                        model: SoakModel) -> List[Tuple[float, str]]:
    """(start, text) of every stretch in which a node ran twice or on a scale the mapping did
    not place it on, for longer than a lease plus LEASE_GRACE_S, outside a planned move's
    overlap. A node with no instance is not counted here: that is a recovery not yet done."""
    windows = handover_windows(rec.events)
    found = []
    for node in model.nodes:
        marks = [(s.t, ", ".join(s.instances.get(node, [])))
                 for s in census if _misplaced(s, node, mapping_at(rec, s.t), model)
                 and not any(a <= s.t <= b for a, b in windows.get(node, []))]
        for start, end, scales in _long_stretches(marks, [s.t for s in census], model):
            where = mapping_at(rec, start).get(node, model.master)
            found.append((start, f"{node} on [{scales}] (mapped to {where}) for "
                                 f"{end - start:.1f} s from t={start:.1f} s "
                                 f"(a lease is {model.lease_s:g} s)"))
    return sorted(found)


def publisher_violations(rec: TestbedRecord, model: SoakModel) -> List[Tuple[float, str]]:
    """(start, text) of every stretch in which the master listed a node's instance on a scale
    the mapping did not place it on as a publisher of a recorded topic, for longer than a
    lease plus LEASE_GRACE_S, outside a planned move's overlap. The /proc census cannot see
    this: a registration outlives its process (a partition, a kill -9) until the decision
    node removes it, and subscribers keep connecting to it for as long as it is listed. An
    instance paused at home (launch.pause_at_home) stays registered by design and publishes
    nothing: the monitor's process sample of the same moment names it, and it is left out."""
    instance_of = {name: key for key, name in model.instance_names.items()}
    windows = handover_windows(rec.events)
    paused = {p.t: set(p.paused) for p in rec.processes}
    polls = [t for t, _ in rec.master_publishers]
    marks: Dict[str, List[Tuple[float, str]]] = {}
    for t, publishers in rec.master_publishers:
        mapping = mapping_at(rec, t)
        for topic, names in sorted(publishers.items()):
            for name in set(names) - paused.get(t, set()):
                node, scale = instance_of.get(name, (None, None))
                if node is not None and scale != mapping.get(node, model.master) and \
                        not any(a <= t <= b for a, b in windows.get(node, [])):
                    marks.setdefault(f"{name} of {topic}", []).append((t, ""))
    found = []
    for what, times in sorted(marks.items()):
        for start, end, _ in _long_stretches(times, polls, model):
            found.append((start, f"the master listed {what} (not where the mapping places it) "
                                 f"for {end - start:.1f} s from t={start:.1f} s (a lease is "
                                 f"{model.lease_s:g} s)"))
    return sorted(found)


def _long_stretches(marks: Sequence[Tuple[float, str]], times: Sequence[float],
                    model: SoakModel) -> List[Tuple[float, float, str]]:
    """(first, last, first's text) of each run of consecutive sampled `times` that are all
    marked, lasting longer than a lease plus LEASE_GRACE_S: a stretch ends at the first sample
    that is not marked."""
    marked = dict(marks)
    found, first, last = [], None, None
    for t in list(times) + [None]:
        if t is not None and t in marked:
            first = t if first is None else first
            last = t
            continue
        if first is not None and last - first > model.lease_s + LEASE_GRACE_S:
            found.append((first, last, marked[first]))
        first = last = None
    return found


def _misplaced(s: CensusSample, node: str, mapping: Dict[str, str], model: SoakModel) -> bool:
    scales = s.instances.get(node, [])
    return len(scales) > 1 or (len(scales) == 1 and scales[0] != mapping.get(node, model.master))


def fixed_node_violations(census: Sequence[CensusSample], rec: TestbedRecord,
                          model: SoakModel) -> List[Tuple[float, str]]:
    """(t, text) of each sign that a node that may not move did: a move event, a mapping that
    places it off the master, a live process of it on another scale (first of each)."""
    found: Dict[Tuple[str, str], Tuple[float, str]] = {}
    for e in rec.events:
        if e.node in model.fixed and e.kind in ("migrate", "migrate_back"):
            found.setdefault((e.node, "event"), (e.decided_t, f"{e.kind} of {e.node} "
                                                 f"{e.from_scale} -> {e.to_scale} (it may not "
                                                 f"move)"))
    for t, mapping, _, _ in rec.mappings:
        for node in model.fixed:
            if mapping.get(node, model.master) != model.master:
                found.setdefault((node, "mapping"), (t, f"the mapping placed {node} on "
                                                        f"{mapping[node]} (it may not move)"))
    for s in census:
        for node in model.fixed:
            away = [x for x in s.instances.get(node, []) if x != model.master]
            if away:
                found.setdefault((node, "process"), (s.t, f"{node} ran on {away[0]} at "
                                                          f"t={s.t:.1f} s (it may not move)"))
    return sorted(found.values())


def process_leak(census: Sequence[CensusSample], rec: TestbedRecord,
                 model: SoakModel, since: float) -> List[str]:
    """A leak of processes: more processes of the ROS system at the last healthy sample than
    at the first one from `since` (the first fault: the start has settled) with the same
    placement of every node (launchers, nodes and supervisors are all counted; a killed
    agent's orphans would show here), or two warm standbys of one instance in one CPU group.

    Standbys are counted apart: whether an agent holds one for a node depends on when the
    node last started there (the next one is prepared some seconds later, and one is kept
    beside a node that crashed there before), not on the placement. A soak of 2026-11-27 (seed
    2) counted 29 processes at t=46 s, just after AMCL moved to the laptop, and 30 at its
    end, the laptop's AMCL standby prepared since. Before the start settles the agents are
    still preparing theirs: a CI soak counted 26 processes at t=5.5 s and 28 from 6.5 s."""
    whole = [s for s in census if s.t >= since and healthy(s, mapping_at(rec, s.t), model) is None]
    if len(whole) < 2:
        return []
    last = whole[-1]
    same = [s for s in whole if s.instances == last.instances]
    first = same[0]
    leaks = []
    standbys = last.standbys or []
    running = (last.processes - len(standbys), first.processes - len(first.standbys or []))
    if running[0] > running[1]:
        apart = "" if last.standbys is None else " besides warm standbys"
        leaks.append(f"{running[0]} processes of the ROS system{apart} at t={last.t:.1f} s "
                     f"against {running[1]} at t={first.t:.1f} s, every node placed alike")
    doubled = sorted({x for x in standbys if standbys.count(x) > 1})
    if doubled:
        leaks.append(f"{len(standbys)} warm standbys at t={last.t:.1f} s, two or more of "
                     + ", ".join(doubled))
    return leaks
