"""A system model that still holds TODOs where `anyscale profile` and `anyscale thresholds` are to
fill in numbers: loaded and validated like any model, with a neutral stand-in at each TODO, and
the list of keys that held one.

`anyscale model draft` writes `TODO` at every value a human (or a measurement) must supply. The
characterisation commands run on such a draft: profile measures `cpu_usage` and `memory_mb`,
thresholds a connection's `freq_min`, `freq_opt` and `tolerance`. Requiring every TODO filled
first would ask the user to type in the numbers the commands exist to measure. So a TODO is
accepted at exactly the numeric keys listed below; anywhere else (a launch package, a node
name) the loader's own error stands. The stand-ins are chosen so that they constrain nothing:
cpu 0 %, memory 0 MB, a scale of ample memory, an unknown tolerance taken as non-critical (the
node may then be profiled on a scale it will never run on: extra work, never a wrong value).
Nothing here talks to ROS.
"""
import copy
from dataclasses import dataclass
from typing import Any, FrozenSet, Mapping, Tuple

from .model import SystemModel
from .model_draft import TODO
from .model_loader import parse_model, read_yaml

# Numeric keys a TODO may stand at, and the stand-in used while it does.
SCALE_STAND_INS = {"cpu_ghz": 1.0, "cores": 1, "memory_mb": 1e12, "alpha": 1.0}
NETWORK_STAND_INS = {"max_bandwidth_mbps": 1.0}
NODE_STAND_INS = {"memory_mb": 0.0}
CPU_USAGE_STAND_IN = 0.0
# A TODO tolerance stands in as > 0: unknown is treated as migratable, see the module docstring.
CONNECTION_STAND_INS = {"tolerance": 1.0, "bandwidth_mbps": 0.0}
TINY_RATE = 1e-9   # freq_min > 0 is required; freq_opt >= freq_min


@dataclass(frozen=True)
class ModelWithTodos:
    model: SystemModel
    todos: FrozenSet[str]    # key paths that held TODO, e.g. "nodes.amcl.cpu_usage.laptop"


def load_model_with_todos(path: str) -> ModelWithTodos:
    return parse_model_with_todos(read_yaml(path), path)


def _is_todo(value: Any) -> bool:
    return isinstance(value, str) and value.strip() == TODO


def _stand_in(item: dict, stand_ins: Mapping[str, Any], prefix: str, todos: set):
    """Each key of `stand_ins` that holds a TODO in `item` gets its stand-in, and its key path
    (`prefix.key`) goes into `todos`."""
    for key, stand_in in stand_ins.items():
        if _is_todo(item.get(key)):
            item[key] = stand_in
            todos.add(f"{prefix}.{key}")


def parse_model_with_todos(data: Any, source: str = "<model>") -> ModelWithTodos:
    """The model with stand-ins at the TODOs it may hold; ModelError as parse_model raises it
    for everything else (a TODO elsewhere included)."""
    tree = copy.deepcopy(data)
    todos = set()
    if not isinstance(tree, dict):
        return ModelWithTodos(parse_model(tree, source), frozenset())
    for scale in _items(tree.get("scales")):
        _stand_in(scale, SCALE_STAND_INS, f"scales.{scale.get('name')}", todos)
    network = tree.get("network")
    if isinstance(network, dict):
        _stand_in(network, {**NETWORK_STAND_INS, "technology": "unknown"}, "network", todos)
    for node in _items(tree.get("nodes")):
        name = node.get("name")
        _stand_in(node, NODE_STAND_INS, f"nodes.{name}", todos)
        usage = node.get("cpu_usage")
        if isinstance(usage, dict):
            _stand_in(usage, dict.fromkeys(usage, CPU_USAGE_STAND_IN), f"nodes.{name}.cpu_usage",
                      todos)
        if _is_todo(node.get("pinned")):
            # The draft offers `pinned: TODO` on nodes that only publish: not decided = not pinned.
            del node["pinned"]
            todos.add(f"nodes.{name}.pinned")
    for conn in _items(tree.get("connections")):
        key = connection_key(conn.get("publisher"), conn.get("subscriber"), conn.get("topic"))
        _stand_in(conn, {**CONNECTION_STAND_INS, "freq_min": TINY_RATE}, key, todos)
        # After freq_min: a TODO freq_opt stands in as freq_min (freq_opt >= freq_min).
        _stand_in(conn, {"freq_opt": _number_or(conn.get("freq_min"), TINY_RATE)}, key, todos)
    return ModelWithTodos(parse_model(tree, source), frozenset(todos))


def connection_key(publisher: Any, subscriber: Any, topic: Any) -> str:
    return f"connections.{publisher}:{subscriber}:{topic}"


def _items(value: Any):
    return [v for v in value if isinstance(v, dict)] if isinstance(value, list) else []


def _number_or(value: Any, default: float) -> float:
    return value if isinstance(value, (int, float)) and not isinstance(value, bool) else default


def home_scale(model: SystemModel, node: str) -> str:
    """Where `node` starts (paper IV): its pinned scale, else the master."""
    return model.node(node).pinned or model.master.name


def home_mapping(model: SystemModel) -> Mapping[str, str]:
    return {n.name: home_scale(model, n.name) for n in model.nodes}


def parse_connection_spec(model: SystemModel, spec: str) -> Tuple[str, str, str]:
    """PUB:SUB:TOPIC of a connection in the model; ModelError naming the known ones otherwise."""
    from .model import ModelError
    parts = spec.split(":")
    if len(parts) != 3 or not all(parts):
        raise ModelError("--connection", "", f"expected PUBLISHER:SUBSCRIBER:TOPIC, got {spec!r}")
    pub, sub, topic = parts
    for c in model.connections:
        if (c.publisher, c.subscriber) == (pub, sub) and c.topic.lstrip("/") == topic.lstrip("/"):
            return c.publisher, c.subscriber, c.topic
    known = ", ".join(f"{c.publisher}:{c.subscriber}:{c.topic}" for c in model.connections)
    raise ModelError("--connection", "", f"no connection {spec} in {model.source} "
                                         f"(connections: {known or 'none'})")
