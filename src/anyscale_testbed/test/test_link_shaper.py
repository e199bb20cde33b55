"""The WiFi link shaper's decisions without ROS or root: settings from bandwidths, tc/ip commands
per change, when to reapply, OccupancyGrid values to a coverage model (row order), the coverage
grid, the schedule and node parameters, and the chosen access point's coverage of the office
loop (45-65 % as in the paper)."""
import os

import numpy as np
import pytest
import yaml

from anyscale_testbed.link_shaper import (CoverageGrid, LinkSetting, SettingTracker, apply_setting,
                                          coverage_grid, coverage_model_from_grid,
                                          coverage_model_from_map_file, coverage_shares,
                                          leg_clear_on, link_setting_for, loop_corners,
                                          parse_schedule, path_points, read_shaper_params,
                                          setting_commands)
from anyscale_testbed.two_scale_testbed import ScaleEnd, TwoScaleError, TwoScaleLayout
from anyscale_testbed.wifi_link_model import RadioParams
from anyscale_nav_demo.occupancy_map import load_map

NAV_DEMO = os.path.normpath(os.path.join(os.path.dirname(__file__), "..", "..",
                                         "anyscale_nav_demo"))
LAYOUT = TwoScaleLayout(robot=ScaleEnd("robot", "r_ns", "r_if", "10.0.0.1", 0.0),
                        laptop=ScaleEnd("laptop", "l_ns", "l_if", "10.0.0.2", 0.0))


def verbs(cmds):
    """Each command as (namespace or interface, what it does): 'tbf 27000kbit', 'up', 'down'."""
    out = []
    for argv in cmds:
        if "tbf" in argv:
            out.append((argv[3], "tbf " + argv[argv.index("rate") + 1]))
        else:
            out.append((argv[2], argv[-1]))
    return out


# --- settings and when they are applied -------------------------------------------------------

@pytest.mark.parametrize("mbps,setting", [(27.0, LinkSetting(True, 27.0)),
                                          (4.5, LinkSetting(True, 4.5)),
                                          (2.00049, LinkSetting(True, 2.0)),
                                          (0.0, LinkSetting(False)), (-1.0, LinkSetting(False)),
                                          (float("nan"), LinkSetting(False))])
def test_bandwidth_to_setting(mbps, setting):
    assert link_setting_for(mbps) == setting


def test_commands_per_change():
    up27, up6, down = LinkSetting(True, 27.0), LinkSetting(True, 6.0), LinkSetting(False)
    # Unknown state: shape, then bring up (no packet at an old rate).
    assert verbs(setting_commands(LAYOUT, None, up27)) == [
        ("r_ns", "tbf 27000kbit"), ("l_ns", "tbf 27000kbit"), ("r_ns", "up"), ("l_ns", "up")]
    assert verbs(setting_commands(LAYOUT, up27, up6)) == [("r_ns", "tbf 6000kbit"),
                                                          ("l_ns", "tbf 6000kbit")]
    assert verbs(setting_commands(LAYOUT, up6, down)) == [("r_ns", "down"), ("l_ns", "down")]
    assert verbs(setting_commands(LAYOUT, down, up6)) == [
        ("r_ns", "tbf 6000kbit"), ("l_ns", "tbf 6000kbit"), ("r_ns", "up"), ("l_ns", "up")]
    assert setting_commands(LAYOUT, up6, up6) == []
    down_argv = setting_commands(LAYOUT, up6, down)[0]
    assert down_argv == ["ip", "-n", "r_ns", "link", "set", "r_if", "down"]


def test_tracker_applies_only_changes_and_down_at_once():
    tracker = SettingTracker()
    applied = []
    for t, mbps in enumerate([27, 27, 27, 24 / 2, 12, 0, 0, 4.5, 4.5]):
        wanted = link_setting_for(mbps)
        if tracker.due(wanted, float(t)):
            applied.append((t, wanted.describe()))
            tracker.succeeded(wanted)
    # Down is applied on the very tick coverage is lost (t=5), nothing is repeated.
    assert applied == [(0, "27.0 Mbit/s"), (3, "12.0 Mbit/s"), (5, "link down"),
                       (7, "4.5 Mbit/s")]


def test_tracker_retries_a_failed_setting_not_on_every_tick():
    tracker = SettingTracker(retry_s=5.0)
    up = LinkSetting(True, 27.0)
    assert tracker.due(up, 0.0)
    tracker.failed(up, 0.0)
    assert not tracker.due(up, 1.0) and not tracker.due(up, 4.9)
    assert tracker.due(up, 5.0)
    # A different setting (coverage lost meanwhile) is not held back by the failure.
    assert tracker.due(LinkSetting(False), 1.0)
    tracker.succeeded(up)
    assert tracker.applied == up and not tracker.due(up, 6.0)


