"""The forecast along the planned path (link_forecast.py): the robot's place on the path and its
speed, the stretches ahead cell by cell, what they carry, a map that disagrees with the live
link, a path that changes, a pose that jumps, a robot off its path or standing."""
import math

import pytest

from anyscale_core.link_forecast import LinkForecast, PathTracker, PoseTrack, forecast_links
from anyscale_core.link_map import LinkMap, LinkMapParams

T0 = 1_800_000_000.0
STRAIGHT = [(float(x), 0.5) for x in range(0, 41)]     # along y = 0.5, x 0..40 m


def corridor(hole=(10, 14), unknown=(), mbps=20.0, margin=0):
    """Cells x = 0..39 on row 0: `mbps`, the link lost in `hole`, no observation in `unknown`;
    `margin`: the map's hole_margin_cells (0: the stretches' own figures alone)."""
    m = LinkMap(LinkMapParams(min_observations=3, hole_margin_cells=margin))
    for x in range(40):
        if x in unknown:
            continue
        lost = hole[0] <= x < hole[1]
        for k in range(3):
            m.add("laptop", T0 + k, x + 0.5, 0.5, math.nan if lost else mbps, lost)
    return m


def ahead(m, x, speed=1.0, path=STRAIGHT, horizon=20.0, y=0.5):
    tracker = PathTracker()
    tracker.set_path(path)
    return forecast_links(m, ["laptop"], tracker, x, y, speed, horizon)["laptop"]


def test_the_link_ahead_carries_until_the_hole_and_says_when_it_falls():
    fc = ahead(corridor(), 2.2)
    assert fc.carries_for_s(5.0, live_mbps=20.0) == pytest.approx(7.8, abs=1e-3)  # x = 10
    assert fc.falls_below(5.0) == (pytest.approx(7.8, abs=1e-3), 0.0)
    assert fc.carries_for_s(25.0, live_mbps=30.0) == pytest.approx(0.8, abs=1e-3)  # 20 < 25
    assert fc.describe(20.0) == ("20 Mbit/s for 8 s, then 0 Mbit/s (lost 100 %) from 8 s, "
                                 "then 20 Mbit/s from 12 s (at 1.00 m/s)")


def test_a_link_that_carries_to_the_horizon_carries_for_the_horizon():
    fc = ahead(corridor(hole=(100, 100)), 2.0, horizon=10.0)
    assert fc.carries_for_s(5.0, 20.0) == 10.0
    assert fc.falls_below(5.0) is None


def test_an_unknown_cell_never_carries_and_never_falls():
    fc = ahead(corridor(unknown=(5, 6)), 2.0)
    assert fc.carries_for_s(5.0, 20.0) == pytest.approx(3.0, abs=1e-3)  # x = 5: unknown
    assert fc.falls_below(5.0) == (pytest.approx(8.0, abs=1e-3), 0.0)  # the hole


def test_the_live_link_judges_the_cell_the_robot_is_in():
    # The map says the robot's cell lost the link, the measurement says 20 Mbit/s: no fall is
    # foreseen (the reactive rules judge the link now), but the cell does not carry either,
    # so no node skips those rules there.
    m = corridor(hole=(2, 3))
    fc = ahead(m, 2.5)
    assert fc.stretches[0].current and fc.stretches[0].stats.lost_fraction == 1.0
    assert fc.falls_below(5.0) is None
    assert fc.carries_for_s(5.0, live_mbps=20.0) == 0.0
    assert ahead(m, 3.5).carries_for_s(5.0, live_mbps=20.0) == 20.0   # past it
    # The map says 20 Mbit/s, the measurement 1: the link bad now is bad.
    fc = ahead(corridor(), 2.5)
    assert fc.carries_for_s(5.0, live_mbps=1.0) == 0.0
    assert fc.carries_for_s(5.0, live_mbps=math.nan) == 0.0


def test_an_empty_map_carries_nothing_even_for_a_standing_robot():
    for speed in (0.0, 1.0):
        fc = ahead(LinkMap(), 2.5, speed=speed)
        assert fc.carries_for_s(5.0, live_mbps=20.0) == 0.0
        assert fc.falls_below(5.0) is None


