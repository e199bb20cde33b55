"""What goes into the decision engine and what comes out of it: its parameters, an agent's
report in the engine's terms, and the actions and events of a tick (no ROS)."""
from dataclasses import dataclass, field
import math
from typing import Dict, FrozenSet, Iterable, List, Mapping, Optional, Tuple

from .constraints import DynamicState
from .link_forecast import LinkForecastParams
from .param_spec import declared
from .restart_backoff import BackoffParams


@dataclass(frozen=True)
class LearningParams:
    """What the decision engine learns from its placements (placement_learning.py), each
    parameter declared once (param_spec)."""
    plan_with_estimates: bool = declared(
        True, "the allocators plan with the live CPU cost estimates (false: the model's)",
        name="learn_costs")
    cost_smoothing_s: float = declared(
        5.0, "time constant of a cost estimate's average", "s", minimum=0.0)
    cost_forget_s: float = declared(
        300.0, "an estimate not refreshed relaxes to the model's figure over this (0: never)",
        "s", minimum=0.0)
    backoff_max_s: float = declared(
        300.0, "a move sent back for rate or CPU waits T, 2T, ... up to this (0: no back-off)",
        "s", name="placement_backoff_max_s", minimum=0.0)
    success_s: float = declared(
        60.0, "a stay this long resets the back-off of its move", "s",
        name="placement_success_s", minimum=0.0)
    retry_room: float = declared(
        10.0, "a scale whose load fell this much ends a back-off early", "% of a scale",
        name="placement_retry_room", minimum=0.0, maximum=100.0)


@dataclass(frozen=True)
class DecisionParams:
    """The decision engine's parameters, each declared once: its ROS parameter (~name), default,
    unit, bounds and meaning (param_spec; the README's table is built from these)."""
    hysteresis_s: float = declared(
        10.0, "the paper's T: a node that came back does not leave again for this long", "s",
        minimum=0.0)
    lease_s: float = declared(
        3.0, "lease of remote instances: their agent stops one not renewed for this long", "s",
        minimum=0.1)
    status_timeout_s: float = declared(
        1.5, "a remote scale whose status is older counts as link down", "s", minimum=0.1)
    act_at_tolerance: float = declared(
        0.5, "move back once this share of a connection's tolerance is spent below freq_min",
        "0..1", minimum=0.0, maximum=1.0)
    act_at_silence: float = declared(
        0.35, "move back once a remote node's connection was silent this share of its "
        "tolerance (0: off)", "0..1", minimum=0.0, maximum=1.0)
    startup_grace_s: float = declared(
        5.0, "a moved or restarted node's connections are not judged this long", "s",
        minimum=0.0)
    cpu_smoothing_s: float = declared(
        2.0, "time constant of the filter on each scale's background CPU load", "s",
        minimum=0.0)
    restart: BackoffParams = BackoffParams()
    bandwidth_hold_s: float = declared(
        5.0, "a move out needs the link to have held its streams plus the margin this long",
        "s", minimum=0.0)
    bandwidth_margin: float = declared(
        0.3, "share above the streams' bandwidth a move out needs (the probe overrates a "
        "stream's share)", "0..1", minimum=0.0)
    bandwidth_stay_margin: float = declared(
        0.15, "a node out stays while the link carries its streams plus this share "
        "(<= ~bandwidth_margin)", "0..1", minimum=0.0)
    weak_link_mbps: float = declared(
        0.0, "a link measured below this carries nothing: nodes come home while a handover "
        "can cross it (0: off)", "Mbit/s", minimum=0.0)
    hold_after_loss_s: float = declared(
        0.0, "after a link loss, no node moves out until the link was up this long (0: only "
        "~bandwidth_hold_s)", "s", minimum=0.0)
    node_hold_after_loss_s: Mapping[str, float] = declared(
        {}, "a node's own hold after a loss, in place of ~hold_after_loss_s", "node: s")
    learning: LearningParams = LearningParams()   # live cost estimates, failed moves' back-off
    # The link map and the forecast along the planned path (link_anticipation.py, issue 36).
    link_forecast: LinkForecastParams = LinkForecastParams()

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
    paused: FrozenSet[str] = frozenset()        # model nodes whose instance here is paused
    # Model nodes the agent lists in any state but a warm standby; None: the report does not
    # say (then no node counts as missing from it).
    listed: Optional[FrozenSet[str]] = None
    # A shared scale: % of its capacity its ledger holds for other robots' nodes (their
    # reservations, which their actual CPU may not show yet); 0 on a scale of this robot's own.
    cpu_held: float = 0.0

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
    # What the node is expected to use there (its live cost estimate, % of the scale, and the
    # model's memory_mb): a shared scale's ledger holds it while the node runs.
    cpu_percent: float = 0.0
    memory_mb: float = 0.0


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
    notes: List[str] = field(default_factory=list)   # lines for the log (a move backed off)
