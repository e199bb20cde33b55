"""The decision engine and a scale weaker than the model says (issue 40): a laptop that cannot
give AMCL its rates sends it home, and AMCL must not go out again every T on the model's 36 %;
a laptop whose load drops gets it again; a failure the estimate does not explain backs off,
doubling; a return for the link is no such failure; a stay that lasts resets the back-off.

The reports are made from the engine's own mapping every 0.5 s, as the agents would report the
bed: the laptop (0.9 cores) with a background load that takes `background` % of it; AMCL there
gets the rest (`starved`), with /scan at 2.6-4.5 Hz on the laptop (freq_min 5) and /amcl_pose at
2.5 of its 5 Hz on the robot, or, with room, 30 % of the laptop at its rates. 3 Mbit/s of link:
AR's camera stream does not fit, so AMCL is the only node that moves."""
from dataclasses import replace
import re

from anyscale_core.allocators import make_allocator
from anyscale_core.characterisation import characterise
from anyscale_core.decision_engine import DecisionEngine
from anyscale_core.decision_types import DecisionParams
from anyscale_core.model_loader import load_model

from core_test_data import TESTBED
from decision_reports import reports

LAPTOP_CORES = 0.9
PERIOD = 0.5
# The bed's defaults, the paper's move out on the bandwidth of the moment (no hold).
PARAMS = DecisionParams(bandwidth_hold_s=0.0)


def bed_reports(t, engine, background, starved, link=True, bandwidth=3.0):
    """The agents' reports at t for the engine's current mapping."""
    out = reports(t, bandwidth=bandwidth, laptop=link)
    if not link:
        return out
    laptop = out["laptop"]
    if engine.mapping()["amcl"] != "laptop":
        out["laptop"] = replace(laptop, cpu_percent=background, capacity_cores=LAPTOP_CORES,
                                running={})
    elif starved:
        scan = 2.6 + (t * 0.7) % 1.9                         # 2.6-4.5 Hz
        out["laptop"] = replace(laptop, cpu_percent=100.0, capacity_cores=LAPTOP_CORES,
                                running={"amcl": (100.0 - background) * LAPTOP_CORES},
                                topic_rates={**laptop.topic_rates, "/scan": scan})
        out["robot"] = replace(out["robot"], topic_rates={**out["robot"].topic_rates,
                                                          "/amcl_pose": 2.5})
    else:
        out["laptop"] = replace(laptop, cpu_percent=background + 30.0,
                                capacity_cores=LAPTOP_CORES, running={"amcl": 27.0})
    return out


def make_engine(background, params=PARAMS):
    """The engine after it started every node on the robot, the laptop `background` % busy."""
    e = DecisionEngine(characterise(load_model(TESTBED)), make_allocator("paper"), params)
    e.adopt_or_start(bed_reports(0.0, e, background, False), 0.0)
    return e


def run(engine, start, end, background, starved=True, link=lambda t: True):
    """Ticks from start to end; AMCL's moves out and back (t, reason) and the log's notes."""
    outs, backs, notes = [], [], []
    t = start
    while t < end:
        result = engine.tick(bed_reports(t, engine, background, starved, link(t)), t)
        for e in result.events:
            if e.node == "amcl" and e.kind == "migrate":
                outs.append(t)
            elif e.node == "amcl" and e.kind == "migrate_back":
                backs.append((t, e.reason))
        notes += getattr(result, "notes", [])
        t += PERIOD
    return outs, backs, notes


def drive(engine, reports_at, end):
    """Ticks on reports_at(t, engine) from PERIOD to end: the times of AMCL's moves out and
    back, and the log's notes."""
    outs, backs, notes = [], [], []
    t = PERIOD
    while t < end:
        result = engine.tick(reports_at(t, engine), t)
        outs += [t for e in result.events if e.node == "amcl" and e.kind == "migrate"]
        backs += [t for e in result.events if e.node == "amcl" and e.kind == "migrate_back"]
        notes += result.notes
        t += PERIOD
    return outs, backs, notes


