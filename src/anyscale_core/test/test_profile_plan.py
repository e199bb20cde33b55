"""`anyscale profile`'s pure part (no roscore): the windows on the test bed's model, the time
prediction, the figures from agent samples (unit: % of the scale's capacity), memory, and the
edits that write them into testbed.yaml without touching anything else."""
import datetime

import pytest
import yaml

from anyscale_core.model import ModelError
from anyscale_core.model_loader import parse_model
from anyscale_core.model_update import update_model_text
from anyscale_core.profile_plan import (MIN_SAMPLES, SATURATED_PERCENT, START_ESTIMATE_S,
                                        STOP_ESTIMATE_S, CpuSample, describe_measurement,
                                        format_duration, measurements_json, memory_figures,
                                        plan_profile, predict_seconds, profile_edits, summarise)


def test_testbed_plan_measures_everything_home_then_moves_only_migratable(testbed):
    plan = plan_profile(testbed)
    home = plan.windows[0]
    assert home.moved is None
    assert dict(home.measures) == {n: ("robot") for n in testbed.node_names}
    moved = [(w.moved, w.scale) for w in plan.windows[1:]]
    assert moved == [("amcl", "laptop"), ("ar_recognition", "laptop")]
    # Critical nodes have a laptop figure in the file, but may never run there.
    assert {(n, s) for n, s, _ in plan.skipped} == {("odometry", "laptop"), ("ekf", "laptop"),
                                                    ("navigation", "laptop")}
    assert all("critical" in why for _, _, why in plan.skipped)
    assert plan.scales_needed == ("robot", "laptop")


def test_plan_for_chosen_nodes_and_unknown_node(testbed):
    plan = plan_profile(testbed, ["amcl"])
    assert [w.measures for w in plan.windows] == [(("amcl", "robot"),), (("amcl", "laptop"),)]
    with pytest.raises(ModelError, match="--nodes: not in .*: nope"):
        plan_profile(testbed, ["amcl", "nope"])


def test_prediction_counts_starts_windows_and_moves(testbed):
    plan = plan_profile(testbed)
    seconds = predict_seconds(plan, warmup_s=10, window_s=30, nodes_to_start=11)
    expected = (11 * START_ESTIMATE_S + 3 * 40 + 2 * 2 * (START_ESTIMATE_S + STOP_ESTIMATE_S)
                + 11 * STOP_ESTIMATE_S)
    assert seconds == pytest.approx(expected)
    assert format_duration(seconds) == f"{int(round(expected)) // 60} min " \
                                       f"{int(round(expected)) % 60} s"
    assert format_duration(42) == "42 s" and format_duration(3700) == "1 h 1 min"


def samples(node, scale, cpus, capacity, quota=True, t0=100.0, rss=100 * 2 ** 20, busy=None):
    return [CpuSample(t0 + 0.5 * i, scale, node, c, rss + i, capacity, quota,
                      busy[i] if busy else float("nan"))
            for i, c in enumerate(cpus)]


def test_cpu_is_mean_over_capacity_within_the_window():
    # 9.5 % of one core on a robot held at 0.34 cores is 27.9 % of the robot.
    inside = samples("amcl", "robot", [9.0, 10.0, 9.5, 9.5], 0.34)
    outside = samples("amcl", "robot", [90.0] * 4, 0.34, t0=200.0)
    other = samples("amcl", "laptop", [50.0] * 4, 0.9)
    m = summarise(inside + outside + other, "amcl", "robot", 100.0, 102.0,
                  {"/amcl_pose": 2.0})
    assert m.samples == 4 and m.quota
    assert m.cpu_one_core == pytest.approx(9.5)
    assert m.cpu_usage == pytest.approx(27.9)
    assert m.output_rates == {"/amcl_pose": 2.0}
    # Without a quota the capacity is the scale's cores: 30 % of one core on 2 cores = 15 %.
    m2 = summarise(samples("x", "robot", [30.0] * 4, 2.0, quota=False), "x", "robot", 0, 1e9)
    assert m2.cpu_usage == 15.0 and not m2.quota


