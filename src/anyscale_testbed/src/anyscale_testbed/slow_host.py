"""The test bed on a host slower than the reference day (issue 41), pure: the system tests'
slow-day mode and an emulated slower host. The reasons and measurements are in the package
README ("A slow host") and docs/measurements/2026-11-28-slow-host.md.

The slow-day mode (`run_testbed.py --host-factor F`) keeps what the tests' fixed quotas mean
on a host F times slower: the work each scale does per message is divided by F in the
calibration's own knobs (AMCL's particles, AR recognition's threshold windows, the simulated
laser's beams), so those nodes take the CPU time they took on the reference day; the quotas
grow by what the nodes it cannot scale (drivers, odometry, EKF, navigation, the agents, the
decision node) need more there; the world leaves out the recorders no test reads.

An emulated slower host (`--emulate-slow-host E`, test bed only): every CPU quota divided by E,
and the world's processes (simulator, monitor, master), outside the scales' quotas, held in a
group of this machine's CPUs / E, so every process gets at most 1/E of the CPU it would get
here. An emulation: CFS hands a quota out in bursts within each 100 ms period where a slow CPU
runs smoothly, and the groups together may take more than the machine's CPUs / E (the
measurements compare their sum with it)."""
from dataclasses import dataclass
import math
from typing import Dict

URG_BEAMS = 682             # anyscale_nav_demo's laser_model.URG_BEAMS: the reference's beams
CAMERA_HZ = 30.0            # the simulated camera's frame rate on the reference day
AR_SWEEP = ("adaptiveThreshWinSizeMin", "adaptiveThreshWinSizeMax", "adaptiveThreshWinSizeStep")
# The cores a quota grows by per unit of F - 1: what a scale's nodes need beyond the work the
# mode scales (drivers, odometry, EKF, navigation, the agent, the decision node, and AMCL's and AR
# recognition's own cost per message). Found on an emulated host 4.5 x slower: robot 1.1 cores
# gave AMCL 3.66 Hz with every node home (2026-11-28, reference day 3.53 Hz at 0.37 cores); the
# laptop's 0.9 cores grow to keep the share of it AMCL and AR use what it was (about 0.6).
ROBOT_FIXED_CORES = 0.21
LAPTOP_FIXED_CORES = 0.06


def check_factor(value: float, what: str) -> float:
    """A factor >= 1, or ValueError naming `what`."""
    if not (math.isfinite(value) and value >= 1.0):
        raise ValueError(f"{what}: expected a factor >= 1, got {value:g}")
    return value


@dataclass(frozen=True)
class SlowDayMode:
    factor: float           # F: how many times slower than the reference day the host is
    robot_cores: float
    laptop_cores: float
    laser_beams: int        # the simulated laser's, and the laser driver's ~beams
    camera_hz: float        # the simulated camera's frame rate
    calibration: dict       # the calibration file's content, its node sections scaled


def beams_used(beams: int, max_beams: int) -> int:
    """How many beams of a scan AMCL weighs: every step-th, as the amcl node subsamples."""
    step = max(1, math.ceil(beams / max_beams))
    return math.ceil(beams / step)


def sweep_windows(low: int, high: int, step: int) -> int:
    """How many threshold windows cv2.aruco tries: low, low + step, .. up to high."""
    return (high - low) // step + 1


def slow_day_mode(factor: float, robot_cores: float, laptop_cores: float,
                  calibration: dict) -> SlowDayMode:
    """The mode for a host `factor` times slower, from the reference quotas and the
    calibration file's content (its amcl and ar_recognition sections are scaled; a laser
    section is added for the driver)."""
    check_factor(factor, "--host-factor")
    out = {k: (dict(v) if isinstance(v, dict) else v) for k, v in calibration.items()}
    beams = max(2, int(round(URG_BEAMS / factor)))
    out["laser"] = dict(out.get("laser", {}), beams=beams)
    amcl = out.get("amcl", {})
    if "laser_max_beams" in amcl:
        # AMCL's cost is particles x beams weighed: fewer beams already take their share
        max_beams = int(amcl["laser_max_beams"])
        per_particle = beams_used(URG_BEAMS, max_beams) / beams_used(beams, max_beams)
        for key in ("min_particles", "max_particles"):
            if key in amcl:
                amcl[key] = max(100, int(round(int(amcl[key]) * per_particle / factor)))
    detector = dict(out.get("ar_recognition", {}).get("detector_params", {}))
    if all(k in detector for k in AR_SWEEP):
        low, high, step = (int(detector[k]) for k in AR_SWEEP)
        windows = max(1, int(round(sweep_windows(low, high, step) / factor)))
        # the same span in fewer, wider steps; one window: low alone
        detector["adaptiveThreshWinSizeStep"] = max(1, (high - low) // max(windows - 1, 1))
        if windows == 1:
            detector["adaptiveThreshWinSizeMax"] = low
        out["ar_recognition"] = dict(out["ar_recognition"], detector_params=detector)
    return SlowDayMode(factor, robot_cores + ROBOT_FIXED_CORES * (factor - 1.0),
                       laptop_cores + LAPTOP_FIXED_CORES * (factor - 1.0), beams,
                       CAMERA_HZ / math.sqrt(factor), out)


@dataclass(frozen=True)
class EmulatedHost:
    slowdown: float         # E: this host's CPU-seconds per emulated CPU-second
    robot_cores: float      # the scales' quotas, divided by E
    laptop_cores: float
    world_cores: float      # the world's group: this host's CPUs / E


def emulated_host(slowdown: float, robot_cores: float, laptop_cores: float,
                  host_cpus: int) -> EmulatedHost:
    """The quotas of a bed on a host `slowdown` times slower than this one, which has
    `host_cpus` CPUs."""
    check_factor(slowdown, "--emulate-slow-host")
    return EmulatedHost(slowdown, robot_cores / slowdown, laptop_cores / slowdown,
                        host_cpus / slowdown)


def describe(mode: SlowDayMode) -> str:
    """The mode in one line, for a run's console."""
    amcl = mode.calibration.get("amcl", {})
    detector = mode.calibration.get("ar_recognition", {}).get("detector_params", {})
    windows = sweep_windows(*(int(detector[k]) for k in AR_SWEEP)) \
        if all(k in detector for k in AR_SWEEP) else "?"
    return (f"host factor {mode.factor:.2f} (the system tests' slow-day mode): laser "
            f"{mode.laser_beams} beams, camera {mode.camera_hz:.1f} Hz, AMCL "
            f"{amcl.get('max_particles', '?')} particles, AR {windows} threshold windows; "
            f"quotas robot {mode.robot_cores:.3f} / laptop {mode.laptop_cores:.3f} cores")


def mode_world_args(mode: SlowDayMode) -> Dict[str, str]:
    """testbed_world.launch's arguments of the mode."""
    return {"laser_beams": str(mode.laser_beams), "camera_rate": f"{mode.camera_hz:.2f}",
            "nav_recorders": "false"}
