"""The test bed's monitor node (evaluation only, not part of a deployment): records what a run
did into a TestbedRecord (JSON) and prints mapping changes as they happen and a table at the
end. It runs on the robot, so its receive times are what the robot's subscribers saw.

It also samples /proc for the processes of the model's nodes (the agents name them with
`__name:=`) and their network namespace: on the one-machine test bed every scale's processes
share one PID namespace, so two live instances of a node are visible even when the link
between their scales is down and the master only knows one of them. A warm standby
(anyscale_agent_cpp's python_standby; comm "python_standby", then "standby:...") has the
node's command line but has not contacted the master: it is no instance until the agent
starts it."""
import math
import os
import struct
import sys
import threading
import time
from typing import Dict, List, Optional, Set

import rosgraph
import roslib.message
import rospy
from anyscale_msgs.msg import Mapping as MappingMsg
from anyscale_msgs.msg import CostEstimates, MigrationEvent, ScaleStatus
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PoseWithCovarianceStamped
from nav_msgs.msg import Odometry
from std_msgs.msg import Float32, String
from visualization_msgs.msg import MarkerArray

from anyscale_core.model import ModelError
from anyscale_core.model_loader import load_model
from anyscale_core.ros_convert import EVENT_NAMES

from .proc_census import is_standby_comm
from .record_saver import BackgroundSaver
from .testbed_figures import colour_violations, format_summary, tolerance_violations
from .testbed_record import (DECISION_PARAMS, LINK_AHEAD_STATUS, EventRecord, ProcessSample,
                             TestbedRecord)


def say(line: str):
    """One line on stdout with the prefix the test-bed script echoes to the console."""
    print(f"[testbed] {line}", flush=True)


def node_processes(instances: Dict[str, str], master_uri: str,
                   paused: Optional[Set[str]] = None,
                   pids: Optional[Dict[str, List[int]]] = None) -> Dict[str, List[str]]:
    """node name -> network namespace (the /proc/PID/ns/net link) of each live process of
    this ROS system (its ROS_MASTER_URI is ours: other systems on the machine do not count).
    `instances`: each name a node's instance may run under (e.g. amcl, amcl__laptop) -> node.
    A stopped process (SIGSTOP: a paused instance, launch.pause_at_home) publishes nothing and
    is no live one; its instance name goes into `paused`, if given. `pids`, if given, gets
    node name -> the pid of each live process, in the order of its namespaces (the fault soak
    signals them and reads their memory)."""
    wanted = {f"__name:={i}".encode(): n for i, n in instances.items()}
    ours = f"ROS_MASTER_URI={master_uri}".encode()
    found: Dict[str, List[str]] = {n: [] for n in set(instances.values())}
    for pid in filter(str.isdigit, os.listdir("/proc")):
        try:
            with open(f"/proc/{pid}/cmdline", "rb") as f:
                args = f.read().split(b"\0")
            if not any(a in wanted for a in args):
                continue
            with open(f"/proc/{pid}/environ", "rb") as f:
                if ours not in f.read().split(b"\0"):
                    continue
            with open(f"/proc/{pid}/stat", "rb") as f:
                stat = f.read()
            comm, state = stat.split(b"(", 1)[1].rsplit(b")", 1)
            if state.split()[0] == b"Z" or is_standby_comm(comm):
                continue            # a zombie or a standby publishes nothing
            if _is_fork_of(int(state.split()[1]), args, comm):
                continue            # an agent's child between its fork and its exec
            if state.split()[0] == b"T":
                if paused is not None:
                    paused.update(a.decode()[len("__name:="):] for a in args if a in wanted)
                continue
            netns = os.readlink(f"/proc/{pid}/ns/net")
            for a in args:
                if a in wanted:
                    found[wanted[a]].append(netns)
                    if pids is not None:
                        pids.setdefault(wanted[a], []).append(int(pid))
        except OSError:
            continue                    # ended while we looked
    return found


def _is_fork_of(parent: int, args: List[bytes], comm: bytes) -> bool:
    """Whether a process with this command line and comm is a fork of `parent` not yet exec'd
    (an agent's child before its exec): the parent has both too. A warm standby's child is its
    node: the standby has renamed itself."""
    try:
        with open(f"/proc/{parent}/cmdline", "rb") as f:
            if f.read().split(b"\0") != args:
                return False
        with open(f"/proc/{parent}/stat", "rb") as f:
            return f.read().split(b"(", 1)[1].rsplit(b")", 1)[0] == comm
    except OSError:
        return False


