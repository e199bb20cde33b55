"""The AnyScale system model as data: scales, network, nodes and connections (immutable), and
ModelError. model_loader.py reads them from YAML and validates them.

Every error is a ModelError that names the file, the key path and what was expected, so the CLI
and the decision node can print it as one line instead of a traceback.
"""
from dataclasses import dataclass, field
from typing import Any, Dict, Mapping, Optional, Tuple

# A node's instance on a remote scale registers as NAME__SCALE (the agents' instanceName).
INSTANCE_SEPARATOR = "__"


class ModelError(ValueError):
    """A system model (or state file) that cannot be used: where and why."""

    def __init__(self, source: str, key: str, message: str):
        self.source, self.key, self.message = source, key, message
        where = f"{source}: {key}" if key else source
        super().__init__(f"{where}: {message}")


@dataclass(frozen=True)
class Scale:
    name: str
    master: bool
    cpu_ghz: float
    cores: int
    memory_mb: float
    alpha: float


@dataclass(frozen=True)
class Network:
    technology: str
    max_bandwidth_mbps: float


@dataclass(frozen=True)
class LaunchSpec:
    """How an agent starts a node: rosrun-style package + executable, args, remaps, params."""
    package: str
    type: str
    args: Tuple[str, ...] = ()
    remaps: Tuple[Tuple[str, str], ...] = ()
    params: Tuple[Tuple[str, Any], ...] = ()
    # rospy nodes only: each agent keeps a pre-imported interpreter of this node ready where
    # it does not run (agent README, "Warm standby"), so a move there skips the imports.
    warm_start: bool = False
    # CPU priority the agent runs it at, -20..19 (roslaunch: launch-prefix="nice -n N").
    nice: int = 0
    # While the node runs on another scale, its instance on the master scale is paused
    # (SIGSTOP), not stopped, and a return resumes it (SIGCONT) instead of starting it: a
    # return forced by a link loss then costs no start on the starved robot. The node must
    # cope with a pause (agent README, "Paused at home"): drop stale input, resume its state.
    pause_at_home: bool = False


@dataclass(frozen=True)
class StateHandoff:
    kind: str      # "pose": start from the last pose on `topic` (initial_pose_* params)
    topic: str


@dataclass(frozen=True)
class Node:
    name: str
    launch: LaunchSpec
    cpu_usage: Mapping[str, float]   # scale -> % of that scale's whole CPU
    memory_mb: float
    pinned: Optional[str] = None     # scale the node must run on (hardware drivers)
    state_handoff: Optional[StateHandoff] = None


@dataclass(frozen=True)
class Connection:
    publisher: str
    subscriber: str
    topic: str
    freq_min: float
    freq_opt: float
    tolerance: float                 # s; 0 = critical
    bandwidth_mbps: float = 0.0      # carried at freq_opt when it crosses scales

    @property
    def name(self) -> str:
        return f"{self.publisher}->{self.subscriber} ({self.topic})"


@dataclass(frozen=True)
class SystemModel:
    scales: Tuple[Scale, ...]
    network: Network
    nodes: Tuple[Node, ...]
    connections: Tuple[Connection, ...]
    source: str = "<model>"
    _scale_index: Dict[str, Scale] = field(default_factory=dict, init=False, compare=False,
                                           repr=False)
    _node_index: Dict[str, Node] = field(default_factory=dict, init=False, compare=False,
                                         repr=False)

    def __post_init__(self):
        self._scale_index.update({s.name: s for s in self.scales})
        self._node_index.update({n.name: n for n in self.nodes})

    @property
    def master(self) -> Scale:
        return next(s for s in self.scales if s.master)

    @property
    def remote_scales(self) -> Tuple[Scale, ...]:
        return tuple(s for s in self.scales if not s.master)

    def scale(self, name: str) -> Scale:
        return self._scale_index[name]

    def node(self, name: str) -> Node:
        return self._node_index[name]

    @property
    def scale_names(self) -> Tuple[str, ...]:
        return tuple(s.name for s in self.scales)

    @property
    def node_names(self) -> Tuple[str, ...]:
        return tuple(n.name for n in self.nodes)

    def instance_name(self, node: str, scale: str) -> str:
        """The fully qualified name `node` registers under on `scale` (the agents' rule)."""
        suffix = "" if self.scale(scale).master else INSTANCE_SEPARATOR + scale
        return f"/{node}{suffix}"

    def output_topics(self, node: str) -> Tuple[str, ...]:
        """Topics `node` publishes on the model's connections, each once."""
        return tuple(dict.fromkeys(c.topic for c in self.connections if c.publisher == node))
