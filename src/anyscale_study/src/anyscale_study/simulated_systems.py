"""Systems for the paper's Fig. 7 study: generated test-bed-like pipelines (sensing ->
processing -> navigation) with N nodes, M of them migratable, on K ever more powerful scales.

Pure numpy. Every range says where it comes from (Tables I and II, Fig. 3); none is tuned to
reproduce the paper's figures.
"""
from typing import Dict, List, Tuple

import numpy as np

from anyscale_core.model import SystemModel
from anyscale_core.model_loader import parse_model

NOMINAL_MBPS = 54.0                # 802.11g

# Scales: the robot (Atom) is the master; remote scales grow more powerful one by one.
MASTER_SCALE = ("robot", 2, 1.6, 2048)                          # name, cores, GHz, MB
REMOTE_SCALES = (("laptop", 4, 2.8, 4096), ("workstation", 8, 3.2, 8192),
                 ("server", 16, 3.4, 16384), ("cluster", 32, 3.6, 32768))

# Connection kinds: freq_min range (Hz), freq_opt/freq_min range, Mbit/s range, tolerance (s).
# Table I gives the frequencies and tolerances, Table II the AMCL (scans) and AR (images) traffic.
CONNECTION_KINDS = {
    "scan": ((2, 5), (2, 5), (0.1, 0.5), (1, 2)),       # Laser-AMCL 5/10 Hz, Laser-Nav 2/10
    "image": ((1, 1), (15, 30), (3, 8), (1, 1)),        # Camera-AR 1/30 Hz, 6 Mbit/s
    "ticks": ((5, 10), (2, 4), (0.02, 0.1), (0, 0)),    # Odometer-Odometry 10/40 Hz
    "pose": ((2, 5), (2, 2.5), (0.01, 0.06), (1, 2)),   # AMCL-EKF 2/5, Odometry-EKF 5/10
    "detection": ((1, 1), (15, 30), (0.01, 0.06), (1, 1)),  # AR-Navigation 1/30 Hz
    "features": ((1, 5), (2, 5), (0.2, 2.0), (1, 2)),   # assumed: between two migratable nodes
    "cmd_vel": ((5, 10), (2, 2), (0.01, 0.01), (0, 0)),  # assumed: navigation -> base driver
}
CPU_RANGES = {"migratable": (33, 50), "critical": (1, 20), "sensor": (2, 6)}  # % of the Atom
MEMORY_RANGES = {"migratable": (100, 150), "critical": (20, 80), "sensor": (20, 60)}  # MB
MASTER_TOTAL_CPU = (80, 100)       # % of the Atom all nodes need at their minimum rates
CHAIN_PROBABILITY = 0.25           # a migratable node fed by another one instead of a sensor


# --- The generated system -----------------------------------------------------------------------
def scale_specs(n_scales: int) -> List[Tuple[str, int, float, int]]:
    """The master and n_scales-1 remote scales, each more powerful (cores x GHz) than the last;
    beyond the fourth remote, each adds 16 cores and 0.05 GHz (GHz must grow: Algorithm 1 sorts
    remote scales by CPU frequency)."""
    specs = [MASTER_SCALE] + list(REMOTE_SCALES[:n_scales - 1])
    for j in range(len(REMOTE_SCALES), n_scales - 1):
        extra = j - len(REMOTE_SCALES) + 1
        specs.append((f"remote{j + 1}", 32 + 16 * extra, round(3.6 + 0.05 * extra, 2),
                      32768 * (extra + 1)))
    return specs


def capacity_ratios(n_scales: int) -> np.ndarray:
    """(K,) cores x GHz relative to the master: Eq. 1's alpha for each scale."""
    specs = scale_specs(n_scales)
    return np.array([c * g for _, c, g, _ in specs]) / (specs[0][1] * specs[0][2])


