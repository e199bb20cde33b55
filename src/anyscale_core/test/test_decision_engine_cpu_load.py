"""The decision engine and the scales' CPU load: the background load leaves out the model's
nodes and the warm standbys importing, and a one-report burst moves nothing back where a lasting
load does."""
import dataclasses

import pytest

from anyscale_core.allocators import make_allocator
from anyscale_core.decision_engine import DecisionEngine
from anyscale_core.decision_types import DecisionParams

from decision_reports import remote, reports


def test_background_load_excludes_the_models_nodes(testbed_ch):
    e = DecisionEngine(testbed_ch, make_allocator("paper"),
                       DecisionParams(bandwidth_hold_s=0.0, cpu_smoothing_s=0.0))
    state = e.dynamic_state(reports(1.0, laptop_load=50.0, laptop_running=("amcl",)), 1.0)
    assert state.scale_load["laptop"] == pytest.approx(50.0 - 10.0 / 4.0)


def test_warm_standbys_importing_are_no_background_load(testbed_ch):
    e = DecisionEngine(testbed_ch, make_allocator("paper"),
                       DecisionParams(bandwidth_hold_s=0.0, cpu_smoothing_s=0.0))
    busy = reports(1.0, laptop_load=80.0)
    busy["laptop"] = dataclasses.replace(busy["laptop"], standby_cpu=300.0)   # 3 of 4 cores
    assert e.dynamic_state(busy, 1.0).scale_load["laptop"] == pytest.approx(80.0 - 75.0)


def test_a_cpu_burst_of_one_report_moves_nothing_back_but_a_lasting_load_does(engine):
    for t in (1.0, 2.0):
        engine.tick(reports(t), t)
    assert remote(engine) == ["amcl", "ar_recognition"]
    # One 0.2 s sample at 100 %: a node starting or stopping there, not a lasting load.
    engine.tick(reports(2.2, laptop_load=100.0), 2.2)
    engine.tick(reports(2.4), 2.4)
    assert remote(engine) == ["amcl", "ar_recognition"]
    t = 2.4
    while remote(engine) and t < 20.0:
        t += 0.2
        engine.tick(reports(t, laptop_load=100.0), t)
    assert remote(engine) == [] and t < 2.4 + 3 * DecisionParams().cpu_smoothing_s
