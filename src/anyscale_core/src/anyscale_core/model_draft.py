"""`anyscale model draft`, the pure part: a snapshot of a running ROS graph (plain data) in, the
text of a system model YAML out, with `TODO` wherever a human must decide.

Nothing here talks to ROS: model_draft_ros.py collects the snapshot (the master's system state,
topic types, pids and command lines, measured rates). The output is in model_loader.py's
schema, so once its TODOs are replaced by values `anyscale check` accepts it. A TODO left in a
numeric field is a string there, which the loader refuses with the key path, so a forgotten one
cannot pass as a default.
"""
import os
import re
from dataclasses import dataclass
from typing import Dict, Iterable, List, Mapping, Optional, Sequence, Set, Tuple

import yaml

from .model import INSTANCE_SEPARATOR

TODO = "TODO"
# ROS's own logging and AnyScale's own traffic are not part of the user's application.
LEFT_OUT_TOPICS = ("/rosout", "/rosout_agg")
ANYSCALE_NAMESPACE = "/anyscale/"
LEFT_OUT_NODES = ("/rosout",)
# The drafting command's own node (anonymous: /anyscale_model_draft_<pid>_<time>).
DRAFT_NODE = "/anyscale_model_draft"
# argv[0] of a process that runs a script: the script is the first argument that is no option.
_INTERPRETER = re.compile(r"^(python[0-9.]*|bash|sh|dash|perl|ruby|node)$")
# roslaunch's and rosrun's special arguments: the name and namespace come from the graph, the
# rest is set by whoever launches the node (the agent sets __name and __ns itself).
_SPECIAL_ARG = re.compile(r"^__[a-z]+:=")
_REMAP = re.compile(r"^([A-Za-z~/][A-Za-z0-9_/~]*):=(.*)$")
_PRIVATE_PARAM = re.compile(r"^_([A-Za-z][A-Za-z0-9_]*):=(.*)$")
_MODEL_NAME_CHARS = re.compile(r"[^A-Za-z0-9_]+")


@dataclass(frozen=True)
class NodeInfo:
    """What is known of one node of the graph. cmdline is None when the node's process cannot
    be read (it runs on another machine, or its pid is unknown)."""
    name: str                                  # ROS name as the master knows it, e.g. /amcl
    host: Optional[str] = None                 # from its XML-RPC URI
    pid: Optional[int] = None
    cmdline: Optional[Tuple[str, ...]] = None  # /proc/PID/cmdline
    package: Optional[str] = None              # of the executable, where it could be found
    executable: Optional[str] = None
    memory_mb: Optional[float] = None          # resident set size when drafted


@dataclass(frozen=True)
class Machine:
    """This machine, when it runs the master: the draft's master scale."""
    cores: int
    cpu_ghz: float
    memory_mb: float


@dataclass(frozen=True)
class Rate:
    """Messages of one publisher on one topic as received by the drafting command."""
    hz: float
    bytes_per_s: float


@dataclass(frozen=True)
class GraphSnapshot:
    publishers: Mapping[str, Sequence[str]]     # topic -> node names (the master's state)
    subscribers: Mapping[str, Sequence[str]]
    types: Mapping[str, str]                    # topic -> message type
    nodes: Mapping[str, NodeInfo]               # every node the master knows
    rates: Mapping[Tuple[str, str], Rate]       # (topic, publisher) -> measured
    seconds: float                              # length of the counting window
    master_uri: str = ""
    machine: Optional[Machine] = None           # None: the master runs elsewhere


@dataclass(frozen=True)
class DraftConnection:
    publisher: str    # ROS names
    subscriber: str
    topic: str
    rate: Optional[Rate]


def is_left_out_topic(topic: str) -> bool:
    """ROS's log topics and AnyScale's own (/anyscale/...) are not the application's."""
    return topic in LEFT_OUT_TOPICS or topic.startswith(ANYSCALE_NAMESPACE)


def anyscale_nodes(snapshot: GraphSnapshot) -> Set[str]:
    """Nodes on AnyScale's own topics (agents, decision node, `anyscale top`): they run the
    model, they are not in it."""
    found: Set[str] = set()
    for table in (snapshot.publishers, snapshot.subscribers):
        for topic, names in table.items():
            if topic.startswith(ANYSCALE_NAMESPACE):
                found.update(names)
    return found


