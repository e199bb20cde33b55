"""The fault soak's silence verdicts, pure (no ROS): which outputs (Δ > 0) and which critical
connections' topics (Δ 0) were silent too long in the monitor's record, counted up to the
run's teardown, in words; which fault a silence is charged to; the worst silence after a
fault. soak_invariants.py charges them to the faults with its other invariants.

Every time here is on the record's clock (s since the monitor started)."""
import statistics
from typing import List, Optional, Sequence, Tuple

from .testbed_figures import record_end, silence_cause, silences_longer_than, tolerance_violations
from .testbed_record import TestbedRecord, Violation

# A critical connection (Δ 0) may never run below its freq_min: its topic silent for longer
# than one period at freq_min is a violation, and on top of that period one period of the
# robot's CPU quota (the cgroup's cfs_period_us, 100 ms on the test bed): a group at its quota
# is held back that long at most, so a message due then comes that much late while the rate
# is not below its minimum.
CRITICAL_SLACK_S = 0.1


def judged_end(rec: TestbedRecord) -> float:
    """Where every silence is counted up to: the last message of any critical topic, not the
    record's end. The run's teardown stops the sensors together some tenths of a second
    before the monitor ends (0.63 s in the first CI soak; 0.68 s in the system test's run 2,
    whose /ar_markers, last heard 0.51 s before, was judged silent 1.19 s > Δ 1 s): a tail no
    fault made. A topic that stops alone is still counted to there. Without the critical
    topics (no ~record_critical), the record's end."""
    last = [ts[-1] for topic in rec.critical_freq_min
            for ts in [sorted(rec.receipts.get(topic, []))] if ts]
    return min(record_end(rec), max(last)) if last else record_end(rec)


def critical_violations(rec: TestbedRecord) -> List[Violation]:
    """Every silence of a critical connection's topic longer than a period at its freq_min
    plus CRITICAL_SLACK_S (their Violation's tolerance_s is that limit), up to judged_end.
    testbed_record's tolerance_violations leaves these out: an evaluation run records no
    critical topic."""
    end = judged_end(rec)
    found = []
    for topic, freq_min in sorted(rec.critical_freq_min.items()):
        limit = 1.0 / freq_min + CRITICAL_SLACK_S
        for a, b in silences_longer_than(rec.receipts.get(topic, []), limit, end):
            words = [w for w in (silence_cause(rec, set(), a, b),
                                 made_or_delivered(rec, topic, a, b, limit),
                                 also_silent(rec, topic, a, b)) if w]
            found.append(Violation(topic, a, b, b - a, limit, "; ".join(words)))
    return found


def made_or_delivered(rec: TestbedRecord, topic: str, a: float, b: float, limit: float) -> str:
    """Whether the messages received at `a` and `b` (a silence's ends) carry data as far apart,
    from their header stamps (their data's time: a driver's sample, or the input a node
    derived them from), in words: "" where the record has no stamps for them."""
    stamped = dict(map(tuple, rec.stamps.get(topic, [])))
    if a not in stamped or b not in stamped:
        return ""
    made, late = stamped[b] - stamped[a], b - stamped[b]
    if made > limit:
        return f"stamped {made:.2f} s apart: its data came late to its publisher"
    return (f"stamped {made:.2f} s apart, the first after it received {late:.2f} s after its "
            f"stamp: its data on time, late from its publisher to the monitor")


def also_silent(rec: TestbedRecord, topic: str, a: float, b: float) -> str:
    """The other critical topics that usually come more than twice between `a` and `b` (their
    median interval) but of which the monitor received nothing then, in words: silent together,
    the stall is shared (the robot's CPU, or the monitor's)."""
    others = []
    for other in sorted(rec.critical_freq_min):
        times = sorted(rec.receipts.get(other, []))
        if other == topic or len(times) < 3:
            continue
        usual = statistics.median(y - x for x, y in zip(times, times[1:]))
        if 2 * usual < b - a and not any(a < t < b for t in times):
            others.append(other)
    return f"nothing received of {', '.join(others)} either" if others else ""


def silence_violations(rec: TestbedRecord) -> List[Tuple[Violation, str]]:
    """Every output silent longer than its Δ and every critical topic silent longer than its
    limit (critical_violations), each with its words; tolerance_s is the limit."""
    found = [(v, f"{v.topic} silent {_seconds(v.silence_s, v.tolerance_s)} s > Δ "
                 f"{v.tolerance_s:g} s from t={v.start_t:.1f} s")
             for v in tolerance_violations(rec, end=judged_end(rec))]
    found += [(v, f"{v.topic} (critical, Δ 0) silent {_seconds(v.silence_s, v.tolerance_s)} s > "
                  f"{_seconds(v.tolerance_s, v.silence_s)} s "
                  f"(a period at its freq_min {rec.critical_freq_min[v.topic]:g} Hz + "
                  f"{CRITICAL_SLACK_S:g} s) from t={v.start_t:.1f} s")
              for v in critical_violations(rec)]
    return found


def _seconds(value: float, other: float) -> str:
    """`value` to 2 decimals, or to as many more (up to 6) as it takes not to show it equal to
    `other`: a silence 4 ms over its limit read "silent 0.20 s > 0.20 s"."""
    digits = 2
    while digits < 6 and f"{value:.{digits}f}" == f"{other:.{digits}f}":
        digits += 1
    return f"{value:.{digits}f}"


def charged_to(struck: Sequence[float], v: Violation) -> Optional[int]:
    """Which of the faults struck at `struck` (in order) a silence is charged to: the last one
    before the silence became a violation (its limit after its last message). A fault cannot
    have made a silence that was already too long when it struck, whatever the topic's rate;
    one that began within its limit before the fault may be the fault's (its last message came
    just before). None before the first fault: the start-up's."""
    before = [i for i, t in enumerate(struck) if t <= v.start_t + v.tolerance_s]
    return before[-1] if before else None


def startup_silences(faults: Sequence, rec: TestbedRecord) -> List[str]:
    """The silences that were violations before the first fault, in words: the start-up's (the
    robot's node set coming up under its quota, the first moves), charged to no fault but
    named, never passed by in silence. `faults`: the injected faults (.t, .error)."""
    struck = sorted(f.t for f in faults if not f.error)
    return [f"{text}: before the first fault (the start-up's, not judged as a fault's)"
            for v, text in silence_violations(rec) if charged_to(struck, v) is None]


def unchecked(rec: TestbedRecord) -> List[str]:
    """What the record lets no invariant check, in words: the soak says so rather than pass
    it by."""
    if not rec.critical_freq_min:
        return ["the critical connections' Δ 0: the record has no receipts of their topics "
                "(recorded by a monitor with ~record_critical, as bench_fault_soak.py starts "
                "it)"]
    return []


def worst_silence(rec: TestbedRecord, since: float, until: float) -> Tuple[str, float, float]:
    """The output silence, begun in [since, until), that is longest against its Δ:
    (topic, silence, Δ); ("", 0, 0) if no output has a tolerance."""
    best = ("", 0.0, 0.0)
    for topic, tol in sorted(rec.tolerances.items()):
        if tol <= 0:
            continue
        times = sorted(rec.receipts.get(topic, []))
        points = times + [until]
        for a, b in zip(points, points[1:]):
            silence = min(b, until) - a
            if since <= a < until and silence > 0 and \
                    (not best[0] or silence / tol > best[1] / best[2]):
                best = (topic, silence, tol)
    return best
