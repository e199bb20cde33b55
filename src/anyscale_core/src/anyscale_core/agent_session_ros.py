"""The agents as `anyscale profile` and `anyscale thresholds` use them (rospy): check the graph
is fit to measure, bring the model's nodes up where the paper starts them, move one node, read
the agents' per-node CPU samples, and leave the system as it was found.

Before anything starts, it refuses (one line, exit 2), so that a measurement never fights
another owner of the nodes:
- no master at ROS_MASTER_URI;
- a decision node running (something publishes /anyscale/mapping): it moves nodes itself;
- a scale to be used whose agent does not report on /anyscale/status;
- a model node registered with the master but supervised by no agent (started by roslaunch):
  starting it through an agent would make the master shut the user's process down;
- a model node running away from home (its pinned scale or the master).

Every node this session starts away from the master scale gets a lease that a thread renews; if
the command dies (even by SIGKILL) the agents end those nodes within the lease. The master's
agent takes no lease: a node started at home outlives a killed command, as the robot's nodes
run there anyway. close() stops what it started and starts
again at home any node it found running and moved, so a run (also one that failed or was
interrupted) leaves the system as it was. Nodes are started with their state hand-off (AMCL
from its last pose), as the decision node starts them.
"""
import threading
import time
from typing import Callable, Dict, List, Mapping, Optional, Sequence

from .agent_client import AgentClient
from .model import ModelError, SystemModel
from .model_draft_ros import system_state
from .model_todos import home_mapping
from .process_group import log_tail
from .profile_plan import CpuSample

RUNNING, EXITED, REPLACED, LEASE_EXPIRED, STANDBY, PAUSED = 1, 3, 4, 5, 6, 7
ENDED = (EXITED, REPLACED, LEASE_EXPIRED)
MAPPING_TOPIC = "/anyscale/mapping"


class SessionError(ModelError):
    """The graph cannot be measured as it is, or a node would not start: one line, exit 2."""


def _log_tail(path: str) -> str:
    """": " and the last lines of a node's log where this machine can read it (the agent of
    another machine keeps it there); "" otherwise."""
    tail = log_tail(path)
    return f": {tail}" if tail else ""


