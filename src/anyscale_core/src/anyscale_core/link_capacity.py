"""What the link to the remote scales may be trusted to carry, from the agents' bandwidth
readings: a move out needs what the link has held for a while (BandwidthHold), a node out stays
while the reading carries its streams plus a smaller margin, and a weak link carries nothing."""
from collections import deque
import math
from typing import List, Optional, Tuple

# After a move, the streams of the mapping before it still count as crossing the link this long
# (the handover, then a bandwidth reading taken without them: the echo runs every second).
STREAMS_SETTLE_S = 3.0


class BandwidthHold:
    """The least bandwidth the link showed over the last hold_s, less a margin: what a move
    out may count on. 0 until the link has been watched that long, and after a loss: a link
    that just came back has shown nothing yet. It keeps the latest loss too, for the longer
    hold after a loss of the nodes that need one (DecisionParams.hold_after_loss)."""

    def __init__(self, hold_s: float, margin: float):
        self.hold_s = hold_s
        self.margin = margin
        self._samples: deque = deque()      # (t, Mbit/s), 0 = link down or weak
        self._since: Optional[float] = None  # when watching began
        self._lost_at = -math.inf            # the latest time the link was seen down

    def add(self, t: float, mbps: float, lost: bool = False):
        """A reading at time t; `lost`: the link was down (not merely weak)."""
        if self._since is None:
            self._since = t
        if lost:
            self._lost_at = t
        self._samples.append((t, mbps))
        while len(self._samples) > 1 and self._samples[1][0] <= t - self.hold_s:
            self._samples.popleft()

    @property
    def lost_at(self) -> float:
        """The latest time the link was seen down (-inf: never)."""
        return self._lost_at

    def restore_loss(self, t: float):
        """A loss the decision node before a restart saw (restart_state.py)."""
        self._lost_at = max(self._lost_at, t)

    def admissible(self, t: float) -> float:
        if self._since is None or t - self._since < self.hold_s:
            return 0.0
        held = min(m for _, m in self._samples)
        return held / (1.0 + self.margin)


class LinkCapacity:
    """The link as the allocator may count on it. `streams_mbps` arguments are what the
    current mapping sends across (constraints.required_bandwidth)."""

    def __init__(self, hold: BandwidthHold, stay_margin: float, weak_link_mbps: float):
        self.hold = hold
        self.stay_margin = stay_margin
        self.weak_link_mbps = weak_link_mbps
        self._earlier: List[Tuple[float, float]] = []   # (until when, Mbit/s) of earlier mappings

    def mapping_changed(self, now: float, streams_before_mbps: float):
        """A move: what crossed until now keeps counting for STREAMS_SETTLE_S."""
        self._earlier = [(t, b) for t, b in self._earlier if t >= now - STREAMS_SETTLE_S]
        self._earlier.append((now, streams_before_mbps))

    def observe(self, now: float, measured_mbps: float, remote_up: bool, streams_mbps: float):
        """One period's reading. Nothing measured (a link that just came back) has shown
        nothing: it counts as 0 for moves out, as a weak link does."""
        shown = measured_mbps if (remote_up and math.isfinite(measured_mbps)
                                  and not self.is_weak(measured_mbps, now, streams_mbps)) else 0.0
        self.hold.add(now, shown, lost=not remote_up)

    def admissible(self, now: float) -> float:
        """What a move out may count on (BandwidthHold)."""
        return self.hold.admissible(now)

    def is_weak(self, measured_mbps: float, now: float, streams_mbps: float) -> bool:
        """Whether the link itself is weak, not just filled by the streams sent across it: the
        echo then measures what they leave (a 6 Mbit/s link carrying AR's camera read 1.1),
        and the bandwidth rule brings the heavy node home. What the link carries is about the
        reading plus those streams, counted for STREAMS_SETTLE_S after they stopped: the old
        instance streams until the new one has published, and the estimate needs a reading
        taken after that."""
        carried = max([b for t, b in self._earlier if t >= now - STREAMS_SETTLE_S] +
                      [streams_mbps])
        return math.isfinite(measured_mbps) and measured_mbps + carried < self.weak_link_mbps

    def usable(self, measured_mbps: float, now: float, streams_mbps: float) -> float:
        """What the allocator may place on a link measured at measured_mbps: the measurement
        less the stay margin (moves out are held to more, see BandwidthHold). A WiFi link is
        seldom lost from full rate: rate adaptation first steps down to its lowest rates, and
        a node brought home while the link still carries the handover is a planned move (the
        new instance publishes before the old one stops), where one brought home by the loss
        leaves its output silent until it has started on the robot. So a weak link carries
        nothing: nodes come home, and none moves out until the link is better again."""
        if self.is_weak(measured_mbps, now, streams_mbps):
            return 0.0
        return measured_mbps / (1.0 + self.stay_margin)
