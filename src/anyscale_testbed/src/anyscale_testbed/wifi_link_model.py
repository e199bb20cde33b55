"""WiFi link model of the two-scale test bed: available bandwidth from the robot's position
(log-distance path loss, walls, 802.11g rate steps), or from a scripted schedule for tests.
Seeded shadowing and interference on top of it: wifi_variation.py.

The constants are typical published values, not fitted to any result:
- reference loss 40 dB at 1 m: free-space loss at 2.4 GHz, 20 log10(4 pi d0 / lambda);
- path-loss exponent 3.0: the usual indoor-office value (2.7-3.5 in the literature);
- 5 dB per wall crossed: plasterboard office partitions (concrete would be 10-15 dB);
- 15 dBm transmit power: a common access point's OFDM output;
- receiver sensitivity per 802.11g rate (6..54 Mbit/s at -82..-65 dBm): the OFDM PHY's
  receiver minimum input sensitivity (IEEE Std 802.11-2016, 17.3.10.2), which vendor
  datasheets repeat;
- about half the PHY rate is usable by TCP (CSMA/CA, ACKs, headers).
"""
from dataclasses import dataclass
import math
from typing import List, Sequence, Tuple

import numpy as np

# (sensitivity dBm, PHY rate Mbit/s), best rate first.
RATE_STEPS_80211G: Tuple[Tuple[float, float], ...] = (
    (-65, 54), (-66, 48), (-70, 36), (-74, 24), (-77, 18), (-79, 12), (-81, 9), (-82, 6))


@dataclass(frozen=True)
class RadioParams:
    tx_power_dbm: float = 15.0
    reference_loss_db: float = 40.0
    reference_distance_m: float = 1.0
    path_loss_exponent: float = 3.0
    wall_loss_db: float = 5.0
    tcp_efficiency: float = 0.5


def received_power_dbm(distance_m: float, walls: int, radio: RadioParams = RadioParams()) -> float:
    """Log-distance path loss plus a fixed loss per wall crossed."""
    d = max(distance_m, radio.reference_distance_m)
    loss = (radio.reference_loss_db
            + 10 * radio.path_loss_exponent * math.log10(d / radio.reference_distance_m)
            + walls * radio.wall_loss_db)
    return radio.tx_power_dbm - loss


def phy_rate_mbps(rx_dbm: float) -> float:
    """The fastest 802.11g rate whose sensitivity the signal meets; 0 = no link."""
    for sensitivity, rate in RATE_STEPS_80211G:
        if rx_dbm >= sensitivity:
            return float(rate)
    return 0.0


def usable_bandwidth_mbps(rx_dbm: float, radio: RadioParams = RadioParams()) -> float:
    return phy_rate_mbps(rx_dbm) * radio.tcp_efficiency


def walls_crossed(occupied: np.ndarray, resolution: float, origin_xy: Sequence[float],
                  a_xy: Sequence[float], b_xy: Sequence[float]) -> int:
    """Number of separate occupied runs along the segment a-b on an occupancy grid (row 0 at
    origin y, as map_server's data after flipping), sampled at half a cell."""
    length = math.hypot(b_xy[0] - a_xy[0], b_xy[1] - a_xy[1])
    samples = max(2, int(math.ceil(length / (resolution / 2))) + 1)
    t = np.linspace(0.0, 1.0, samples)
    x = a_xy[0] + t * (b_xy[0] - a_xy[0])
    y = a_xy[1] + t * (b_xy[1] - a_xy[1])
    col = np.floor((x - origin_xy[0]) / resolution).astype(int)
    row = np.floor((y - origin_xy[1]) / resolution).astype(int)
    inside = (row >= 0) & (row < occupied.shape[0]) & (col >= 0) & (col < occupied.shape[1])
    hit = np.zeros(samples, dtype=bool)
    hit[inside] = occupied[row[inside], col[inside]]
    return int(np.count_nonzero(hit[1:] & ~hit[:-1]) + hit[0])


@dataclass(frozen=True)
class CoverageModel:
    """Bandwidth available between the robot and an access point fixed on the floor."""
    occupied: np.ndarray            # (rows, cols) bool, row 0 at origin y
    resolution: float               # m per cell
    origin_xy: Tuple[float, float]  # world position of cell (0, 0)'s corner
    access_point_xy: Tuple[float, float]
    radio: RadioParams = RadioParams()

    def received_power_at(self, x: float, y: float) -> Tuple[float, int]:
        """(received power in dBm, walls crossed) with the robot at (x, y)."""
        walls = walls_crossed(self.occupied, self.resolution, self.origin_xy,
                              self.access_point_xy, (x, y))
        distance = math.hypot(x - self.access_point_xy[0], y - self.access_point_xy[1])
        return received_power_dbm(distance, walls, self.radio), walls

    def bandwidth_at(self, x: float, y: float) -> float:
        """Mbit/s usable by TCP with the robot at (x, y); 0 = out of coverage."""
        return usable_bandwidth_mbps(self.received_power_at(x, y)[0], self.radio)


class ScriptedSchedule:
    """Bandwidth over time as steps: [(t_s, mbps), ...]; 0 Mbit/s means the link is down."""

    def __init__(self, steps: List[Tuple[float, float]]):
        if not steps:
            raise ValueError("a schedule needs at least one (time, bandwidth) step")
        times = [t for t, _ in steps]
        if any(b < a for a, b in zip(times, times[1:])):
            raise ValueError("schedule times must not decrease")
        if any(mbps < 0 for _, mbps in steps):
            raise ValueError("schedule bandwidths must be >= 0")
        self.steps = list(steps)

    def bandwidth_at(self, t: float) -> float:
        current = self.steps[0][1]
        for start, mbps in self.steps:
            if start > t:
                break
            current = mbps
        return current