def test_a_figure_on_a_scale_at_its_limit_is_named_a_share_with_its_cost_per_message():
    # The robot of 2026-11-27 (0.236 cores, throttled in every period): AMCL 6.1 % of a core at
    # 2.43 Hz is 25.1 ms of CPU per pose, the figure that does not move with the split.
    busy_robot = summarise(samples("amcl", "robot", [6.0, 6.2, 6.1], 0.236, busy=[97, 99, 95]),
                           "amcl", "robot", 0, 1e9, {"/amcl_pose": 2.43, "/silent": 0.0})
    assert busy_robot.scale_busy == pytest.approx(97.0) and busy_robot.saturated
    assert busy_robot.cpu_ms_per_message == {"/amcl_pose": pytest.approx(25.1, abs=0.05)}
    line = describe_measurement(busy_robot)
    assert "/amcl_pose 2.4 Hz, 25.1 ms of CPU per message" in line
    assert "the scale 97 % busy, at its limit: the figure is the share the node got" in line
    row = measurements_json([busy_robot])[0]
    assert row["cpu_ms_per_message"] == {"/amcl_pose": 25.1} and row["saturated"]
    assert row["scale_busy_percent"] == 97.0
    # A laptop with room: its figure is the node's demand, not named a share.
    idle = summarise(samples("amcl", "laptop", [9.2] * 3, 0.9, busy=[40, 45, 50]), "amcl",
                     "laptop", 0, 1e9, {"/amcl_pose": 4.73})
    assert not idle.saturated and "45 % busy" in describe_measurement(idle)
    assert "share" not in describe_measurement(idle)
    # An agent that does not say how busy its scale is: nothing claimed either way.
    unknown = summarise(samples("x", "robot", [1.0] * 3, 1), "x", "robot", 0, 1e9)
    assert not unknown.saturated and "busy" not in describe_measurement(unknown)
    assert measurements_json([unknown])[0]["scale_busy_percent"] is None
    assert SATURATED_PERCENT == 90.0


def test_too_few_samples_is_an_error_naming_node_and_scale():
    with pytest.raises(ModelError, match="amcl on laptop: 2 CPU samples"):
        summarise(samples("amcl", "laptop", [1.0, 2.0], 0.9), "amcl", "laptop", 0, 1e9)
    assert MIN_SAMPLES == 3


def test_memory_is_the_largest_rss_on_any_scale_rounded_up():
    a = summarise(samples("amcl", "robot", [1] * 3, 1, rss=100 * 2 ** 20), "amcl", "robot", 0,
                  1e9)
    b = summarise(samples("amcl", "laptop", [1] * 3, 1, rss=int(120.2 * 2 ** 20)), "amcl",
                  "laptop", 0, 1e9)
    assert memory_figures([a, b]) == {"amcl": 121.0}


def test_edits_write_figures_into_testbed_yaml_and_keep_the_rest(testbed_path):
    with open(testbed_path) as f:
        text = f.read()
    tree = yaml.safe_load(text)
    ms = [summarise(samples("amcl", "robot", [9.5] * 4, 0.34), "amcl", "robot", 0, 1e9,
                    {"/amcl_pose": 2.0}),
          summarise(samples("amcl", "laptop", [14.6] * 4, 0.9), "amcl", "laptop", 0, 1e9,
                    {"/amcl_pose": 5.0})]
    when = datetime.datetime(2026, 11, 24, 10, 30)
    numbers, comments = profile_edits(tree, ms, when, 10, 30)
    out = update_model_text(text, numbers, comments, testbed_path)
    model = parse_model(yaml.safe_load(out), "out")
    assert dict(model.node("amcl").cpu_usage) == {"robot": 27.9, "laptop": 16.2}
    assert model.node("amcl").memory_mb == 101
    # Everything else is as it was, comments included.
    assert dict(model.node("ar_recognition").cpu_usage) == {"robot": 33, "laptop": 12}
    for line in text.splitlines():
        if "cpu_usage: {robot: 50, laptop: 36}" in line or line.strip() == "memory_mb: 120":
            continue
        assert line in out
    assert "  # profile: 2026-11-24 10:30 by `anyscale profile`" in out
    assert "robot 27.9 % (9.5 % of one core" in out and "/amcl_pose 5.0 Hz" in out
    block_end = out.index("  - name: amcl")
    assert out[:block_end].rstrip().splitlines()[-1].startswith("  # profile: ")
    # A second run replaces the block instead of adding one.
    again = update_model_text(out, numbers, comments, testbed_path)
    assert again == out
    assert all(len(line) <= 100 for line in out.splitlines() if "# profile:" in line)
