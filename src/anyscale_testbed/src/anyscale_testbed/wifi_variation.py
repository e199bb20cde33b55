"""Seeded variation of the test bed's WiFi coverage, so that runs on the same floor differ as
the paper's four tests did (people, doors, interference): log-normal shadowing correlated along
the robot's path, and interference episodes in time. Pure; seed 0 is the unchanged,
deterministic model of wifi_link_model.py.

Shadowing (the slow, location-dependent part of the received power that the path-loss and wall
model does not predict) is a zero-mean Gaussian in dB, correlated along the travelled distance
d as exp(-d / d_corr) (Gudmundson, "Correlation model for shadow fading in mobile radio
systems", Electronics Letters 27(23), 1991; the form 3GPP uses), drawn as a first-order
autoregressive sequence every STEP_M. Constants from 3GPP TR 38.901 (v16), indoor hotspot
(InH-Office):
- shadow fading sigma: 3 dB in line of sight, 8.03 dB without (Table 7.4.1-1);
- decorrelation distance: 10 m in line of sight, 6 m without (Table 7.5-6, part 2).
Line of sight here means no wall of the map between the robot and the access point; the two
processes are independent, as 38.901 generates LOS and NLOS shadowing separately.

Interference episodes (a microwave oven, a neighbouring network's burst, a door closed, a
crowd in the corridor): Poisson arrivals in time, exponential durations. No standard gives
their rates for an office floor; these values are assumptions stated before any seeded run,
not fitted to a result: one episode a minute on average, lasting 8 s on average; one in four
takes the link away (a loss the rate adaptation cannot ride through), the others cost 10 dB of
signal-to-interference margin (about the loss of one person's body in the line of sight at
2.4 GHz, cf. Januszkiewicz, Sensors 18(10) 3412, 2018), which the 802.11g rate steps turn into
a lower rate or, at the edge of coverage, no link.
"""
from dataclasses import dataclass
import math
from typing import List, Optional, Tuple

import numpy as np

from .wifi_link_model import CoverageModel, usable_bandwidth_mbps

# Distance between two draws of a shadowing sequence (m): well below both decorrelation
# distances, and finer than the robot moves in one tick of the shaper (0.4 m/s at 5 Hz).
STEP_M = 0.1
# Independent random streams derived from one seed (numpy SeedSequence spawn keys), so that a
# value does not depend on the order in which the streams are queried.
_LOS_STREAM, _NLOS_STREAM, _INTERFERENCE_STREAM = 1, 2, 3


@dataclass(frozen=True)
class ShadowingParams:
    los_sigma_db: float = 3.0
    nlos_sigma_db: float = 8.03
    los_decorrelation_m: float = 10.0
    nlos_decorrelation_m: float = 6.0


@dataclass(frozen=True)
class InterferenceParams:
    episodes_per_min: float = 1.0
    mean_duration_s: float = 8.0
    drop_share: float = 0.25        # share of the episodes that take the link away
    penalty_db: float = 10.0        # margin lost in the other episodes


@dataclass(frozen=True)
class Episode:
    start_s: float
    end_s: float
    drops_link: bool
    penalty_db: float


def _rng(seed: int, stream: int) -> np.random.Generator:
    return np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(stream,)))


class ShadowingSequence:
    """Unit-variance Gaussian sequence over travelled distance with correlation
    exp(-distance / decorrelation_m), drawn lazily every STEP_M from its own seeded stream:
    the value at a distance depends only on the seed and the distance."""

    def __init__(self, seed: int, stream: int, decorrelation_m: float):
        if not decorrelation_m > 0:
            raise ValueError(f"decorrelation distance must be > 0 m, got {decorrelation_m!r}")
        self._rng = _rng(seed, stream)
        self._rho = math.exp(-STEP_M / decorrelation_m)
        self._values = [float(self._rng.standard_normal())]

    def at(self, distance_m: float) -> float:
        index = max(0, int(round(distance_m / STEP_M)))
        innovation = math.sqrt(1.0 - self._rho ** 2)
        while len(self._values) <= index:
            self._values.append(self._rho * self._values[-1]
                                + innovation * float(self._rng.standard_normal()))
        return self._values[index]


def interference_episodes(seed: int, horizon_s: float,
                          params: InterferenceParams = InterferenceParams()) -> List[Episode]:
    """The episodes that start before `horizon_s`, in time order (seed 0: none)."""
    if seed == 0 or params.episodes_per_min <= 0:
        return []
    rng = _rng(seed, _INTERFERENCE_STREAM)
    mean_gap_s = 60.0 / params.episodes_per_min
    episodes, t = [], 0.0
    while True:
        t += float(rng.exponential(mean_gap_s))
        duration = float(rng.exponential(params.mean_duration_s))
        drops = bool(rng.random() < params.drop_share)
        if t >= horizon_s:
            return episodes
        episodes.append(Episode(t, t + duration, drops, 0.0 if drops else params.penalty_db))


def interference_at(episodes: List[Episode], t_s: float) -> Tuple[bool, float]:
    """(link dropped, dB of margin lost) at time t_s: a drop wins; overlapping penalties take
    the worst one, not the sum (one interferer at a time sets the margin)."""
    active = [e for e in episodes if e.start_s <= t_s < e.end_s]
    return (any(e.drops_link for e in active),
            max((e.penalty_db for e in active), default=0.0))


class VariedCoverage:
    """A CoverageModel with seeded shadowing along the path and interference episodes in time.
    With seed 0 every bandwidth is exactly the model's."""

    # Episodes are drawn up to this horizon once; a run is minutes, a day is plenty.
    HORIZON_S = 24 * 3600.0

    def __init__(self, model: CoverageModel, seed: int,
                 shadowing: ShadowingParams = ShadowingParams(),
                 interference: InterferenceParams = InterferenceParams()):
        if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
            raise ValueError(f"seed must be an integer >= 0, got {seed!r}")
        self.model, self.seed, self.shadowing = model, seed, shadowing
        self._los = ShadowingSequence(seed, _LOS_STREAM, shadowing.los_decorrelation_m)
        self._nlos = ShadowingSequence(seed, _NLOS_STREAM, shadowing.nlos_decorrelation_m)
        self.episodes = interference_episodes(seed, self.HORIZON_S, interference)

    def shadowing_db(self, travelled_m: float, line_of_sight: bool) -> float:
        if self.seed == 0:
            return 0.0
        if line_of_sight:
            return self.shadowing.los_sigma_db * self._los.at(travelled_m)
        return self.shadowing.nlos_sigma_db * self._nlos.at(travelled_m)

    def bandwidth_at(self, x: float, y: float, travelled_m: float, t_s: float) -> float:
        """Mbit/s usable by TCP with the robot at (x, y), `travelled_m` along its path, `t_s`
        since the shaper started (the episodes' clock); 0 = no link."""
        if self.seed == 0:
            return self.model.bandwidth_at(x, y)
        rx_dbm, walls = self.model.received_power_at(x, y)
        dropped, penalty_db = interference_at(self.episodes, t_s)
        if dropped:
            return 0.0
        rx_dbm += self.shadowing_db(travelled_m, walls == 0) - penalty_db
        return usable_bandwidth_mbps(rx_dbm, self.model.radio)


class TravelledDistance:
    """Distance along the path from successive positions (the shaper's ticks)."""

    def __init__(self):
        self.metres = 0.0
        self._last: Optional[Tuple[float, float]] = None

    def update(self, x: float, y: float) -> float:
        if self._last is not None:
            self.metres += math.hypot(x - self._last[0], y - self._last[1])
        self._last = (x, y)
        return self.metres