class AgentSession:
    def __init__(self, model: SystemModel, caller: str, lease_s: float = 10.0,
                 start_timeout_s: float = 60.0, agent_timeout_s: float = 10.0,
                 tick: Callable[[], None] = lambda: None):
        self.model = model
        self.caller = caller
        self.lease_s = lease_s
        self.start_timeout_s = start_timeout_s
        self.agent_timeout_s = agent_timeout_s
        self.tick = tick
        self.home = dict(home_mapping(model))
        self.agents = AgentClient(timeout_s=10.0, stop_timeout_s=30.0, stop_sigint_timeout_s=3.0)
        self._lock = threading.Lock()
        self._statuses: Dict[str, object] = {}
        self._samples: List[CpuSample] = []
        self._recording = False
        self._handoff: Dict[str, Dict[str, float]] = {}
        self.initial: Dict[str, str] = {}           # node -> scale where it ran when found
        self.started: Dict[str, str] = {}           # node -> scale, started by this session
        self._stopped_initial: Dict[str, str] = {}  # found running, stopped by this session
        self._closing = threading.Event()
        self._renewer: Optional[threading.Thread] = None
        self._opened = False

    # -- set-up ---------------------------------------------------------------------------
    def open(self, scales: Sequence[str]):
        """Checks the graph (see the module docstring) and starts listening to the agents."""
        import rosgraph
        import rospy
        from anyscale_msgs.msg import ScaleStatus
        master = rosgraph.Master(self.caller)
        publishers, _, _ = system_state(master)
        owners = publishers.get(MAPPING_TOPIC, [])
        if owners:
            raise SessionError(MAPPING_TOPIC, "", f"a decision node runs ({', '.join(owners)}): "
                               "it moves nodes itself; run the agents without it (e.g. "
                               "roslaunch anyscale_nav_demo robot.launch decision:=false)")
        rospy.init_node(self.caller.lstrip("/"), anonymous=True, disable_signals=True)
        self._opened = True
        rospy.Subscriber("/anyscale/status", ScaleStatus, self._on_status, queue_size=50)
        self._subscribe_handoffs()
        end = time.monotonic() + self.agent_timeout_s
        missing = list(scales)
        while time.monotonic() < end:
            with self._lock:
                missing = [s for s in scales if s not in self._statuses]
            if not missing:
                break
            time.sleep(0.1)
            self.tick()
        if missing:
            raise SessionError("/anyscale/status", "", f"no status from the agent of "
                               f"{', '.join(missing)} within {self.agent_timeout_s:g} s (is its "
                               "agent running? robot.launch decision:=false on the robot, "
                               "laptop.launch on the laptop)")
        running = self.running()
        self._check_unsupervised(master, running)
        away = {n: s for n, s in running.items() if s != self.home[n]}
        if away:
            node, scale = sorted(away.items())[0]
            raise SessionError(node, "", f"runs on {scale}, not at home on {self.home[node]}: "
                               f"stop it first (rosservice call /anyscale/{scale}/stop_node "
                               f"\"{{node: {node}, wait: true}}\")")
        self.initial = running
        self._renewer = threading.Thread(target=self._renew_leases, daemon=True,
                                         name="lease renewal")
        self._renewer.start()

    def _subscribe_handoffs(self):
        import rospy
        from geometry_msgs.msg import PoseWithCovarianceStamped
        from .ros_convert import handoff_params_from_pose
        for node in self.model.nodes:
            if node.state_handoff is not None and node.state_handoff.kind == "pose":
                def on_pose(msg, name=node.name):
                    with self._lock:
                        self._handoff[name] = handoff_params_from_pose(msg)
                rospy.Subscriber(node.state_handoff.topic, PoseWithCovarianceStamped, on_pose,
                                 queue_size=1)

    def _check_unsupervised(self, master, running: Mapping[str, str]):
        """A model node in the master's system state under any of its instance names that no
        agent supervises was started by someone else. (lookupNode is no test: the master keeps
        the URI of a node that left while it still holds a parameter subscription.)"""
        publishers, subscribers, service_nodes = system_state(master)
        registered = set(service_nodes)
        for table in (publishers, subscribers):
            for names in table.values():
                registered.update(names)
        for node in self.model.node_names:
            if node in running:
                continue
            for scale in self.model.scale_names:
                instance = self.model.instance_name(node, scale)
                if instance in registered:
                    raise SessionError(node, "", f"{instance} is registered with the master but "
                                       "no agent supervises it (started by roslaunch?): stop it "
                                       "and let the agents start the model's nodes")

    def _on_status(self, msg):
        now = time.monotonic()
        capacity = msg.cpu_quota_cores if msg.cpu_quota_cores > 0 else float(msg.cores)
        with self._lock:
            self._statuses[msg.scale] = msg
            if not self._recording:
                return
            for p in msg.nodes:
                if p.state == RUNNING:
                    self._samples.append(CpuSample(now, msg.scale, p.name.lstrip("/"),
                                                   p.cpu_percent, p.rss_bytes, capacity,
                                                   msg.cpu_quota_cores > 0, msg.cpu_percent))

    # -- what runs where ------------------------------------------------------------------
    def processes(self, scale: str):
        return self.agents.call(scale, "list_nodes").nodes

    def running(self) -> Dict[str, str]:
        """node -> scale for the model's nodes that run (or are starting) under an agent."""
        out = {}
        with self._lock:
            scales = list(self._statuses)
        for scale in scales:
            for p in self.processes(scale):
                name = p.name.lstrip("/")
                # A paused instance (launch.pause_at_home) is not where the node runs.
                if p.state not in ENDED and p.state not in (STANDBY, PAUSED) and name in self.home:
                    out[name] = scale
        return out

    # -- starting and stopping ------------------------------------------------------------
    def bring_home(self, on_start: Callable[[str, str], None] = lambda n, s: None):
        """Starts every node of the model that does not run, at home, one by one (in the
        model's order: drivers before the nodes that need their data)."""
        for node in self.model.node_names:
            if node not in self.initial and node not in self.started:
                on_start(node, self.home[node])
                self.start(node, self.home[node])

    def handoff(self, node: str) -> Dict[str, float]:
        """The private parameters `node` is started with: its state hand-off (the last pose)."""
        with self._lock:
            return dict(self._handoff.get(node, {}))

    def start(self, node: str, scale: str, lease: bool = True) -> int:
        """Starts `node` on `scale` and waits until the master lists it; SessionError with the
        agent's reason, the exit and the log's last lines when it does not come up."""
        from .ros_convert import param_overrides_to_kv
        overrides = sorted(self.handoff(node).items())
        lease_s = self.lease_s if lease and scale != self.model.master.name else 0.0
        model_node = self.model.node(node)   # what a shared scale's ledger holds for it
        try:
            reply = self.agents.start(scale, node, param_overrides_to_kv(overrides), lease_s,
                                      model_node.cpu_usage.get(scale, 0.0), model_node.memory_mb)
        except Exception as e:  # noqa: BLE001 - a service failure: one line for the user
            raise SessionError(f"{node} on {scale}", "", f"start_node failed: {e}") from None
        if not reply.success:
            raise SessionError(f"{node} on {scale}", "", f"the agent refused to start it: "
                                                         f"{reply.message}")
        if lease:
            with self._lock:
                self.started[node] = scale
        end = time.monotonic() + self.start_timeout_s
        while time.monotonic() < end:
            # The agent keeps one record per node (and one per standby); an ended process's
            # record no longer carries its pid.
            mine = [p for p in self.processes(scale)
                    if p.name.lstrip("/") == node and p.state != STANDBY]
            if mine and mine[0].state == RUNNING and mine[0].pid == reply.pid:
                return reply.pid
            if mine and mine[0].state in ENDED:
                p = mine[0]
                how = (f"signal {p.exit_signal}" if p.exit_signal else f"exit code {p.exit_code}")
                raise SessionError(f"{node} on {scale}", "", f"failed to start: it ended with "
                                   f"{how}; log {p.log_file}{_log_tail(p.log_file)}")
            time.sleep(0.2)
            self.tick()
        raise SessionError(f"{node} on {scale}", "", f"not registered with the master within "
                           f"{self.start_timeout_s:g} s of its start (pid {reply.pid})")

    def stop(self, node: str, scale: str):
        try:
            self.agents.stop(scale, node)
        finally:
            with self._lock:
                if self.started.get(node) == scale:
                    del self.started[node]
                if self.initial.get(node) == scale:
                    self._stopped_initial[node] = scale

    def move(self, node: str, scale: str):
        """`node` from where it runs now to `scale` (stop first: two instances would both use
        CPU, and roscpp nodes cannot hand a name over, see the agent's README)."""
        where = self.where(node)
        if where == scale:
            return
        if where is not None:
            self.stop(node, where)
        self.start(node, scale)

    def where(self, node: str) -> Optional[str]:
        with self._lock:
            if node in self.started:
                return self.started[node]
        scale = self.initial.get(node)
        return None if scale is None or node in self._stopped_initial else scale

    def _renew_leases(self):
        period = max(0.5, self.lease_s / 4)
        while not self._closing.wait(period):
            with self._lock:
                per_scale: Dict[str, List[str]] = {}
                for node, scale in self.started.items():
                    per_scale.setdefault(scale, []).append(node)
            for scale, nodes in per_scale.items():
                try:
                    self.agents.renew(scale, nodes, self.lease_s)
                except Exception:  # noqa: BLE001 - retried next period; the lease has slack
                    pass

    # -- samples --------------------------------------------------------------------------
    def record(self, on: bool):
        with self._lock:
            if on:
                self._samples.clear()
            self._recording = on

    def samples(self) -> List[CpuSample]:
        with self._lock:
            return list(self._samples)

    # -- teardown -------------------------------------------------------------------------
    def close(self, log: Callable[[str], None] = lambda line: None) -> List[str]:
        """Stops what this session started, starts again at home what it found running and
        stopped; returns what could not be done, in words (never raises)."""
        problems = []
        if not self._opened:
            return problems
        with self._lock:
            started = list(self.started.items())
        for node, scale in reversed(started):
            try:
                self.stop(node, scale)
            except Exception as e:  # noqa: BLE001 - go on with the rest; the lease ends it
                problems.append(f"stop {node} on {scale}: {e} (its lease ends it within "
                                f"{self.lease_s:g} s)")
        self._closing.set()
        for node, scale in list(self._stopped_initial.items()):
            try:
                log(f"starting {node} on {scale} again, where it ran before")
                self.start(node, scale, lease=False)
                del self._stopped_initial[node]
            except Exception as e:  # noqa: BLE001
                problems.append(f"start {node} on {scale} again: {e}")
        import rospy
        rospy.signal_shutdown("done")
        return problems


def check_running(session: AgentSession, node: str, scale: str):
    """SessionError when `node` no longer runs on `scale` (it ended during a measurement)."""
    for p in session.processes(scale):
        if p.name.lstrip("/") == node and p.state == RUNNING:
            return
    ended = [p for p in session.processes(scale) if p.name.lstrip("/") == node and p.state in ENDED]
    how = ""
    if ended:
        p = ended[-1]
        how = (f": signal {p.exit_signal}" if p.exit_signal else f": exit code {p.exit_code}") + \
            f"; log {p.log_file}{_log_tail(p.log_file)}"
    raise SessionError(f"{node} on {scale}", "", f"ended during its measurement{how}")
