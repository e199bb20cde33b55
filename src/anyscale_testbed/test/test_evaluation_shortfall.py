"""evaluation_shortfall on a synthetic test: the seconds the run left of the coverage bound go
to the cause that held at each step, and the moves out cost the seconds until the robot sped
up."""
import pytest

from anyscale_testbed.path_steps import path_steps
from anyscale_testbed.evaluation_shortfall import (AHEAD, BACKOFF, BANDWIDTH_HOLD, HOLD,
                                                   HYSTERESIS, OTHER, START, WEAK,
                                                   PolicyParams, shortfall)
from anyscale_testbed.testbed_record import EventRecord, TestbedRecord, mapping_at

AMCL_MBPS = 0.22


def on(amcl):
    return {"amcl": amcl, "ar_recognition": "robot", "navigation": "robot"}


def event(decided_t, kind, reason=""):
    return EventRecord(t=decided_t + 1.0, kind=kind, node="amcl", from_scale="robot",
                       to_scale="laptop" if kind == "migrate" else "robot", reason=reason,
                       duration_s=1.0, success=True, decided_t=decided_t)


def driven(mappings, end_s, **record):
    """A record of the robot driving at 0.4 m/s with AMCL out, 0.2 m/s with it home."""
    rec = TestbedRecord(mappings=mappings)
    times = [round(0.1 * k, 1) for k in range(0, int(end_s * 10) + 1)]
    x = [0.0]
    for t in times[:-1]:
        x.append(x[-1] + 0.1 * (0.4 if mapping_at(rec, t)["amcl"] == "laptop" else 0.2))
    return TestbedRecord(world="small_loop", link="coverage", finished_t=end_s,
                         truth=[(t, xt, 0.0) for t, xt in zip(times, x)], mappings=mappings,
                         **record)


def test_each_second_left_goes_to_its_cause():
    """AMCL out 30-60 s (the robot speeds up to 0.4 m/s 2 s after the decision), home at
    0.2 m/s otherwise; the link 10 Mbit/s, 3 Mbit/s (weak) 90-100 s, down 100-110 s; the
    mission 10-150 s."""
    mappings = [(0.0, on("robot"), 0.0, 0.0), (30.0, on("laptop"), 0.0, 0.0),
                (60.0, on("robot"), 0.0, 0.0)]
    rec = TestbedRecord(mappings=mappings)
    times = [round(0.1 * k, 1) for k in range(0, 1601)]
    x = [0.0]
    for t in times[:-1]:
        fast = mapping_at(rec, t)["amcl"] == "laptop" and t >= 32.0 - 1e-9
        x.append(x[-1] + 0.1 * (0.4 if fast else 0.2))
    rec = TestbedRecord(
        world="small_loop", link="coverage", finished_t=160.0,
        truth=[(t, xt, 0.0) for t, xt in zip(times, x)], mappings=mappings,
        bandwidth=[(0.0, 10.0), (90.0, 3.0), (100.0, 0.0), (110.0, 10.0)],
        navigation_status=[(10.0, "drive 0/4"), (150.0, "done 4/4")],
        events=[event(30.0, "migrate"), event(60.0, "migrate_back")])
    steps = path_steps(rec, AMCL_MBPS)
    left = shortfall(rec, steps)
    per_s = 1.0 - 0.2 / steps.out_mps        # saved per second driven home at 0.2 m/s
    expected = {START: 20.0, HYSTERESIS: 10.0, OTHER: 20.0 + 20.0, WEAK: 10.0, HOLD: 20.0}
    for cause, seconds in expected.items():
        assert left.by_cause[cause] == pytest.approx(seconds * per_s, abs=0.06), cause
    # 30-32 s mapped out but driven at 0.2 m/s; 32-34 s already at 0.4 m/s: nothing.
    assert left.moving_s == pytest.approx(2.0 * per_s, abs=0.06)


def test_the_causes_are_judged_by_the_runs_own_parameters_where_the_record_keeps_them():
    old = TestbedRecord()
    assert PolicyParams.of_record(old) == PolicyParams(5.5, 20.0, 10.0)
    new = TestbedRecord(decision_params={"hold_after_loss_s": 20.0, "hysteresis_s": 15,
                                         "node_hold_after_loss_s": {"amcl": 0.0}})
    assert PolicyParams.of_record(new) == PolicyParams(5.5, 0.0, 15.0)
    assert PolicyParams.of_record(new, "ar_recognition").hold_after_loss_s == 20.0


def test_the_forecasts_holds_the_back_off_and_the_bandwidth_hold_are_causes_of_their_own():
    """AMCL out 30-60 s, brought home by the link ahead (held until 75 s), out 75-100 s, home
    for its rate and backed off 20 s; the link weak 130-135 s; the mission 10-170 s."""
    mappings = [(0.0, on("robot"), 0.0, 0.0), (30.0, on("laptop"), 0.0, 0.0),
                (60.0, on("robot"), 0.0, 0.0), (75.0, on("laptop"), 0.0, 0.0),
                (100.0, on("robot"), 0.0, 0.0)]
    rec = driven(
        mappings, 180.0, bandwidth=[(0.0, 10.0), (130.0, 3.0), (135.0, 10.0)],
        navigation_status=[(10.0, "drive 0/4"), (170.0, "done 4/4")],
        decision_params={"hysteresis_s": 10.0, "bandwidth_hold_s": 5.0, "weak_link_mbps": 5.5,
                         "hold_after_loss_s": 0.0},
        link_ahead=[(58.0, "amcl home: link ahead: 0.0 Mbit/s in 3.0 s on laptop", True),
                    (75.0, "no node moved by it", True)],
        events=[event(30.0, "migrate"), event(60.0, "migrate_back", "link ahead: 0.0 Mbit/s"),
                event(75.0, "migrate"),
                event(100.0, "migrate_back", "connection spending its tolerance: laser->amcl "
                                             "(/scan) 2.2 Hz on laptop; backed off 20 s")])
    left = shortfall(rec, path_steps(rec, AMCL_MBPS))
    per_s = 1.0 - 0.2 / 0.4
    expected = {START: 20.0, HYSTERESIS: 10.0 + 10.0, AHEAD: 5.0, BACKOFF: 10.0, WEAK: 5.0,
                BANDWIDTH_HOLD: 5.0, OTHER: 10.0 + 30.0, HOLD: 0.0}
    for cause, seconds in expected.items():
        assert left.by_cause[cause] == pytest.approx(seconds * per_s, abs=0.06), cause