def test_new_observations_update_the_cell_that_disagreed():
    m = corridor()
    assert ahead(m, 8.0).falls_below(5.0)[0] == pytest.approx(2.0, abs=1e-3)
    for k in range(30):                      # the link is back at x = 10..13 on this pass
        for x in range(10, 14):
            m.add("laptop", T0 + 100 + k, x + 0.5, 0.5, 18.0, False)
    assert ahead(m, 8.0).falls_below(5.0) is None
    assert ahead(m, 8.0).carries_for_s(5.0, 20.0) == 20.0


def test_a_standing_robot_stays_in_its_cell_for_the_whole_horizon():
    fc = ahead(corridor(), 9.5, speed=0.0)
    assert len(fc.stretches) == 1 and fc.stretches[0].current
    assert fc.carries_for_s(5.0, 20.0) == 20.0
    assert fc.falls_below(5.0) is None               # the hole 0.5 m ahead is not reached
    assert fc.describe(20.0) == "20 Mbit/s for 20 s (the horizon) (standing)"


def test_past_the_end_of_the_path_the_robot_stays_at_its_end():
    fc = ahead(corridor(), 2.0, path=STRAIGHT[:11] + [(10.5, 0.5)])   # it ends in the hole
    assert fc.stretches[-1].end_s == 20.0
    assert fc.stretches[-1].start_s == pytest.approx(8.0, abs=1e-3)
    assert fc.carries_for_s(5.0, 20.0) == pytest.approx(8.0, abs=1e-3)


def test_a_robot_off_its_path_has_no_forecast():
    tracker = PathTracker(max_offset_m=1.5)
    tracker.set_path(STRAIGHT)
    assert forecast_links(corridor(), ["laptop"], tracker, 5.0, 2.5, 1.0, 20.0) is None
    tracker.set_path([])
    assert forecast_links(corridor(), ["laptop"], tracker, 5.0, 0.5, 1.0, 20.0) is None


def test_a_path_that_changes_replaces_the_old_one():
    m = corridor()
    tracker = PathTracker()
    tracker.set_path(STRAIGHT)
    assert forecast_links(m, ["laptop"], tracker, 8.0, 0.5, 1.0, 20.0)["laptop"] \
        .falls_below(5.0)[0] == pytest.approx(2.0, abs=1e-3)
    tracker.set_path([(float(x), 0.5) for x in range(8, -1, -1)])   # turned back, to x = 0
    back = forecast_links(m, ["laptop"], tracker, 8.0, 0.5, 1.0, 20.0)["laptop"]
    assert back.falls_below(5.0) is None
    assert back.carries_for_s(5.0, 20.0) == 20.0


# A U: out along y = 0.5 to x = 10, then back along y = 2.5, 2 m beside the way out.
U_PATH = [(float(x), 0.5) for x in range(11)] + [(float(x), 2.5) for x in range(10, -1, -1)]


def test_the_place_on_the_path_follows_the_robot_not_the_nearest_branch():
    tracker = PathTracker(max_offset_m=1.5, jump_m=2.0)
    tracker.set_path(U_PATH)
    assert tracker.project(2.0, 0.5) == pytest.approx(2.0)
    # 1.4 m up, nearer the way back (1.1 m off) than the way out (1.4 m): still the way out.
    assert tracker.project(2.3, 1.9) == pytest.approx(2.3)


def test_a_pose_that_jumps_is_placed_on_the_whole_path_again():
    tracker = PathTracker(max_offset_m=1.5, jump_m=2.0)
    tracker.set_path(U_PATH)
    assert tracker.project(2.0, 0.5) == pytest.approx(2.0)
    s = tracker.project(3.0, 2.5)            # a relocalisation 2.2 m away: on the way back
    assert s == pytest.approx(10 + 2 + 7)
    assert tracker.project(9.0, 9.0) is None        # lost: far from any part of the path


def test_the_speed_comes_from_the_pose_track_and_a_jump_restarts_it():
    track = PoseTrack(window_s=2.0)
    assert track.speed() == 0.0
    for k in range(11):
        track.add(100.0 + 0.2 * k, 0.08 * k, 0.0)     # 0.4 m/s
    assert track.speed() == pytest.approx(0.4)
    assert track.at(100.5) == pytest.approx((0.2, 0.0))
    assert track.at(103.0) is None                   # after the track: no pose there
    track.add(102.2, 30.0, 0.0)                       # 29 m in 0.2 s: a jump
    assert track.speed() == 0.0 and track.latest() == (102.2, 30.0, 0.0)