def application_nodes(snapshot: GraphSnapshot) -> List[str]:
    """The nodes the model describes, sorted: every node the master knows but /rosout, drafting
    commands (also another one running now) and AnyScale's own."""
    known = set(snapshot.nodes)
    for table in (snapshot.publishers, snapshot.subscribers):
        for names in table.values():
            known.update(names)
    skip = set(LEFT_OUT_NODES) | anyscale_nodes(snapshot)
    return sorted(n for n in known - skip if not n.startswith(DRAFT_NODE))


def graph_connections(snapshot: GraphSnapshot, nodes: Iterable[str]) -> List[DraftConnection]:
    """Every (publisher, subscriber, topic) between two of `nodes`, sorted by topic; a node that
    both publishes and subscribes a topic is no connection to itself."""
    keep = set(nodes)
    out = []
    for topic in sorted(snapshot.publishers):
        if is_left_out_topic(topic):
            continue
        for pub in sorted(set(snapshot.publishers[topic]) & keep):
            for sub in sorted(set(snapshot.subscribers.get(topic, ())) & keep):
                if pub != sub:
                    out.append(DraftConnection(pub, sub, topic, snapshot.rates.get((topic, pub))))
    return out


def model_names(ros_names: Iterable[str]) -> Dict[str, str]:
    """ROS name -> a name the model accepts (letters, digits, _; no namespace, no '__', starting
    with a letter), unique: /ns/cam -> ns_cam, /my__node -> my_node; a clash gets _2, _3..."""
    out: Dict[str, str] = {}
    taken: Set[str] = set()
    for ros_name in sorted(ros_names):
        base = _MODEL_NAME_CHARS.sub("_", ros_name.strip("/"))
        while INSTANCE_SEPARATOR in base:
            base = base.replace(INSTANCE_SEPARATOR, "_")
        base = base.strip("_")
        if not base or not base[0].isalpha():
            base = "node_" + base if base else "node"
        name, k = base, 2
        while name in taken:
            name, k = f"{base}_{k}", k + 1
        taken.add(name)
        out[ros_name] = name
    return out


def executable_index(cmdline: Sequence[str]) -> int:
    """Index of the executable in a command line: argv[0], or after an interpreter (python3
    SCRIPT ...) the first argument that is not an option."""
    if not cmdline or not _INTERPRETER.match(os.path.basename(cmdline[0])):
        return 0
    for i in range(1, len(cmdline)):
        if not cmdline[i].startswith("-"):
            return i
    return 0


@dataclass(frozen=True)
class LaunchArgs:
    args: Tuple[str, ...]
    remaps: Tuple[Tuple[str, str], ...]
    params: Tuple[Tuple[str, object], ...]


def launch_args(cmdline: Sequence[str]) -> LaunchArgs:
    """The arguments after the executable, split as rosrun reads them: `from:=to` remaps,
    `_param:=value` private parameters (value read as YAML, as rosrun does), __special:= dropped
    (roslaunch's __name, __ns and __log), the rest plain args."""
    args, remaps, params = [], [], []
    for arg in cmdline[executable_index(cmdline) + 1:]:
        if _SPECIAL_ARG.match(arg):
            continue
        elif _PRIVATE_PARAM.match(arg):
            name, value = _PRIVATE_PARAM.match(arg).groups()
            params.append((name, _yaml_value(value)))
        elif _REMAP.match(arg):
            remaps.append(_REMAP.match(arg).groups())
        else:
            args.append(arg)
    return LaunchArgs(tuple(args), tuple(remaps), tuple(params))


def _yaml_value(text: str) -> object:
    try:
        return yaml.safe_load(text)
    except yaml.YAMLError:
        return text


