"""The decision node's per-node hold after a link loss as a parameter: read, checked, and checked
against the model (no ROS)."""
import pytest

from anyscale_core.decision_params import ParamError, prepare_decision, read_params
from anyscale_core.decision_types import DecisionParams
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
