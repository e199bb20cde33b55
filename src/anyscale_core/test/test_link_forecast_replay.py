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
from anyscale_core.link_map import LinkMap

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


def link_at(s):
    return 0.0 if HOLE[0] <= s % (4 * SIDE_M) < HOLE[1] else 20.0


def drive(ch, forecast: bool, laps: int = 2):
    """The engine's events per lap, and the distance driven when each was decided."""
    e = DecisionEngine(ch, make_allocator("paper"),
                       DecisionParams(**PARAMS, link_forecast=LinkForecastParams(
                           enabled=forecast)))
    e.adopt_or_start(reports(0.0), 0.0)
    link_map, path, poses = LinkMap(), PathTracker(), PoseTrack()
    s, t, heard, events = 0.0, 0.0, False, []
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
        goal = next(g for g in GOALS if g > s % (4 * SIDE_M))
        lap_start = s - s % (4 * SIDE_M)
        path.set_path([place(d) for d in np.arange(s, lap_start + goal, 0.2)] +
                      [place(lap_start + goal)])
        e.set_link_forecast(forecast_links(link_map, ["laptop"], path, x, y, poses.speed(),
                                           20.0) if forecast else None)
        result = e.tick(rep, t)
        events += [(s, ev) for ev in result.events]
        s += (0.4 if e.mapping()["amcl"] == "laptop" else 0.2) * PERIOD_S
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
