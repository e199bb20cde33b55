"""The link map, the forecast and the decision engine together, without ROS, on a made-up
floor: a robot drives a 40 m square loop twice (0.4 m/s with AMCL on the laptop, 0.2 m/s with
AMCL home, as on the test bed) through a hole in the coverage; the agents' reports come every
period, the laptop's only while the link is up, the robot's uplink losing its carrier at once.
The decision node's wrapper is played by the same calls it makes: observations into the map,
the plan to the next goal, the forecast before each tick. On lap 1 AMCL meets the hole with a
link-loss return; on lap 2 it comes home planned before it, and out again early after it."""
from dataclasses import replace
import math

import numpy as np

from anyscale_core.allocators import make_allocator
from anyscale_core.decision_engine import DecisionEngine
from anyscale_core.decision_types import DecisionParams
from anyscale_core.link_forecast import LinkForecastParams, PathTracker, PoseTrack, forecast_links
from anyscale_core.link_map import LinkMap, LinkMapParams

from decision_reports import reports

SIDE_M, PERIOD_S = 10.0, 0.25
HOLE = (12.0, 16.0)                 # lost along the loop from 12 to 16 m
GOALS = (10.0, 20.0, 30.0, 40.0)    # navigation's goals, one per side
# robot.launch's reactive rules: the paper's T, the bandwidth hold, the weak link, the hold after
# a loss for every node but AMCL.
PARAMS = dict(hysteresis_s=10.0, bandwidth_hold_s=5.0, weak_link_mbps=5.5,
              hold_after_loss_s=20.0, node_hold_after_loss_s={"amcl": 0.0},
              status_timeout_s=2.0)


