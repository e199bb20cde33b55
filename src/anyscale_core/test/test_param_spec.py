"""Parameters declared once: checked reading, errors that name the parameter, README rows."""
from dataclasses import dataclass

import pytest

from anyscale_core.param_spec import (REQUIRED, Param, ParamError, dataclass_params, declared,
                                      read_all, read_dataclass)


def getter(values):
    return lambda name, default: values.get(name, default)


def test_a_number_within_its_bounds_is_read_and_a_default_used_when_unset():
    p = Param("period_s", 1.0, "decision period", "s", minimum=0.05)
    assert p.read(getter({"~period_s": 2})) == 2.0
    assert p.read(getter({})) == 1.0


@pytest.mark.parametrize("value", [0.01, "fast", float("nan"), float("inf"), True, None, [1]])
def test_a_bad_number_is_refused_naming_the_parameter_and_what_was_expected(value):
    p = Param("period_s", 1.0, "decision period", "s", minimum=0.05)
    with pytest.raises(ParamError, match=r"~period_s: expected a number >= 0.05, got"):
        p.read(getter({"~period_s": value}))


def test_exclusive_minimum_maximum_and_integers():
    rate = Param("rate_hz", 5.0, "rate", "Hz", minimum=0.0, above=True)
    with pytest.raises(ParamError, match="expected a number > 0"):
        rate.check(0.0)
    share = Param("act_at_tolerance", 0.5, "share", maximum=1.0, minimum=0.0)
    with pytest.raises(ParamError, match=">= 0 and <= 1"):
        share.check(1.5)
    count = Param("handover_messages", 3, "messages", kind="int", minimum=1)
    assert count.check(4.0) == 4 and isinstance(count.check(4.0), int)
    with pytest.raises(ParamError, match="an integer >= 1"):
        count.check(2.5)


def test_flags_frames_choices_and_required():
    assert Param("x", False, "a flag").check(True) is True
    with pytest.raises(ParamError, match="true or false"):
        Param("x", False, "a flag").check("false")
    assert Param("f", "map", "frame", kind="frame").check("/map") == "map"
    with pytest.raises(ParamError, match="a tf frame name"):
        Param("f", "map", "frame", kind="frame").check("/")
    with pytest.raises(ParamError, match="one of coverage, schedule"):
        Param("mode", "coverage", "m", kind="choice", choices=("coverage", "schedule")).check("x")
    with pytest.raises(ParamError, match=r"~model: required, not set \(the system model\)"):
        Param("model", REQUIRED, "the system model", kind="str").read(getter({}))


def test_node_seconds():
    p = Param("node_hold_after_loss_s", {}, "holds", "s", kind="node_seconds")
    assert p.check({"amcl": 2}) == {"amcl": 2.0}
    with pytest.raises(ParamError, match="node name: seconds >= 0, got 'amcl': -1"):
        p.check({"amcl": -1})


def test_an_unknown_kind_is_a_programming_error():
    with pytest.raises(ValueError, match="unknown parameter kind"):
        Param("x", 1, "x", kind="complex")


@dataclass(frozen=True)
class Example:
    model: str
    hysteresis_s: float = declared(10.0, "the paper's T", "s", minimum=0.0)
    retries: int = declared(3, "attempts", minimum=1)
    live: bool = declared(True, "use the live figures")
    holds: dict = declared({}, "per node", "s")


def test_a_dataclass_is_read_from_its_declarations():
    params = read_dataclass(Example, getter({"~hysteresis_s": 4, "~retries": 2}), model="m.yaml")
    assert params == Example("m.yaml", 4.0, 2, True, {})
    assert Example("m").hysteresis_s == 10.0      # the one default, in the field
    with pytest.raises(ParamError, match="~retries"):
        read_dataclass(Example, getter({"~retries": 0}), model="m")


def test_table_rows_show_default_unit_and_meaning():
    rows = [p.table_row() for p in dataclass_params(Example)]
    assert rows == ["| `~hysteresis_s` | `10` | s | the paper's T |",
                    "| `~retries` | `3` | - | attempts |",
                    "| `~live` | `true` | - | use the live figures |",
                    "| `~holds` | `{}` | s | per node |"]
    assert read_all(dataclass_params(Example), getter({}))["retries"] == 3


def test_inf_is_a_value_only_where_declared():
    off = Param("pose_rejection_threshold", float("inf"), "off by default", finite=False,
                minimum=0.0)
    assert off.check(float("inf")) == float("inf") and off.check(3) == 3.0
    with pytest.raises(ParamError, match="a number or inf >= 0, got nan"):
        off.check(float("nan"))
    with pytest.raises(ParamError, match="expected a number, got inf"):
        Param("x", 1.0, "finite").check(float("inf"))
