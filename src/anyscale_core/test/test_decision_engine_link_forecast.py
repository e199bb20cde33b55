"""The decision engine with the link ahead (link_anticipation.py): out early (the bandwidth
hold, the weak-link wait, the hold after a loss and T skipped for a node the link carries now and
ahead), home early (a planned return before a hole), held at home while a hole is near, and the
measurement winning over the forecast; with no forecast, or the switch off, the engine decides
as it always did."""
import math

import pytest

from anyscale_core.allocators import make_allocator
from anyscale_core.decision_engine import DecisionEngine
from anyscale_core.decision_types import DecisionParams, StartNode, StopNode
from anyscale_core.link_forecast import LinkForecast, LinkForecastParams, Stretch
from anyscale_core.link_map import CellStats

from decision_reports import remote, reports

AHEAD = LinkForecastParams(horizon_s=20.0, move_cost_s=3.0, home_lead_s=3.0)


def forecast(*stretches, horizon=20.0):
    """{'laptop': a forecast} from (start s, Mbit/s or None for unknown, lost share) stretches;
    the first is the robot's cell, judged by the measurement."""
    out = []
    for k, (start, mbps, lost) in enumerate(stretches):
        end = stretches[k + 1][0] if k + 1 < len(stretches) else horizon
        stats = None if mbps is None else CellStats(mbps, lost, 10)
        out.append(Stretch(start, end, stats, current=k == 0))
    return {"laptop": LinkForecast("laptop", horizon, tuple(out), 0.4)}


GOOD = forecast((0.0, 20.0, 0.0), (1.0, 24.0, 0.0))
HOLE_IN = lambda s: forecast((0.0, 20.0, 0.0), (1.0, 20.0, 0.0), (s, 0.0, 1.0))  # noqa: E731


def engine(testbed_ch, **params):
    e = DecisionEngine(testbed_ch, make_allocator("paper"),
                       DecisionParams(link_forecast=AHEAD, **params))
    e.adopt_or_start(reports(0.0), 0.0)
    return e


def tick(e, t, fc, **report):
    e.set_link_forecast(fc)
    return e.tick(reports(t, **report), t)


def test_out_early_when_the_link_carries_the_node_now_and_ahead(testbed_ch):
    e = engine(testbed_ch, bandwidth_hold_s=5.0)
    result = tick(e, 0.5, GOOD)
    assert [(ev.node, ev.reason) for ev in result.events] == [
        ("amcl", "laptop can take it (36 % CPU there); link ahead carries it 20 s")]
    tick(e, 1.0, GOOD)
    assert remote(e) == ["amcl", "ar_recognition"]      # both carried: no 5 s hold


def test_without_the_forecast_the_same_link_waits_for_the_hold(testbed_ch):
    e = engine(testbed_ch, bandwidth_hold_s=5.0)
    for t in (0.5, 1.0, 5.0):                            # watched from 0.5 s
        assert tick(e, t, None).events == []
    tick(e, 5.5, None)
    assert remote(e) == ["amcl"]


def test_an_unknown_stretch_ahead_leaves_the_reactive_rules(testbed_ch):
    e = engine(testbed_ch, bandwidth_hold_s=5.0)
    unknown = forecast((0.0, 20.0, 0.0), (1.0, None, 0.0))
    for t in (0.5, 1.0, 5.0):
        assert tick(e, t, unknown).events == []
    tick(e, 5.5, unknown)
    assert remote(e) == ["amcl"]


def test_a_link_that_carries_a_node_too_briefly_does_not_clear_it(testbed_ch):
    e = engine(testbed_ch, bandwidth_hold_s=5.0)
    brief = forecast((0.0, 20.0, 0.0), (1.0, 24.0, 0.0), (5.0, None, 0.0))  # < 3 + 3 s
    assert tick(e, 0.5, brief).events == []


@pytest.mark.parametrize("live", [0.2, math.nan])
def test_the_measurement_wins_over_a_forecast_that_carries(testbed_ch, live):
    # AMCL sends 0.22 Mbit/s, 0.29 with the margin: a link measured at 0.2, or not yet
    # measured, carries nothing now, whatever the map says.
    e = engine(testbed_ch, bandwidth_hold_s=0.0, weak_link_mbps=5.5)
    for t in (0.5, 1.0, 2.0, 3.0):
        tick(e, t, GOOD, bandwidth=live)
    assert remote(e) == []


def test_out_early_on_a_weak_link_and_staying_while_the_link_ahead_carries(testbed_ch):
    e = engine(testbed_ch, bandwidth_hold_s=5.0, weak_link_mbps=5.5)
    thin = forecast((0.0, 4.5, 0.0), (1.0, 4.5, 0.0))
    tick(e, 0.5, thin, bandwidth=4.5)
    assert remote(e) == ["amcl"]                         # AR's 6 Mbit/s: not on 4.5
    for t in (1.0, 2.0, 3.0):
        assert tick(e, t, thin, bandwidth=4.5).events == []
    fading = forecast((0.0, 4.5, 0.0), (1.0, 4.5, 0.0), (2.5, None, 0.0))
    result = tick(e, 4.0, fading, bandwidth=4.5)         # carried 2.5 s only: the weak rule
    assert [(ev.node, ev.reason) for ev in result.events] == [
        ("amcl", "bandwidth 4.5 Mbit/s, below weak_link_mbps 5.5: home before the link is lost")]
    assert StopNode("amcl", "laptop", after_output_on="robot") in result.actions


def test_without_the_forecast_a_weak_link_keeps_every_node_home(testbed_ch):
    e = engine(testbed_ch, bandwidth_hold_s=0.0, weak_link_mbps=5.5)
    for t in (0.5, 1.0, 2.0):
        tick(e, t, None, bandwidth=4.5)
    assert remote(e) == []


