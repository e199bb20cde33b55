"""The path-by-configuration accounting behind the paper's Fig. 5 (anyscale_core.
configuration_path): labels and names, stable colours, continuous segments at configuration
changes, decimation, the memory cap and the per-configuration distance/time totals."""
import math

import pytest

from anyscale_core.configuration_path import (ALL_ON_MASTER, MASTER_COLOUR, PALETTE,
                                              ConfigurationColours, PathAccumulator, PathPoint,
                                              configuration_name, configuration_of,
                                              format_totals, split_segments)

ROBOT_ONLY = {"amcl": "robot", "ar_recognition": "robot", "laser": "robot"}
AMCL_LAPTOP = {"amcl": "laptop", "ar_recognition": "robot", "laser": "robot"}
BOTH_LAPTOP = {"amcl": "laptop", "ar_recognition": "laptop", "laser": "robot"}


def config(mapping):
    return configuration_of(mapping, "robot")


# --- labels and names -------------------------------------------------------------------------

def test_everything_on_the_master_is_the_empty_configuration():
    assert config(ROBOT_ONLY) == ALL_ON_MASTER == ()
    assert configuration_name((), "robot") == "all on robot"


def test_label_is_the_sorted_off_master_nodes_whatever_the_mapping_order():
    a = configuration_of({"ar_recognition": "laptop", "laser": "robot", "amcl": "laptop"},
                         "robot")
    assert a == config(BOTH_LAPTOP) == (("amcl", "laptop"), ("ar_recognition", "laptop"))
    assert configuration_name(a, "robot") == "laptop: amcl, ar_recognition"
    assert configuration_name(config(AMCL_LAPTOP), "robot") == "laptop: amcl"


def test_several_remote_scales_are_different_configurations_and_named_per_scale():
    on_laptop = configuration_of({"amcl": "laptop", "ar": "server"}, "robot")
    on_server = configuration_of({"amcl": "server", "ar": "laptop"}, "robot")
    assert on_laptop != on_server
    assert configuration_name(on_laptop, "robot") == "laptop: amcl; server: ar"
    assert configuration_name(on_server, "robot") == "laptop: ar; server: amcl"


def test_the_master_scale_name_is_a_parameter():
    assert configuration_of({"amcl": "robot"}, "laptop") == (("amcl", "robot"),)
    assert configuration_name((), "base") == "all on base"


# --- colours ----------------------------------------------------------------------------------

def test_all_on_master_always_has_the_master_colour_and_takes_no_palette_slot():
    colours = ConfigurationColours()
    assert colours.colour(config(AMCL_LAPTOP)) == PALETTE[0]
    assert colours.colour(()) == MASTER_COLOUR
    assert colours.colour(config(BOTH_LAPTOP)) == PALETTE[1]
    assert ConfigurationColours().colour(()) == MASTER_COLOUR


def test_colours_follow_first_appearance_and_stay_stable():
    colours = ConfigurationColours()
    first = colours.colour(config(BOTH_LAPTOP))
    second = colours.colour(config(AMCL_LAPTOP))
    assert (first, second) == (PALETTE[0], PALETTE[1])
    for _ in range(3):
        assert colours.colour(config(AMCL_LAPTOP)) == second
        assert colours.colour(config(BOTH_LAPTOP)) == first
    # Two runs seeing the same configurations in the same order get the same colours.
    again = ConfigurationColours()
    assert [again.colour(config(m)) for m in (BOTH_LAPTOP, AMCL_LAPTOP)] == [first, second]


def test_palette_cycles_when_there_are_more_configurations_than_colours():
    colours = ConfigurationColours(palette=[(0, 1, 0, 1), (0, 0, 1, 1)])
    got = [colours.colour(((f"n{i}", "laptop"),)) for i in range(3)]
    assert got == [(0, 1, 0, 1), (0, 0, 1, 1), (0, 1, 0, 1)]
    with pytest.raises(ValueError):
        ConfigurationColours(palette=[])