def test_a_forecast_with_no_stretch_carries_for_its_horizon():
    fc = LinkForecast("laptop", 20.0, (), 1.0)
    assert fc.carries_for_s(5.0, 0.0) == 20.0 and fc.falls_below(5.0) is None
    assert fc.describe(0.0) == "no forecast"


def test_the_cruise_speed_outlasts_a_stop_at_a_goal():
    """The forecast drives at the top speed of the last cruise_s: 5 s standing at a goal, or
    pulling away from it, does not make the robot 'standing' with only its own cell ahead."""
    track = PoseTrack(window_s=2.0, cruise_s=15.0)
    t = 100.0
    for k in range(51):                               # 10 s at 0.4 m/s
        track.add(t + 0.2 * k, 0.08 * k, 0.0)
    t += 10.0
    for k in range(1, 26):                            # 5 s standing at the goal
        track.add(t + 0.2 * k, 4.0, 0.0)
    assert track.speed() == 0.0
    assert track.cruise_speed() == pytest.approx(0.4)
    for k in range(1, 76):                            # 15 s more standing: it stands
        track.add(t + 5.0 + 0.2 * k, 4.0, 0.0)
    assert track.cruise_speed() == pytest.approx(0.0)


def test_a_short_track_cruises_at_its_own_speed():
    track = PoseTrack(window_s=2.0, cruise_s=15.0)
    assert track.cruise_speed() == 0.0
    track.add(0.0, 0.0, 0.0)
    track.add(0.3, 0.12, 0.0)                         # 0.3 s of track: shorter than a window
    assert track.cruise_speed() == pytest.approx(0.4)


def test_one_loss_among_a_cells_observations_makes_it_a_hole():
    """A blip at a coverage edge is one observation of ten in its cell, but the pass that met it
    lost the link: the cell is a hole (link_map_hole_lost_fraction 0), or with a looser
    threshold a cell whose losses are rarer than it."""
    def blip(params):
        m = LinkMap(params)
        for x in range(40):
            for k in range(3):
                m.add("laptop", T0 + k, x + 0.5, 0.5, 20.0, False)
        for k in range(8):
            m.add("laptop", T0 + 10 + k, 6.5, 0.5, 20.0, False)
        m.add("laptop", T0 + 20, 6.5, 0.5, math.nan, True)      # 1 of 12 observations lost
        return m
    fc = ahead(blip(LinkMapParams(min_observations=3, hole_margin_cells=0)), 2.2)
    assert fc.stretches[4].stats.low_mbps == 20.0               # the quantile does not see it
    assert fc.falls_below(5.0) == (pytest.approx(3.8, abs=1e-3), 0.0)
    assert fc.carries_for_s(5.0, live_mbps=20.0) == pytest.approx(3.8, abs=1e-3)
    fc = ahead(blip(LinkMapParams(min_observations=3, hole_lost_fraction=0.1,
                                  hole_margin_cells=0)), 2.2)
    assert fc.falls_below(5.0) is None and fc.carries_for_s(5.0, live_mbps=20.0) == 20.0


def test_a_cell_beside_a_hole_clears_no_node_but_foresees_no_fall():
    """The coverage's edge flickers beside where it was lost before: within hole_margin_cells
    of a hole the link does not carry (no node skips the reactive rules there), ahead of it and
    behind it; only the hole itself is a fall foreseen."""
    fc = ahead(corridor(margin=1), 2.2)                     # the hole at x = 10..13
    assert fc.carries_for_s(5.0, live_mbps=20.0) == pytest.approx(6.8, abs=1e-3)  # x = 9
    assert fc.falls_below(5.0) == (pytest.approx(7.8, abs=1e-3), 0.0)
    assert ahead(corridor(margin=1), 14.5).carries_for_s(5.0, live_mbps=20.0) == 0.0
    assert ahead(corridor(margin=1), 15.5).carries_for_s(5.0, live_mbps=20.0) == 20.0
    assert ahead(corridor(margin=2), 15.5).carries_for_s(5.0, live_mbps=20.0) == 0.0