def package_of_executable(path: str, package_dirs: Mapping[str, str],
                          lib_executables: Mapping[str, Sequence[str]]
                          ) -> Optional[Tuple[str, str]]:
    """(package, executable) that `rosrun` would start for the file at `path`, or None.
    package_dirs: package -> its directory; lib_executables: executable name -> the packages
    that install one of that name in <prefix>/lib/<package>/ (where the agent looks first).
    Tried in order: a file inside a package's directory; <prefix>/lib/<package>/<exe>; a file
    elsewhere (Debian's /usr/bin/rostopic) whose name exactly one package installs."""
    exe = os.path.basename(path)
    inside = [(len(d), p) for p, d in package_dirs.items()
              if path.startswith(d.rstrip("/") + "/")]
    if inside:
        return max(inside)[1], exe
    parent = os.path.dirname(path)
    if (os.path.basename(os.path.dirname(parent)) == "lib"
            and os.path.basename(parent) in package_dirs):
        return os.path.basename(parent), exe
    owners = lib_executables.get(exe, ())
    if len(owners) == 1:
        return owners[0], exe
    return None


def _flow(value: object) -> str:
    """One YAML value on one line, quoted where YAML needs it (args such as 'data: hi')."""
    text = yaml.safe_dump(value, default_flow_style=True, width=1 << 30, allow_unicode=True)
    return text[:-len("\n...\n")] if text.endswith("\n...\n") else text.rstrip("\n")


def rounded_rate(hz: float) -> float:
    """A measured rate as a first freq_opt: 0.1 Hz steps, two significant digits below 1 Hz."""
    return round(hz, 1) if hz >= 1 else float(f"{hz:.2g}")


def rounded_mbps(bytes_per_s: float) -> float:
    """Bytes/s as Mbit/s, three significant digits (the bandwidth constraint needs no more)."""
    return float(f"{bytes_per_s * 8e-6:.3g}")


def decimal(value: float) -> str:
    """A number as YAML reads it back as a float: never 1e-05, which YAML 1.1 reads as text."""
    return f"{value:.10f}".rstrip("0").rstrip(".") or "0"


def is_source(node: str, connections: Sequence[DraftConnection]) -> bool:
    """Publishes on a connection and subscribes to none: a sensor driver, often."""
    return (any(c.publisher == node for c in connections)
            and not any(c.subscriber == node for c in connections))


def draft_model(snapshot: GraphSnapshot, master_scale: str = "robot",
                remote_scale: str = "laptop") -> str:
    """The model YAML text for `snapshot`, with a TODO at every value a human must decide."""
    nodes = application_nodes(snapshot)
    names = model_names(nodes)
    connections = graph_connections(snapshot, nodes)
    scales = (master_scale, remote_scale)
    lines = _header(snapshot)
    lines += _scales(snapshot.machine, master_scale, remote_scale)
    lines += ["network:",
              f"  technology: {TODO}              # e.g. 802.11ac",
              f"  max_bandwidth_mbps: {TODO}      # the link's maximum between the scales",
              "", "nodes:"]
    for node in nodes:
        lines += _node(snapshot.nodes.get(node, NodeInfo(node)), names[node], scales,
                       connections)
    lines += ["", "connections:" + ("" if connections else " []")]
    if connections:
        lines += [f"  # freq_opt and bandwidth_mbps: measured over {snapshot.seconds:g} s by "
                  "this draft.",
                  "  # freq_min: the lowest rate at which the subscriber still works; tolerance: "
                  "seconds",
                  "  # it may stay below freq_min (0 = critical: both ends stay on the master)."]
    for c in connections:
        lines += _connection(c, names, snapshot.types.get(c.topic, "?"))
    return "\n".join(lines) + "\n"


def _header(snapshot: GraphSnapshot) -> List[str]:
    return [
        "# AnyScale system model drafted by `anyscale model draft` from the ROS graph at "
        f"{snapshot.master_uri or 'the master'}.",
        "# Replace every TODO, then validate it with: anyscale check THIS_FILE",
        "# Units: cpu_usage in % of that scale's whole CPU (all cores); memory in MB; bandwidth in",
        "# Mbit/s; frequencies in Hz; tolerance in s. Left out: /rosout and AnyScale's own nodes.",
        "# cpu_usage: the node's CPU on each scale it may run on, where it runs at the rate that",
        "# scale sustains (`anyscale check` says which nodes are critical, pinned, migratable).",
        ""]


