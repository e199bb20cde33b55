"""The decision node's parameters (the hold after a link loss, the learning and link forecast
parameters, the allocator's time budget, every default declared once): read, checked, and the
node names checked against the model (no ROS)."""
import os

import pytest

from anyscale_core.decision_params import (ParamError, parameter_table, prepare_decision,
                                           read_params)
from anyscale_core.decision_types import DecisionParams, LearningParams
from core_test_data import TESTBED


def params(**values):
    return lambda name, default: values.get(name.lstrip("~"), default)


def test_a_node_named_gets_its_own_hold_after_a_loss_the_others_the_common_one():
    p = read_params(params(model="/m.yaml", hold_after_loss_s=20,
                           node_hold_after_loss_s={"amcl": 0}))
    assert p.engine.hold_after_loss("amcl") == 0.0
    assert p.engine.hold_after_loss("ar_recognition") == 20.0
    assert p.engine.longest_hold_after_loss() == 20.0
    assert DecisionParams(node_hold_after_loss_s={"amcl": 30.0}).longest_hold_after_loss() == 30
    assert read_params(params(model="/m.yaml")).engine.node_hold_after_loss_s == {}


@pytest.mark.parametrize("bad", [[("amcl", 0)], "amcl: 0", {"amcl": -1}, {"amcl": "long"},
                                 {"amcl": float("nan")}, {"amcl": True}, {3: 1.0}])
def test_a_malformed_node_hold_is_refused_by_name(bad):
    with pytest.raises(ParamError, match="~node_hold_after_loss_s"):
        read_params(params(model="/m.yaml", node_hold_after_loss_s=bad))


def test_a_node_hold_for_a_node_the_model_lacks_is_refused_naming_it():
    with pytest.raises(ParamError, match="~node_hold_after_loss_s: amlc: no such node"):
        prepare_decision(TESTBED, "paper", DecisionParams(node_hold_after_loss_s={"amlc": 0.0}))
    prepare_decision(TESTBED, "paper", DecisionParams(node_hold_after_loss_s={"amcl": 0.0}))


def test_every_parameter_has_its_one_default_and_bad_values_are_named():
    p = read_params(params(model="/m.yaml"))
    assert p.engine == DecisionParams()          # the declarations' defaults, nowhere else
    assert (p.allocator, p.period_s, p.handover_messages, p.control_nice) == ("paper", 1.0, 3, 0)
    for name, bad, message in [("act_at_tolerance", 1.5, "<= 1"), ("lease_s", 0.01, ">= 0.1"),
                               ("control_nice", 5, "<= 0"), ("handover_messages", 0, ">= 1"),
                               ("restart_delay_s", -1, ">= 0"), ("period_s", "fast", "number")]:
        with pytest.raises(ParamError, match=f"~{name}: expected .*{message}"):
            read_params(params(model="/m.yaml", **{name: bad}))
    with pytest.raises(ParamError, match="~model: required"):
        read_params(params())
    with pytest.raises(ParamError, match="~bandwidth_stay_margin .* must not exceed"):
        read_params(params(model="/m.yaml", bandwidth_stay_margin=0.5))


def test_the_readme_table_is_the_declarations():
    readme = os.path.join(os.path.dirname(__file__), "..", "README.md")
    text = open(readme).read()
    section = text[text.index("### decision_node"):]
    section = section[:section.index("\n### ", 1)]
    table = section[section.index("| parameter | default |"):].split("\n\n")[0]
    documented = {line for line in table.splitlines() if line.startswith("| `~")}
    declared = set(parameter_table())
    assert declared - documented == set(), "declared, but not in the README as declared"
    extra = {row.split("|")[1].strip() for row in documented - declared}
    assert extra == {"`~diagnostic_period`", "`~restart_state`"}, \
        "in the README, but not declared"


def test_learning_parameters_have_their_defaults_and_are_read():
    learning = read_params(params(model="/m.yaml")).engine.learning
    assert learning == LearningParams(True, 5.0, 300.0, 300.0, 60.0, 10.0)
    p = read_params(params(model="/m.yaml", learn_costs=False, cost_smoothing_s=2,
                           cost_forget_s=0, placement_backoff_max_s=120,
                           placement_success_s=30, placement_retry_room=20))
    assert p.engine.learning == LearningParams(False, 2.0, 0.0, 120.0, 30.0, 20.0)
    assert p.learned_costs_out == ""


