"""Pure conversions between anyscale_msgs / standard messages and the decision engine's terms."""
import math
from typing import Dict, Iterable, List, Mapping, Sequence, Tuple

from anyscale_msgs.msg import (CostEstimate, CostEstimates, MigrationEvent, NodeAssignment,
                               NodeProcess)
from anyscale_msgs.msg import Mapping as MappingMsg
from diagnostic_msgs.msg import KeyValue

from .decision_types import ScaleReport, effective_rate, pose_handoff_params
from .model import SystemModel

# A node counts as running on a scale from its fork on: adopting a STARTING node avoids
# starting a duplicate while it is still importing.
ALIVE_STATES = (NodeProcess.STARTING, NodeProcess.RUNNING)
# Ended there: by itself or a stop, or by its lease (a lease of a microsecond, or renewals that
# did not come, on the scale the node is due to run on).
ENDED_STATES = (NodeProcess.EXITED, NodeProcess.LEASE_EXPIRED)

EVENT_KINDS = {"start": MigrationEvent.START, "migrate": MigrationEvent.MIGRATE,
               "migrate_back": MigrationEvent.MIGRATE_BACK, "adopt": MigrationEvent.ADOPT,
               "failed": MigrationEvent.FAILED, "restart": MigrationEvent.RESTART}
EVENT_NAMES = {v: k for k, v in EVENT_KINDS.items()}


def model_node_name(process_name: str) -> str:
    """The model's name of an agent's fully qualified node name ('/relay' -> 'relay')."""
    return process_name[1:] if process_name.startswith("/") else process_name


def scale_report_from_msg(msg, received_at: float, model_node_names: Iterable[str],
                          sample_age_s: float = 0.0) -> ScaleReport:
    """A ScaleStatus as the engine's ScaleReport; nodes outside the model are left out (their
    CPU then counts as background load, which is what it is). sample_age_s: how old its stamp
    was when it was received (the scales' clocks are synchronised, chrony on real machines); a
    negative age (a clock ahead) counts as 0."""
    names = set(model_node_names)
    running = {model_node_name(p.name): float(p.cpu_percent) for p in msg.nodes
               if p.state in ALIVE_STATES and model_node_name(p.name) in names}
    ended = {model_node_name(p.name): how_it_ended(p) for p in msg.nodes
             if p.state in ENDED_STATES
             and model_node_name(p.name) in names and model_node_name(p.name) not in running}
    paused = frozenset(model_node_name(p.name) for p in msg.nodes
                       if p.state == NodeProcess.PAUSED and model_node_name(p.name) in names)
    listed = frozenset(model_node_name(p.name) for p in msg.nodes
                       if p.state != NodeProcess.STANDBY and model_node_name(p.name) in names)
    standby = sum(float(p.cpu_percent) for p in msg.nodes if p.state == NodeProcess.STANDBY)
    rates = {t.topic: effective_rate(float(t.rate_hz), float(t.last_message_age_s))
             for t in msg.topics}
    silence = {t.topic: float(t.last_message_age_s) for t in msg.topics}
    capacity = float(msg.cpu_quota_cores) if msg.cpu_quota_cores > 0 else float(msg.cores)
    # On the master, link.up is the carrier of its uplink (true if none is watched); it has
    # no bandwidth estimate, its roscore being local.
    link_up = bool(msg.link.up)
    bandwidth = math.nan if msg.is_master else float(msg.link.bandwidth_mbps)
    sampled_at = received_at - max(sample_age_s, 0.0) if math.isfinite(sample_age_s) \
        else math.nan
    return ScaleReport(msg.scale, received_at, float(msg.cpu_percent), capacity, running,
                       rates, link_up, bandwidth, standby, ended, silence, sampled_at, paused,
                       listed, float(msg.cpu_held_percent))


def how_it_ended(process) -> str:
    """'signal N' or 'exit code N' of a process that ended (its lease's end for one the agent
    stopped on it), and where its log is."""
    how = f"signal {process.exit_signal}" if process.exit_signal else \
        f"exit code {process.exit_code}"
    if process.state == NodeProcess.LEASE_EXPIRED:
        how = f"its lease ran out ({how})"
    return f"{how}, log {process.log_file}" if process.log_file else how