class _Drawer:
    """Random draws from the documented ranges."""

    def __init__(self, rng: np.random.Generator):
        self.rng = rng

    def uniform(self, bounds) -> float:
        return float(self.rng.uniform(bounds[0], bounds[1]))

    def connection(self, kind, pub, sub, topic, critical=False) -> Dict:
        """A connection of this kind; critical ones (Table I's tolerance-0 rows) get tolerance 0."""
        fmin_r, ratio_r, bw_r, tol_r = CONNECTION_KINDS[kind]
        fmin = round(self.uniform(fmin_r), 1)
        tolerance = float(self.rng.integers(tol_r[0], tol_r[1] + 1))
        return {"publisher": pub, "subscriber": sub, "topic": topic, "freq_min": fmin,
                "freq_opt": round(fmin * self.uniform(ratio_r), 1),
                "tolerance": 0.0 if critical else tolerance,
                "bandwidth_mbps": round(self.uniform(bw_r), 3)}


def _sensor_kinds(n_nodes: int, rng) -> List[str]:
    """Input-data nodes (not counted in N, as in the paper): the test bed's laser, odometer and
    camera, plus one more scan or image sensor per 6 nodes beyond 6."""
    extra = max(0, (n_nodes - 6) // 6)
    return ["scan", "ticks", "image"] + [str(rng.choice(["scan", "image"])) for _ in range(extra)]


def _critical_roles(n_critical: int) -> List[str]:
    """Fig. 3's critical chain: navigation, the base driver (actuators), then state estimators
    (like EKF) and pre-processors (like odometry), estimators first."""
    roles = ["navigation", "base"][:n_critical]
    rest = n_critical - len(roles)
    return roles + ["fusion"] * ((rest + 1) // 2) + ["preproc"] * (rest // 2)


def generate_model(n_nodes: int, n_migratable: int, n_scales: int,
                   rng: np.random.Generator) -> SystemModel:
    """A Fig. 3-like sensing -> processing -> navigation pipeline of n_nodes nodes (input-data
    nodes extra), n_migratable of them migratable, on n_scales scales; validated by parse_model."""
    if n_scales < 1 or n_nodes < 1 or not 0 <= n_migratable < n_nodes:
        raise ValueError(f"need K >= 1 and 0 <= M < N (navigation is critical), "
                         f"got N={n_nodes} M={n_migratable} K={n_scales}")
    draw = _Drawer(rng)
    specs = scale_specs(n_scales)
    ratios = capacity_ratios(n_scales)
    scales = [{"name": nm, "master": j == 0, "cores": c, "cpu_ghz": g, "memory_mb": mb,
               "alpha": round(float(ratios[j]), 4)} for j, (nm, c, g, mb) in enumerate(specs)]
    sensors = [(f"{kind}_sensor{j}", kind) for j, kind in enumerate(_sensor_kinds(n_nodes, rng))]
    roles = _critical_roles(n_nodes - n_migratable)
    critical = [(f"{role}{j}" if role in ("fusion", "preproc") else role, role)
                for j, role in enumerate(roles)]
    conns, rate_of = _wire(draw, sensors, critical, n_migratable)
    nodes = [_node_dict(name, "sensor", draw) for name, _ in sensors]
    nodes += [_node_dict(name, "critical", draw) for name, _ in critical]
    nodes += [_node_dict(f"proc{j}", "migratable", draw) for j in range(n_migratable)]
    _normalise_master_load(nodes, draw)
    _fit_memory(nodes, specs[0][3])
    for node in nodes:
        if node["name"] in rate_of:   # migratable: its work grows with the rate it reaches
            _spread_cpu(node, rate_of[node["name"]], specs, ratios)
    model = {"scales": scales, "network": {"technology": "802.11g",
                                           "max_bandwidth_mbps": NOMINAL_MBPS},
             "nodes": nodes, "connections": conns}
    return parse_model(model, f"<generated {n_nodes}N x {n_migratable}M x {n_scales}K>")


def _wire(draw, sensors, critical, n_migratable):
    """Connections of the pipeline, and each migratable node's freq_opt/freq_min (its output's)."""
    conns = []

    def by_kind(kind):
        return [n for n, k in sensors if k == kind] or [sensors[0][0]]

    names = {role: [n for n, r in critical if r == role] for role in ("fusion", "preproc")}
    estimators = names["fusion"] or ["navigation"]
    # The critical chain, with Table I's tolerance-0 rows: Laser-Navigation, EKF-Navigation,
    # Odometer-Odometry, Odometry-EKF (and navigation -> base driver, the actuators).
    conns.append(draw.connection("scan", by_kind("scan")[0], "navigation", "/scan", True))
    if any(r == "base" for _, r in critical):
        conns.append(draw.connection("cmd_vel", "navigation", "base", "/cmd_vel", True))
    for name in names["fusion"]:
        conns.append(draw.connection("pose", name, "navigation", f"/{name}/pose", True))
    for j, name in enumerate(names["preproc"]):
        ticks = by_kind("ticks")
        conns.append(draw.connection("ticks", ticks[j % len(ticks)], name, "/ticks", True))
        conns.append(draw.connection("pose", name, estimators[j % len(estimators)],
                                     f"/{name}/odom", True))
    rate_of = {}
    for j in range(n_migratable):
        name = f"proc{j}"
        recognises = bool(draw.rng.random() < 0.5)    # AR-like; otherwise AMCL-like
        if j > 0 and draw.rng.random() < CHAIN_PROBABILITY:
            upstream = f"proc{int(draw.rng.integers(0, j))}"
            conns.append(draw.connection("features", upstream, name, f"/{upstream}/features"))
        else:
            source = by_kind("image" if recognises else "scan")
            conns.append(draw.connection("image" if recognises else "scan",
                                         source[j % len(source)], name,
                                         "/image" if recognises else "/scan"))
        out = (draw.connection("detection", name, "navigation", f"/{name}/detections")
               if recognises else
               draw.connection("pose", name, estimators[j % len(estimators)], f"/{name}/pose"))
        conns.append(out)
        rate_of[name] = out["freq_opt"] / out["freq_min"]
    return conns, rate_of


def _node_dict(name: str, kind: str, draw: _Drawer) -> Dict:
    return {"name": name, "launch": {"package": "anyscale_sim", "type": name},
            "cpu_usage": {MASTER_SCALE[0]: draw.uniform(CPU_RANGES[kind])},
            "memory_mb": round(draw.uniform(MEMORY_RANGES[kind])),
            **({"pinned": MASTER_SCALE[0]} if kind == "sensor" else {})}


def _normalise_master_load(nodes: List[Dict], draw: _Drawer):
    """The robot sustains every minimum frequency (paper IV), so all nodes at their minimum rates
    fit its CPU: scale the drawn weights to a total of 80-100 %."""
    robot = MASTER_SCALE[0]
    factor = draw.uniform(MASTER_TOTAL_CPU) / sum(n["cpu_usage"][robot] for n in nodes)
    for n in nodes:
        n["cpu_usage"][robot] = round(n["cpu_usage"][robot] * factor, 3)


def _fit_memory(nodes: List[Dict], master_mb: float):
    """Every node starts on the robot: shrink memory proportionally if it would not fit 90 %."""
    total = sum(n["memory_mb"] for n in nodes)
    if total > 0.9 * master_mb:
        for n in nodes:
            n["memory_mb"] = float(np.floor(n["memory_mb"] * 0.9 * master_mb / total))


def _spread_cpu(node: Dict, opt_ratio: float, specs, ratios: np.ndarray):
    """On scale k the node runs at min(freq_opt, freq_min x capacity ratio); its work grows with
    its rate, so its share of k's CPU is cpu_master x (rate / freq_min) / capacity ratio."""
    base = node["cpu_usage"][MASTER_SCALE[0]]
    for j in range(1, len(specs)):
        speedup = min(opt_ratio, ratios[j])
        node["cpu_usage"][specs[j][0]] = round(base * speedup / ratios[j], 3)