def header_stamp(buff: bytes) -> Optional[float]:
    """The stamp (s) of a serialised message that starts with a std_msgs/Header (seq, then the
    stamp's secs and nsecs, uint32 each), None if too short for one."""
    if len(buff) < 12:
        return None
    secs, nsecs = struct.unpack_from("<II", buff, 4)
    return secs + nsecs * 1e-9


class TestbedMonitor:
    def __init__(self):
        model_path = rospy.get_param("~model")
        self.model = load_model(model_path)
        self.record_path = rospy.get_param("~record_path")
        self.saver = BackgroundSaver(self.record_path)
        self.duration_s = float(rospy.get_param("~duration_s", 0.0))
        self.exit_when_done = bool(rospy.get_param("~exit_when_done", True))
        self.rec = TestbedRecord(started_wall=time.time(), world=rospy.get_param("~world", ""),
                                 link=rospy.get_param("~link", ""),
                                 scales=[self.model.master.name] + [
                                     s.name for s in self.model.remote_scales])
        self.decision_params_read = False
        self.lock = threading.Lock()
        self.link_up = True
        self.markers = set()        # ids of the AR markers recognised so far
        self.done = threading.Event()
        # Output topics of the nodes that may move, and the tolerances of their connections.
        critical = {n for c in self.model.connections if c.tolerance == 0
                    for n in (c.publisher, c.subscriber)}
        movable = {n.name for n in self.model.nodes
                   if n.pinned is None and n.name not in critical}
        self.outputs: Dict[str, str] = {}
        self.tolerances: Dict[str, float] = {}
        for c in self.model.connections:
            if c.publisher in movable and c.tolerance > 0:
                self.outputs.setdefault(c.publisher, c.topic)
                self.tolerances[c.topic] = max(self.tolerances.get(c.topic, 0.0), c.tolerance)
                self.rec.subscribers.setdefault(c.topic, []).append(c.subscriber)
        # In the record too: its violations can be read, and recomputed, without the model.
        self.rec.outputs, self.rec.tolerances = dict(self.outputs), dict(self.tolerances)
        # The critical connections' topics as well, on request (the fault soak checks that they
        # never run below freq_min): off by default, as every subscriber adds to the work of
        # the publishers on the robot, whose CPU the test bed's calibration measured without.
        if rospy.get_param("~record_critical", False):
            for c in self.model.connections:
                if c.tolerance == 0:
                    self.rec.critical_freq_min[c.topic] = max(
                        self.rec.critical_freq_min.get(c.topic, 0.0), float(c.freq_min))
        self.has_header: Dict[str, bool] = {}     # message type -> whether it has a header
        self.node_names = [n.name for n in self.model.nodes]
        self.master = rosgraph.Master(rospy.get_name())
        self.pose_topic = rospy.get_param("~pose_topic", "/amcl_pose")
        self.markers_topic = rospy.get_param("~markers_topic", "/ar_markers")
        for topic in sorted(set(self.outputs.values()) | set(self.rec.critical_freq_min)
                            | {self.pose_topic, self.markers_topic} - {""}):
            self.rec.receipts[topic] = []
            self.rec.senders[topic] = []
            rospy.Subscriber(topic, rospy.AnyMsg, self._on_output, callback_args=topic,
                             queue_size=50)
        # Inputs of the moving nodes (and of what feeds them): a silence of an output is then
        # told apart from a stall of its inputs. Off by default: each is one more subscriber
        # that the robot's publishers serve on the robot's quota. Never a heavy stream: it
        # would cross the robot's link to reach this recorder.
        inputs = rospy.get_param("~record_inputs", [])
        if not isinstance(inputs, list) or not all(isinstance(t, str) and t.startswith("/")
                                                   for t in inputs):
            raise SystemExit("testbed_monitor: ~record_inputs must be a list of resolved topic "
                             f"names such as [/scan, /odom], got {inputs!r}")
        self.rec.inputs = list(dict.fromkeys(inputs))
        for topic in self.rec.inputs:
            if topic in self.rec.receipts:
                continue                    # recorded already (an output)
            self.rec.receipts[topic] = []
            rospy.Subscriber(topic, rospy.AnyMsg, self._on_input, callback_args=topic,
                             queue_size=100)
        rospy.Subscriber("/anyscale/mapping", MappingMsg, self._on_mapping, queue_size=5)
        rospy.Subscriber("/anyscale/events", MigrationEvent, self._on_event, queue_size=50)
        rospy.Subscriber("/anyscale/wifi/bandwidth_mbps", Float32, self._on_bandwidth,
                         queue_size=10)
        rospy.Subscriber("/anyscale/status", ScaleStatus, self._on_scale_status, queue_size=10)
        rospy.Subscriber("/anyscale/cost_estimates", CostEstimates, self._on_costs, queue_size=1)
        rospy.Subscriber("/diagnostics", DiagnosticArray, self._on_diagnostics, queue_size=10)
        rospy.Subscriber(rospy.get_param("~ground_truth_topic", "/sim/ground_truth"), Odometry,
                         self._on_truth, queue_size=20)
        rospy.Subscriber(rospy.get_param("~status_topic", "/navigation/status"), String,
                         self._on_status, queue_size=5)
        say(f"recording to {self.record_path}")

    def now(self) -> float:
        return time.time() - self.rec.started_wall

    # --- callbacks ------------------------------------------------------------------------------
    def _on_input(self, _msg, topic):
        now = self.now()
        with self.lock:
            self.rec.receipts[topic].append(now)

    def _on_output(self, msg, topic):
        now = self.now()
        # rospy puts the sending connection's header on each message it delivers.
        header = getattr(msg, "_connection_header", {})
        sender = header.get("callerid", "")
        stamp = (self._stamp(msg, header.get("type", "")) if topic in self.rec.critical_freq_min
                 else None)
        with self.lock:
            self.rec.receipts[topic].append(now)
            if stamp is not None:
                self.rec.stamps.setdefault(topic, []).append(
                    (now, stamp - self.rec.started_wall))
            senders = self.rec.senders[topic]
            if not senders or senders[-1][1] != sender:
                senders.append((now, sender))
        if topic == self.pose_topic:
            # One rospy subscription per topic and process: the pose comes out of the raw one.
            # At its stamp, not its arrival: after a partition heals, TCP may still deliver a
            # pose the old instance sent before the link went down.
            pose = PoseWithCovarianceStamped().deserialize(msg._buff)
            p, stamp = pose.pose.pose.position, pose.header.stamp.to_sec()
            with self.lock:
                self.rec.estimate.append((stamp - self.rec.started_wall, p.x, p.y))
        elif topic == self.markers_topic:
            ids = {m.id for m in MarkerArray().deserialize(msg._buff).markers}
            if not ids <= self.markers:
                with self.lock:
                    self.markers |= ids
                    self.rec.markers_seen = sorted(self.markers)

    def _stamp(self, msg, msg_type: str) -> Optional[float]:
        """The header stamp (s) of a raw message whose type has a header, else None."""
        if msg_type not in self.has_header:
            cls = roslib.message.get_message_class(msg_type) if msg_type else None
            self.has_header[msg_type] = bool(cls is not None and cls._has_header)
        return header_stamp(msg._buff) if self.has_header[msg_type] else None

    def _on_mapping(self, msg):
        mapping = {a.node: a.scale for a in msg.assignments}
        if not self.decision_params_read:
            self.decision_params_read = True
            self._keep_decision_params(msg._connection_header.get("callerid", ""))
        with self.lock:
            before = self.rec.mappings[-1][1] if self.rec.mappings else None
            self.rec.mappings.append((self.now(), mapping, msg.perf, msg.objective))
        off = sorted(n for n, s in mapping.items() if s != self.model.master.name)
        if before != mapping:
            say(f"t={self.now():6.1f} s  mapping: " +
                ("all on " + self.model.master.name if not off else
                 ", ".join(f"{n}@{mapping[n]}" for n in off)) + f"  (Perf {msg.perf:.0f})")

    def _keep_decision_params(self, decision_node: str):
        """The decision node's parameters the figures are judged by, once (a master call)."""
        try:
            params = rospy.get_param(decision_node, {}) if decision_node else {}
        except (rospy.ROSException, KeyError, OSError) as e:
            rospy.logwarn("testbed monitor: %s's parameters unreadable: %s", decision_node, e)
            return
        kept = {k: params[k] for k in DECISION_PARAMS if isinstance(params, dict) and k in params}
        with self.lock:
            self.rec.decision_params = kept

    def _on_event(self, msg):
        e = EventRecord(self.now(), EVENT_NAMES.get(msg.kind, str(msg.kind)), msg.node,
                        msg.from_scale, msg.to_scale, msg.reason, float(msg.duration_s),
                        msg.success, msg.header.stamp.to_sec() - self.rec.started_wall)
        with self.lock:
            self.rec.events.append(e)
        if e.kind != "start":
            took = f", running after {e.duration_s:.2f} s" if math.isfinite(e.duration_s) else ""
            say(f"t={e.decided_t:6.1f} s  {e.kind} {e.node} {e.from_scale or '-'} -> "
                f"{e.to_scale}: {e.reason}{took}")

    def _on_bandwidth(self, msg):
        up = msg.data > 0
        with self.lock:
            self.rec.bandwidth.append((self.now(), float(msg.data)))
            changed, self.link_up = up != self.link_up, up
        if changed:
            say(f"t={self.now():6.1f} s  WiFi " + (f"back: {msg.data:.1f} Mbit/s" if up
                                                   else "lost (no coverage)"))

    def _on_scale_status(self, msg):
        with self.lock:
            self.rec.scale_cpu.setdefault(msg.scale, []).append((self.now(),
                                                                 float(msg.cpu_percent)))

    def _on_costs(self, msg):
        costs = [{"node": c.node, "scale": c.scale, "model_percent": float(c.model_percent),
                  "live_percent": float(c.live_percent),
                  "measured_percent": float(c.measured_percent), "samples": int(c.samples),
                  "lower_bound": bool(c.lower_bound), "failures": int(c.failures)}
                 for c in msg.estimates]
        with self.lock:
            self.rec.cost_estimates = costs

    def _on_diagnostics(self, msg):
        """The decision node's "link ahead" status, kept where it changes: what the forecast
        made the engine do (a node held home makes no event) and whether there was one."""
        for status in msg.status:
            if not status.name.endswith(LINK_AHEAD_STATUS):
                continue
            available = any(not kv.value.startswith("no forecast") for kv in status.values)
            note = (status.message, available)
            with self.lock:
                if not self.rec.link_ahead or tuple(self.rec.link_ahead[-1][1:]) != note:
                    self.rec.link_ahead.append((self.now(),) + note)

    def _on_truth(self, msg):
        p, t = msg.pose.pose.position, msg.header.stamp.to_sec() - self.rec.started_wall
        q = msg.pose.pose.orientation
        yaw = math.atan2(2.0 * (q.w * q.z + q.x * q.y), 1.0 - 2.0 * (q.y * q.y + q.z * q.z))
        with self.lock:
            if not self.rec.truth or t - self.rec.truth[-1][0] >= 0.1:
                self.rec.truth.append((t, p.x, p.y))
                self.rec.truth_yaw.append((t, yaw))

    def _on_status(self, msg):
        with self.lock:
            self.rec.navigation_status.append((self.now(), msg.data))
        if msg.data.startswith("done") and self.exit_when_done and not self.done.is_set():
            say(f"t={self.now():6.1f} s  navigation: {msg.data}")     # once: the run ends here
            self.done.set()

    # --- sampling -------------------------------------------------------------------------------
    def _sample(self):
        paused = set()
        instances = node_processes(
            {self.model.instance_name(n, s).lstrip("/"): n
             for n in self.node_names for s in self.model.scale_names},
            rosgraph.get_master_uri(), paused)
        try:
            publishers = {t: sorted(nodes) for t, nodes in self.master.getSystemState()[0]
                          if t in self.rec.receipts}
        except Exception:  # noqa: BLE001 - the master is ours; a failed poll is skipped
            publishers = None
        now = self.now()
        with self.lock:
            self.rec.processes.append(ProcessSample(now, self.link_up, instances,
                                                    sorted("/" + p for p in paused)))
            if publishers is not None:      # same time as its process sample
                self.rec.master_publishers.append((now, publishers))

    def run(self):
        rate = rospy.Rate(float(rospy.get_param("~sample_rate_hz", 5.0)))
        last_save = time.monotonic()
        ended_by = "shutdown"
        while not rospy.is_shutdown():
            if self.done.is_set():
                ended_by = "done"
                break
            if self.duration_s > 0 and self.now() >= self.duration_s:
                ended_by = "duration"
                break
            self._sample()
            if time.monotonic() - last_save > 5.0:
                with self.lock:
                    copy = self.rec.snapshot()
                copy.violations = tolerance_violations(copy)
                self.saver.start(copy)      # a killed run still leaves its record
                last_save = time.monotonic()
            try:
                rate.sleep()
            except rospy.ROSInterruptException:
                break
        with self.lock:
            self.rec.finished_t = self.now()
            self.rec.ended_by = ended_by
            self.rec.violations = tolerance_violations(self.rec)
            last = self.rec.snapshot()
        self.saver.finish(last)
        terminal = sys.stdout.isatty()     # on the test bed a pipe: run_testbed.py colours
        for line in format_summary(self.rec, self.outputs, self.tolerances).splitlines():
            say(colour_violations(line, terminal))


def main(argv=None) -> int:
    rospy.init_node("testbed_monitor", argv=argv, disable_signals=False)
    try:
        monitor = TestbedMonitor()
    except KeyError as e:
        rospy.logfatal("testbed monitor: parameter %s is required", e)
        return 1
    except ModelError as e:
        rospy.logfatal("testbed monitor: %s", e)
        return 1
    monitor.run()
    return 0


if __name__ == "__main__":
    sys.exit(main())
