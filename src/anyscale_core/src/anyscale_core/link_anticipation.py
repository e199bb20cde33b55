"""What the decision engine does with the link forecast (link_forecast.py), without ROS: it
adjusts the state and context a tick's allocator decides on, and never overrides a measurement.

- Out early: a node at home whose traffic (the streams its move would make cross, with
  bandwidth_margin) the link carries now, as measured, and ahead for its move cost plus its home
  lead is cleared: for it the bandwidth hold, the weak-link wait, the hold after a loss and, after
  a return for the link, the paper's T are skipped. Every other node keeps the reactive rules.
- Staying: a node out on a link measured weak stays while the link carries the streams now and
  the forecast carries them (with bandwidth_stay_margin) for longer than its home lead.
- Home early: a node out whose own streams a known cell ahead will not carry within its home
  lead comes home by a planned move (make before break), reason "link ahead: ...".
- Held: a node at home does not move out (by any rule) while a known cell ahead within its move
  cost plus home lead will not carry what it would send: it would only come straight back.
With no forecast (no map, no path, no pose, or the switch off) state and context pass unchanged.
"""
from dataclasses import dataclass, replace
import math
from typing import AbstractSet, Dict, Mapping, Optional, Sequence

import numpy as np

from .allocators import AllocationContext, Move
from .characterisation import Characterisation
from .constraints import DynamicState, required_bandwidth
from .decision_types import DecisionParams
from .link_forecast import LinkForecast

# Returns for the link, whose T an out-early move may skip: a loss, the bandwidth or weak-link
# rule, and this module's own.
LINK_REASONS = ("link to", "bandwidth", "link ahead")


@dataclass(frozen=True)
class Anticipation:
    """What the forecast changed in a tick (for the events' reasons and the diagnostics)."""
    cleared: Dict[int, float]           # node at home -> seconds the link carries it ahead
    staying: AbstractSet[int]           # nodes out kept on a weak link
    home: Dict[int, str]                # node out -> why the forecast's rules bring it home
    held: Dict[int, str]                # node at home -> why it may not move out


NOTHING = Anticipation({}, frozenset(), {}, {})
# The "link ahead" diagnostics' summary of a tick in which the forecast changed nothing.
NOTHING_DONE = "no node moved by it"