def place(s):
    """(x, y) at s m along the square loop (counter-clockwise from the origin)."""
    s = s % (4 * SIDE_M)
    side, d = int(s // SIDE_M), s % SIDE_M
    return [(d, 0.0), (SIDE_M, d), (SIDE_M - d, SIDE_M), (0.0, SIDE_M - d)][side]


def link_at(s, hole=HOLE):
    return 0.0 if hole[0] <= s % (4 * SIDE_M) < hole[1] else 20.0


def drive(ch, forecast: bool, laps: int = 2, hole=HOLE, stop_s: float = 0.0,
          route: bool = False, speed=PoseTrack.cruise_speed, margin: int = 1):
    """The engine's events per lap, and the distance driven when each was decided. The robot
    stands stop_s at each goal; the path is the plan to the next goal, or with `route` the
    mission's route on through the goal after it (navigation's ~mission_plan); `speed` is the
    pose track's figure the forecast drives at; `margin` the map's hole_margin_cells."""
    e = DecisionEngine(ch, make_allocator("paper"),
                       DecisionParams(**PARAMS, link_forecast=LinkForecastParams(
                           enabled=forecast)))
    e.adopt_or_start(reports(0.0), 0.0)
    link_map = LinkMap(LinkMapParams(hole_margin_cells=margin))
    path, poses = PathTracker(), PoseTrack()
    s, t, heard, events, standing_until, stood_at = 0.0, 0.0, False, [], 0.0, set()

    def link_at(s):
        return globals()["link_at"](s, hole)
    while s < laps * 4 * SIDE_M:
        t += PERIOD_S
        x, y = place(s)
        up = link_at(s) > 0
        rep = reports(t, bandwidth=link_at(s), laptop=up)
        if not up:              # the robot's uplink has lost its carrier
            rep["robot"] = replace(rep["robot"], link_up=False)
        poses.add(t, x, y)
        if up:
            heard = True
            link_map.add("laptop", 1.8e9 + t, x, y, link_at(s), False)
        elif heard:
            link_map.add("laptop", 1.8e9 + t, x, y, math.nan, True)
        lap_start = s - s % (4 * SIDE_M)
        goal = lap_start + next(g for g in GOALS if g > s % (4 * SIDE_M))
        if t < standing_until:
            goal = s                    # its current goal is the one it stands at
        end = goal + (SIDE_M if route else 0.0)
        path.set_path([place(d) for d in np.arange(s, end, 0.2)] + [place(end)])
        e.set_link_forecast(forecast_links(link_map, ["laptop"], path, x, y, speed(poses),
                                           20.0) if forecast else None)
        result = e.tick(rep, t)
        events += [(s, ev) for ev in result.events]
        if t < standing_until:
            continue
        step = (0.4 if e.mapping()["amcl"] == "laptop" else 0.2) * PERIOD_S
        if stop_s and goal not in stood_at and s + step >= goal - 1e-9:
            s, standing_until = goal, t + stop_s        # arrived: stand at the goal
            stood_at.add(goal)
        else:
            s += step
    return events


def amcl_returns(events, lap, reason):
    lo, hi = (lap - 1) * 4 * SIDE_M, lap * 4 * SIDE_M
    return [round(s, 1) for s, ev in events if ev.node == "amcl" and ev.kind == "migrate_back"
            and lo <= s < hi and ev.reason.startswith(reason)]


def test_lap_2_comes_home_before_the_hole_that_lap_1_met(testbed_ch):
    ch = testbed_ch
    events = drive(ch, forecast=True)
    assert len(amcl_returns(events, 1, "link to")) == 1, events
    assert amcl_returns(events, 2, "link to") == [], events
    planned = amcl_returns(events, 2, "link ahead")
    assert len(planned) == 1, events
    # 3 s of lead at 0.4 m/s: about 1.2 m before the hole, and not before 2 m.
    assert 4 * SIDE_M + HOLE[0] - 2.0 <= planned[0] < 4 * SIDE_M + HOLE[0], planned


def test_lap_2_moves_out_sooner_after_the_hole_than_the_reactive_rules(testbed_ch):
    ch = testbed_ch

    def first_out_after_hole(events, lap):
        hole_end = (lap - 1) * 4 * SIDE_M + HOLE[1]
        return min(s for s, ev in events if ev.node == "amcl" and ev.kind == "migrate"
                   and s >= hole_end)
    with_forecast = drive(ch, forecast=True)
    reactive = drive(ch, forecast=False)
    assert len(amcl_returns(reactive, 2, "link to")) == 1       # it meets the hole again
    assert first_out_after_hole(with_forecast, 2) < first_out_after_hole(reactive, 2)


# A hole that starts 1 m past a goal, in the next 1 m cell: at 0.4 m/s the robot reaches it
# 2.5 s after leaving the goal, within AMCL's 3 s home lead, so the return must be decided while
# the robot stands there.
HOLE_PAST_GOAL = (11.0, 14.0)
HOME_LEAD_M = 3.0 * 0.4             # the home lead at the cruise speed


def lap_2_amcl(events):
    return [(round(s - 4 * SIDE_M, 2), ev.kind) for s, ev in events if ev.node == "amcl"
            and 4 * SIDE_M <= s < 4 * SIDE_M + HOLE_PAST_GOAL[1]]


def test_a_hole_just_past_a_goal_is_foreseen_while_the_robot_stands_at_it(testbed_ch):
    """With the route past the goal and the cruise speed, lap 2's return starts a full home
    lead before the hole, and AMCL stays home until past it."""
    events = drive(testbed_ch, forecast=True, hole=HOLE_PAST_GOAL, stop_s=5.0, route=True)
    assert len(amcl_returns(events, 1, "link to")) == 1, events
    assert amcl_returns(events, 2, "link to") == [], events
    moves = lap_2_amcl(events)
    assert [kind for _, kind in moves] == ["migrate_back"], moves
    assert moves[0][0] <= HOLE_PAST_GOAL[0] - HOME_LEAD_M + 0.1, moves


def test_a_plan_that_ends_at_the_goal_or_a_standing_speed_is_late_for_it(testbed_ch):
    """Why navigation publishes the route past the goal and the forecast drives at the cruise
    speed: with the plan to the goal and the speed measured, the return starts as the robot
    pulls away, half the lead before the hole; with the route but the measured speed, AMCL
    moves out while the robot stands at the goal and comes straight back (without the margin
    beside a hole, which on its own keeps it home there)."""
    late = drive(testbed_ch, forecast=True, hole=HOLE_PAST_GOAL, stop_s=5.0, route=False,
                 speed=PoseTrack.speed)
    moves = lap_2_amcl(late)
    assert [kind for _, kind in moves] == ["migrate_back"], moves
    assert moves[0][0] > HOLE_PAST_GOAL[0] - HOME_LEAD_M + 0.1, moves
    flap = drive(testbed_ch, forecast=True, hole=HOLE_PAST_GOAL, stop_s=5.0, route=True,
                 speed=PoseTrack.speed, margin=0)
    kinds = [kind for _, kind in lap_2_amcl(flap)]
    assert kinds == ["migrate_back", "migrate", "migrate_back"], lap_2_amcl(flap)
    kept = drive(testbed_ch, forecast=True, hole=HOLE_PAST_GOAL, stop_s=5.0, route=True,
                 speed=PoseTrack.speed)
    assert [kind for _, kind in lap_2_amcl(kept)] == ["migrate_back"], lap_2_amcl(kept)