# --- segments ---------------------------------------------------------------------------------

def drive(path, mappings_by_x, t0=0.0, dt=1.0):
    """Drive along y = 0 in 0.1 m steps; mappings_by_x: [(x, mapping)], each active from x on."""
    t = t0
    for i in range(0, 31):
        x = round(0.1 * i, 6)
        active = [m for start, m in mappings_by_x if x >= start][-1]
        path.add(t, x, 0.0, config(active))
        t += dt
    return t


def test_segments_share_the_boundary_point_at_a_configuration_change():
    path = PathAccumulator(min_step_m=0.05)
    drive(path, [(0.0, ROBOT_ONLY), (1.0, AMCL_LAPTOP), (2.0, BOTH_LAPTOP)])
    segments = path.segments()
    assert [s.config for s in segments] == [(), config(AMCL_LAPTOP), config(BOTH_LAPTOP)]
    for before, after in zip(segments, segments[1:]):
        assert before.points[-1] == after.points[0]     # no gap in the drawn line
    assert segments[0].points[0] == (0.0, 0.0)
    assert segments[0].points[-1] == (1.0, 0.0)         # first point seen under AMCL on laptop
    assert segments[-1].points[-1] == (3.0, 0.0)
    # Every kept point is drawn exactly once apart from the shared boundaries.
    assert sum(len(s.points) for s in segments) == len(path.points) + len(segments) - 1


def test_a_configuration_that_comes_back_starts_a_new_segment():
    path = PathAccumulator()
    drive(path, [(0.0, ROBOT_ONLY), (1.0, AMCL_LAPTOP), (2.0, ROBOT_ONLY)])
    assert [s.config for s in path.segments()] == [(), config(AMCL_LAPTOP), ()]


def test_split_segments_of_nothing_and_of_one_point():
    assert split_segments([]) == []
    (only,) = split_segments([PathPoint(0.0, 1.0, 2.0, ())])
    assert only.points == ((1.0, 2.0),) and only.config == ()


# --- min step and memory cap -----------------------------------------------------------------

def test_samples_closer_than_min_step_are_dropped_unless_the_configuration_changed():
    path = PathAccumulator(min_step_m=0.05)
    assert path.add(0.0, 0.0, 0.0, ())
    assert not path.add(0.25, 0.03, 0.0, ())         # 3 cm: too close
    assert not path.add(0.5, 0.0, 0.049, ())
    assert path.add(0.75, 0.0, 0.05, ())             # exactly min_step: kept
    assert path.add(1.0, 0.0, 0.05, config(AMCL_LAPTOP))   # standing still, but a change
    assert not path.add(1.25, 0.0, 0.05, config(AMCL_LAPTOP))
    assert len(path.points) == 3


def test_zero_min_step_keeps_every_move_and_bad_arguments_raise():
    path = PathAccumulator(min_step_m=0.0)
    for i in range(5):
        path.add(float(i), 0.001 * i, 0.0, ())
    assert len(path.points) == 5
    for bad in (dict(min_step_m=-0.1), dict(min_step_m=math.nan), dict(max_points=1),
                dict(max_points=2.5)):
        with pytest.raises(ValueError):
            PathAccumulator(**bad)


def test_memory_is_capped_by_dropping_the_oldest_points():
    path = PathAccumulator(min_step_m=0.05, max_points=100)
    for i in range(1000):
        path.add(float(i), 0.1 * i, 0.0, () if i < 500 else config(AMCL_LAPTOP))
    points = path.points
    assert len(points) == 100
    assert points[0].x == pytest.approx(90.0) and points[-1].x == pytest.approx(99.9)
    # Only the newest configuration is left on the map, but the totals still cover it all.
    assert [s.config for s in path.segments()] == [config(AMCL_LAPTOP)]
    totals = path.totals()
    assert totals[()].distance_m == pytest.approx(50.0)
    assert totals[config(AMCL_LAPTOP)].distance_m == pytest.approx(49.9)


