"""`anyscale top`: a terminal view of the scales, nodes, connection rates and events (pure
render() plus a small rospy loop)."""
import math
import sys
import threading
import time
from typing import Dict, List, Mapping, Optional, Sequence

from .model import SystemModel

STATE_NAMES = {0: "STARTING", 1: "RUNNING", 2: "STOPPING", 3: "EXITED", 4: "REPLACED",
               5: "LEASE_EXPIRED", 6: "STANDBY", 7: "PAUSED"}
STANDBY, PAUSED = 6, 7
# The decision node's /diagnostics status of the link forecast (link_forecast_ros.diagnose).
LINK_AHEAD = ": link ahead"
KIND_NAMES = {0: "START", 1: "MIGRATE", 2: "MIGRATE_BACK", 3: "ADOPT", 4: "FAILED", 5: "RESTART"}


def _number_or_dash(value: float, fmt: str, unit: str = "") -> str:
    return "-" if value is None or not math.isfinite(value) else f"{value:{fmt}}{unit}"


def _stamp_s(stamp) -> float:
    return stamp.secs + stamp.nsecs * 1e-9


def render(statuses: Mapping[str, object], mapping, events: Sequence[object],
           model: Optional[SystemModel], now: Optional[float] = None, costs=None,
           link_ahead: Optional[object] = None) -> str:
    """One frame. statuses: scale -> latest ScaleStatus; mapping: the latest Mapping message or
    None; events: MigrationEvent messages, oldest first; now: ROS time in s (lease times);
    costs: the latest CostEstimates message or None; link_ahead: the decision node's latest
    "link ahead" DiagnosticStatus, if any."""
    out: List[str] = []
    assigned = {a.node: a.scale for a in mapping.assignments} if mapping else {}
    if mapping is not None:
        out.append(f"mapping by {mapping.allocator or '?'}: Perf (Eq. 1) {mapping.perf:.1f}, "
                   f"objective (Eq. 2) {mapping.objective:.0f}")
    else:
        out.append("mapping: none yet (is the decision node running?)")
    out += ["", f"{'SCALE':<10} {'CPU':>6} {'MEM used':>9}  {'LINK':<5} {'RTT':>8} "
                f"{'BANDWIDTH':>12}"]
    for scale in sorted(statuses):
        s = statuses[scale]
        total = s.memory_total_bytes
        mem = 100.0 * (total - s.memory_available_bytes) / total if total else math.nan
        if s.is_master:
            link, rtt, bw = "master", "-", "-"
        else:
            link = "up" if s.link.up else "DOWN"
            rtt = _number_or_dash(s.link.rtt_mean_s * 1e3, ".1f", " ms")
            bw = _number_or_dash(s.link.bandwidth_mbps, ".1f", " Mbit/s")
        out.append(f"{scale:<10} {_number_or_dash(s.cpu_percent, '5.1f', '%'):>6} "
                   f"{_number_or_dash(mem, '5.1f', '%'):>9}  {link:<5} {rtt:>8} {bw:>12}")
    for scale in sorted(statuses):
        link = statuses[scale].link
        if statuses[scale].is_master and link.uplink_interface:
            out.append(f"uplink of {scale}: {link.uplink_interface}, " +
                       ("carrier" if link.carrier else
                        "NO CARRIER: every other scale is out of reach"))
    if link_ahead is not None:
        out += [f"link ahead ({kv.key}): {kv.value}" for kv in link_ahead.values]
        out.append(f"link ahead: {link_ahead.message}")
    out += ["", f"{'NODE':<20} {'SCALE':<10} {'STATE':<13} {'CPU':>7} {'RSS':>9} {'LEASE':>7}"]
    rows: Dict[str, List[str]] = {}
    standbys: List[str] = []
    paused: List[str] = []
    for scale in sorted(statuses):
        for p in statuses[scale].nodes:
            name = p.name.lstrip("/")
            if p.state == STANDBY:
                standbys.append(f"{name} on {scale} ({p.rss_bytes / 2**20:.0f} MB)")
                continue
            if p.state == PAUSED:
                paused.append(f"{name} on {scale} ({p.rss_bytes / 2**20:.0f} MB)")
                continue
            if p.state not in (0, 1, 2) and name in rows:
                continue     # an exited instance does not hide the live one
            lease = "-"
            if _stamp_s(p.lease_expiry) > 0 and now is not None:
                lease = f"{max(0.0, _stamp_s(p.lease_expiry) - now):.1f} s"
            rows[name] = [name, scale, STATE_NAMES.get(p.state, str(p.state)),
                          f"{p.cpu_percent:.1f}%", f"{p.rss_bytes / 2**20:.1f} MB", lease]
    for node, scale in assigned.items():
        if node not in rows:
            rows[node] = [node, scale, "not seen", "-", "-", "-"]
    for name in sorted(rows):
        r = rows[name]
        want = assigned.get(name)
        where = r[1] if want in (None, r[1]) else f"{r[1]}>{want}"
        out.append(f"{r[0]:<20} {where:<10} {r[2]:<13} {r[3]:>7} {r[4]:>9} {r[5]:>7}")
    if standbys:
        out.append("warm standby: " + ", ".join(standbys))
    if paused:
        out.append("paused (resumed by a return): " + ", ".join(paused))
    if model is not None:
        out += ["", f"{'CONNECTION':<40} {'RATE':>8} {'MIN':>6} {'OPT':>6}  STATUS"]
        for c in model.connections:
            where = assigned.get(c.subscriber, model.master.name)
            s = statuses.get(where)
            topic = next((t for t in s.topics if t.topic == c.topic), None) if s else None
            if topic is None:
                rate, status = math.nan, f"not measured on {where}"
            else:
                rate = topic.rate_hz if topic.last_message_age_s <= 2.0 / max(c.freq_min, 1e-3) \
                    else 0.0
                status = "below min" if rate < c.freq_min else \
                    ("ok" if rate >= 0.9 * c.freq_opt else "above min")
            label = f"{c.publisher}->{c.subscriber} {c.topic}"
            rate_text = _number_or_dash(rate, '.1f', ' Hz')
            out.append(f"{label[:40]:<40} {rate_text:>8} {c.freq_min:>6g} "
                       f"{c.freq_opt:>6g}  {status}" + (" (critical)" if c.tolerance == 0 else ""))
    if costs is not None:
        out += [""] + cost_lines(costs)
    out += ["", "LAST EVENTS (received since top started)"]
    for e in list(events)[-8:]:
        dur = _number_or_dash(e.duration_s, ".2f", " s")
        out.append(f"  {KIND_NAMES.get(e.kind, e.kind):<12} {e.node:<16} "
                   f"{e.from_scale or '-'} -> {e.to_scale}  {dur:>7}  {e.reason}"
                   + ("" if e.success else "  FAILED"))
    if not events:
        out.append("  none")
    return "\n".join(out)


