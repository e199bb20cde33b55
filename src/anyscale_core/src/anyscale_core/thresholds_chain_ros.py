"""`anyscale thresholds`, what it starts and listens to (rospy): the chain that feeds the
subscriber, the arrival log of what the subscriber got, and the topic probe. The run that steps
through rates and interruptions with them is thresholds_ros.py.

The chain, all stock tools but the subscriber itself:

    PUB --TOPIC--> throttle --TOPIC_throttle--> mux --TOPIC_thresholds--> SUB (remapped)

- `topic_tools throttle messages TOPIC RATE TOPIC_throttle` sets the rate; it takes its rate
  only on the command line, so each rate step starts it anew (the settling time covers that).
- `topic_tools mux` cuts the stream for an interruption (`select __none`) and restores it
  (`select TOPIC_throttle`) with a service call: stopping and restarting the throttle instead
  would add its start and the subscriber's reconnection, a few hundred ms, to every cut.
- The subscriber is stopped at its agent and started here with its model command line plus
  the remap TOPIC -> TOPIC_thresholds (the agents start only the model's command line, with no
  extra remaps: that is their security boundary), with its state hand-off as private
  parameters, as the decision node would start it. Its model parameters are on the parameter
  server already: its agent set them when it started it.
"""
import threading
import time
from typing import Dict, List, Optional

from .agent_session_ros import SessionError
from .model import ModelError
from .model_draft_ros import system_state
from .process_group import OwnProcess
from .thresholds_search import (ProbeBroken, check_message, compile_condition,
                                rate_and_longest_silence, subscriber_remaps, summarise_checks,
                                throttle_argument)

THROTTLE_NODE = "anyscale_thresholds_throttle"
MUX_NODE = "anyscale_thresholds_mux"
PROBE_TOPIC_WAIT_S = 15.0


def find_executable(package: str, executable: str) -> str:
    """Where rosrun and roslaunch find a node's executable (roslib.packages.find_node)."""
    import roslib.packages
    try:
        found = roslib.packages.find_node(package, executable)
    except roslib.packages.ROSPkgException as e:
        raise ModelError(f"{package}/{executable}", "", str(e)) from None
    if not found:
        raise ModelError(f"{package}/{executable}", "", "no such executable in the package")
    return found[0]


class ArrivalLog:
    """Receipt times of the subscriber's input (the mux's output) while open: the rate it got
    and its longest silence (the interruption as the subscriber saw it). RateCounter counts
    but keeps no times, hence this."""

    def __init__(self, topic: str):
        import rospy
        self._times: List[float] = []
        self._open = False
        self._start = 0.0
        self._sub = rospy.Subscriber(topic, rospy.AnyMsg, self._on_message, queue_size=100)

    def _on_message(self, _msg):
        if self._open:
            self._times.append(time.monotonic())

    def open(self):
        self._times = []
        self._start = time.monotonic()
        self._open = True

    def close(self):
        """(messages per second, longest silence in s) since open()."""
        self._open = False
        return rate_and_longest_silence(self._start, self._times, time.monotonic())

    def unregister(self):
        self._sub.unregister()


