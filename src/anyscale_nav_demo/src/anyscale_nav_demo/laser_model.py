"""The simulated Hokuyo URG-04LX: geometry, range noise, and its raw millimetre output."""
import numpy as np

URG_ANGLE_MIN = -2.0943951   # -120 deg
URG_ANGLE_MAX = 2.0943951
URG_BEAMS = 682
URG_RANGE_MIN = 0.02
URG_RANGE_MAX = 5.6
URG_NO_ECHO_MM = 0           # URG error codes are values below 20 mm; 0 = no echo


def noisy_ranges(true_ranges, rng, std_near=0.01, rel_far=0.01):
    """URG-04LX accuracy: +-10 mm up to 1 m, 1 % of the distance beyond (as 1-sigma noise)."""
    r = np.asarray(true_ranges, dtype=float)
    sigma = np.where(r < 1.0, std_near, rel_far * r)
    with np.errstate(invalid="ignore"):
        return r + sigma * rng.standard_normal(r.shape)


def ranges_to_raw_mm(ranges, range_min=URG_RANGE_MIN, range_max=URG_RANGE_MAX):
    """What the sensor's serial protocol sends: integer millimetres, error code where no echo."""
    r = np.asarray(ranges, dtype=float)
    ok = np.isfinite(r) & (r >= range_min) & (r <= range_max)
    out = np.full(r.shape, URG_NO_ECHO_MM, dtype=np.int32)
    out[ok] = np.round(r[ok] * 1000.0).astype(np.int32)
    return out


def raw_mm_to_ranges(raw_mm, range_min=URG_RANGE_MIN):
    """The driver's conversion to LaserScan metres; no echo becomes +inf (REP 117)."""
    raw = np.asarray(raw_mm, dtype=float)
    out = raw / 1000.0
    out[raw < range_min * 1000.0] = np.inf
    return out