def test_a_laptop_that_cannot_give_amcl_its_rates_does_not_get_it_every_t():
    """The issue's run: AMCL out on the model's 36 %, home 9-12 s later for /scan at 2.6-4.5 Hz
    on the laptop, and out again about T later, six times in a row. Here, six minutes of it."""
    engine = make_engine(50.0)
    outs, backs, _ = run(engine, PERIOD, 360.0, background=50.0)
    assert 1 <= len(outs) <= 3, f"AMCL moved out {len(outs)} times, at {outs}"
    assert backs and len(backs) >= len(outs) - 1


def test_a_laptop_whose_load_drops_gets_amcl_again():
    engine = make_engine(50.0)
    run(engine, PERIOD, 360.0, background=50.0)
    # The background load ends (the compile is over): AMCL fits, goes out and stays.
    outs, backs, _ = run(engine, 360.0, 480.0, background=5.0, starved=False)
    assert len(outs) == 1 and outs[0] < 370.0 and backs == []
    assert engine.mapping()["amcl"] == "laptop"
    row = next(r for r in engine.learning.rows(480.0)
               if (r.cost.node, r.cost.scale) == ("amcl", "laptop"))
    assert abs(row.cost.live - 30.0) < 1.0 and not row.cost.lower_bound


def test_a_failure_the_estimate_does_not_explain_backs_off_doubling():
    """AMCL takes the model's 36 % on a laptop with 50 % of background (moved onto up to
    90 %), which reads 95 % busy (saturated) with it, its output at its rate, but /scan
    on the laptop at 4 Hz: sent home each time, and each wait at home doubles, T, 2T, 4T, ...,
    as nothing says that a new try would go better."""
    engine = make_engine(50.0)

    def fits_but_slow(t, e):
        out = bed_reports(t, e, 50.0, False)
        if e.mapping()["amcl"] == "laptop":
            out["laptop"] = replace(out["laptop"], cpu_percent=95.0, running={"amcl": 32.4},
                                    topic_rates={**out["laptop"].topic_rates, "/scan": 4.0})
        return out

    outs, backs, notes = drive(engine, fits_but_slow, 400.0)
    waits = [o - b for b, o in zip(backs, outs[1:])]
    assert len(waits) >= 4 and [round(w) for w in waits] == [10, 20, 40, 80, 160][:len(waits)]
    assert len(notes) == len(backs)                        # each back-off logged once
    assert "2nd return in a row" in notes[1] and "not tried again for 20 s" in notes[1]
    assert "/scan" in notes[1] and re.search(r"laptop 9\d % busy", notes[1])


def test_forgetting_a_lower_bound_does_not_cut_a_back_off_short():
    """AR on a 0.9-core laptop (stop 46's live-migration bed): home over capacity at a lower
    bound of 75-83 %, the estimate relaxed toward the model's 12 % back to a fit within about a
    minute, and AR went out again that often however long its back-off said. Here AMCL, with a
    forgetting of 30 s: each wait at home is the back-off its note states or longer, and grows."""
    from anyscale_core.decision_types import LearningParams
    engine = make_engine(50.0, replace(PARAMS, learning=LearningParams(cost_forget_s=30.0)))
    outs, backs, notes = run(engine, PERIOD, 1500.0, background=50.0)
    waits = [o - b for (b, _), o in zip(backs, outs[1:])]
    stated = [float(re.search(r"not tried again for (\d+) s", n).group(1)) for n in notes]
    assert len(waits) >= 4 and all(w >= s for w, s in zip(waits, stated)), (waits, stated)
    assert all(a < b for a, b in zip(waits, waits[1:])), waits
    assert len(outs) <= 8, f"AMCL moved out {len(outs)} times in 25 minutes, at {outs}"


def test_a_return_for_the_link_is_no_failure():
    engine = make_engine(5.0)
    # AMCL out with room; the link goes for 3 s at t = 20 and every 40 s after.
    outs, backs, notes = run(engine, PERIOD, 200.0, background=5.0, starved=False,
                             link=lambda t: t < 20.0 or (t - 20.0) % 40.0 >= 3.0)
    assert len(backs) >= 4 and notes == []
    assert all("link" in why for _, why in backs)
    assert engine.learning.backoff.backoffs == {}


