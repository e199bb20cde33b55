"""What an AnyScale test left of the coverage bound, in seconds, by cause (pure, no ROS).

The bound (evaluation_figures.coverage_bound) has AMCL on the laptop wherever the link carries
its traffic; a test saves less where AMCL stayed home on such a stretch. Each such driving
step's seconds (its time less its length at the speed with AMCL out) go to the first cause
that held at its start, in this order:
- weak link: the link was below weak_link_mbps, where the decision node brings nodes home and
  lets none out, so that a handover can still cross a link that is about to go;
- hold after a loss: the link had come back less than hold_after_loss_s before;
- hysteresis T: the node had come home less than hysteresis_s before (the paper's T);
- before the first move out: the start-up (the node set coming up, the first bandwidth hold);
- held by the link ahead: the decision node's "link ahead" diagnostics (the record's
  link_ahead) had the node held home, or brought home, before a hole the link map foresaw;
- placement back-off: a return for rate or CPU there had backed the move off ("backed off N s");
- bandwidth hold: the link had been weak or down less than bandwidth_hold_s before (a move out
  waits for the link to show its streams that long);
- other: the move's own start, and the link estimate lagging the link.
Apart from these, the moves out themselves cost time the bound does not remove either: from the
decision until the new instance publishes and the robot speeds up, the steps mapped out were
driven at the robot's speed; their seconds against the speed with AMCL out are `moving`.
The thresholds are robot.launch's defaults, which the evaluation runs with. `steps` are
path_steps.PathSteps."""
from dataclasses import dataclass, field
import math
import re
from typing import Dict, List, Optional, Tuple

import numpy as np

from .path_steps import PathSteps
from .testbed_figures import link_transitions, move_window
from .testbed_record import TestbedRecord

WEAK, HOLD, HYSTERESIS, START, AHEAD, BACKOFF, BANDWIDTH_HOLD, OTHER = (
    "weak link", "hold after a loss", "hysteresis T", "before the first move out",
    "held by the link ahead", "placement back-off", "bandwidth hold", "other")
CAUSES = (WEAK, HOLD, HYSTERESIS, START, AHEAD, BACKOFF, BANDWIDTH_HOLD, OTHER)
BACKED_OFF = re.compile(r"backed off (\d+(?:\.\d+)?) s")


@dataclass(frozen=True)
class PolicyParams:
    """The decision node's parameters the causes are judged by; the defaults are robot.launch's
    of the runs recorded before records kept them (AMCL then held 20 s after a loss too)."""
    weak_link_mbps: float = 5.5
    hold_after_loss_s: float = 20.0     # the judged node's own
    hysteresis_s: float = 10.0
    bandwidth_hold_s: float = 5.0

    @staticmethod
    def of_record(rec: TestbedRecord, node: str = "amcl") -> "PolicyParams":
        """The parameters the run's decision node had (TestbedRecord.decision_params), each
        missing one the default."""
        p, default = rec.decision_params, PolicyParams()
        hold = p.get("hold_after_loss_s", default.hold_after_loss_s)
        own = p.get("node_hold_after_loss_s")
        if isinstance(own, dict) and node in own:
            hold = own[node]
        return PolicyParams(float(p.get("weak_link_mbps", default.weak_link_mbps)), float(hold),
                            float(p.get("hysteresis_s", default.hysteresis_s)),
                            float(p.get("bandwidth_hold_s", default.bandwidth_hold_s)))


@dataclass(frozen=True)
class Shortfall:
    # seconds of the bound's saving not made, per cause; empty: not judged (a baseline)
    by_cause: Dict[str, float] = field(default_factory=dict)
    moving_s: float = math.nan      # seconds the moves out took before the robot sped up

    @property
    def total_s(self) -> float:
        return sum(self.by_cause.values()) if self.by_cause else math.nan


NO_SHORTFALL = Shortfall()


def _since_last(moments: List[float], t: float) -> float:
    before = [m for m in moments if m <= t]
    return t - before[-1] if before else math.inf


def step_causes(rec: TestbedRecord, steps: PathSteps, params: PolicyParams,
                node: str = "amcl") -> List[str]:
    """The cause of each step (CAUSES), for every step; meaningful where AMCL stayed home on a
    carried stretch."""
    link_back = [t for t, up in link_transitions(rec.bandwidth) if up]
    moved = [e for e in rec.events if e.node == node and e.success]
    returns = [e.decided_t for e in moved if e.kind == "migrate_back"]
    first_out = min([e.decided_t for e in moved if e.kind == "migrate"], default=math.inf)
    backoffs = [(e.decided_t, e.decided_t + float(m.group(1))) for e in moved
                if e.kind == "migrate_back" for m in [BACKED_OFF.search(e.reason)] if m]
    kept_home = (f"{node} held:", f"{node} home:")
    ahead = [(t, any(k in summary for k in kept_home)) for t, summary, _ in rec.link_ahead]
    causes, weak_at = [], -math.inf
    for t, mbps in zip(steps.t, steps.mbps):
        if mbps < params.weak_link_mbps:
            weak_at = t
            causes.append(WEAK)
        elif _since_last(link_back, t) < params.hold_after_loss_s:
            causes.append(HOLD)
        elif _since_last(returns, t) < params.hysteresis_s:
            causes.append(HYSTERESIS)
        elif t < first_out:
            causes.append(START)
        elif _latest(ahead, t):
            causes.append(AHEAD)
        elif any(a <= t < b for a, b in backoffs):
            causes.append(BACKOFF)
        elif t - weak_at < params.bandwidth_hold_s:
            causes.append(BANDWIDTH_HOLD)
        else:
            causes.append(OTHER)
    return causes


def _latest(changes: List[Tuple[float, bool]], t: float) -> bool:
    """The value of the latest change at or before t (False before the first)."""
    before = [v for at, v in changes if at <= t]
    return before[-1] if before else False


def shortfall(rec: TestbedRecord, steps: PathSteps, params: Optional[PolicyParams] = None,
              node: str = "amcl") -> Shortfall:
    """params: the record's (PolicyParams.of_record) unless given."""
    params = params or PolicyParams.of_record(rec, node)
    saved = steps.saved_by_moving_out()
    causes = np.array(step_causes(rec, steps, params, node))
    by_cause = {c: float(saved[causes == c].sum()) for c in CAUSES}
    in_move = np.zeros(len(steps.t), dtype=bool)
    for e in rec.events:
        if e.node == node and e.kind == "migrate" and e.success:
            start, end = move_window(e)
            in_move |= (steps.t >= start) & (steps.t < end)
    moving = steps.driving & steps.out & in_move
    moving_s = float(np.sum(np.maximum(steps.dt[moving] - steps.length[moving] / steps.out_mps,
                                       0.0)))
    return Shortfall(by_cause, moving_s)