@pytest.mark.parametrize("name,bad,match", [
    ("learn_costs", "yes", "~learn_costs: expected true or false"),
    ("cost_smoothing_s", -1, "~cost_smoothing_s: expected a number >= 0"),
    ("cost_forget_s", "long", "~cost_forget_s: expected a number"),
    ("placement_backoff_max_s", float("inf"), "~placement_backoff_max_s"),
    ("placement_success_s", -5, "~placement_success_s"),
    ("placement_retry_room", 150, "~placement_retry_room: expected a number >= 0 and <= 100"),
    ("learned_costs_out", 3, "~learned_costs_out: expected a file path"),
    ("learned_costs_out", "/no/such/dir/costs.yaml", "directory /no/such/dir does not exist"),
])
def test_a_bad_learning_parameter_is_refused_by_name(name, bad, match):
    with pytest.raises(ParamError, match=match):
        read_params(params(model="/m.yaml", **{name: bad}))


def test_learned_costs_out_becomes_an_absolute_path(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert read_params(params(model="/m.yaml", learned_costs_out="costs.yaml")) \
        .learned_costs_out == str(tmp_path / "costs.yaml")
    with pytest.raises(ParamError, match="is a directory"):
        read_params(params(model="/m.yaml", learned_costs_out=str(tmp_path)))


def test_the_link_forecast_parameters_have_their_defaults_and_are_read():
    default = read_params(params(model="/m.yaml")).engine.link_forecast
    assert default == DecisionParams().link_forecast
    assert (default.enabled, default.horizon_s, default.map_file, default.path_topic) == \
        (True, 20.0, "", "")
    p = read_params(params(model="/m.yaml", link_forecast=False, link_forecast_horizon_s=30,
                           node_link_forecast_move_cost_s={"amcl": 2.5},
                           link_map_resolution_m=0.5, link_map_file="/tmp/m.yaml",
                           path_topic="/navigation/global_plan")).engine.link_forecast
    assert (p.enabled, p.horizon_s, p.move_cost("amcl"), p.move_cost("ar_recognition")) == \
        (False, 30.0, 2.5, 3.0)
    assert (p.map.resolution_m, p.map_file, p.path_topic) == \
        (0.5, "/tmp/m.yaml", "/navigation/global_plan")


@pytest.mark.parametrize("name, bad, says", [
    ("link_forecast", "yes", "~link_forecast: expected true or false"),
    ("link_forecast_horizon_s", 0.5, "~link_forecast_horizon_s: expected a number >= 1"),
    ("link_map_quantile", 1.5, "~link_map_quantile: expected a number >= 0 and <= 1"),
    ("link_map_resolution_m", 0, "~link_map_resolution_m"),
    ("link_map_file", 3, "~link_map_file: expected a string"),
    ("node_link_forecast_home_lead_s", {"amcl": -1}, "~node_link_forecast_home_lead_s"),
    ("map_frame", "", "~map_frame"),
])
def test_a_bad_link_forecast_parameter_is_refused_by_name(name, bad, says):
    with pytest.raises(ParamError, match=says):
        read_params(params(model="/m.yaml", **{name: bad}))


def test_a_link_forecast_figure_for_a_node_the_model_lacks_is_refused_naming_it():
    from anyscale_core.link_forecast import LinkForecastParams
    with pytest.raises(ParamError, match="~node_link_forecast_home_lead_s: amlc: no such node"):
        prepare_decision(TESTBED, "paper", DecisionParams(
            link_forecast=LinkForecastParams(node_home_lead_s={"amlc": 2.0})))


def test_the_time_budget_reaches_the_allocator_and_stays_within_the_period():
    p = read_params(params(model="/m.yaml"))
    assert p.time_budget_s == 0.1
    p = read_params(params(model="/m.yaml", allocator="paper_local", time_budget_s=0.05))
    _, _, allocator = prepare_decision(TESTBED, p.allocator, p.engine, p.time_budget_s)
    assert allocator.time_budget_s == 0.05
    with pytest.raises(ParamError, match="~time_budget_s .1. must be less than ~period_s .1."):
        read_params(params(model="/m.yaml", time_budget_s=1.0))
    with pytest.raises(ParamError, match="~time_budget_s"):
        read_params(params(model="/m.yaml", time_budget_s=-0.1))
