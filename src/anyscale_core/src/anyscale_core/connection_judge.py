"""Which connections of the nodes out on remote scales spend their tolerance (no ROS): each
connection's rate where its subscriber runs against freq_min and Δ (the paper's rule), its
silence against a share of Δ, and the grace a moved node gets while its new instance starts.
The decision engine asks it every tick which remote nodes must come home, and why."""
import math
from typing import Dict, FrozenSet, List, Mapping, Optional

import numpy as np

from .characterisation import Characterisation
from .constraints import FrequencyToleranceTracker
from .decision_types import DecisionParams, ScaleReport


class ConnectionJudge:
    def __init__(self, ch: Characterisation, params: DecisionParams):
        self.ch = ch
        self.params = params
        self.trackers = [FrequencyToleranceTracker(c.freq_min, c.tolerance)
                         for c in ch.model.connections]
        self.moved_at: Dict[int, float] = {}        # node -> its latest start, move or restart
        self.output_seen_at: Dict[int, float] = {}  # node -> its new instance published
        # The nodes of the latest violating() whose connection still delivers, but below
        # freq_min: a slow rate, not a silence (an instance that died, or a link that stalls).
        self.slow_rate: FrozenSet[int] = frozenset()

    def moved(self, i: int, now: float):
        """Node i was started, moved or restarted: its connections settle for startup_grace_s."""
        self.moved_at[i] = now

    def output_seen(self, i: int, now: float):
        """The new instance of moved node i has published (_handed_over)."""
        self.output_seen_at[i] = now

    def violating(self, assign: np.ndarray, reports: Mapping[str, ScaleReport],
                  now: float) -> Dict[int, str]:
        """Feed each connection's rate as received where its subscriber runs; return the
        remote nodes on connections that spent `act_at_tolerance` of their tolerance below
        freq_min, or were silent for `act_at_silence` of it, each with why."""
        violating, slow = {}, set()
        for c, tracker in enumerate(self.trackers):
            ends = self._remote_ends(assign, c)
            if not ends:
                continue
            conn = self.ch.model.connections[c]
            scale = self.ch.scale_names[assign[self.ch.conn_sub[c]]]
            report = reports.get(scale)
            why = silent = self._silence_judged(c, report, now)
            if self._settling(c, now):
                tracker.update(now, math.inf)      # settling after a move: rates not judged
            else:
                rate = report.topic_rates.get(conn.topic, math.nan) if report else math.nan
                tracker.update(now, rate)
                if tracker.violated(now) or \
                        tracker.used_fraction(now) >= self.params.act_at_tolerance:
                    counted = f"{rate:.1f} Hz" if math.isfinite(rate) else "no rate"
                    why = (f"{conn.name} {counted} on {scale} < {conn.freq_min:g} Hz for "
                           f"{tracker.below_for(now):.1f} s of {conn.tolerance:g} s")
                    if rate > 0 and not silent:
                        slow.update(ends)
            if why:
                violating.update((i, why) for i in ends if not self.ch.pinned[i])
        self.slow_rate = frozenset(i for i in slow if i in violating)
        return violating

    def silence_alarm(self, assign: np.ndarray, report: ScaleReport, now: float) -> bool:
        """Whether `report` shows a judged connection subscribed on its scale silent for
        act_at_silence of its tolerance: the wrapper then ticks at once, not a period later."""
        for c in range(len(self.trackers)):
            if (self.ch.scale_names[assign[self.ch.conn_sub[c]]] == report.scale
                    and any(not self.ch.pinned[i] for i in self._remote_ends(assign, c))
                    and self._silence_judged(c, report, now)):
                return True
        return False

    def _remote_ends(self, assign: np.ndarray, c: int) -> List[int]:
        return [i for i in (self.ch.conn_pub[c], self.ch.conn_sub[c])
                if assign[i] != self.ch.master]

    def _settling(self, c: int, now: float) -> bool:
        """An end of connection c moved less than startup_grace_s ago: it is not judged."""
        return any(now - self.moved_at.get(i, -math.inf) < self.params.startup_grace_s
                   for i in (self.ch.conn_pub[c], self.ch.conn_sub[c]))

    def _silence_judged(self, c: int, report: Optional[ScaleReport], now: float) -> str:
        """_silence_spent; inside the start-up grace only once the moved ends have handed over,
        and only for a topic the agent has heard (it may have begun counting it just now)."""
        if not self._settling(c, now):
            return self._silence_spent(c, report)
        return self._silence_spent(c, report, heard_only=True) if self._handed_over(c, now) else ""

    def _handed_over(self, c: int, now: float) -> bool:
        """Every end of connection c still settling has published from its new instance since:
        the grace covers a start, and the old instance publishes until the new one has (make
        before break), so a silence after that is the output's own and is judged at once, not
        only when the grace runs out (docs/results.md, "Δ at a move")."""
        settling = [i for i in (self.ch.conn_pub[c], self.ch.conn_sub[c])
                    if now - self.moved_at.get(i, -math.inf) < self.params.startup_grace_s]
        return all(self.output_seen_at.get(i, -math.inf) >= self.moved_at[i] for i in settling)

    def _silence_spent(self, c: int, report: Optional[ScaleReport],
                       heard_only: bool = False) -> str:
        """Why connection c must come home for its silence ('' if it need not): once the silence
        has used act_at_silence of its tolerance, so that the return lands before the tolerance
        is spent (docs/design/live_migration.md, "Home before a silence reaches Δ")."""
        conn = self.ch.model.connections[c]
        share = self.params.act_at_silence
        if report is None or share <= 0 or conn.tolerance <= 0:
            return ""
        silence = report.topic_silence.get(conn.topic, math.nan)
        if not silence >= share * conn.tolerance or (heard_only and math.isinf(silence)):
            return ""
        quiet = f"silent {silence:.2f} s" if math.isfinite(silence) else "never received"
        return (f"{conn.name} {quiet} on {report.scale}, over {100 * share:.0f} % of its "
                f"{conn.tolerance:g} s tolerance")
