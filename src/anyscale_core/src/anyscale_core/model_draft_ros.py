"""`anyscale model draft`, the ROS part: collects a GraphSnapshot of the running graph (the
master's system state and topic types, each node's pid over its XML-RPC API and, for nodes on
this machine, /proc/PID/cmdline and RSS; rates and bytes/s counted here) for model_draft.py.

Rates are counted by this command with rospy.AnyMsg subscribers rather than asked of the
AnyScale agents: a model is drafted before AnyScale runs (there is no model for the agents to
start with, and an agent counts only the topics a decision node asked it to watch), so the
draft must work on any graph started with roslaunch. AnyMsg keeps each message's raw buffer
(its serialized size) and the publisher's callerid, so two publishers of one topic are counted
apart. The cost: this command receives one more copy of every counted stream for the window.
"""
import os
import socket
import time
import xmlrpc.client
from collections import defaultdict
from typing import Dict, List, Optional, Sequence, Set, Tuple
from urllib.parse import urlparse

from .model import ModelError
from .model_draft import (DRAFT_NODE, GraphSnapshot, Machine, NodeInfo, Rate, application_nodes,
                          executable_index, graph_connections, package_of_executable)

CALLER_ID = DRAFT_NODE
XMLRPC_TIMEOUT_S = 2.0
# Connections need a moment to come up; a latched topic's first message arrives then too.
SETTLE_S = 1.0


class DraftError(ModelError):
    """A graph that cannot be drafted (no master): one line, exit 2, like a bad file."""


def _master():
    import rosgraph
    return rosgraph.Master(CALLER_ID)


def system_state(master) -> Tuple[Dict[str, List[str]], Dict[str, List[str]], Set[str]]:
    """publishers and subscribers (topic -> nodes) and every node that offers a service."""
    import rosgraph
    try:
        pubs, subs, services = master.getSystemState()
    except (OSError, rosgraph.MasterException) as e:
        raise DraftError(f"ROS_MASTER_URI={rosgraph.get_master_uri()}", "",
                         f"no ROS master there (is roscore running?): {e}") from None
    service_nodes = {n for _, names in services for n in names}
    return ({t: list(n) for t, n in pubs}, {t: list(n) for t, n in subs}, service_nodes)


class _TimeoutTransport(xmlrpc.client.Transport):
    """A node that hangs must not hang the draft."""

    def make_connection(self, host):
        connection = super().make_connection(host)
        connection.timeout = XMLRPC_TIMEOUT_S
        return connection


def node_uri_and_pid(master, node: str) -> Tuple[Optional[str], Optional[int]]:
    """The node's XML-RPC URI (from the master) and pid (from the node), None where not known."""
    try:
        uri = master.lookupNode(node)
        code, _, pid = xmlrpc.client.ServerProxy(uri, transport=_TimeoutTransport()).getPid(
            CALLER_ID)
        return uri, (pid if code == 1 else None)
    except Exception:  # noqa: BLE001 - a node that is gone or does not answer: no pid, a TODO
        return None, None


def is_this_machine(host: str) -> bool:
    """Binding to an address succeeds only where it is one of this machine's own."""
    try:
        address = socket.gethostbyname(host)
        with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
            s.bind((address, 0))
        return True
    except OSError:
        return False


def read_cmdline(pid: int) -> Optional[Tuple[str, ...]]:
    try:
        with open(f"/proc/{pid}/cmdline", "rb") as f:
            raw = f.read()
    except OSError:
        return None
    parts = raw.split(b"\0")
    return tuple(p.decode("utf-8", "replace") for p in (parts[:-1] if parts[-1] == b"" else parts))


def read_rss_mb(pid: int) -> Optional[float]:
    try:
        with open(f"/proc/{pid}/status") as f:
            for line in f:
                if line.startswith("VmRSS:"):
                    return int(line.split()[1]) / 1024.0
    except OSError:
        pass
    return None


def executable_path(pid: int, cmdline: Sequence[str]) -> str:
    """The executable's absolute path: a relative one is relative to the process's cwd, and a
    bare name (argv[0] found on PATH) is the process's own binary."""
    exe = cmdline[executable_index(cmdline)]
    if "/" not in exe:
        try:
            return os.path.realpath(f"/proc/{pid}/exe")
        except OSError:
            return exe
    try:
        return os.path.realpath(os.path.join(os.readlink(f"/proc/{pid}/cwd"), exe))
    except OSError:
        return os.path.realpath(exe)


def package_index() -> Tuple[Dict[str, str], Dict[str, List[str]]]:
    """package -> directory (rospkg, as rosrun finds them) and executable name -> packages
    that install it in <prefix>/lib/<package>/ (where the agent looks first)."""
    import rospkg
    pack = rospkg.RosPack()
    dirs = {}
    for name in pack.list():
        try:
            dirs[name] = os.path.realpath(pack.get_path(name))
        except rospkg.ResourceNotFound:
            continue
    prefixes = [p for p in os.environ.get("CMAKE_PREFIX_PATH", "").split(":") if p] + ["/usr"]
    owners: Dict[str, List[str]] = defaultdict(list)
    for prefix in dict.fromkeys(prefixes):
        for name in dirs:
            lib = os.path.join(prefix, "lib", name)
            if os.path.isdir(lib):
                for exe in os.listdir(lib):
                    if name not in owners[exe] and os.access(os.path.join(lib, exe), os.X_OK):
                        owners[exe].append(name)
    return dirs, dict(owners)


