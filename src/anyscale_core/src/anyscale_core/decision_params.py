"""The decision node's parameters, read and checked, and what it starts from (model,
characterisation, allocator): no ROS, so both are tested without a master."""
from dataclasses import dataclass, replace
import os
from typing import List

from .allocators import DEFAULT_ALLOCATOR, DEFAULT_TIME_BUDGET_S, make_allocator
from .characterisation import characterise
from .decision_types import DecisionParams, LearningParams
from .link_forecast import LinkForecastParams
from .link_map import LinkMapParams
from .model_loader import load_model
from .param_spec import REQUIRED, ParamError, dataclass_params, declared, read_dataclass
from .restart_backoff import BackoffParams


@dataclass(frozen=True)
class NodeParams:
    """The decision node's own parameters (the engine's are DecisionParams), each declared
    once (param_spec)."""
    engine: DecisionParams
    model: str = declared(REQUIRED, "system model YAML", "path", kind="str")
    allocator: str = declared(DEFAULT_ALLOCATOR, "paper (Algorithm 1, one iteration a "
                              "period), paper_local or optimal", kind="str")
    period_s: float = declared(1.0, "decision period", "s", minimum=0.05)
    service_timeout_s: float = declared(
        5.0, "timeout of start_node and set_watched_topics (renew_leases: at most ~lease_s)",
        "s", minimum=0.1)
    stop_timeout_s: float = declared(
        20.0, "timeout of a stop_node that waits (the agent's SIGINT 15 s + SIGTERM 2 s)", "s",
        minimum=0.1)
    adopt_wait_s: float = declared(
        5.0, "at start, the wait for every remote scale's first status before adopting", "s",
        minimum=0.0)
    stop_sigint_timeout_s: float = declared(
        0.5, "a stopped old instance gets SIGKILL this long after SIGINT, or once off the "
        "master", "s", minimum=0.0)
    handover_timeout_s: float = declared(
        20.0, "a new instance that has not published by then is stopped; the node stays", "s",
        minimum=0.1)
    handover_messages: int = declared(
        3, "messages the new instance publishes before the old one is stopped", minimum=1)
    control_nice: int = declared(
        0, "the decision node's own nice (needs CAP_SYS_NICE; 0: as started)", "nice",
        minimum=-20, maximum=0)
    learned_costs_out: str = declared(
        "", "where the live cost estimates are written, every 30 s and at exit (empty: not)",
        "path", kind="raw")
    time_budget_s: float = declared(
        DEFAULT_TIME_BUDGET_S, "what a searching allocator (paper_local, optimal) may spend on "
        "a decision (< ~period_s)", "s", minimum=0.0)


def parameter_table() -> List[str]:
    """The README's rows of the decision node's parameters, in declaration order."""
    return [p.table_row() for cls in (NodeParams, DecisionParams, BackoffParams, LearningParams,
                                      LinkForecastParams, LinkMapParams)
            for p in dataclass_params(cls)]


def read_params(get) -> NodeParams:
    """The private parameters, checked; ParamError names the bad one. `get` is
    rospy.get_param's signature (name, default)."""
    link_forecast = read_dataclass(LinkForecastParams, get,
                                   map=read_dataclass(LinkMapParams, get))
    engine = read_dataclass(DecisionParams, get, restart=read_dataclass(BackoffParams, get),
                            learning=read_dataclass(LearningParams, get),
                            link_forecast=link_forecast)
    if engine.bandwidth_stay_margin > engine.bandwidth_margin:
        raise ParamError(f"~bandwidth_stay_margin ({engine.bandwidth_stay_margin:g}) must not "
                         f"exceed ~bandwidth_margin ({engine.bandwidth_margin:g}): a node would "
                         f"come back as soon as it moved out")
    params = read_dataclass(NodeParams, get, engine=engine)
    if params.time_budget_s >= params.period_s:
        raise ParamError(f"~time_budget_s ({params.time_budget_s:g}) must be less than ~period_s "
                         f"({params.period_s:g}): a decision would delay the next period")
    return replace(params, learned_costs_out=learned_costs_out(params.learned_costs_out))


def learned_costs_out(value) -> str:
    """~learned_costs_out as an absolute path ("" = off); refused where it cannot be written,
    at start-up rather than at shutdown, when the run's learning would be lost."""
    if not isinstance(value, str):
        raise ParamError(f"~learned_costs_out: expected a file path, got {value!r}")
    if not value:
        return ""
    path = os.path.abspath(os.path.expanduser(value))
    directory = os.path.dirname(path)
    if os.path.isdir(path):
        raise ParamError(f"~learned_costs_out: {value} is a directory; give a file path")
    if not os.path.isdir(directory) or not os.access(directory, os.W_OK):
        raise ParamError(f"~learned_costs_out: {value}: directory {directory} does not exist "
                         f"or is not writable")
    return path


def prepare_decision(model_path: str, allocator_name: str,
                     engine: DecisionParams = DecisionParams(),
                     time_budget_s: float = DEFAULT_TIME_BUDGET_S):
    """The model, its characterisation and the allocator the decision node starts from, with no
    ROS involved (tested by fuzzing); raises only ModelError or ParamError, which main() turns
    into one FATAL line. `engine`'s node names are checked against the model."""
    model = load_model(model_path)
    names = {n.name for n in model.nodes}
    for param, given in (("node_hold_after_loss_s", engine.node_hold_after_loss_s),
                         ("node_link_forecast_move_cost_s", engine.link_forecast.node_move_cost_s),
                         ("node_link_forecast_home_lead_s", engine.link_forecast.node_home_lead_s)):
        unknown = sorted(set(given) - names)
        if unknown:
            raise ParamError(f"~{param}: {', '.join(unknown)}: no such node in {model_path}")
    try:
        allocator = make_allocator(allocator_name, time_budget_s)
    except ValueError as e:
        raise ParamError(f"~allocator: {e}") from None
    return model, characterise(model), allocator


if __name__ == "__main__":
    # The README's rows: /usr/bin/python3 -m anyscale_core.decision_params
    print("\n".join(parameter_table()))
