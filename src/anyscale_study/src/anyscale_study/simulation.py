"""The paper's Fig. 7 study (section V): generated test-bed-like systems driven round a 115 m loop
with patchy WiFi, timed under each allocator and compared with no migration.

Pure numpy: no ROS, no plotting. Every range and constant below says where it comes from; none is
tuned to reproduce the paper's figures. The package README explains the model.
"""
from dataclasses import dataclass
from typing import Callable, Dict, Iterable, List, Optional, Sequence, Tuple

import numpy as np

from anyscale_core.allocators import AllocationContext, make_allocator
from anyscale_core.characterisation import Characterisation, characterise
from anyscale_core.constraints import DynamicState, is_feasible
from anyscale_core.cost import ObjectiveIntegrator, perf

from .simulated_systems import NOMINAL_MBPS, generate_model

# --- Facts of the paper's test bed (sections IV and V) --------------------------------------
PATH_LENGTH_M = 115.0              # the square path of Test 1-4
V_MIN, V_MAX = 0.2, 0.4            # m/s: all on the robot / AMCL at its optimal rate
COVERAGE_RANGE = (0.45, 0.65)      # share of the path with network (section V)
RATE_STEPS_MBPS = (6, 9, 12, 18, 24, 36, 48, 54)   # 802.11g OFDM rates
# --- Our assumptions (not in the paper) -------------------------------------------------------
TCP_EFFICIENCY = 0.5               # usable TCP goodput / 802.11g PHY rate (MAC, ACKs, contention)
FULL_USABLE_MBPS = NOMINAL_MBPS * TCP_EFFICIENCY   # what "the full network" delivers
STRETCH_COUNTS = (2, 3, 4)         # covered stretches per loop (Fig. 5 shows a few)
MIN_PIECE_M = 5.0                  # shortest covered stretch and shortest gap
RAMP_M = 4.0                       # at each end of a stretch the rate climbs 6 -> 54 over this
DECISION_PERIOD_S = 1.0            # the allocator runs once a second
HYSTERESIS_S = 10.0                # the paper's T: no re-migration within T of a migration back
# Allocators run as a bound rather than as deployed: the exact optimum decides every period with
# no hysteresis, so its path time is the least any allocator can reach on that coverage (with
# T > 0 its myopic swaps get held back and it can lose to the heuristic; see the README).
BOUND_ALLOCATORS = ("optimal",)
FIG7_PAIRS = ((6, 2), (12, 6), (18, 9))            # (N, M) of Fig. 7
FIG7_SCALES = (2, 3, 4, 5)                         # K: test bed, then one more scale each time
FIG7_CONFIGS = tuple((n, m, k) for n, m in FIG7_PAIRS for k in FIG7_SCALES)


# --- Coverage along the loop --------------------------------------------------------------------
@dataclass(frozen=True)
class Coverage:
    """Covered stretches (start, end) in metres along the loop; end may pass the loop's length
    (the stretch wraps round the start point)."""
    length_m: float
    stretches: Tuple[Tuple[float, float], ...]
    everywhere: bool = False       # the best case: the top rate all round the loop

    @property
    def covered_fraction(self) -> float:
        if self.everywhere:
            return 1.0
        return sum(e - s for s, e in self.stretches) / self.length_m

    def usable_mbps(self, position_m: float) -> float:
        """TCP bandwidth at a position: 0 outside coverage; inside, the 802.11g rate step for the
        distance to the nearer edge of the stretch, times TCP_EFFICIENCY."""
        if self.everywhere:
            return FULL_USABLE_MBPS
        for start, end in self.stretches:
            for s in (position_m, position_m + self.length_m):
                if start <= s < end:
                    return rate_at_edge_distance(min(s - start, end - s)) * TCP_EFFICIENCY
        return 0.0

    @staticmethod
    def full(length_m: float = PATH_LENGTH_M) -> "Coverage":
        """The best case: network everywhere at its top rate."""
        return Coverage(length_m, (), everywhere=True)


def rate_at_edge_distance(d_m: float) -> float:
    """802.11g PHY rate d_m metres inside a covered stretch: one rate step per RAMP_M/8 m."""
    step = int(d_m / (RAMP_M / len(RATE_STEPS_MBPS)))
    return float(RATE_STEPS_MBPS[min(step, len(RATE_STEPS_MBPS) - 1)])


