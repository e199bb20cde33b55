"""What goes into the decision engine and what comes out of it: its parameters, an agent's
report in the engine's terms, and the actions and events of a tick (no ROS)."""
from dataclasses import dataclass, field
import math
from typing import Dict, Iterable, List, Mapping, Tuple

from .constraints import DynamicState
from .restart_backoff import BackoffParams


@dataclass(frozen=True)
class DecisionParams:
    hysteresis_s: float = 10.0          # the paper's T: no re-migration this soon after a return
    lease_s: float = 3.0                # remote instances end this long after the last renewal
    status_timeout_s: float = 1.5       # a remote scale silent this long counts as link down
    act_at_tolerance: float = 0.5       # move back once this share of a tolerance is spent
    # ... or once a connection of a remote node has been silent for this share of its tolerance
    # (0: off): see DecisionEngine._silent_connections.
    act_at_silence: float = 0.35
    startup_grace_s: float = 5.0        # a moved node's connections are not judged this long
    cpu_smoothing_s: float = 2.0        # time constant of the background-load filter
    restart: BackoffParams = BackoffParams()  # nodes that end unasked: at once, then backing off
    bandwidth_hold_s: float = 5.0       # a move out needs the link to have shown its bandwidth
    bandwidth_margin: float = 0.3       # this long, with this share above what it will carry
    # A node out stays while the link measures its streams plus this share (<= bandwidth_margin,
    # or what moved out would come back at once): the probe overrates what a stream gets.
    bandwidth_stay_margin: float = 0.15
    # A link measured below this is about to be lost: it counts as carrying nothing, so nodes
    # come home while a handover can still cross it (0: off). See LinkCapacity.usable.
    weak_link_mbps: float = 0.0
    # After a link loss, a node moves out only once the link has been up this long (0: only
    # bandwidth_hold_s), unless node_hold_after_loss_s names the node. See hold_after_loss.
    hold_after_loss_s: float = 0.0
    node_hold_after_loss_s: Mapping[str, float] = field(default_factory=dict)

    def hold_after_loss(self, node: str) -> float:
        """How long after a link loss `node` stays home: a node whose link-loss return fits
        its tolerances with room to spare (measured, e.g. AMCL's) can move out on the link's
        first good seconds, where one whose return comes close to its tolerance should wait
        until the link has shown it stays."""
        return self.node_hold_after_loss_s.get(node, self.hold_after_loss_s)

    def longest_hold_after_loss(self) -> float:
        return max([self.hold_after_loss_s, *self.node_hold_after_loss_s.values()])


@dataclass(frozen=True)
class ScaleReport:
    """One agent's latest status, in the engine's terms."""
    scale: str
    received_at: float                           # engine clock (s)
    cpu_percent: float                           # % of the scale's capacity
    capacity_cores: float                        # cores, or the cgroup quota in cores
    running: Mapping[str, float] = field(default_factory=dict)  # node -> CPU % of one core
    topic_rates: Mapping[str, float] = field(default_factory=dict)  # topic -> effective Hz
    link_up: bool = True                         # the master's: its uplink has a carrier
    bandwidth_mbps: float = math.nan             # measured estimate; NaN = not yet measured
    standby_cpu: float = 0.0                     # warm standbys' CPU, % of one core
    ended: Mapping[str, str] = field(default_factory=dict)  # node -> how it ended there
    # topic -> seconds since its last message on this scale when the agent sampled (inf: none)
    topic_silence: Mapping[str, float] = field(default_factory=dict)
    # engine clock: when the agent took the sample, by its stamp (NaN: as received). After a
    # link loss, statuses queued on the old connection arrive seconds after the answer to a
    # start made since, which came on a new one: received late, they are old all the same.
    sampled_at: float = math.nan

    def sample_time(self) -> float:
        return self.sampled_at if math.isfinite(self.sampled_at) else self.received_at


def effective_rate(rate_hz: float, last_message_age_s: float) -> float:
    """The window rate, but no more than silence allows: a topic quiet for 2 s is at most
    0.5 Hz now, whatever its window still says."""
    if last_message_age_s > 0 and math.isfinite(last_message_age_s):
        return min(rate_hz, 1.0 / last_message_age_s)
    if math.isinf(last_message_age_s):
        return 0.0
    return rate_hz


def silent_scales(scales: Iterable[str], received_at: Mapping[str, float], subscribed_at: float,
                  now: float, after_s: float) -> List[str]:
    """The scales whose status has not come for `after_s`: since their last one, or since the
    status subscription was made if that is later or none came yet. A scale never heard from
    counts too: rospy does not ask a publisher again whose requestTopic failed (an agent that
    came up while the link was down), so its subscription stays empty until it is made anew."""
    return [s for s in scales
            if now - max(received_at.get(s, -math.inf), subscribed_at) > after_s]


def pose_handoff_params(x: float, y: float, yaw: float, cov_xx: float, cov_yy: float,
                        cov_aa: float, stamp: float = 0.0) -> Dict[str, float]:
    """AMCL's initial-pose parameters (ROS amcl's names) from the last estimated pose, and
    initial_pose_stamp (s, the pose's time): the new instance knows it is resuming."""
    return {"initial_pose_x": x, "initial_pose_y": y, "initial_pose_a": yaw,
            "initial_cov_xx": cov_xx, "initial_cov_yy": cov_yy, "initial_cov_aa": cov_aa,
            "initial_pose_stamp": stamp}


@dataclass(frozen=True)
class StartNode:
    node: str
    scale: str
    param_overrides: Tuple[Tuple[str, float], ...]
    lease_s: float                      # 0 on the master


@dataclass(frozen=True)
class StopNode:
    node: str
    scale: str
    # Make before break: stop only once the node's new instance on this scale has published
    # its output ("" = stop at once).
    after_output_on: str = ""
    # The scale counts as out of reach (its status went silent) while the master's uplink still
    # has its carrier: the link may be saturated rather than gone, and a stop that gets through
    # ends the old instance's stream before its lease does. Sent, but not waited for.
    best_effort: bool = False
    # Pause the instance instead (launch.pause_at_home, the master scale only): the next start
    # there resumes it.
    pause: bool = False
    # An instance found running where the mapping does not place its node (DecisionEngine's
    # _strays): stopped only if the agent still reports it so when the stop is made.
    stray: bool = False


@dataclass(frozen=True)
class RenewLeases:
    scale: str
    nodes: Tuple[str, ...]
    lease_s: float


@dataclass(frozen=True)
class Event:
    kind: str                           # "start", "migrate", "migrate_back", "adopt", "restart"
    node: str
    from_scale: str
    to_scale: str
    reason: str


@dataclass
class TickResult:
    actions: List[object]
    events: List[Event]
    state: DynamicState
    violating: List[str]
