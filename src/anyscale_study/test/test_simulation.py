"""The Fig. 7 simulation: generated systems, coverage, path time, and `anyscale simulate`."""
import argparse
import csv

import numpy as np
import pytest

from anyscale_study import simulation as sim
from anyscale_study import simulation_report as report
from anyscale_core.characterisation import characterise
from anyscale_core.constraints import is_feasible

SMALL = [(6, 2, 2), (6, 2, 3), (12, 6, 2), (12, 6, 3)]   # exact optimum by enumeration: fast
# One decision period at V_MAX over the baseline: how far time-stepping alone can move a result.
STEP_NOISE = sim.DECISION_PERIOD_S / (sim.PATH_LENGTH_M / sim.V_MIN)


def generated_model(n, m, k, seed=0):
    return sim.generate_model(n, m, k, np.random.default_rng(seed))


@pytest.mark.parametrize("n,m,k", SMALL + [(18, 9, 5), (200, 100, 20)])
def test_generated_models_validate_with_m_migratable_nodes(n, m, k):
    model = generated_model(n, m, k)
    ch = characterise(model)
    assert ch.migratable.sum() == m
    # N excludes the input-data nodes (the paper's convention); they are pinned to the robot.
    sensors = [node for node in model.nodes if node.name.endswith(tuple(
        f"_sensor{j}" for j in range(len(model.nodes))))]
    assert len(model.nodes) - len(sensors) == n
    assert all(node.pinned == "robot" for node in sensors)
    computing = [i for i, node in enumerate(model.nodes) if node not in sensors]
    assert ch.critical[computing].sum() == n - m
    assert ch.critical[ch.node_index("navigation")]
    assert len(model.scales) == k and model.master.name == "robot"


def test_remote_scales_grow_more_powerful_and_alpha_is_capacity():
    model = generated_model(6, 2, 20)
    capacity = [s.cores * s.cpu_ghz for s in model.scales]
    assert all(b > a for a, b in zip(capacity, capacity[1:]))
    assert all(b.cpu_ghz > a.cpu_ghz for a, b in zip(model.scales[1:], model.scales[2:]))
    assert [s.alpha for s in model.scales] == pytest.approx([c / capacity[0] for c in capacity],
                                                            abs=1e-4)
    assert (model.scales[1].cores, model.scales[1].cpu_ghz) == (4, 2.8)   # the test-bed laptop


def test_migratable_work_grows_with_the_rate_it_reaches():
    model = generated_model(12, 6, 5, seed=3)
    outputs = {c.publisher: c for c in reversed(model.connections)}
    for node in model.nodes:
        if len(node.cpu_usage) == 1:
            continue
        out = outputs[node.name]
        base = node.cpu_usage["robot"]
        for scale in model.remote_scales:
            rate_gain = min(out.freq_opt / out.freq_min, scale.alpha)
            assert node.cpu_usage[scale.name] * scale.alpha == pytest.approx(base * rate_gain,
                                                                             rel=1e-3, abs=1e-2)


def test_all_nodes_at_minimum_rates_fit_the_robot():
    for seed in range(5):
        total = sum(n.cpu_usage["robot"] for n in generated_model(18, 9, 3, seed).nodes)
        assert 80 - 0.01 <= total <= 100 + 0.01


def test_coverage_within_45_to_65_percent_in_a_few_stretches():
    for seed in range(100):
        cov = sim.generate_coverage(np.random.default_rng(seed))
        assert 0.45 <= cov.covered_fraction <= 0.65
        assert len(cov.stretches) in sim.STRETCH_COUNTS
        probe = np.linspace(0, cov.length_m, 2301, endpoint=False)
        covered = np.array([cov.usable_mbps(s) > 0 for s in probe])
        assert covered.mean() == pytest.approx(cov.covered_fraction, abs=0.01)
        assert max(cov.usable_mbps(s) for s in probe) <= sim.FULL_USABLE_MBPS


def test_bandwidth_steps_up_from_the_edge_of_a_stretch():
    cov = sim.Coverage(115.0, ((10.0, 40.0),))
    assert cov.usable_mbps(9.9) == 0 and cov.usable_mbps(40.0) == 0
    assert cov.usable_mbps(10.0) == 6 * sim.TCP_EFFICIENCY
    assert cov.usable_mbps(25.0) == 54 * sim.TCP_EFFICIENCY
    inside = [cov.usable_mbps(10.0 + d) for d in np.arange(0, sim.RAMP_M + 0.5, 0.25)]
    assert inside == sorted(inside)
    wrapped = sim.Coverage(115.0, ((110.0, 125.0),))
    assert wrapped.usable_mbps(5.0) > 0 and wrapped.usable_mbps(12.0) == 0


def test_links_are_down_outside_coverage():
    ch = characterise(generated_model(6, 2, 3))
    cov = sim.Coverage(115.0, ((10.0, 40.0),))
    out = sim.state_at(ch, cov, 50.0)
    assert out.bandwidth_mbps == 0 and not any(out.link_up.values())
    assert all(sim.state_at(ch, cov, 20.0).link_up.values())


