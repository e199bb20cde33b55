"""The decision engine and the connections' tolerance: a slow connection moves its node back
before the tolerance runs out, so does a silent one, a moved node gets a start-up grace, and a
silent topic's rate decays with its silence."""
from dataclasses import replace
import math

import pytest

from anyscale_core.allocators import make_allocator
from anyscale_core.decision_engine import DecisionEngine
from anyscale_core.decision_types import DecisionParams, effective_rate

from decision_reports import PAPER, remote, reports


def test_slow_connection_moves_its_node_back_before_the_tolerance_runs_out(engine):
    engine.tick(reports(1.0), 1.0)
    assert remote(engine) == ["amcl"]
    # /amcl_pose (AMCL -> EKF, freq_min 2 Hz, tolerance 2 s) drops to 1 Hz at t = 2.
    engine.tick(reports(2.0, rates={"/amcl_pose": 1.0}, bandwidth=3.0), 2.0)
    assert remote(engine) == ["amcl"]                                  # 0 s of 2 s spent
    result = engine.tick(reports(3.0, rates={"/amcl_pose": 1.0}, bandwidth=3.0), 3.0)
    assert result.violating == ["amcl"]                               # half the tolerance
    assert [(e.kind, e.node) for e in result.events] == [("migrate_back", "amcl")]


def test_a_silence_over_its_share_of_the_tolerance_brings_the_node_home(engine):
    engine.tick(reports(1.0), 1.0)
    assert remote(engine) == ["amcl"]
    # /amcl_pose (tolerance 2 s) silent 0.6 s, its window rate still 5 Hz: 30 % of 2 s.
    # (3 Mbit/s: too little for AR's camera stream, so only AMCL is out.)
    result = engine.tick(reports(2.0, bandwidth=3.0, silence={"/amcl_pose": 0.6}), 2.0)
    assert result.violating == [] and remote(engine) == ["amcl"]
    # 0.7 s: the 35 % of act_at_silence, whatever the window's rate still says.
    result = engine.tick(reports(2.2, bandwidth=3.0, silence={"/amcl_pose": 0.7}), 2.2)
    assert result.violating == ["amcl"]
    [event] = [e for e in result.events if e.node == "amcl"]
    assert event.kind == "migrate_back" and "silent 0.70 s on robot" in event.reason, event


def test_a_silent_input_on_the_remote_scale_brings_the_node_home(engine):
    engine.tick(reports(1.0), 1.0)
    # /scan into AMCL, as received on the laptop where AMCL runs.
    laptop_silent = reports(2.0)
    laptop_silent["laptop"] = replace(laptop_silent["laptop"],
                                      topic_silence={"/scan": 0.8})
    assert engine.silence_alarm(laptop_silent["laptop"], 2.0)
    assert not engine.silence_alarm(laptop_silent["robot"], 2.0)   # /scan is not judged there
    result = engine.tick(laptop_silent, 2.0)
    assert remote(engine) == [] and "/scan" in result.events[0].reason


def test_silence_of_a_node_at_home_raises_no_alarm(testbed_ch):
    e = DecisionEngine(testbed_ch, make_allocator("paper"), PAPER)
    e.adopt_or_start(reports(0.0), 0.0)
    assert remote(e) == []
    silent = reports(1.0, silence={"/amcl_pose": 5.0, "/scan": 5.0})
    assert not any(e.silence_alarm(r, 1.0) for r in silent.values())


def test_act_at_silence_0_judges_rates_only(testbed_ch):
    e = DecisionEngine(testbed_ch, make_allocator("paper"), replace(PAPER, act_at_silence=0.0))
    e.adopt_or_start(reports(0.0), 0.0)
    e.tick(reports(1.0), 1.0)
    assert remote(e) == ["amcl"]
    silent = reports(2.0, bandwidth=3.0, silence={"/amcl_pose": 1.9})
    assert not e.silence_alarm(silent["robot"], 2.0)
    assert e.tick(silent, 2.0).violating == [] and remote(e) == ["amcl"]