class LinkAnticipation:
    def __init__(self, ch: Characterisation, params: DecisionParams):
        self.ch = ch
        self.params = params
        self.forecasts: Optional[Mapping[str, LinkForecast]] = None
        self.link_return_at: Dict[int, float] = {}   # node -> its latest return for the link
        self.last = NOTHING

    def update(self, forecasts: Optional[Mapping[str, LinkForecast]]):
        """The forecast per remote scale for this tick; None: there is none."""
        self.forecasts = forecasts if self.params.link_forecast.enabled else None

    def adjust(self, assign: np.ndarray, state: DynamicState, ctx: AllocationContext,
               measured: float, weak: bool, up: np.ndarray):
        """The state and context the allocator decides on this tick (see the module). `state`
        and `ctx` are the reactive rules'; `measured` the links' least live estimate (NaN: none),
        `weak` whether it counts as weak, `up` each scale's link."""
        self.last = NOTHING
        if not self.forecasts:
            return state, ctx
        fp = self.params.link_forecast
        stay, margin = 1.0 + self.params.bandwidth_stay_margin, 1.0 + self.params.bandwidth_margin
        live = measured if math.isfinite(measured) else 0.0
        streams = required_bandwidth(self.ch, assign)
        cleared, staying, home, held = {}, set(), {}, {}
        for i, name in enumerate(self.ch.node_names):
            if self.ch.pinned[i]:
                continue
            lead, cost = fp.home_lead(name), fp.move_cost(name)
            if assign[i] != self.ch.master:
                k = int(assign[i])
                fc = self.forecasts.get(self.ch.scale_names[k])
                if fc is None or not up[k]:
                    continue                    # no forecast, or lost: the reactive rules
                own = streams - required_bandwidth(self.ch, _moved(assign, i, self.ch.master))
                fall = fc.falls_below(own * stay)
                if fall is not None and fall[0] <= lead:
                    home[i] = f"link ahead: {fall[1]:.1f} Mbit/s in {fall[0]:.1f} s"
                elif weak and live >= streams * stay and \
                        fc.carries_for_s(streams * stay, live) > lead:
                    staying.add(i)
                continue
            verdicts = self._out_verdicts(assign, i, up, live, margin, cost + lead)
            if verdicts is not None:
                carried, why_held = verdicts
                if why_held:
                    held[i] = why_held
                elif carried is not None:
                    cleared[i] = carried
        self.last = Anticipation(cleared, frozenset(staying), home, held)
        return self._relaxed(assign, state, ctx, measured, weak, up)

    def _out_verdicts(self, assign, i, up, live, margin, needed_s):
        """For node i at home, over the remote scales it could go to now: (the seconds the
        link ahead carries what its move would send, if the measurement carries it too and the
        forecast for at least needed_s on every such scale, else None; why it is held, '' if
        it is not: every such scale foresees a fall within needed_s). None if one of them has
        no forecast: the reactive rules then."""
        targets = [k for k in range(self.ch.num_scales)
                   if k != self.ch.master and self.ch.allowed[i, k] and up[k]]
        verdicts = []
        for k in targets:
            fc = self.forecasts.get(self.ch.scale_names[k])
            if fc is None:
                return None
            need = required_bandwidth(self.ch, _moved(assign, i, k)) * margin
            verdicts.append((k, fc.falls_below(need), fc.carries_for_s(need, live), need))
        if not verdicts:
            return None
        falls = [(k, f) for k, f, _, _ in verdicts if f is not None and f[0] < needed_s]
        if len(falls) == len(verdicts):
            k, (in_s, mbps) = falls[0]
            return None, (f"link ahead: {mbps:.1f} Mbit/s in {in_s:.1f} s on "
                          f"{self.ch.scale_names[k]}")
        if all(live >= need and ahead >= needed_s for _, _, ahead, need in verdicts):
            return min(ahead for _, _, ahead, _ in verdicts), ""
        return None, ""

    def _relaxed(self, assign, state, ctx, measured, weak, up):
        """State and context with the holds lifted for the cleared and staying nodes, the
        reactive rules kept for every other node, and the forecast's returns and holds added."""
        a = self.last
        # A connection's own reason first: it is the measurement.
        violating = {**a.home, **ctx.violating}
        held = set(ctx.held_after_loss) | set(a.held)
        if not a.cleared and not a.staying:
            return state, replace(ctx, violating=violating, held_after_loss=frozenset(held))
        usable = state.bandwidth_mbps
        if weak and math.isfinite(measured):
            usable = measured / (1.0 + self.params.bandwidth_stay_margin)
        admit = state.admit_bandwidth_mbps
        if a.cleared and math.isfinite(measured):
            admit = max(admit, measured / (1.0 + self.params.bandwidth_margin))
        # The reactive limit on what may cross after a move out (constraints.admission_state).
        streams = required_bandwidth(self.ch, assign)
        reactive = min(state.bandwidth_mbps, max(state.admit_bandwidth_mbps, streams))
        for i in range(self.ch.num_nodes):
            if self.ch.pinned[i]:
                continue
            if assign[i] == self.ch.master:
                if i in a.cleared:
                    held.discard(i)
                elif not any(required_bandwidth(self.ch, _moved(assign, i, k)) <= reactive + 1e-9
                             for k in range(self.ch.num_scales)
                             if k != self.ch.master and self.ch.allowed[i, k] and up[k]):
                    held.add(i)         # the reactive rules would not let it out either
            elif weak and i not in a.staying and i not in violating:
                violating[i] = a.home[i] = (
                    f"bandwidth {measured:.1f} Mbit/s, below weak_link_mbps "
                    f"{self.params.weak_link_mbps:g}: home before the link is lost")
        back = {i: t for i, t in ctx.migrated_back_at.items()
                if not (i in a.cleared and self.link_return_at.get(i) == t)}
        return (replace(state, bandwidth_mbps=usable, admit_bandwidth_mbps=admit),
                replace(ctx, violating=violating, held_after_loss=frozenset(held),
                        migrated_back_at=back))

    def reason(self, move: Move, reason: str) -> str:
        """The event's reason: a planned return before a hole says so, a move out early says
        how long the link ahead carries it."""
        a = self.last
        if move.target == self.ch.master:
            why = a.home.get(move.node)
            return why if why and reason.endswith(why) else reason
        if move.node in a.cleared:
            return f"{reason}; link ahead carries it {a.cleared[move.node]:.0f} s"
        return reason

    def moved(self, moves: Sequence[Move], reasons: Sequence[str], now: float):
        """The tick's moves with their events' reasons: returns for the link are noted (T may
        be skipped after them)."""
        for move, reason in zip(moves, reasons):
            if move.target == self.ch.master and reason.startswith(LINK_REASONS):
                self.link_return_at[move.node] = now


def _moved(assign: np.ndarray, i: int, k: int) -> np.ndarray:
    trial = assign.copy()
    trial[i] = k
    return trial