def cost_lines(costs) -> List[str]:
    """The decision node's live cost estimates beside the model's figures (% of the scale's
    capacity; "≥": learned on a saturated scale, a lower bound), and the moves backed off."""
    out = [f"{'CPU COST (% of the scale)':<32} {'MODEL':>6} {'LIVE':>7} {'LEARNED':>8} "
           f"{'REPORTS':>8}  BACK-OFF"]
    for c in costs.estimates:
        learned = "-" if not c.samples else \
            ("≥" if c.lower_bound else "") + _number_or_dash(c.measured_percent, ".1f")
        backoff = "-" if not c.failures else (
            f"{c.failures} failed in a row" + (f", {c.retry_in_s:.0f} s left"
                                               if c.retry_in_s > 0 else "") + f": {c.reason}")
        out.append(f"{c.node + ' on ' + c.scale:<32} {c.model_percent:>6g} "
                   f"{c.live_percent:>7.1f} {learned:>8} {c.samples:>8}  {backoff}")
    return out


def run(model_path: Optional[str], once: bool, period_s: float = 1.0, wait_s: float = 10.0) -> int:
    """Subscribe and redraw every period_s; with once, print one frame after the first data."""
    import rosgraph
    import rospy
    from anyscale_msgs.msg import CostEstimates, MigrationEvent, ScaleStatus
    from anyscale_msgs.msg import Mapping as MappingMsg
    from diagnostic_msgs.msg import DiagnosticArray

    from .model_loader import load_model

    if not rosgraph.is_master_online():
        print("anyscale top: error: no ROS master at "
              f"{rosgraph.get_master_uri()} (is roscore running?)", file=sys.stderr)
        return 1
    rospy.init_node("anyscale_top", anonymous=True, disable_signals=True)
    model_path = model_path or rospy.get_param("/anyscale/model", None)
    model = load_model(model_path) if model_path else None
    lock = threading.Lock()
    statuses, events, latest = {}, [], {"mapping": None, "costs": None, "link_ahead": None}

    def on_status(msg):
        with lock:
            statuses[msg.scale] = msg

    def on_event(msg):
        with lock:
            events.append(msg)
            del events[:-50]

    def on_mapping(msg):
        with lock:
            latest["mapping"] = msg

    def on_costs(msg):
        with lock:
            latest["costs"] = msg

    def on_diagnostics(msg):
        for status in msg.status:
            if status.hardware_id == "anyscale_decision" and status.name.endswith(LINK_AHEAD):
                with lock:
                    latest["link_ahead"] = status

    rospy.Subscriber("/diagnostics", DiagnosticArray, on_diagnostics, queue_size=5)
    rospy.Subscriber("/anyscale/status", ScaleStatus, on_status, queue_size=20)
    rospy.Subscriber("/anyscale/events", MigrationEvent, on_event, queue_size=50)
    rospy.Subscriber("/anyscale/mapping", MappingMsg, on_mapping, queue_size=1)
    rospy.Subscriber("/anyscale/cost_estimates", CostEstimates, on_costs, queue_size=1)
    try:
        if once:
            # One frame once every scale has reported (or wait_s passed) and the mapping is in.
            end = time.monotonic() + wait_s
            want = len(model.scales) if model else 1
            while time.monotonic() < end and not rospy.is_shutdown():
                with lock:
                    if len(statuses) >= want and latest["mapping"] is not None:
                        break
                time.sleep(0.1)
        while True:
            with lock:
                frame = render(dict(statuses), latest["mapping"], list(events), model,
                               rospy.Time.now().to_sec(), latest["costs"],
                               latest["link_ahead"])
            if once:
                print(frame)
                return 0 if statuses else 1
            sys.stdout.write("\x1b[H\x1b[2J" + time.strftime("%H:%M:%S  anyscale top\n") + frame
                             + "\n")
            sys.stdout.flush()
            time.sleep(period_s)
    except KeyboardInterrupt:
        return 0
    finally:
        rospy.signal_shutdown("anyscale top done")