def generate_coverage(rng: np.random.Generator, length_m: float = PATH_LENGTH_M) -> Coverage:
    """Availability a ~ U(45 %, 65 %) of the loop as 2-4 stretches; covered and uncovered length
    are each split at random (every piece >= MIN_PIECE_M), stretches and gaps alternate, and the
    pattern starts at a random point of the loop."""
    a = rng.uniform(*COVERAGE_RANGE)
    count = int(rng.choice(STRETCH_COUNTS))
    lengths = _split(a * length_m, count, rng)
    gaps = _split((1 - a) * length_m, count, rng)
    at, stretches = rng.uniform(0, length_m), []
    for cover, gap in zip(lengths, gaps):
        stretches.append((at, at + cover))
        at += cover + gap
    # Re-base so every start lies within one loop.
    stretches = [(s % length_m, s % length_m + (e - s)) for s, e in stretches]
    return Coverage(length_m, tuple(stretches))


def _split(total: float, count: int, rng) -> np.ndarray:
    return MIN_PIECE_M + (total - count * MIN_PIECE_M) * rng.dirichlet(np.ones(count))


def state_at(ch: Characterisation, coverage: Coverage, position_m: float) -> DynamicState:
    """The dynamic state at a position: the bandwidth there, every remote link down outside."""
    mbps = coverage.usable_mbps(position_m)
    up = mbps > 0
    return DynamicState(mbps, link_up={s: up for i, s in enumerate(ch.scale_names)
                                       if i != ch.master})


# --- Mapping -> speed -> path time --------------------------------------------------------------
@dataclass(frozen=True)
class SpeedModel:
    """Robot speed from Eq. 1: V_MIN with every node on the robot, V_MAX with the best mapping the
    full network allows, linear in Perf in between."""
    perf_master: float
    perf_ideal: float

    @staticmethod
    def of(ch: Characterisation) -> "SpeedModel":
        exact = make_allocator("optimal", time_budget_s=None)
        ideal = exact.decide(ch, ch.initial_mapping(), DynamicState(FULL_USABLE_MBPS),
                             AllocationContext()).assign
        return SpeedModel(perf(ch, ch.initial_mapping()), perf(ch, ideal))

    def speed(self, perf_value: float) -> float:
        span = self.perf_ideal - self.perf_master
        if span <= 1e-12:
            return V_MIN
        share = min(1.0, max(0.0, (perf_value - self.perf_master) / span))
        return V_MIN + (V_MAX - V_MIN) * share


def speed_of(ch: Characterisation, speed_model: SpeedModel, assign: np.ndarray,
             state: DynamicState) -> float:
    """A mapping that breaks a constraint (a node cut off, too little bandwidth) gives the robot
    no faster localisation than the all-on-robot mapping: V_MIN."""
    if not is_feasible(ch, assign, state):
        return V_MIN
    return speed_model.speed(perf(ch, assign))


class _Policy:
    """An allocator as the decision loop calls it once per period: step(), which for the paper's
    heuristic is one iteration of Algorithm 1 and for the others a full decision. None never
    moves. Allocators are pure functions of their inputs and states repeat along the loop, so
    decisions are cached. The study judges decisions, not how fast this host makes them: no
    time budget, so a run is the same on any host."""

    def __init__(self, name: Optional[str]):
        self.allocator = make_allocator(name, time_budget_s=None) if name else None
        self._cache = {}

    def __call__(self, ch, assign, state, ctx):
        if self.allocator is None:
            return None
        held = frozenset(i for i in range(ch.num_nodes) if ctx.held_on_master(i))
        key = (assign.tobytes(), state.bandwidth_mbps, tuple(sorted(state.link_up.items())),
               tuple(sorted(state.scale_load.items())), held)
        if key not in self._cache:
            self._cache[key] = self.allocator.step(ch, assign, state, ctx)
        return self._cache[key]


@dataclass(frozen=True)
class RunResult:
    time_s: float             # to complete the loop
    migrations: int           # moves to a remote scale (or between remote scales)
    migrations_back: int      # moves back to the master
    mean_perf: float          # Eq. 2 divided by the run's time


