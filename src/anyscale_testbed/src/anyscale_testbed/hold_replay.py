"""A node's hold after a link loss, replayed on recorded links (pure, no ROS): of the time the
link carried the node, how much it would have spent out under a hold policy, and how many of
its moves out a loss ended soon after (each such end is a link-loss return, the move that
strains a tolerance on the starved robot).

The rules are the decision node's, reduced to one node and the link: the node moves out once
the link has been above weak_link_mbps for bandwidth_hold_s, the hold after the latest loss has
run and no return lies within the hysteresis T; it comes home when the link falls below
weak_link_mbps. An approximation, said where it is used: the robot is where the record has it,
while out of the record a faster robot would cross the coverage sooner; the bandwidth the node
needs and CPU do not enter.
"""
from dataclasses import dataclass
import math
from typing import Callable, List, Sequence, Tuple

# (the times the link went down so far, now) -> the hold after the latest loss, s
HoldPolicy = Callable[[Sequence[float], float], float]


def fixed_hold(seconds: float) -> HoldPolicy:
    return lambda losses, now: seconds


def doubling_hold(base_s: float, window_s: float, cap_s: float) -> HoldPolicy:
    """base_s after a loss with none in the window_s before it, doubled for each further loss
    in that window, at most cap_s: route-flap damping's idea (RFC 2439), short after a clean
    loss, long on a link that keeps coming and going."""
    def hold(losses: Sequence[float], now: float) -> float:
        recent = sum(1 for t in losses if now - t < window_s)
        return min(cap_s, base_s * 2.0 ** max(recent - 1, 0))
    return hold


@dataclass(frozen=True)
class ReplayRules:
    weak_link_mbps: float = 5.5       # robot.launch's
    bandwidth_hold_s: float = 5.0     # robot.launch's
    hysteresis_s: float = 10.0        # robot.launch's T
    ended_soon_s: float = 10.0        # a move out a loss ends within this is counted


@dataclass(frozen=True)
class ReplayResult:
    carried_s: float      # time the link was at or above weak_link_mbps
    out_s: float          # time the node was out
    moves_out: int
    ended_soon: int       # moves out a loss ended within ended_soon_s (link-loss returns)

    @property
    def out_share(self) -> float:
        return self.out_s / self.carried_s if self.carried_s > 0 else math.nan


def replay_hold(bandwidth: Sequence[Tuple[float, float]], policy: HoldPolicy,
                rules: ReplayRules = ReplayRules()) -> ReplayResult:
    """The node under `policy` on a recorded link: (t, Mbit/s) samples in time order, 0 = down.
    A return on a weak link that is not lost is planned (make before break) and not counted."""
    if not bandwidth:
        return ReplayResult(0.0, 0.0, 0, 0)
    carried = out_s = 0.0
    moves = soon = 0
    losses: List[float] = []
    lost_at = back_at = moved_at = -math.inf
    good_since = None
    out = down = False
    for (t, mbps), (t_next, _) in zip(bandwidth, list(bandwidth[1:]) + [bandwidth[-1]]):
        if mbps <= 0:
            if not down:
                losses.append(t)
            lost_at = t               # the engine's loss time: the latest sample seen down
        down = mbps <= 0
        if mbps < rules.weak_link_mbps:
            good_since = None
            if out:
                out, back_at = False, t
                soon += mbps <= 0 and t - moved_at < rules.ended_soon_s
        else:
            good_since = t if good_since is None else good_since
            if (not out and t - good_since >= rules.bandwidth_hold_s
                    and t - lost_at >= policy(losses, lost_at)
                    and t - back_at >= rules.hysteresis_s):
                out, moved_at = True, t
                moves += 1
            carried += t_next - t
        if out:
            out_s += t_next - t
    return ReplayResult(carried, out_s, moves, soon)
