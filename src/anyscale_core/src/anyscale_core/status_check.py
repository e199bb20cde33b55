"""Whether an agent's ScaleStatus can be believed: every figure the decision node reads is finite
and in its range (no ROS: works on any object with the message's fields). One status with
cpu_percent NaN, forged or from a bug, kept that scale's smoothed load at NaN and failed every
CPU check until the decision node restarted; a refused status is not used at all, so the
scale's last good one stays."""
import math
from typing import Optional

# A process group's CPU (% of one core, top's convention) is at most 100 per core; a sample
# period's tick rounding adds up to a few percent, one core's worth is room to spare.
NODE_CPU_SLACK = 100.0
# No topic of a ROS system runs at a megahertz: a figure above it is no measurement.
MAX_RATE_HZ = 1e6


def _bad(value, low: float, high: float, nan: bool = False, inf: bool = False) -> bool:
    value = float(value)
    if math.isnan(value):
        return not nan
    if math.isinf(value):
        return not (inf and value > 0)
    return not low <= value <= high


def _expect(low: float, high: float, nan: bool, inf: bool) -> str:
    what = f"a number from {low:g} to {high:g}" if math.isfinite(high) else \
        f"a number >= {low:g}"
    extra = [w for w, ok in (("NaN (unknown)", nan), ("+inf (never)", inf)) if ok]
    return what + (f" or {' or '.join(extra)}" if extra else "")


def status_problem(msg) -> Optional[str]:
    """None if every figure of `msg` the decision node reads is in range; else the first that is
    not, as 'field is value (expected ...)', the field by its path in the message."""
    checks = [("cores", msg.cores, 1, math.inf, False, False),
              ("cpu_percent", msg.cpu_percent, 0.0, 100.0, False, False),
              ("cpu_held_percent", msg.cpu_held_percent, 0.0, 100.0, False, False),
              ("cpu_quota_cores", msg.cpu_quota_cores, 0.0, math.inf, False, False),
              ("cpu_max_ghz", msg.cpu_max_ghz, 0.0, math.inf, False, False),
              ("sample_period_s", msg.sample_period_s, 0.0, math.inf, False, False),
              ("link.bandwidth_mbps", msg.link.bandwidth_mbps, 0.0, math.inf, True, False),
              ("link.rtt_s", msg.link.rtt_s, 0.0, math.inf, True, False),
              ("link.rtt_mean_s", msg.link.rtt_mean_s, 0.0, math.inf, True, False),
              ("link.loss_ratio", msg.link.loss_ratio, 0.0, 1.0, False, False)]
    node_cpu = 100.0 * max(int(msg.cores), 1) + NODE_CPU_SLACK
    for i, p in enumerate(msg.nodes):
        checks.append((f"nodes[{i}] ({p.name[:80]}).cpu_percent", p.cpu_percent, 0.0, node_cpu,
                       False, False))
    for i, t in enumerate(msg.topics):
        where = f"topics[{i}] ({t.topic[:80]})"
        checks += [(f"{where}.rate_hz", t.rate_hz, 0.0, MAX_RATE_HZ, False, False),
                   (f"{where}.last_message_age_s", t.last_message_age_s, 0.0, math.inf, False,
                    True),
                   (f"{where}.bytes_per_second", t.bytes_per_second, 0.0, math.inf, False,
                    False)]
    for field, value, low, high, nan, inf in checks:
        if _bad(value, low, high, nan, inf):
            return f"{field} is {float(value):g} (expected {_expect(low, high, nan, inf)})"
    return None
