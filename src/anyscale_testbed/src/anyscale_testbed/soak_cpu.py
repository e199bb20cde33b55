"""Who had the CPU while a topic was silent, pure (no ROS): from the CPU time of every process
of the ROS system in the soak's census, the cores each used over a span, per CPU cgroup (the
scales' quotas, "/" outside them), in words for the soak's findings.

It tells the two causes of a silence on the starved robot apart: a group that got its quota
while the silent node got little lost it to a neighbour inside the group (a boost, a return);
a group well below its quota was held back from outside it (on the one-machine test bed, by
processes outside every quota on the shared cores: the world, the soak, a roscore starting)."""
from typing import Dict, Mapping, Sequence, Tuple

# Named in a group's words: the processes that used the most, this many.
TOP = 4


def cpu_during(census: Sequence, start: float,
               end: float) -> Tuple[float, Dict[Tuple[str, str], float]]:
    """(span, {(cgroup, name): cores}): the cores each process name used on average from the
    last census sample at or before `start` to the first at or after `end` (the span between
    them, in s). A process that started in the span counts from its start. Samples in time
    order, each with .t and .cpu, a list of (name, cgroup, pid, CPU seconds so far)."""
    before = [s for s in census if s.t <= start]
    after = [s for s in census if s.t >= end]
    if not before or not after or after[0].t <= before[-1].t:
        return 0.0, {}
    first, last = before[-1], after[0]
    had = {pid: seconds for _, _, pid, seconds in first.cpu}
    span = last.t - first.t
    used: Dict[Tuple[str, str], float] = {}
    for name, cgroup, pid, seconds in last.cpu:
        key = (cgroup, name)
        used[key] = used.get(key, 0.0) + max(0.0, seconds - had.get(pid, 0.0)) / span
    return span, used


def describe_cpu(span: float, used: Mapping[Tuple[str, str], float],
                 quotas: Mapping[str, Tuple[str, float]]) -> str:
    """One line: per cgroup, its cores against its quota and its busiest processes. `quotas`:
    cgroup -> (scale, cores)."""
    if not used:
        return "no CPU sample spans it"
    groups: Dict[str, Dict[str, float]] = {}
    for (cgroup, name), cores in used.items():
        groups.setdefault(cgroup, {})[name] = cores
    words = []
    for cgroup, names in sorted(groups.items(), key=lambda g: (g[0] not in quotas, g[0])):
        scale, quota = quotas.get(cgroup, ("outside the quotas", 0.0))
        total = sum(names.values())
        busiest = sorted(names.items(), key=lambda n: -n[1])[:TOP]
        words.append(f"{scale} {total:.2f}" + (f" of {quota:g}" if quota else "") + " cores ("
                     + ", ".join(f"{n} {c:.2f}" for n, c in busiest) + ")")
    return f"over {span:.1f} s: " + "; ".join(words)