def test_apply_runs_the_commands_and_stops_at_the_first_failure():
    ran = []
    cmds = apply_setting(LAYOUT, None, LinkSetting(True, 9.0), 64, ran.append)
    assert ran == cmds and len(cmds) == 4 and "64kbit" in cmds[0]

    def failing(argv):
        ran.append(argv)
        raise TwoScaleError("`tc ...` failed (2): Cannot find device")
    ran.clear()
    with pytest.raises(TwoScaleError, match="Cannot find device"):
        apply_setting(LAYOUT, None, LinkSetting(True, 9.0), 32, failing)
    assert len(ran) == 1


# --- the grid and the coverage model ----------------------------------------------------------

def grid_with_wall(width=40, height=20, wall_row=10):
    """OccupancyGrid-ordered data (row 0 at origin y): free, unknown in a corner, and a wall
    across the whole map at row `wall_row` (y = 5.0..5.5 m with 0.5 m cells)."""
    cells = np.zeros((height, width), dtype=int)
    cells[wall_row, :] = 100
    cells[0:2, 0:2] = -1
    return cells.ravel().tolist()


def test_grid_rows_start_at_origin_y():
    data = grid_with_wall()
    strong_wall = RadioParams(wall_loss_db=40.0)     # so that one wall always shows
    model = coverage_model_from_grid(40, 20, 0.5, -1.0, 2.0, data, (4.0, 4.0), strong_wall)
    # Row 10 is at y = 2.0 + 10 * 0.5 = 7.0..7.5 m: above the AP (y 4), below the point (y 9).
    assert model.occupied[10].all() and not model.occupied[9].any()
    assert not model.occupied[0, 0]                 # unknown is open space for the radio
    same_side = model.bandwidth_at(4.0, 6.5)        # 2.5 m, no wall
    behind_wall = model.bandwidth_at(4.0, 9.0)      # 5 m, across the wall
    beside = model.bandwidth_at(9.0, 4.0)           # 5 m, no wall
    assert same_side == 27.0 and beside > behind_wall
    # Flipped rows (image order) would put the wall at y = 2 + 9 * 0.5 = 6.5..7 and both
    # points would see it: the unflipped reading must not.
    assert model.bandwidth_at(4.0, 6.9) == 27.0


def test_grid_size_mismatch_is_an_error():
    with pytest.raises(ValueError, match="799 cells, expected 40 x 20 = 800"):
        coverage_model_from_grid(40, 20, 0.5, 0, 0, [0] * 799, (1, 1))
    with pytest.raises(ValueError, match="resolution"):
        coverage_model_from_grid(40, 20, 0.0, 0, 0, [0] * 800, (1, 1))


def test_coverage_grid_shape_and_values():
    model = coverage_model_from_grid(40, 20, 0.25, 1.0, -2.0, grid_with_wall(), (3.0, 0.0))
    grid = coverage_grid(model, 0.5)                 # 10 m x 5 m map
    assert grid.mbps.shape == (10, 20)
    assert grid.origin_xy == (1.0, -2.0) and grid.resolution == 0.5
    assert grid.mbps[4, 4] == 27.0                   # the AP's own cell: (3.25, 0.25)
    values = grid.occupancy_values()
    assert len(values) == 200 and values[4 * 20 + 4] == 100
    assert all(0 <= v <= 100 for v in values)
    # float32 resolutions from the message do not add a sliver of a cell.
    model = coverage_model_from_grid(100, 100, float(np.float32(0.1)), 0, 0, [0] * 10000, (1, 1))
    assert coverage_grid(model, 0.5).mbps.shape == (20, 20)
    assert CoverageGrid(np.array([[0.0, 13.5], [3.0, 40.0]]), 0.5,
                        (0, 0)).occupancy_values() == [0, 50, 11, 100]


# --- parameters -------------------------------------------------------------------------------

def test_schedule_parsing():
    s = parse_schedule([[0, 27], [10.5, 0], [20, 6.0]])
    assert [s.bandwidth_at(t) for t in (0, 10, 11, 25)] == [27, 27, 0, 6]