def watched_topics(model: SystemModel,
                   mapping: Mapping[str, str]) -> Dict[str, List[Tuple[str, str]]]:
    """Per scale, (topic, subscriber) for each of the model's connections whose subscriber
    runs there: the agent counts the topic once it runs that node, without waiting for the
    master's graph to show the subscription (SetWatchedTopics.srv)."""
    out: Dict[str, set] = {s.name: set() for s in model.scales}
    for c in model.connections:
        scale = mapping.get(c.subscriber)
        if scale in out:
            out[scale].add((c.topic, qualified_node_name(c.subscriber)))
    return {s: sorted(pairs) for s, pairs in out.items()}


def qualified_node_name(name: str) -> str:
    """A model node's name as the agents know it: /amcl for amcl."""
    return name if name.startswith("/") else "/" + name


def yaml_scalar(value) -> str:
    """A parameter value as YAML text for StartNode.param_overrides (NaN/inf in YAML's
    spelling, which Python's repr does not use)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        if math.isnan(value):
            return ".nan"
        if math.isinf(value):
            return ".inf" if value > 0 else "-.inf"
        return repr(value)
    return str(value)


def param_overrides_to_kv(overrides: Sequence[Tuple[str, object]]) -> List[KeyValue]:
    return [KeyValue(key=k, value=yaml_scalar(v)) for k, v in overrides]


def handoff_params_from_pose(msg) -> Dict[str, float]:
    """AMCL's initial-pose parameters from a geometry_msgs/PoseWithCovarianceStamped."""
    p, q = msg.pose.pose.position, msg.pose.pose.orientation
    yaw = math.atan2(2.0 * (q.w * q.z + q.x * q.y), 1.0 - 2.0 * (q.y * q.y + q.z * q.z))
    cov = msg.pose.covariance
    return pose_handoff_params(p.x, p.y, yaw, cov[0], cov[7], cov[35],
                               msg.header.stamp.to_sec())


def mapping_msg(mapping: Mapping[str, str], perf: float, objective: float, allocator: str,
                stamp) -> MappingMsg:
    msg = MappingMsg(perf=perf, objective=objective, allocator=allocator)
    msg.header.stamp = stamp
    msg.assignments = [NodeAssignment(node=n, scale=s) for n, s in mapping.items()]
    return msg


def event_msg(kind: str, node: str, from_scale: str, to_scale: str, reason: str, stamp,
              duration_s: float = math.nan, success: bool = True) -> MigrationEvent:
    msg = MigrationEvent(kind=EVENT_KINDS[kind], node=node, from_scale=from_scale,
                         to_scale=to_scale, reason=reason, duration_s=duration_s,
                         success=success)
    msg.header.stamp = stamp
    return msg


def cost_estimates_msg(rows, stamp) -> CostEstimates:
    """placement_learning.PlacementRow's as the message top and the test bed's record read."""
    msg = CostEstimates(estimates=[CostEstimate(
        node=r.cost.node, scale=r.cost.scale, model_percent=r.cost.model,
        live_percent=r.cost.live, measured_percent=r.cost.measured, samples=r.cost.samples,
        lower_bound=r.cost.lower_bound, retry_in_s=r.retry_in_s, failures=r.failures,
        reason=r.reason) for r in rows])
    msg.header.stamp = stamp
    return msg


def cost_estimates_key(rows) -> tuple:
    """What a CostEstimates message says, to the precision shown: unchanged, not sent again."""
    return tuple((r.cost.node, r.cost.scale, round(r.cost.live), r.cost.samples > 0,
                  r.cost.lower_bound, math.ceil(r.retry_in_s), r.failures) for r in rows)


def describe_change(before: Mapping[str, str], after: Mapping[str, str],
                    reasons: Mapping[str, str]) -> str:
    """One log line for a mapping change: what moved where and why."""
    moved = [f"{n} {before.get(n, '?')} -> {s}" + (f" ({reasons[n]})" if n in reasons else "")
             for n, s in after.items() if before.get(n) != s]
    return "mapping changed: " + ("; ".join(moved) if moved else "no node moved")