def test_non_finite_samples_are_ignored():
    path = PathAccumulator()
    path.add(0.0, 0.0, 0.0, ())
    assert not path.add(1.0, math.nan, 0.0, ())
    assert not path.add(math.inf, 1.0, 0.0, ())
    path.add(2.0, 1.0, 0.0, ())
    assert path.totals()[()].distance_m == pytest.approx(1.0)
    assert path.totals()[()].time_s == pytest.approx(2.0)


# --- totals ----------------------------------------------------------------------------------

def test_distance_and_time_go_to_the_configuration_active_during_each_stretch():
    path = PathAccumulator(min_step_m=0.05)
    end = drive(path, [(0.0, ROBOT_ONLY), (1.0, AMCL_LAPTOP), (2.5, BOTH_LAPTOP)], dt=0.5)
    totals = path.totals()
    assert list(totals) == [(), config(AMCL_LAPTOP), config(BOTH_LAPTOP)]   # first-use order
    assert totals[()].distance_m == pytest.approx(1.0)
    assert totals[config(AMCL_LAPTOP)].distance_m == pytest.approx(1.5)
    assert totals[config(BOTH_LAPTOP)].distance_m == pytest.approx(0.5)
    assert totals[()].time_s == pytest.approx(5.0)            # 10 steps of 0.5 s
    assert totals[config(AMCL_LAPTOP)].time_s == pytest.approx(7.5)
    assert totals[config(BOTH_LAPTOP)].time_s == pytest.approx(2.5)
    assert sum(t.time_s for t in totals.values()) == pytest.approx(end - 0.5)
    assert path.distance_m() == pytest.approx(3.0)


def test_standing_still_counts_time_but_no_distance():
    path = PathAccumulator()
    for i in range(10):
        path.add(float(i), 2.0, 3.0, config(AMCL_LAPTOP))
    t = path.totals()[config(AMCL_LAPTOP)]
    assert (t.distance_m, t.time_s) == (0.0, pytest.approx(9.0))
    assert len(path.points) == 1


def test_a_clock_going_back_adds_no_negative_time():
    path = PathAccumulator()
    path.add(10.0, 0.0, 0.0, ())
    path.add(2.0, 1.0, 0.0, ())
    path.add(3.0, 2.0, 0.0, ())
    assert path.totals()[()].time_s == pytest.approx(1.0)


def test_totals_table_lists_every_configuration_with_distance_time_and_share():
    path = PathAccumulator()
    drive(path, [(0.0, ROBOT_ONLY), (1.0, AMCL_LAPTOP)], dt=1.0)
    table = format_totals(path.totals(), "robot")
    lines = table.splitlines()
    assert lines[0].split() == ["configuration", "distance", "time", "share"]
    assert lines[1].startswith("all on robot") and "1.00 m" in lines[1] and "10.0 s" in lines[1]
    assert lines[2].startswith("laptop: amcl") and "2.00 m" in lines[2] and "66.7%" in lines[2]
    assert lines[-1].startswith("total") and "3.00 m" in lines[-1] and "30.0 s" in lines[-1]
    assert format_totals({}, "robot").splitlines()[-1].split()[:2] == ["total", "0.00"]


def test_the_nodes_parameters_have_their_defaults_and_name_a_bad_one():
    from anyscale_core.configuration_path_ros import read_params
    from anyscale_core.param_spec import ParamError
    p = read_params(lambda name, default: default)
    assert (p["global_frame"], p["base_frame"], p["master"], p["rate_hz"]) == \
        ("map", "base_link", "robot", 4.0)
    assert p["max_points"] == 20000
    with pytest.raises(ParamError, match=r"~publish_period_s: expected a number >= 1"):
        read_params(lambda name, default: 0.5 if name == "~publish_period_s" else default)
    assert read_params(lambda name, default: "/odom" if name == "~global_frame"
                       else default)["global_frame"] == "odom"
