"""Constraints: bandwidth of crossing connections, scale CPU, links; the frequency/tolerance
tracker; state files."""
import math

import pytest

from anyscale_core.constraints import (DynamicState, FrequencyToleranceTracker, is_feasible,
                                       parse_state, required_bandwidth, scale_cpu, violations)
from anyscale_core.model import ModelError


def _with(ch, **placement):
    assign = ch.initial_mapping()
    for node, scale in placement.items():
        assign[ch.node_index(node)] = ch.scale_index(scale)
    return assign


def test_bandwidth_counts_only_crossing_connections(testbed_ch):
    assert required_bandwidth(testbed_ch, testbed_ch.initial_mapping()) == 0
    # AMCL away: /scan in (0.2) and /amcl_pose out (0.02) cross the link.
    assert required_bandwidth(testbed_ch, _with(testbed_ch, amcl="laptop")) == pytest.approx(0.22)
    both = _with(testbed_ch, amcl="laptop", ar_recognition="laptop")
    assert required_bandwidth(testbed_ch, both) == pytest.approx(0.22 + 6.05)


def test_scale_cpu_adds_background_load(testbed_ch):
    assign = _with(testbed_ch, amcl="laptop")
    cpu = scale_cpu(testbed_ch, assign, DynamicState(54, {"laptop": 30}).load_vector(testbed_ch))
    assert cpu[testbed_ch.scale_index("laptop")] == pytest.approx(30 + 36)


def test_violations_name_what_breaks(testbed_ch):
    both = _with(testbed_ch, amcl="laptop", ar_recognition="laptop")
    assert is_feasible(testbed_ch, both, DynamicState(54))
    kinds = {v.kind for v in violations(testbed_ch, both, DynamicState(
        2.0, {"laptop": 70}, {"laptop": False}))}
    assert kinds == {"bandwidth", "cpu", "link"}
    # The master is exempt from the CPU limit: everything can always come back.
    assert is_feasible(testbed_ch, testbed_ch.initial_mapping(), DynamicState(0, {"robot": 100}))


def test_critical_node_off_master_is_a_placement_violation(testbed_ch):
    assign = _with(testbed_ch, ekf="laptop")
    assert [v.kind for v in violations(testbed_ch, assign, DynamicState(54))] == ["placement"]


def test_tracker_violates_after_tolerance():
    tr = FrequencyToleranceTracker(freq_min=2.0, tolerance_s=2.0)
    tr.update(0.0, 5.0)
    assert not tr.violated(0.0) and tr.below_for(0.0) == 0.0
    tr.update(1.0, 1.0)             # below from t=1
    assert tr.below_for(2.5) == pytest.approx(1.5)
    assert tr.used_fraction(2.0) == pytest.approx(0.5)
    assert not tr.violated(3.0)     # exactly the tolerance: not yet longer than it
    assert tr.violated(3.1)
    tr.update(3.2, 2.0)             # back at freq_min: recovered
    assert not tr.violated(3.2) and tr.used_fraction(3.2) == 0.0


def test_tracker_nan_rate_counts_as_silence():
    tr = FrequencyToleranceTracker(1.0, 1.0)
    tr.update(0.0, math.nan)
    assert tr.below_for(0.5) == 0.5


def test_tracker_zero_tolerance_violates_at_once():
    tr = FrequencyToleranceTracker(10.0, 0.0)
    tr.update(0.0, 9.9)
    assert tr.violated(0.0) and tr.used_fraction(0.0) == 1.0


def test_tracker_rejects_time_going_back():
    tr = FrequencyToleranceTracker(1.0, 1.0)
    tr.update(2.0, 1.0)
    with pytest.raises(ValueError):
        tr.update(1.0, 1.0)


def test_state_defaults_and_values(testbed):
    st = parse_state({"bandwidth_mbps": 4, "scale_load": {"laptop": 20},
                      "link_up": {"laptop": False}}, testbed, "s.yaml")
    assert st.bandwidth_mbps == 4 and st.scale_load == {"laptop": 20.0}
    assert st.link_up == {"laptop": False}
    assert parse_state(None, testbed).bandwidth_mbps == 54


@pytest.mark.parametrize("data,words", [
    ({"bandwidth_mbps": -1}, "s.yaml: bandwidth_mbps: expected a number >= 0"),
    ({"scale_load": {"server": 3}}, "s.yaml: scale_load.server: unknown scale 'server'"),
    ({"scale_load": {"laptop": 130}}, "s.yaml: scale_load.laptop: expected a number from 0"),
    ({"link_up": {"laptop": "yes"}}, "s.yaml: link_up.laptop: expected true or false"),
    ({"link_up": {"robot": True}}, "s.yaml: link_up.robot: the master scale has no link"),
    ({"bandwith_mbps": 3}, "s.yaml: bandwith_mbps: unknown key"),
    ([1], "s.yaml: expected a mapping"),
])
def test_bad_state_names_file_and_key(testbed, data, words):
    with pytest.raises(ModelError) as err:
        parse_state(data, testbed, "s.yaml")
    assert str(err.value).startswith(words)