def test_home_early_before_a_hole_as_a_planned_move(testbed_ch):
    e = engine(testbed_ch, bandwidth_hold_s=0.0, hysteresis_s=0.0)
    tick(e, 0.5, None)
    tick(e, 1.0, None)
    assert remote(e) == ["amcl", "ar_recognition"]
    assert tick(e, 2.0, HOLE_IN(4.0)).events == []       # further than the 3 s lead
    result = tick(e, 2.5, HOLE_IN(2.8))
    assert sorted((ev.node, ev.kind, ev.reason) for ev in result.events) == [
        ("amcl", "migrate_back", "link ahead: 0.0 Mbit/s in 2.8 s"),
        ("ar_recognition", "migrate_back", "link ahead: 0.0 Mbit/s in 2.8 s")]
    assert StopNode("amcl", "laptop", after_output_on="robot") in result.actions
    assert any(isinstance(a, StartNode) and a.node == "amcl" and a.scale == "robot"
               for a in result.actions)
    assert remote(e) == []


def test_a_node_brought_home_early_stays_until_the_link_ahead_is_good_again(testbed_ch):
    e = engine(testbed_ch, bandwidth_hold_s=0.0, hysteresis_s=0.0)
    tick(e, 0.5, None)
    tick(e, 2.0, HOLE_IN(2.0))
    assert remote(e) == []
    # Approaching the hole, the link measured good: the reactive rules (no hold, no T) would
    # move AMCL out at once; the hole 1-5 s ahead, within its move cost and lead, holds it.
    for t, hole in ((3.0, 1.0), (4.0, 5.0)):
        assert tick(e, t, HOLE_IN(hole)).events == [], t
    assert e.anticipation.last.held[e.ch.node_index("amcl")].startswith("link ahead: 0.0")
    # Through the hole (lost: the laptop silent), then out again once the link ahead carries.
    e.set_link_forecast(forecast((0.0, 0.0, 1.0), (2.0, 20.0, 0.0)))
    assert e.tick({"robot": reports(5.0)["robot"]}, 5.0).events == []
    result = tick(e, 7.5, GOOD)
    assert [ev.node for ev in result.events] == ["amcl"]


def test_an_unforeseen_loss_gets_the_reactive_return(testbed_ch):
    e = engine(testbed_ch, bandwidth_hold_s=0.0)
    tick(e, 0.5, GOOD)
    tick(e, 1.0, GOOD)
    e.set_link_forecast(GOOD)
    result = e.tick({"robot": reports(2.0)["robot"]}, 2.0)      # the laptop went silent
    assert sorted((ev.node, ev.reason) for ev in result.events) == [
        ("amcl", "link to laptop down"), ("ar_recognition", "link to laptop down")]


def test_out_early_after_a_loss_skips_the_hold_after_a_loss_and_T(testbed_ch):
    params = dict(bandwidth_hold_s=5.0, hold_after_loss_s=20.0, hysteresis_s=10.0)
    with_forecast, without = engine(testbed_ch, **params), engine(testbed_ch, **params)
    for e, fc in ((with_forecast, GOOD), (without, None)):
        for t in range(1, 8):
            tick(e, float(t), None)
        assert remote(e) == ["amcl", "ar_recognition"]
        e.tick({"robot": reports(8.0)["robot"]}, 8.0)               # lost
        assert remote(e) == []
        tick(e, 9.0, fc)                                             # back, measured
        tick(e, 9.5, fc)
    assert remote(with_forecast) == ["amcl", "ar_recognition"]
    assert remote(without) == []


def test_T_still_holds_a_node_that_came_home_for_its_connection(testbed_ch):
    e = engine(testbed_ch, bandwidth_hold_s=0.0, hysteresis_s=10.0, startup_grace_s=0.0)
    tick(e, 0.5, GOOD)
    assert remote(e) == ["amcl"]
    result = tick(e, 2.0, GOOD, rates={"/amcl_pose": 0.0}, silence={"/amcl_pose": 1.5})
    assert [(ev.node, ev.kind) for ev in result.events] == [("amcl", "migrate_back")]
    for t in (3.0, 5.0, 11.0):
        tick(e, t, GOOD)
        assert "amcl" not in remote(e), t                           # T: 10 s from 2.0
    tick(e, 12.5, GOOD)
    assert "amcl" in remote(e)


def scripted_run(testbed_ch, fc_of, enabled=True):
    """The events of a run with a link that comes, goes weak, is lost and comes back, with
    `fc_of(t)` as the forecast given before each tick (None: never given)."""
    params = DecisionParams(bandwidth_hold_s=2.0, weak_link_mbps=5.5, hold_after_loss_s=4.0,
                            link_forecast=LinkForecastParams(enabled=enabled))
    e = DecisionEngine(testbed_ch, make_allocator("paper"), params)
    out = [e.adopt_or_start(reports(0.0), 0.0).events]
    for k in range(1, 60):
        t = 0.5 * k
        if fc_of is not None:
            e.set_link_forecast(fc_of(t))
        if 12 <= t < 15:
            rep = {"robot": reports(t)["robot"]}
        else:
            rep = reports(t, bandwidth=4.0 if 8 <= t < 12 else 20.0)
        result = e.tick(rep, t)
        out.append((result.events, result.actions))
    return out


@pytest.mark.parametrize("fc_of, enabled", [(lambda t: None, True), (lambda t: GOOD, False)])
def test_with_no_forecast_or_the_switch_off_nothing_changes(testbed_ch, fc_of, enabled):
    reactive = scripted_run(testbed_ch, None)
    assert scripted_run(testbed_ch, fc_of, enabled) == reactive
    assert any(events for events, _ in reactive[1:])    # the script does move nodes