def test_moved_node_gets_a_start_up_grace(testbed_ch):
    e = DecisionEngine(testbed_ch, make_allocator("paper"),
                       DecisionParams(bandwidth_hold_s=0.0, startup_grace_s=5.0))
    e.adopt_or_start(reports(0.0), 0.0)
    e.tick(reports(6.0), 6.0)                                          # AMCL moves out
    silent = {"/amcl_pose": 0.0}
    for t in (7.0, 9.0, 10.9):
        assert "amcl" in remote(e) and e.tick(reports(t, rates=silent), t).violating == []
    # After the grace the tolerance starts: half of its 2 s are spent at t = 13.
    assert e.tick(reports(12.0, rates=silent), 12.0).violating == []
    assert e.tick(reports(13.0, rates=silent), 13.0).violating == ["amcl"]


def test_a_moved_node_that_published_is_judged_by_its_silence_inside_the_grace(testbed_ch):
    """Evaluation run (office floor): AMCL's laptop instance published for 1.4 s, then lost
    its lease behind a link AR's camera had filled; /amcl_pose stayed silent 5.9 s (Δ 2 s)
    because the 8 s grace judged nothing."""
    e = DecisionEngine(testbed_ch, make_allocator("paper"),
                       DecisionParams(bandwidth_hold_s=0.0, startup_grace_s=8.0))
    e.adopt_or_start(reports(0.0), 0.0)
    e.tick(reports(10.0, bandwidth=3.0), 10.0)                        # AMCL moves out
    assert remote(e) == ["amcl"]
    silent = reports(12.0, bandwidth=3.0, silence={"/amcl_pose": 0.8})
    # Starting (the old instance still publishes until the new one has): no alarm.
    assert not e.silence_alarm(silent["robot"], 12.0)
    assert e.tick(silent, 12.0).violating == [] and remote(e) == ["amcl"]
    e.output_seen("amcl", 12.5)
    # A topic an agent has not heard yet (it may have begun counting just now) is no silence.
    unheard = reports(12.6, bandwidth=3.0, silence={"/amcl_pose": math.inf})
    assert not e.silence_alarm(unheard["robot"], 12.6)
    assert e.tick(unheard, 12.6).violating == []
    silent = reports(13.0, bandwidth=3.0, silence={"/amcl_pose": 0.8})
    assert e.silence_alarm(silent["robot"], 13.0)
    result = e.tick(silent, 13.0)
    assert result.violating == ["amcl"] and remote(e) == []
    assert "silent 0.80 s on robot" in result.events[0].reason
    # Rates are still not judged inside the grace: the agents' windows are filling.
    e.tick(reports(30.0, bandwidth=3.0), 30.0)                        # out again
    assert remote(e) == ["amcl"]
    e.output_seen("amcl", 30.5)
    assert e.tick(reports(31.0, bandwidth=3.0, rates={"/amcl_pose": 0.0}), 31.0).violating == []


@pytest.mark.parametrize("rate,age,expected", [(10.0, 0.05, 10.0), (10.0, 2.0, 0.5),
                                               (5.0, math.inf, 0.0), (5.0, 0.0, 5.0)])
def test_effective_rate_follows_silence(rate, age, expected):
    assert effective_rate(rate, age) == expected


def test_the_return_reason_names_the_slow_connection(testbed_ch):
    e = DecisionEngine(testbed_ch, make_allocator("paper"),
                       DecisionParams(bandwidth_hold_s=0.0, startup_grace_s=0.0))
    e.adopt_or_start(reports(0.0), 0.0)
    e.tick(reports(1.0), 1.0)
    e.tick(reports(2.0), 2.0)
    assert "amcl" in remote(e)
    slow = {"/scan": 1.0}
    reasons = [ev.reason for t in (3.0, 4.0, 5.0) for ev in e.tick(reports(t, rates=slow), t).events
               if ev.node == "amcl"]
    assert reasons and "/scan" in reasons[0] and "1.0 Hz on laptop" in reasons[0], reasons
