"""The decision node's parameters, read and checked, and what it starts from (model,
characterisation, allocator): no ROS, so both are tested without a master."""
import math
from dataclasses import dataclass

from .allocators import make_allocator
from .characterisation import characterise
from .decision_types import DecisionParams
from .model_loader import load_model
from .restart_backoff import BackoffParams


class ParamError(ValueError):
    """A private parameter of the decision node is missing or out of range; names it."""


@dataclass(frozen=True)
class NodeParams:
    model: str
    allocator: str
    period_s: float
    engine: DecisionParams
    service_timeout_s: float
    stop_timeout_s: float
    adopt_wait_s: float
    stop_sigint_timeout_s: float
    handover_timeout_s: float
    handover_messages: int
    control_nice: int


def read_params(get) -> NodeParams:
    """The private parameters, checked; ParamError names the bad one. `get` is
    rospy.get_param's signature (name, default)."""
    def number(name, default, minimum=0.0):
        value = get("~" + name, default)
        try:
            value = float(value)
        except (TypeError, ValueError):
            raise ParamError(f"~{name}: expected a number, got {value!r}") from None
        if not math.isfinite(value) or value < minimum:
            raise ParamError(f"~{name}: expected a finite number >= {minimum:g}, got {value!r}")
        return value

    def node_seconds(name):
        """A dict of node name -> seconds (>= 0); {} if unset."""
        value = get("~" + name, {})
        if not isinstance(value, dict):
            raise ParamError(f"~{name}: expected a dict of node name: seconds, got {value!r}")
        out = {}
        for node, seconds in value.items():
            if not isinstance(node, str) or isinstance(seconds, bool) \
                    or not isinstance(seconds, (int, float)) \
                    or not (math.isfinite(seconds) and seconds >= 0):
                raise ParamError(f"~{name}: expected node name: seconds >= 0, got "
                                 f"{node!r}: {seconds!r}")
            out[node] = float(seconds)
        return out

    model = get("~model", None)
    if not isinstance(model, str) or not model:
        raise ParamError("~model: required (path of the system model YAML)")
    engine = DecisionParams(hysteresis_s=number("hysteresis_s", 10.0),
                            lease_s=number("lease_s", 3.0, 0.1),
                            status_timeout_s=number("status_timeout_s", 1.5, 0.1),
                            act_at_tolerance=number("act_at_tolerance", 0.5),
                            act_at_silence=number("act_at_silence", 0.35),
                            startup_grace_s=number("startup_grace_s", 5.0),
                            cpu_smoothing_s=number("cpu_smoothing_s", 2.0),
                            restart=BackoffParams(number("restart_delay_s", 1.0),
                                                  number("restart_delay_max_s", 30.0),
                                                  number("restart_reset_s", 30.0)),
                            bandwidth_hold_s=number("bandwidth_hold_s", 5.0),
                            bandwidth_margin=number("bandwidth_margin", 0.3),
                            bandwidth_stay_margin=number("bandwidth_stay_margin", 0.15),
                            weak_link_mbps=number("weak_link_mbps", 0.0),
                            hold_after_loss_s=number("hold_after_loss_s", 0.0),
                            node_hold_after_loss_s=node_seconds("node_hold_after_loss_s"))
    for name in ("act_at_tolerance", "act_at_silence"):
        if getattr(engine, name) > 1.0:
            raise ParamError(f"~{name}: expected 0..1, got {getattr(engine, name):g}")
    if engine.bandwidth_stay_margin > engine.bandwidth_margin:
        raise ParamError(f"~bandwidth_stay_margin ({engine.bandwidth_stay_margin:g}) must not "
                         f"exceed ~bandwidth_margin ({engine.bandwidth_margin:g}): a node would "
                         f"come back as soon as it moved out")
    control_nice = get("~control_nice", 0)
    if not isinstance(control_nice, int) or isinstance(control_nice, bool) \
            or not -20 <= control_nice <= 0:
        raise ParamError(f"~control_nice: expected a nice value from -20 to 0 (0: the priority "
                         f"it was started at), got {control_nice!r}")
    return NodeParams(model, str(get("~allocator", "paper")), number("period_s", 1.0, 0.05),
                      engine, number("service_timeout_s", 5.0, 0.1),
                      number("stop_timeout_s", 20.0, 0.1), number("adopt_wait_s", 5.0),
                      number("stop_sigint_timeout_s", 0.5),
                      number("handover_timeout_s", 20.0, 0.1),
                      int(number("handover_messages", 3, 1)), control_nice)


def prepare_decision(model_path: str, allocator_name: str,
                     engine: DecisionParams = DecisionParams()):
    """The model, its characterisation and the allocator the decision node starts from, with no
    ROS involved (tested by fuzzing); raises only ModelError or ParamError, which main() turns
    into one FATAL line. `engine`'s node names are checked against the model."""
    model = load_model(model_path)
    unknown = sorted(set(engine.node_hold_after_loss_s) - {n.name for n in model.nodes})
    if unknown:
        raise ParamError(f"~node_hold_after_loss_s: {', '.join(unknown)}: no such node in "
                         f"{model_path}")
    try:
        allocator = make_allocator(allocator_name)
    except ValueError as e:
        raise ParamError(f"~allocator: {e}") from None
    return model, characterise(model), allocator
