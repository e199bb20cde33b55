"""The scales of a test-bed run (run_testbed.py --scales, issue 39): robot and laptop, or those
and a server behind the access point (access_point_layout.py). For each set: the model it runs
unless --model names one (and whether a model given fits it), the CPU quota of each scale (the
server's own, and in the slow-day and emulated-host modes), whether the quotas leave the world
room on this host, the start line's words for them, and the bed's layout. No ROS, no root (it
reads a model file). The two-scale set gives what the two-scale bed always had."""
from typing import Dict, Optional, Sequence, Tuple

from anyscale_core.model import ModelError
from anyscale_core.model_loader import load_model

from .access_point_layout import WIRED_MBPS, access_point_layout
from .slow_host import LAPTOP_FIXED_CORES
from .testbed_session import layout_with_cpu

TWO_SCALES = ("robot", "laptop")
THREE_SCALES = ("robot", "laptop", "server")
SCALE_SETS = (TWO_SCALES, THREE_SCALES)
# anyscale_nav_demo's config/ file of each set's model.
MODEL_FILES = {TWO_SCALES: "testbed.yaml", THREE_SCALES: "testbed_three_scales.yaml"}
# The server's quota: the model's server is 1.5 x the robot's capacity (its alpha), and 0.5 is
# that of the robot's calibrated 0.34. With the laptop's 0.9 the three take 1.74 cores of this
# 2-core host.
SERVER_CPU_CORES = 0.5
# What the world needs beside the scales' quotas (simulator 0.09-0.11 cores, the monitor's
# census of /proc, the link shaper, the master): three quotas that leave less than this of the
# host to it starve the sensors every scale depends on.
WORLD_RESERVE_CORES = 0.2
# A quota the option accepts, as --robot-cpu's (quota_for_the_day.parse_robot_cpu).
MIN_CORES, MAX_CORES = 0.05, 2.0


def parse_scales(text: str) -> Tuple[str, ...]:
    """The scale set named by `text` ("robot,laptop" or "robot,laptop,server"); ValueError in
    one line otherwise."""
    names = tuple(s.strip() for s in text.split(",") if s.strip())
    if names not in SCALE_SETS:
        raise ValueError(f"--scales: expected {' or '.join(','.join(s) for s in SCALE_SETS)}, "
                         f"got {text!r}")
    return names


def check_server_cpu(cores: Optional[float], scales: Sequence[str]):
    """--server-cpu: only with a server, and a quota the kernel and this host can give."""
    if cores is None:
        return
    if "server" not in scales:
        raise ValueError("--server-cpu: the server's quota; it needs --scales "
                         + ",".join(THREE_SCALES))
    if not MIN_CORES <= cores <= MAX_CORES:
        raise ValueError(f"--server-cpu: expected {MIN_CORES:g} to {MAX_CORES:g} cores, "
                         f"got {cores:g}")


def scale_cores(robot: float, laptop: float, server: Optional[float] = None) -> Dict[str, float]:
    """scale -> CPU quota in cores, robot first; a server only when it has a quota (None: the
    two-scale set)."""
    cores = {"robot": robot, "laptop": laptop}
    if server is not None:
        cores["server"] = server
    return cores


def slow_day_server_cores(cores: float, factor: float) -> float:
    """The server's quota in the slow-day mode for a host `factor` times slower: grown as the
    laptop's is (slow_host.slow_day_mode), as it runs the same nodes."""
    return cores + LAPTOP_FIXED_CORES * (factor - 1.0)


def fit_problem(cores: Dict[str, float], host_cpus: float) -> str:
    """Why the quotas do not fit this host with WORLD_RESERVE_CORES left to the world, in one
    line ('' when they fit). A quota is a ceiling, not a reservation; but with every scale busy
    (all of them are once nodes move out) they would share the host, and a scale would get
    less than its quota: the bed would no longer be what its quotas say."""
    total = sum(cores.values())
    if total + WORLD_RESERVE_CORES <= host_cpus + 1e-9:
        return ""
    return (f"the CPU quotas ({quota_words(cores)}) add up to {total:.2f} cores: with the "
            f"{WORLD_RESERVE_CORES:g} the world needs they do not fit this host's "
            f"{host_cpus:g} CPUs; lower --server-cpu or --laptop-cpu")


def quota_words(cores: Dict[str, float]) -> str:
    """The start line's quotas: 'CPU quota robot 0.34 / laptop 0.9 cores' (and '/ server 0.5')."""
    return "CPU quota " + " / ".join(f"{s} {c:g}" for s, c in cores.items()) + " cores"


def bed_layout(cores: Dict[str, float], link: str):
    """The bed's layout for the scales of `cores`: the two-scale bed's veth pair, or the
    access point's with the server's wired segment (not shaped with --link unshaped, which
    shapes nothing)."""
    if "server" not in cores:
        return layout_with_cpu(cores["robot"], cores["laptop"])
    return access_point_layout(cores, 0.0 if link == "unshaped" else WIRED_MBPS)


def model_problem(path: str, scales: Sequence[str]) -> str:
    """Why the model at `path` cannot run on the set's agents, in one line ('' if it can): the
    bed starts an agent for each scale of the set, and an agent serves only its model's."""
    try:
        model_scales = load_model(path).scale_names
    except ModelError as e:
        return f"--model: {e}"
    if sorted(model_scales) == sorted(scales):
        return ""
    return (f"--model {path}: its scales are {','.join(model_scales)}, the bed's (--scales) "
            f"{','.join(scales)}: a model for them is anyscale_nav_demo's config/"
            f"{MODEL_FILES[tuple(scales)]}")