@pytest.mark.parametrize("value,message", [
    (None, r"~schedule must be a non-empty list"),
    ([], r"~schedule must be a non-empty list"),
    ("0 27", r"~schedule must be a non-empty list"),
    ([[0, 27], [5]], r"~schedule\[1\] must be a pair of numbers \[t_s, mbps\], got \[5\]"),
    ([[0, 27], [5, "fast"]], r"~schedule\[1\] must be a pair.*'fast'"),
    ([[0, True]], r"~schedule\[0\] must be a pair"),
    ([[0, float("inf")]], r"~schedule\[0\] must be a pair"),
    ([[0, 27], [1, -3]], r"~schedule\[1\]: bandwidth must be >= 0 Mbit/s, got \[1, -3\]"),
    ([[5, 27], [1, 3]], r"~schedule\[1\]: times must not decrease, got \[1, 3\] after \[5, 27\]"),
])
def test_schedule_errors_name_the_parameter_and_element(value, message):
    with pytest.raises(ValueError, match=message):
        parse_schedule(value)


def getter(**params):
    return lambda name, default: params.get(name.lstrip("~"), default)


def test_node_params_defaults_and_layout():
    p = read_shaper_params(getter(access_point_x=24, access_point_y=34.5))
    assert p.mode == "coverage" and p.access_point_xy == (24.0, 34.5)
    assert p.rate_hz == 5.0 and p.burst_kbit == 32 and p.dry_run is False and p.seed == 0
    assert read_shaper_params(getter(access_point_x=1, access_point_y=1, seed=3)).seed == 3
    assert p.map_file == ""
    assert read_shaper_params(getter(access_point_x=1, access_point_y=1,
                                     map_file="/m.yaml")).map_file == "/m.yaml"
    assert (p.layout.robot.namespace, p.layout.robot.interface) == ("anyscale_robot",
                                                                    "asv_robot")
    assert (p.layout.laptop.namespace, p.layout.laptop.interface) == ("anyscale_laptop",
                                                                      "asv_laptop")
    p = read_shaper_params(getter(mode="schedule", schedule=[[0, 3]], robot_namespace="a",
                                  laptop_interface="b", dry_run=True, rate_hz=2))
    assert p.schedule.bandwidth_at(1) == 3 and p.layout.robot.namespace == "a"
    assert p.layout.laptop.interface == "b" and p.dry_run and p.access_point_xy is None


@pytest.mark.parametrize("params,message", [
    (dict(mode="wifi"), r"~mode: expected one of coverage, schedule, got 'wifi'"),
    (dict(access_point_y=1), r"~access_point_x: required, not set"),
    (dict(access_point_x=1, access_point_y="x"), r"~access_point_y: expected a number"),
    (dict(mode="schedule"), r"~schedule must be a non-empty list"),
    (dict(access_point_x=1, access_point_y=1, burst_kbit=0), r"~burst_kbit: expected an int"),
    (dict(access_point_x=1, access_point_y=1, rate_hz=0), r"~rate_hz: expected a number > 0"),
    (dict(access_point_x=1, access_point_y=1, burst_kbit=2.5), r"~burst_kbit: expected an int"),
    (dict(access_point_x=1, access_point_y=1, dry_run="yes"), r"~dry_run: expected true or"),
    (dict(access_point_x=1, access_point_y=1, robot_namespace="a b"), r"~robot_namespace"),
    (dict(access_point_x=1, access_point_y=1, seed=-1), r"~seed: expected an integer >= 0"),
    (dict(access_point_x=1, access_point_y=1, seed=1.5), r"~seed: expected an integer >= 0"),
    (dict(mode="schedule", schedule=[[0, 3]], seed=2), r"~seed: varies the coverage model"),
    (dict(access_point_x=1, access_point_y=1, map_file=3), r"~map_file: expected the path"),
    (dict(mode="schedule", schedule=[[0, 3]], map_file="/m.yaml"), r"~map_file: the coverage"),
])
def test_bad_node_params_name_the_parameter(params, message):
    with pytest.raises(ValueError, match=message):
        read_shaper_params(getter(**params))


# --- paths, and the chosen access point on the office floor -----------------------------------

def test_path_points_every_step_without_repeats():
    pts = path_points(loop_corners((0, 0), [(1, 0), (1, 0.5)]))
    assert len(pts) == 10 + 5 + 12                   # 1 m, 0.5 m, and 1.118 m back (ceil)
    assert np.allclose(pts[0], (0, 0)) and np.allclose(pts[10], (1, 0))
    assert len({tuple(np.round(p, 6)) for p in pts}) == len(pts)