class TopicProbe:
    """One check per message on the probe topic while open."""

    def __init__(self, topic: str, condition_text: str, value_text: Optional[str]):
        self.topic = topic
        self.description = f"{topic}: `{condition_text}`" + (
            f", value `{value_text}`" if value_text else "")
        self._condition = compile_condition(condition_text, "--condition")
        self._value = compile_condition(value_text, "--value") if value_text else None
        self._lock = threading.Lock()
        self._open = False
        self._checks: List = []
        self._broken: Optional[ProbeBroken] = None
        self._sub = None

    def connect(self, tick):
        import rostopic
        import rospy
        end = time.monotonic() + PROBE_TOPIC_WAIT_S
        msg_class = None
        while msg_class is None and time.monotonic() < end:
            msg_class, _, _ = rostopic.get_topic_class(self.topic, blocking=False)
            if msg_class is None:
                time.sleep(0.2)
                tick()
        if msg_class is None:
            raise ModelError("--probe", "", f"nobody publishes {self.topic} (waited "
                                            f"{PROBE_TOPIC_WAIT_S:g} s)")
        self._sub = rospy.Subscriber(self.topic, msg_class, self._on_message, queue_size=100)

    def _on_message(self, msg):
        with self._lock:
            if not self._open or self._broken is not None:
                return
            try:
                self._checks.append(check_message(self._condition, self._value, msg,
                                                  "--condition/--value"))
            except ProbeBroken as e:
                self._broken = e

    def open(self):
        with self._lock:
            self._checks, self._open = [], True

    def close(self):
        """(passed, checks, mean value or None); ProbeBroken if an expression raised."""
        with self._lock:
            self._open = False
            if self._broken is not None:
                raise self._broken
            checks = list(self._checks)
        return summarise_checks(checks)

    def check_broken(self):
        with self._lock:
            if self._broken is not None:
                raise self._broken

    def unregister(self):
        if self._sub is not None:
            self._sub.unregister()


class Chain:
    """throttle -> mux -> subscriber, started and stopped by this command."""

    def __init__(self, topic: str, log_dir: str):
        self.topic = topic
        self.throttled = f"{topic}_throttle"          # throttle's own default output name
        self.fed = f"{topic}_thresholds"
        self.log_dir = log_dir
        self.throttle: Optional[OwnProcess] = None
        self.mux: Optional[OwnProcess] = None
        self.subscriber: Optional[OwnProcess] = None
        self._throttle_exe = find_executable("topic_tools", "throttle")
        self._mux_exe = find_executable("topic_tools", "mux")

    def set_rate(self, source_hz: float, rate_hz: float):
        if self.throttle is not None:
            self.throttle.stop()
        arg = throttle_argument(source_hz, rate_hz)
        self.throttle = OwnProcess("throttle", [
            self._throttle_exe, "messages", self.topic, f"{arg:.6g}", self.throttled,
            f"__name:={THROTTLE_NODE}"], self.log_dir)

    def start_mux(self):
        self.mux = OwnProcess("mux", [self._mux_exe, self.fed, self.throttled,
                                      f"mux:={MUX_NODE}", f"__name:={MUX_NODE}"], self.log_dir)

    def select(self, topic: str):
        """Feeds the subscriber from `topic`, or from nothing with '__none'."""
        import rospy
        from topic_tools.srv import MuxSelect
        service = f"/{MUX_NODE}/select"
        rospy.wait_for_service(service, timeout=10.0)
        rospy.ServiceProxy(service, MuxSelect)(topic)

    def start_subscriber(self, model, sub: str, scale: str, overrides: Dict[str, float]):
        """`sub` under the name its agent gives it on `scale` (its parameters are there)."""
        node = model.node(sub)
        argv = [find_executable(node.launch.package, node.launch.type), *node.launch.args,
                *subscriber_remaps(node.launch.remaps, self.topic, self.fed),
                *(f"_{key}:={value!r}" for key, value in sorted(overrides.items())),
                f"__name:={model.instance_name(sub, scale).lstrip('/')}"]
        self.subscriber = OwnProcess(sub, argv, self.log_dir)

    def stop(self):
        for proc in (self.subscriber, self.throttle, self.mux):
            if proc is not None:
                proc.stop()


def wait_subscribed(master, node: str, topic: str, proc: OwnProcess, timeout_s: float, tick):
    """Until the master lists `node` as a subscriber of `topic`; SessionError with its log when
    it exits or does not get there in time."""
    end = time.monotonic() + timeout_s
    while time.monotonic() < end:
        _, subscribers, _ = system_state(master)
        if f"/{node.lstrip('/')}" in subscribers.get(topic, []):
            return
        if not proc.alive():
            raise SessionError(node, "", f"failed to start with its input remapped: exit "
                               f"{proc.proc.returncode}; log {proc.log_path}: {proc.log_tail()}")
        time.sleep(0.2)
        tick()
    raise SessionError(node, "", f"did not subscribe {topic} within {timeout_s:g} s; log "
                                 f"{proc.log_path}")