def test_speed_is_v_min_on_the_robot_and_v_max_at_the_ideal_mapping():
    ch = characterise(generated_model(12, 6, 3))
    model = sim.SpeedModel.of(ch)
    assert model.speed(model.perf_master) == sim.V_MIN
    assert model.speed(model.perf_ideal) == pytest.approx(sim.V_MAX)
    assert sim.V_MIN < model.speed((model.perf_master + model.perf_ideal) / 2) < sim.V_MAX


def test_baseline_time_is_the_loop_at_v_min():
    ch = characterise(generated_model(6, 2, 2))
    cov = sim.generate_coverage(np.random.default_rng(0))
    run = sim.simulate_run(ch, cov, None, sim.SpeedModel.of(ch))
    assert run.time_s == pytest.approx(115.0 / 0.2, abs=1e-6)
    assert run.migrations == run.migrations_back == 0


def test_seeded_runs_reproduce():
    assert sim.run_config(6, 2, 2, 0, seed=5) == sim.run_config(6, 2, 2, 0, seed=5)
    assert sim.run_config(6, 2, 2, 0, seed=5) != sim.run_config(6, 2, 2, 0, seed=6)
    assert sim.run_study([(6, 2, 2)], runs=1, seed=5) == [sim.run_config(6, 2, 2, 0, 5)]


@pytest.mark.parametrize("n,m,k", SMALL)
def test_optimum_beats_heuristic_and_best_case_beats_normal(n, m, k):
    for run in range(2):
        row = sim.run_config(n, m, k, run, seed=11)
        assert row["improvement_optimal"] >= row["improvement_paper"] - 2 * STEP_NOISE
        for name in ("paper", "optimal"):
            assert row[f"best_improvement_{name}"] >= row[f"improvement_{name}"]
            assert 0 < row[f"improvement_{name}"] < 0.5
        # Full network from the start: the optimum drives at V_MAX all the way.
        assert row["best_improvement_optimal"] == pytest.approx(1 - sim.V_MIN / sim.V_MAX)


def test_link_drops_force_migrations_back_and_mappings_stay_feasible():
    ch = characterise(generated_model(12, 6, 3, seed=2))
    cov = sim.generate_coverage(np.random.default_rng(2))
    run = sim.simulate_run(ch, cov, "paper", sim.SpeedModel.of(ch))
    assert run.migrations_back >= len(cov.stretches) - 1 and run.migrations > 0
    policy = sim._Policy("paper")
    assign, ctx = ch.initial_mapping(), sim.AllocationContext()
    for position in np.arange(0, 115, 0.5):
        state = sim.state_at(ch, cov, position)
        assign = policy(ch, assign, state, ctx).assign
        assert is_feasible(ch, assign, state)


def simulate_args(tmp_path, *extra):
    parser = argparse.ArgumentParser()
    report.add_arguments(parser)
    return parser.parse_args(["--out", str(tmp_path / "out"), "--no-progress", *extra])


def test_simulate_command_writes_csv_and_chart(tmp_path, capsys):
    args = simulate_args(tmp_path, "--configs", "6x2x2,6Nx2Mx3K", "--runs", "1")
    assert report.main(args) == 0
    out = capsys.readouterr().out
    assert "6Nx2Mx2K" in out and "39 % mean" in out and "wrote" in out
    with open(tmp_path / "out" / "fig7.csv") as f:
        rows = list(csv.DictReader(f))
    assert [r["config"] for r in rows] == ["6Nx2Mx2K", "6Nx2Mx3K"]
    assert (tmp_path / "out" / "fig7.png").stat().st_size > 1000


@pytest.mark.parametrize("extra,message", [
    (["--runs", "0"], "--runs"), (["--configs", "6x6x2"], "--configs"),
    (["--configs", "six"], "--configs"), (["--allocators", "paper,nope"], "nope"),
    (["--seed", "x"], "--seed"), (["--hysteresis", "-2"], "--hysteresis")])
def test_bad_arguments_give_one_line_and_exit_2(tmp_path, capsys, extra, message):
    assert report.main(simulate_args(tmp_path, *extra)) == 2
    err = capsys.readouterr().err.strip()
    assert message in err and "\n" not in err and err.startswith("anyscale simulate: error")


def test_paper_local_is_feasible_and_never_below_the_paper_heuristic():
    from anyscale_core.allocators import AllocationContext, make_allocator
    from anyscale_core.constraints import DynamicState
    from anyscale_core.cost import perf
    for seed in range(12):
        rng = np.random.default_rng(seed)
        ch = characterise(sim.generate_model(12, 6, 4, rng))
        remote = ch.scale_names[1:]
        state = DynamicState(float(rng.choice([3.0, 6.0, 13.5, 27.0])),
                             {s: float(rng.uniform(0, 90)) for s in remote},
                             {s: bool(rng.random() < 0.8) for s in remote})
        start, ctx = ch.initial_mapping(), AllocationContext()
        paper = make_allocator("paper").decide(ch, start, state, ctx).assign
        local = make_allocator("paper_local").decide(ch, start, state, ctx).assign
        assert is_feasible(ch, local, state)
        assert (local[ch.critical] == ch.master).all()
        assert perf(ch, local) >= perf(ch, paper) - 1e-9