def test_legs_through_walls_go_round_the_corner():
    model = coverage_model_from_grid(40, 20, 0.5, 0.0, 0.0, grid_with_wall(), (0, 0))
    clear = leg_clear_on(model)
    # A clear diagonal stays straight; one through a wall with no way round stays straight too.
    assert loop_corners((1, 1), [(3, 4)], clear) == [(1, 1), (3, 4), (1, 1)]
    assert loop_corners((1, 1), [(3, 9)], clear) == [(1, 1), (3, 9), (1, 1)]
    # An L-shaped corridor: south strip (y < 2) and east strip (x > 16) free, the rest solid.
    cells = np.zeros((20, 40), dtype=int)
    cells[4:20, 0:32] = 100
    model = coverage_model_from_grid(40, 20, 0.5, 0.0, 0.0, cells.ravel().tolist(), (0, 0))
    corners = loop_corners((1, 1), [(18, 8)], leg_clear_on(model))
    assert corners == [(1, 1), (18, 1), (18, 8), (18, 1), (1, 1)]


def office_shares(world_name="office_floor"):
    """Coverage shares of a world's loop with the access point of its shipped config."""
    with open(os.path.join(NAV_DEMO, "config", f"wifi_{world_name}.yaml")) as f:
        wifi = yaml.safe_load(f)
    with open(os.path.join(NAV_DEMO, "maps", f"{world_name}_world.yaml")) as f:
        world = yaml.safe_load(f)
    occ = load_map(os.path.join(NAV_DEMO, "maps", world["map"]))
    model = coverage_model_from_grid(occ.width, occ.height, occ.resolution, occ.origin[0],
                                     occ.origin[1], occ.data.ravel().tolist(),
                                     (wifi["access_point_x"], wifi["access_point_y"]))
    start, goals = world["start"][:2], [g[:2] for g in world["goals"]]
    straight = path_points(loop_corners(start, goals), 0.1)
    corridors = path_points(loop_corners(start, goals, leg_clear_on(model)), 0.1)
    thresholds = (3.0, 12.0, 27.0)
    return (wifi, coverage_shares(model.bandwidth_at, straight, thresholds),
            coverage_shares(model.bandwidth_at, corridors, thresholds), len(corridors))


def test_office_access_point_covers_45_to_65_percent_of_the_loop():
    wifi, straight, corridors, n_corridor = office_shares()
    assert wifi["mode"] == "coverage"
    assert n_corridor * 0.1 == pytest.approx(115.2, abs=0.2)   # the corridor loop, not diagonals
    for shares in (straight, corridors):
        assert 0.45 <= shares["covered"] <= 0.65, shares
        # Good near the AP, lower steps further away, none in part: all three occur.
        assert 0.1 < shares[">=27"] < shares[">=12"] < shares["covered"] < 1.0, shares
    # The figures quoted in the config's comment.
    assert corridors["covered"] == pytest.approx(0.525, abs=0.0005)
    assert straight["covered"] == pytest.approx(0.594, abs=0.0005)


def test_small_loop_access_point_covers_about_half_the_loop_enough_for_amcl_only():
    wifi, _, corridors, _ = office_shares("small_loop")
    assert wifi["mode"] == "coverage"
    assert corridors["covered"] == pytest.approx(0.471, abs=0.0005)   # quoted in the config
    assert corridors[">=3"] == corridors["covered"] and corridors[">=12"] == 0.0


def test_the_coverage_model_from_the_map_file_is_the_one_from_the_map_topic(tmp_path):
    path = os.path.join(NAV_DEMO, "maps", "office_floor.yaml")
    occ = load_map(path)
    from_file = coverage_model_from_map_file(path, (24.0, 34.5))
    from_topic = coverage_model_from_grid(occ.width, occ.height, occ.resolution, occ.origin[0],
                                          occ.origin[1], occ.data.ravel().tolist(), (24.0, 34.5))
    for x, y in ((7.4, 5.9), (24.0, 33.0), (30.0, 20.0)):
        assert from_file.bandwidth_at(x, y) == from_topic.bandwidth_at(x, y)
    with pytest.raises(ValueError, match="nowhere.yaml"):
        coverage_model_from_map_file(str(tmp_path / "nowhere.yaml"), (0.0, 0.0))
    rotated = tmp_path / "rotated.yaml"
    rotated.write_text(open(path).read().replace("image: ", "image: " + os.path.dirname(path)
                                                 + "/").replace("origin: [0.0, 0.0, 0.0]",
                                                                "origin: [0.0, 0.0, 0.5]"))
    with pytest.raises(ValueError, match="rotated"):
        coverage_model_from_map_file(str(rotated), (0.0, 0.0))