def node_info(master, node: str, packages) -> NodeInfo:
    uri, pid = node_uri_and_pid(master, node)
    host = urlparse(uri).hostname if uri else None
    if pid is None or not host or not is_this_machine(host):
        return NodeInfo(node, host=host, pid=pid)
    cmdline = read_cmdline(pid)
    if not cmdline:
        return NodeInfo(node, host=host, pid=pid)
    found = package_of_executable(executable_path(pid, cmdline), *packages)
    package, executable = found if found else (None, None)
    return NodeInfo(node, host, pid, cmdline, package, executable, read_rss_mb(pid))


def this_machine() -> Machine:
    """Cores, the fastest core's clock and the memory of this machine (/proc)."""
    ghz = 0.0
    try:
        with open("/proc/cpuinfo") as f:
            mhz = [float(line.split(":")[1]) for line in f if line.startswith("cpu MHz")]
        ghz = max(mhz) / 1000.0 if mhz else 0.0
    except OSError:
        pass
    memory_mb = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES") / 2 ** 20
    return Machine(os.cpu_count() or 1, round(ghz, 2) or 1.0, memory_mb)


class RateCounter:
    """Messages and serialized bytes per (topic, publisher) received between open() and
    close(), with rospy.AnyMsg subscribers: nothing is deserialised, and the callerid tells two
    publishers of one topic apart. Shared by `model draft` and `profile` (a node's output rate
    while its CPU is measured)."""

    def __init__(self, topics: Sequence[str]):
        import rospy
        self._counts: Dict[Tuple[str, str], List[float]] = defaultdict(lambda: [0, 0])
        self._open = False
        self._start = 0.0
        self._subscribers = [rospy.Subscriber(t, rospy.AnyMsg, self._on_message,
                                              callback_args=t, queue_size=100) for t in topics]

    def _on_message(self, msg, topic):
        if self._open:
            entry = self._counts[(topic, msg._connection_header.get("callerid", ""))]
            entry[0] += 1
            # rospy gives one process one subscription per topic: where this process also
            # subscribes the topic typed (profile's state hand-off of /amcl_pose), the message
            # arrives deserialised and its size is not known; it is counted without bytes.
            entry[1] += len(getattr(msg, "_buff", b""))

    def open(self):
        self._counts.clear()
        self._start = time.monotonic()
        self._open = True

    def close(self) -> Dict[Tuple[str, str], Rate]:
        """The rates over the window since open(); the subscribers are kept for another."""
        self._open = False
        elapsed = max(time.monotonic() - self._start, 1e-9)
        return {key: Rate(n / elapsed, size / elapsed) for key, (n, size) in self._counts.items()}

    def unregister(self):
        for s in self._subscribers:
            s.unregister()


def count_rates(topics: Sequence[str], seconds: float) -> Dict[Tuple[str, str], Rate]:
    """(topic, publisher) -> messages and bytes per second received over `seconds`, counted
    after SETTLE_S so connection set-up and latched messages are not counted."""
    counter = RateCounter(topics)
    try:
        time.sleep(SETTLE_S)
        counter.open()
        time.sleep(seconds)
        return counter.close()
    finally:
        counter.unregister()


def collect_snapshot(seconds: float) -> GraphSnapshot:
    """The running graph as plain data; DraftError when there is no master."""
    import rosgraph
    import rospy
    master = _master()
    publishers, subscribers, service_nodes = system_state(master)
    try:
        types = dict(master.getTopicTypes())
    except (OSError, rosgraph.MasterException) as e:
        raise DraftError(f"ROS_MASTER_URI={rosgraph.get_master_uri()}", "", str(e)) from None
    names = set(service_nodes)
    for table in (publishers, subscribers):
        for nodes in table.values():
            names.update(nodes)
    packages = package_index()
    nodes = {n: node_info(master, n, packages) for n in sorted(names)}
    bare = GraphSnapshot(publishers, subscribers, types, nodes, {}, seconds,
                         rosgraph.get_master_uri())
    # Only topics on a connection are counted: a camera nobody subscribes costs nothing.
    counted = sorted({c.topic for c in graph_connections(bare, application_nodes(bare))})
    rospy.init_node(CALLER_ID.lstrip("/"), anonymous=True, disable_signals=True)
    try:
        rates = count_rates(counted, seconds) if counted else {}
    finally:
        rospy.signal_shutdown("model drafted")
    master_host = urlparse(rosgraph.get_master_uri()).hostname or ""
    return GraphSnapshot(publishers, subscribers, types, nodes, rates, seconds,
                         rosgraph.get_master_uri(),
                         this_machine() if is_this_machine(master_host) else None)
