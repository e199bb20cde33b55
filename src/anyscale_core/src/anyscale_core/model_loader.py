"""Loading a system model from YAML and validating it: every rule of the model, each error a
ModelError naming the file, the key path and what was expected. The data classes are model.py.
"""
import math
import re
from typing import Any, List, Mapping, Optional, Tuple

import yaml

from .model import (INSTANCE_SEPARATOR, Connection, LaunchSpec, ModelError, Network, Node, Scale,
                    StateHandoff, SystemModel)

# Each pattern must match the whole string (fullmatch: `$` also matched before a trailing
# newline, and the CLI accepted a name the agent refuses).
# A ROS graph resource name without namespace: what a node of the model may be called.
_NODE_NAME = re.compile(r"[A-Za-z][A-Za-z0-9_]*")
_SCALE_NAME = _NODE_NAME
_PACKAGE_NAME = re.compile(r"[a-z][a-z0-9_]*")
# An executable inside a package: a file name, never a path.
_EXECUTABLE = re.compile(r"[A-Za-z0-9_][A-Za-z0-9_.\-]*")
_TOPIC = re.compile(r"/?[A-Za-z~][A-Za-z0-9_/]*")
_HANDOFF_KINDS = ("pose",)
# A node's launch.params, aliases expanded, hold at most this many values (scalars, lists and
# maps) nested at most this deep, as the agent's model loader checks them (node_model.h): an
# alias bomb of a dozen lines expands to billions, converted into parameters at every start.
MAX_PARAM_VALUES = 10000
MAX_PARAM_DEPTH = 32


def load_model(path: str) -> SystemModel:
    """Reads and validates a model file; raises ModelError naming the file and key."""
    return parse_model(read_yaml(path), path)


def read_yaml(path: str) -> Any:
    """The YAML tree of a model or state file; every way a file can be unreadable is a
    one-line ModelError (the CLI prints one line, never a traceback)."""
    try:
        with open(path, encoding="utf-8") as f:
            return yaml.safe_load(f)
    except OSError as e:
        raise ModelError(path, "", f"cannot read: {e.strerror}") from None
    except UnicodeDecodeError as e:
        raise ModelError(path, "", f"not UTF-8 text: byte 0x{e.object[e.start]:02x} at offset "
                                   f"{e.start}") from None
    except RecursionError:
        raise ModelError(path, "", "invalid YAML: nested too deeply") from None
    except yaml.YAMLError as e:
        mark = getattr(e, "problem_mark", None)
        where = f"line {mark.line + 1}, column {mark.column + 1}: " if mark else ""
        problem = " ".join((getattr(e, "problem", None) or str(e)).split())
        raise ModelError(path, "", f"invalid YAML: {where}{problem}") from None