def test_a_slow_rate_on_a_laptop_with_room_is_no_failure():
    """/scan slow on a laptop 35 % busy: the link, not the laptop (the link's rules handle it)."""
    engine = make_engine(5.0)

    def slow_scan(t, e, background, starved, link=True):
        out = bed_reports(t, e, background, starved, link)
        out["laptop"] = replace(out["laptop"], topic_rates={**out["laptop"].topic_rates,
                                                            "/scan": 3.0})
        return out

    backs, notes, t = [], [], PERIOD
    while t < 120.0:
        result = engine.tick(slow_scan(t, engine, 5.0, False), t)
        backs += [t for e in result.events if e.node == "amcl" and e.kind == "migrate_back"]
        notes += result.notes
        t += PERIOD
    assert len(backs) >= 3 and notes == [] and engine.learning.backoff.backoffs == {}


def test_a_stay_that_lasts_resets_the_back_off():
    from anyscale_core.decision_types import LearningParams
    engine = make_engine(50.0, replace(PARAMS, learning=LearningParams(success_s=60.0)))
    _, backs, notes = run(engine, PERIOD, 40.0, background=50.0)
    assert len(backs) == 1 and len(notes) == 1
    # Room again: out, and 60 s there.
    outs, _, notes = run(engine, 40.0, 200.0, background=5.0, starved=False)
    assert len(outs) == 1 and notes == [
        "amcl ran on laptop for 60 s without a return for rate or CPU: its back-off there is "
        "reset"]
    assert engine.learning.backoff.backoffs == {}


def test_with_plan_with_estimates_false_the_allocators_see_the_model():
    from anyscale_core.decision_types import LearningParams
    engine = make_engine(50.0, replace(PARAMS,
                                       learning=LearningParams(plan_with_estimates=False)))
    run(engine, PERIOD, 30.0, background=50.0)
    assert engine.learning.planning(30.0) is engine.ch


def test_a_slow_rate_on_a_laptop_with_room_over_a_link_that_carries_it_is_a_failure():
    """/scan at 4 of 5 Hz on a laptop 70-82 % busy, over 27 Mbit/s (half of 802.11g's nominal, far
    more than what crosses it): not the link's doing, so each return backs off, doubling."""
    engine = make_engine(5.0)

    def slow_scan(t, e):
        out = bed_reports(t, e, 5.0, False, bandwidth=27.0)
        there = {n for n, s in e.mapping().items() if s == "laptop"}
        running = {"ar_recognition": 10.0} if "ar_recognition" in there else {}
        if "amcl" in there:
            running["amcl"] = 58.5
            out["laptop"] = replace(out["laptop"], topic_rates={**out["laptop"].topic_rates,
                                                                "/scan": 4.0})
        busy = 5.0 + 12.0 * ("ar_recognition" in there) + 65.0 * ("amcl" in there)
        out["laptop"] = replace(out["laptop"], cpu_percent=busy, running=running)
        return out

    outs, backs, notes = drive(engine, slow_scan, 200.0)
    waits = [round(o - b) for b, o in zip(backs, outs[1:])]
    assert len(waits) >= 2 and waits == [10, 20, 40, 80][:len(waits)], (outs, backs)
    assert len(notes) == len(backs) and re.search(r"the link at 2\d Mbit/s", notes[0])


def test_a_silence_on_a_laptop_with_room_over_a_link_that_carries_it_is_no_failure():
    """AMCL's instance on the laptop dies with the laptop's agent, 4 s after each move out
    (the shared-laptop bed's agent restart): /amcl_pose falls silent on the robot over
    27 Mbit/s. A silence says nothing of the laptop's room, so nothing backs off."""
    engine = make_engine(5.0)
    out_at = {}

    def dies_there(t, e):
        out = bed_reports(t, e, 5.0, False, bandwidth=27.0)
        if e.mapping()["amcl"] != "laptop":
            out_at.pop("amcl", None)
            return out
        silent = t - out_at.setdefault("amcl", t) - 4.0
        if silent > 0:
            robot = out["robot"]
            out["robot"] = replace(robot, topic_rates={**robot.topic_rates, "/amcl_pose": 0.0},
                                   topic_silence={**robot.topic_silence, "/amcl_pose": silent})
        return out

    outs, backs, notes = drive(engine, dies_there, 120.0)
    assert len(backs) >= 3 and len(outs) >= len(backs), (outs, backs)
    assert notes == [] and engine.learning.backoff.backoffs == {}