def _scales(machine: Optional[Machine], master: str, remote: str) -> List[str]:
    if machine is None:
        cpu = [f"    cpu_ghz: {TODO}", f"    cores: {TODO}", f"    memory_mb: {TODO}"]
        where = "runs on another machine: TODO its figures"
    else:
        cpu = [f"    cpu_ghz: {machine.cpu_ghz:g}", f"    cores: {machine.cores}",
               f"    memory_mb: {machine.memory_mb:.0f}"]
        where = "this machine, as measured when drafted"
    return ["scales:",
            f"  - name: {master}     # the master scale (runs roscore): {where}",
            "    master: true", *cpu,
            "    alpha: 1.0           # gain of Eq. 1: capacity relative to the master",
            f"  - name: {remote}    # TODO: a machine nodes may move to (or delete it and its "
            "cpu_usage)",
            f"    cpu_ghz: {TODO}", f"    cores: {TODO}", f"    memory_mb: {TODO}",
            f"    alpha: {TODO}         # (cores x GHz) / the master's", ""]


def _node(info: NodeInfo, name: str, scales: Sequence[str],
          connections: Sequence[DraftConnection]) -> List[str]:
    lines = [f"  - name: {name}"]
    if "/" + name != info.name:
        # A namespace on the command line (__ns:=) is part of the ROS name, so it is said here.
        lines.append(f"    # TODO: ROS name {info.name}; AnyScale starts it as /{name} (a model "
                     "has no namespaces or '__'): check its relative names")
    if not any(info.name in (c.publisher, c.subscriber) for c in connections):
        lines.append("    # no connection to another node when drafted")
    lines += _launch(info)
    usage = ", ".join(f"{s}: {TODO}" for s in scales)
    lines.append(f"    cpu_usage: {{{usage}}}   # leave out a scale it may not run on")
    if info.memory_mb is not None:
        lines.append(f"    memory_mb: {info.memory_mb:.0f}       # RSS when drafted")
    else:
        lines.append(f"    memory_mb: {TODO}")
    if is_source(info.name, connections):
        lines.append(f"    pinned: {TODO}          # publishes only: a hardware driver? the "
                     "scale of its hardware, or delete this line")
    return lines


def _launch(info: NodeInfo) -> List[str]:
    if info.cmdline is None:
        where = f"on {info.host}" if info.host else "where its process could not be read"
        return [f"    launch: {{package: {TODO}, type: {TODO}}}   # TODO: runs {where}: "
                "its package, executable, args and remaps"]
    spec = launch_args(info.cmdline)
    lines = ["    launch:"]
    if info.package and info.executable:
        lines += [f"      package: {_flow(info.package)}", f"      type: {_flow(info.executable)}"]
    else:
        exe = info.cmdline[executable_index(info.cmdline)]
        lines += [f"      package: {TODO}      # TODO: no package installs {_flow(exe)}",
                  f"      type: {TODO}"]
    if spec.args:
        lines.append(f"      args: {_flow(list(spec.args))}")
    if spec.remaps:
        lines.append(f"      remaps: {_flow(dict(spec.remaps))}")
    if spec.params:
        lines.append(f"      params: {_flow(dict(spec.params))}")
    return lines


def _connection(c: DraftConnection, names: Mapping[str, str], msg_type: str) -> List[str]:
    head = (f"  - {{publisher: {names[c.publisher]}, subscriber: {names[c.subscriber]}, "
            f"topic: {_flow(c.topic)},")
    if c.rate is None or c.rate.hz <= 0:
        return [f"  # {msg_type}: no message in the counting window (latched, or sent on "
                "events): TODO freq_opt",
                head, f"     freq_min: {TODO}, freq_opt: {TODO}, tolerance: {TODO}, "
                      "bandwidth_mbps: 0}"]
    return [f"  # {msg_type}: {c.rate.hz:.2f} Hz, {c.rate.bytes_per_s:.0f} B/s measured",
            head, f"     freq_min: {TODO}, freq_opt: {decimal(rounded_rate(c.rate.hz))}, "
                  f"tolerance: {TODO}, "
                  f"bandwidth_mbps: {decimal(rounded_mbps(c.rate.bytes_per_s))}}}"]