def is_finite_number(value: Any) -> bool:
    """An int or float (not a bool) that is finite as a float: 10**400 is not."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return False
    try:
        return math.isfinite(float(value))
    except OverflowError:
        return False


class _Reader:
    """Typed access to a YAML tree that reports errors by key path."""

    def __init__(self, source: str):
        self.source = source

    def fail(self, key: str, message: str):
        raise ModelError(self.source, key, message)

    def mapping(self, value: Any, key: str) -> Mapping:
        if not isinstance(value, Mapping):
            self.fail(key, f"expected a mapping, got {_describe(value)}")
        return value

    def sequence(self, value: Any, key: str) -> List:
        if not isinstance(value, list):
            self.fail(key, f"expected a list, got {_describe(value)}")
        return value

    def require(self, data: Mapping, name: str, key: str) -> Any:
        if name not in data or data[name] is None:
            self.fail(f"{key}.{name}" if key else name, "missing required key")
        return data[name]

    def number(self, value: Any, key: str, minimum: Optional[float] = None,
               strictly_above: Optional[float] = None, maximum: Optional[float] = None) -> float:
        if not is_finite_number(value):
            self.fail(key, f"expected a finite number, got {_describe(value)}")
        if minimum is not None and value < minimum:
            self.fail(key, f"expected a number >= {minimum:g}, got {value:g}")
        if strictly_above is not None and value <= strictly_above:
            self.fail(key, f"expected a number > {strictly_above:g}, got {value:g}")
        if maximum is not None and value > maximum:
            self.fail(key, f"expected a number <= {maximum:g}, got {value:g}")
        return float(value)

    def integer(self, value: Any, key: str, minimum: int, maximum: float = math.inf) -> int:
        if isinstance(value, bool) or not isinstance(value, int) or not minimum <= value <= maximum:
            bound = f">= {minimum}" if maximum == math.inf else f"from {minimum} to {maximum}"
            self.fail(key, f"expected an integer {bound}, got {_describe(value)}")
        return value

    def string(self, value: Any, key: str, pattern: Optional[re.Pattern] = None,
               what: str = "") -> str:
        if not isinstance(value, str) or not value:
            self.fail(key, f"expected a non-empty string, got {_describe(value)}")
        if pattern is not None and not pattern.fullmatch(value):
            self.fail(key, f"expected {what}, got {value!r}")
        return value

    def boolean(self, value: Any, key: str) -> bool:
        if not isinstance(value, bool):
            self.fail(key, f"expected true or false, got {_describe(value)}")
        return value

    def no_unknown_keys(self, data: Mapping, allowed: Tuple[str, ...], key: str):
        for name in data:
            if name not in allowed:
                where = f"{key}.{name}" if key else str(name)
                self.fail(where, f"unknown key (expected one of: {', '.join(allowed)})")


def _describe(value: Any) -> str:
    if value is None:
        return "nothing"
    if isinstance(value, (dict, list)):
        return type(value).__name__
    return f"{type(value).__name__} {value!r}"


def parse_model(data: Any, source: str = "<model>") -> SystemModel:
    """Validates a YAML tree (as yaml.safe_load returns it) and builds the SystemModel."""
    r = _Reader(source)
    top = r.mapping(data, "")
    r.no_unknown_keys(top, ("scales", "network", "nodes", "connections"), "")
    scales = _parse_scales(r, r.require(top, "scales", ""))
    network = _parse_network(r, r.require(top, "network", ""))
    scale_names = {s.name for s in scales}
    nodes = _parse_nodes(r, r.require(top, "nodes", ""), scale_names)
    node_names = {n.name for n in nodes}
    connections = _parse_connections(r, r.require(top, "connections", ""), node_names)
    _check_start_scales(r, scales, nodes, connections)
    return SystemModel(tuple(scales), network, tuple(nodes), tuple(connections), source)


def _check_start_scales(r: _Reader, scales: List[Scale], nodes: List[Node],
                        connections: List[Connection]):
    """Every node starts on its pinned scale or the master (paper IV): it must be able to."""
    master = next(s for s in scales if s.master)
    critical = {c.publisher for c in connections if c.tolerance == 0}
    critical |= {c.subscriber for c in connections if c.tolerance == 0}
    memory = {s.name: 0.0 for s in scales}
    for i, node in enumerate(nodes):
        key = f"nodes[{i}] ({node.name})"
        if node.name in critical and node.pinned not in (None, master.name):
            r.fail(f"{key}.pinned", f"critical node (a connection with tolerance 0) must run on "
                                    f"the master scale '{master.name}', not '{node.pinned}'")
        start = node.pinned or master.name
        if start not in node.cpu_usage:
            r.fail(f"{key}.cpu_usage", f"missing the usage on '{start}', where the node starts")
        memory[start] += node.memory_mb
    for scale in scales:
        if memory[scale.name] > scale.memory_mb:
            r.fail("nodes", f"the nodes that start on scale '{scale.name}' need "
                            f"{memory[scale.name]:g} MB > its memory_mb {scale.memory_mb:g}")


def _parse_scales(r: _Reader, value: Any) -> List[Scale]:
    items = r.sequence(value, "scales")
    if not items:
        r.fail("scales", "expected at least one scale")
    scales, seen = [], set()
    for i, item in enumerate(items):
        key = f"scales[{i}]"
        d = r.mapping(item, key)
        r.no_unknown_keys(d, ("name", "master", "cpu_ghz", "cores", "memory_mb", "alpha"), key)
        name = r.string(r.require(d, "name", key), f"{key}.name", _SCALE_NAME,
                        "a name of letters, digits and _")
        if name in seen:
            r.fail(f"{key}.name", f"duplicate scale name '{name}'")
        seen.add(name)
        scales.append(Scale(
            name=name,
            master=r.boolean(d.get("master", False), f"{key}.master"),
            cpu_ghz=r.number(r.require(d, "cpu_ghz", key), f"{key}.cpu_ghz", strictly_above=0),
            cores=r.integer(r.require(d, "cores", key), f"{key}.cores", 1),
            memory_mb=r.number(r.require(d, "memory_mb", key), f"{key}.memory_mb",
                               strictly_above=0),
            alpha=r.number(r.require(d, "alpha", key), f"{key}.alpha", strictly_above=0)))
    masters = [s.name for s in scales if s.master]
    if not masters:
        r.fail("scales", "no scale has master: true (exactly one must)")
    if len(masters) > 1:
        r.fail("scales", f"more than one master scale: {', '.join(masters)} (exactly one must be)")
    return scales


def _parse_network(r: _Reader, value: Any) -> Network:
    d = r.mapping(value, "network")
    r.no_unknown_keys(d, ("technology", "max_bandwidth_mbps"), "network")
    return Network(
        technology=r.string(d.get("technology", "unknown"), "network.technology"),
        max_bandwidth_mbps=r.number(r.require(d, "max_bandwidth_mbps", "network"),
                                    "network.max_bandwidth_mbps", strictly_above=0))


def _parse_nodes(r: _Reader, value: Any, scale_names: set) -> List[Node]:
    items = r.sequence(value, "nodes")
    if not items:
        r.fail("nodes", "expected at least one node")
    nodes, seen = [], set()
    for i, item in enumerate(items):
        key = f"nodes[{i}]"
        d = r.mapping(item, key)
        name = r.string(r.require(d, "name", key), f"{key}.name", _NODE_NAME,
                        "a ROS node name (letters, digits, _; no namespace)")
        if INSTANCE_SEPARATOR in name:
            r.fail(f"{key}.name", f"'{INSTANCE_SEPARATOR}' is reserved for the names instances "
                                  f"run under on remote scales (NAME{INSTANCE_SEPARATOR}SCALE), "
                                  f"got '{name}'")
        if name in seen:
            r.fail(f"{key}.name", f"duplicate node name '{name}'")
        seen.add(name)
        key = f"nodes[{i}] ({name})"
        r.no_unknown_keys(d, ("name", "launch", "cpu_usage", "memory_mb", "pinned",
                              "state_handoff"), key)
        cpu = r.mapping(r.require(d, "cpu_usage", key), f"{key}.cpu_usage")
        if not cpu:
            r.fail(f"{key}.cpu_usage", "expected the CPU usage on at least one scale")
        cpu_usage = {}
        for scale, usage in cpu.items():
            if scale not in scale_names:
                r.fail(f"{key}.cpu_usage.{scale}", f"unknown scale '{scale}' "
                                                   f"(scales: {', '.join(sorted(scale_names))})")
            cpu_usage[scale] = r.number(usage, f"{key}.cpu_usage.{scale}", minimum=0, maximum=100)
        pinned = d.get("pinned")
        if pinned is not None:
            pinned = r.string(pinned, f"{key}.pinned")
            if pinned not in scale_names:
                r.fail(f"{key}.pinned", f"unknown scale '{pinned}'")
            if pinned not in cpu_usage:
                r.fail(f"{key}.cpu_usage", f"pinned to '{pinned}' but has no cpu_usage there")
        nodes.append(Node(
            name=name,
            launch=_parse_launch(r, d.get("launch"), f"{key}.launch"),
            cpu_usage=cpu_usage,
            memory_mb=r.number(r.require(d, "memory_mb", key), f"{key}.memory_mb", minimum=0),
            pinned=pinned,
            state_handoff=_parse_handoff(r, d.get("state_handoff"), f"{key}.state_handoff")))
    return nodes


def _parse_launch(r: _Reader, value: Any, key: str) -> LaunchSpec:
    if value is None:
        r.fail(key, "missing: a node needs launch.package and launch.type to be started")
    d = r.mapping(value, key)
    r.no_unknown_keys(d, ("package", "type", "args", "remaps", "params", "warm_start", "nice",
                          "pause_at_home"),
                      key)
    package = r.string(r.require(d, "package", key), f"{key}.package", _PACKAGE_NAME,
                       "a ROS package name")
    exe = r.string(r.require(d, "type", key), f"{key}.type", _EXECUTABLE,
                   "an executable name inside the package (no path)")
    args = tuple(r.string(a, f"{key}.args[{j}]") if not isinstance(a, (int, float)) else str(a)
                 for j, a in enumerate(r.sequence(d.get("args", []) or [], f"{key}.args")))
    remaps = tuple((r.string(k, f"{key}.remaps"), r.string(v, f"{key}.remaps.{k}"))
                   for k, v in r.mapping(d.get("remaps", {}) or {}, f"{key}.remaps").items())
    params = tuple(r.mapping(d.get("params", {}) or {}, f"{key}.params").items())
    budget = [MAX_PARAM_VALUES]
    for pname, value in params:
        r.string(pname, f"{key}.params", _NODE_NAME, "a parameter name")
        _check_param_value(r, value, f"{key}.params.{pname}", budget, 1)
    nice = r.integer(d.get("nice", 0), f"{key}.nice", -20, 19)
    return LaunchSpec(package, exe, args, remaps, params,
                      r.boolean(d.get("warm_start", False), f"{key}.warm_start"), nice,
                      r.boolean(d.get("pause_at_home", False), f"{key}.pause_at_home"))


def _check_param_value(r: _Reader, value: Any, key: str, budget: List[int], depth: int):
    """A ROS parameter value walked as the agent converts it, every alias expanded, within
    budget[0] values and MAX_PARAM_DEPTH levels."""
    if budget[0] <= 0:
        r.fail(key, f"launch.params hold more than {MAX_PARAM_VALUES} values with their YAML "
                    f"aliases expanded")
    budget[0] -= 1
    if depth > MAX_PARAM_DEPTH:
        r.fail(key, f"launch.params nested deeper than {MAX_PARAM_DEPTH} levels")
    if value is None:
        r.fail(key, "a null value cannot be a ROS parameter")
    if isinstance(value, list):
        for i, item in enumerate(value):
            _check_param_value(r, item, f"{key}[{i}]", budget, depth + 1)
    elif isinstance(value, Mapping):
        for name, item in value.items():
            if not isinstance(name, str):
                r.fail(key, f"expected parameter names as keys, got {_describe(name)}")
            _check_param_value(r, item, f"{key}.{name}", budget, depth + 1)


def _parse_handoff(r: _Reader, value: Any, key: str) -> Optional[StateHandoff]:
    if value is None:
        return None
    d = r.mapping(value, key)
    r.no_unknown_keys(d, ("kind", "topic"), key)
    kind = r.string(r.require(d, "kind", key), f"{key}.kind")
    if kind not in _HANDOFF_KINDS:
        r.fail(f"{key}.kind", f"expected one of: {', '.join(_HANDOFF_KINDS)}, got {kind!r}")
    topic = r.string(r.require(d, "topic", key), f"{key}.topic", _TOPIC, "a topic name")
    return StateHandoff(kind, topic)


def _parse_connections(r: _Reader, value: Any, node_names: set) -> List[Connection]:
    items = r.sequence(value, "connections")
    connections, seen = [], set()
    for i, item in enumerate(items):
        key = f"connections[{i}]"
        d = r.mapping(item, key)
        r.no_unknown_keys(d, ("publisher", "subscriber", "topic", "freq_min", "freq_opt",
                              "tolerance", "bandwidth_mbps"), key)
        ends = []
        for end in ("publisher", "subscriber"):
            name = r.string(r.require(d, end, key), f"{key}.{end}")
            if name not in node_names:
                r.fail(f"{key}.{end}", f"unknown node '{name}'")
            ends.append(name)
        if ends[0] == ends[1]:
            r.fail(f"{key}.subscriber", f"'{ends[0]}' is the publisher too: a connection joins "
                                        "two different nodes")
        topic = r.string(r.require(d, "topic", key), f"{key}.topic", _TOPIC, "a topic name")
        if (ends[0], ends[1], topic) in seen:
            r.fail(key, f"duplicate connection {ends[0]} -> {ends[1]} on {topic}")
        seen.add((ends[0], ends[1], topic))
        freq_min = r.number(r.require(d, "freq_min", key), f"{key}.freq_min", strictly_above=0)
        freq_opt = r.number(r.require(d, "freq_opt", key), f"{key}.freq_opt")
        if freq_opt < freq_min:
            r.fail(f"{key}.freq_opt", f"expected freq_opt >= freq_min ({freq_min:g}), "
                                      f"got {freq_opt:g}")
        connections.append(Connection(
            publisher=ends[0], subscriber=ends[1], topic=topic,
            freq_min=freq_min, freq_opt=freq_opt,
            tolerance=r.number(r.require(d, "tolerance", key), f"{key}.tolerance", minimum=0),
            bandwidth_mbps=r.number(d.get("bandwidth_mbps", 0.0), f"{key}.bandwidth_mbps",
                                    minimum=0)))
    return connections