def simulate_run(ch: Characterisation, coverage: Coverage, allocator: Optional[str],
                 speed_model: SpeedModel, period_s: float = DECISION_PERIOD_S,
                 hysteresis_s: float = HYSTERESIS_S) -> RunResult:
    """Drives the loop once: each period the allocator sees the state at the robot's position,
    its mapping sets the speed for that period; a move back to the master starts the hysteresis."""
    policy = _Policy(allocator)
    assign = ch.initial_mapping()
    back_at: Dict[int, float] = {}
    t = position = 0.0
    objective = ObjectiveIntegrator(0.0, perf(ch, assign))
    out = back = 0
    while True:
        state = state_at(ch, coverage, position)
        decision = policy(ch, assign, state, AllocationContext(t, hysteresis_s, dict(back_at)))
        if decision is not None and decision.moves:
            for move in decision.moves:
                if move.target == ch.master:
                    back_at[move.node] = t
                    back += 1
                else:
                    out += 1
            assign = decision.assign
            objective.change(t, perf(ch, assign))
        v = speed_of(ch, speed_model, assign, state)
        if position + v * period_s >= coverage.length_m:
            t += (coverage.length_m - position) / v     # the last, partial period
            return RunResult(t, out, back, objective.mean_perf(t))
        position += v * period_s
        t += period_s


# --- The study ----------------------------------------------------------------------------------
DEFAULT_SEED = 1


def run_config(n_nodes: int, n_migratable: int, n_scales: int, run: int, seed: int,
               allocators: Sequence[str] = ("paper", "optimal"),
               hysteresis_s: float = HYSTERESIS_S) -> Dict:
    """One seeded run of one configuration: a system, a coverage pattern, the loop timed without
    migration and under each allocator, with that coverage and in the best case."""
    rng = np.random.default_rng([seed, n_nodes, n_migratable, n_scales, run])
    ch = characterise(generate_model(n_nodes, n_migratable, n_scales, rng))
    coverage = generate_coverage(rng)
    speed_model = SpeedModel.of(ch)
    baseline = simulate_run(ch, coverage, None, speed_model).time_s
    row = {"config": config_label(n_nodes, n_migratable, n_scales), "n_nodes": n_nodes,
           "n_migratable": n_migratable, "n_scales": n_scales, "run": run, "seed": seed,
           "coverage": coverage.covered_fraction, "stretches": len(coverage.stretches),
           "baseline_s": baseline}
    for name in allocators:
        hold = 0.0 if name in BOUND_ALLOCATORS else hysteresis_s
        normal = simulate_run(ch, coverage, name, speed_model, hysteresis_s=hold)
        best = simulate_run(ch, Coverage.full(coverage.length_m), name, speed_model,
                            hysteresis_s=hold)
        row.update({f"time_{name}_s": normal.time_s,
                    f"improvement_{name}": 1.0 - normal.time_s / baseline,
                    f"migrations_{name}": normal.migrations + normal.migrations_back,
                    f"best_time_{name}_s": best.time_s,
                    f"best_improvement_{name}": 1.0 - best.time_s / baseline})
    return row


def config_label(n_nodes: int, n_migratable: int, n_scales: int) -> str:
    return f"{n_nodes}Nx{n_migratable}Mx{n_scales}K"


def run_study(configs: Iterable[Tuple[int, int, int]] = FIG7_CONFIGS, runs: int = 3,
              seed: int = DEFAULT_SEED, allocators: Sequence[str] = ("paper", "optimal"),
              progress: Optional[Callable[[int, int, str], None]] = None,
              hysteresis_s: float = HYSTERESIS_S) -> List[Dict]:
    """One row per (configuration, run); progress(done, total, label) after each."""
    configs = list(configs)
    total, rows = len(configs) * runs, []
    for n, m, k in configs:
        for run in range(runs):
            rows.append(run_config(n, m, k, run, seed, allocators, hysteresis_s))
            if progress is not None:
                progress(len(rows), total, f"{config_label(n, m, k)} run {run + 1}/{runs}")
    return rows
