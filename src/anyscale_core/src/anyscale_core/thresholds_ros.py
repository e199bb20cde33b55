"""`anyscale thresholds`, the rospy glue: the subscriber fed through topic_tools throttle and
mux, the probe watched step by step, the run from the source's rate to the thresholds found.
The ladders and verdicts are thresholds_search.py, the script probe script_probe.py, the report
and the model edit thresholds_report.py (all pure, no ROS).

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
Everything started here is in its own process group and ended at the end, also on an error or
Ctrl-C; the agent then starts the subscriber at home again if it ran before.
"""
import datetime
import json
import sys
import tempfile
import threading
import time
from typing import Dict, List, Optional

from .agent_session_ros import AgentSession, SessionError
from .model import ModelError
from .model_draft_ros import RateCounter, system_state
from .model_todos import load_model_with_todos, parse_connection_spec
from .process_group import OwnProcess
from .profile_plan import format_duration
from .progress import TimeProgress
from .script_probe import ScriptProbe
from .thresholds_report import ThresholdsRun, write_into_model
from .thresholds_search import (ProbeBroken, StepResult, check_message, compile_condition,
                                describe_step, next_step, outage_ladder, predict_seconds,
                                rate_and_longest_silence, rate_ladder, subscriber_remaps,
                                summarise_checks, throttle_argument, thresholds)

CALLER = "/anyscale_thresholds"
THROTTLE_NODE = "anyscale_thresholds_throttle"
MUX_NODE = "anyscale_thresholds_mux"
SOURCE_COUNT_S = 3.0
SET_UP_ESTIMATE_S = 15.0      # bringing the system up and the subscriber's restart
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


def _watch(probe, arrivals: ArrivalLog, progress: TimeProgress, actions):
    """Runs `actions` (a list of (seconds, callable or None)) with the probe and the arrival log
    open; returns (passed, checks, mean value, delivered Hz, longest silence)."""
    probe.open()
    arrivals.open()
    try:
        for seconds, action in actions:
            if action is not None:
                action()
            progress.sleep(seconds)
            probe.check_broken()
    finally:
        delivered, silence = arrivals.close()
        passed, checks, value = probe.close()
    return passed, checks, value, delivered, silence


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


def run(args) -> int:
    model = load_model_with_todos(args.model).model
    pub, sub, topic = parse_connection_spec(model, args.connection)
    probe = (TopicProbe(args.probe, args.condition, args.value) if args.probe
             else ScriptProbe(args.probe_script, args.probe_period))
    outages = outage_ladder(args.outages)
    session = AgentSession(model, CALLER, start_timeout_s=args.start_timeout)
    chain = Chain(topic, tempfile.mkdtemp(prefix="anyscale-thresholds-"))
    say = (lambda line: print(line, file=sys.stderr, flush=True))
    progress: Optional[TimeProgress] = None
    arrivals: Optional[ArrivalLog] = None
    rate_steps: List[StepResult] = []
    outage_steps: List[StepResult] = []
    try:
        session.open(sorted(set(session.home.values())))
        session.bring_home()
        source_hz = measure_source(model.instance_name(pub, session.home[pub]), topic,
                                   args.connection)
        ladder = rate_ladder(source_hz, args.rates)
        predicted = predict_seconds(len(ladder), outages, args.settle, args.step,
                                    SET_UP_ESTIMATE_S, args.recover)
        say(f"anyscale thresholds: {pub} -> {sub} on {topic}, source {source_hz:.2f} Hz; rates "
            f"{', '.join(f'{r:g}' for r in ladder)} Hz, then interruptions of "
            f"{', '.join(f'{d:g}' for d in outages)} s; probe {probe.description}; at most "
            f"{format_duration(predicted)}")
        progress = TimeProgress(predicted)
        session.tick = progress.tick
        feed_subscriber(session, chain, sub, source_hz, ladder[0], args.start_timeout, progress)
        arrivals = ArrivalLog(chain.fed)
        probe.connect(progress.tick)
        step_rates(chain, probe, arrivals, progress, args, sub, source_hz, ladder, rate_steps)
        at = thresholds(rate_steps, [], args.quota, args.improvement).freq_opt
        chain.set_rate(source_hz, at)
        unmeasured = ""
        if not rate_steps[-1].correct(args.quota) and \
                not recover(probe, arrivals, progress, args, at):
            # A stateful subscriber (AMCL) may stay lost after the failed step, and a fresh
            # start would need a state to start from that is not stale: interruptions judged
            # on it would say nothing of the connection.
            unmeasured = (f"{sub} did not work again within {args.recover:g} s at {at:g} Hz "
                          f"after the incorrect step at {rate_steps[-1].rate_hz:g} Hz; give "
                          "--rates that stop above it")
            progress.write(f"  {unmeasured}")
        else:
            step_outages(chain, probe, arrivals, progress, args, at, outages, outage_steps)
        found = thresholds(rate_steps, outage_steps, args.quota, args.improvement, unmeasured)
    finally:
        for listener in (arrivals, probe):
            if listener is not None:
                listener.unregister()
        if progress is not None:
            progress.phase("stopping what was started")
        chain.stop()
        problems = session.close(log=say)
        if progress is not None:
            progress.close()
        for problem in problems:
            say(f"anyscale thresholds: warning: {problem}")

    result = ThresholdsRun(pub, sub, topic, source_hz, probe.description, args.quota,
                           rate_steps + outage_steps, found)
    written = False
    if not args.dry_run:
        write_into_model(args.model, result, f"{datetime.datetime.now():%Y-%m-%d %H:%M}")
        written = True
    if args.json:
        print(json.dumps(result.as_json(written), indent=2))
        return 0
    for line in result.text_lines(args.model, written):
        print(line)
    return 0


def measure_source(instance: str, topic: str, connection: str) -> float:
    """The rate at which `instance` publishes `topic`, counted for SOURCE_COUNT_S."""
    counter = RateCounter([topic])
    try:
        time.sleep(1.0)          # the counter's connection comes up
        counter.open()
        time.sleep(SOURCE_COUNT_S)
        source = counter.close().get((topic, instance))
    finally:
        counter.unregister()
    if source is None or source.hz <= 0:
        raise SessionError(connection, "", f"no message on {topic} from {instance} in "
                                           f"{SOURCE_COUNT_S:g} s")
    return source.hz


def feed_subscriber(session: AgentSession, chain: Chain, sub: str, source_hz: float,
                    first_rate: float, start_timeout_s: float, progress: TimeProgress):
    """Stops `sub` at its agent and starts it here, fed through the throttle at `first_rate`
    and the mux, with the hand-off the session keeps (AMCL's last pose)."""
    import rosgraph
    progress.phase(f"restarting {sub} fed through throttle")
    overrides = session.handoff(sub)
    chain.start_mux()
    chain.set_rate(source_hz, first_rate)
    home = session.home[sub]
    session.stop(sub, home)
    chain.start_subscriber(session.model, sub, home, overrides)
    wait_subscribed(rosgraph.Master(CALLER), session.model.instance_name(sub, home), chain.fed,
                    chain.subscriber, start_timeout_s, progress.tick)
    chain.select(chain.throttled)


def step_rates(chain: Chain, probe, arrivals: ArrivalLog, progress: TimeProgress, args,
               sub: str, source_hz: float, ladder: List[float], rate_steps: List[StepResult]):
    """Down the rate ladder until a step is incorrect (appended to `rate_steps`); SessionError
    when the probe fails already at the first, the source's full rate."""
    while True:
        rate = next_step(ladder, rate_steps, args.quota)
        if rate is None:
            return
        progress.phase(f"{rate:g} Hz: settling")
        if rate_steps:
            chain.set_rate(source_hz, rate)
        progress.sleep(args.settle)
        progress.phase(f"{rate:g} Hz: probing")
        passed, checks, value, delivered, _ = _watch(probe, arrivals, progress,
                                                     [(args.step, None)])
        step = StepResult(rate, 0.0, passed, checks, value, delivered)
        rate_steps.append(step)
        progress.write("  " + describe_step(step, args.quota))
        if len(rate_steps) == 1 and not step.correct(args.quota):
            raise SessionError("probe", "", f"never passed at the source's full rate "
                               f"{rate:g} Hz ({passed} of {checks} checks of "
                               f"{probe.description}): check the probe, and that "
                               f"{sub} works unthrottled")


def recover(probe, arrivals: ArrivalLog, progress: TimeProgress, args, at: float) -> bool:
    """After an incorrect rate step, the stream back at `at` Hz: whether a probe window of
    --step seconds is correct again within --recover seconds."""
    deadline = time.monotonic() + args.recover
    while True:
        progress.phase(f"{at:g} Hz: waiting for the subscriber to work again")
        passed, checks, value, delivered, _ = _watch(probe, arrivals, progress,
                                                     [(args.step, None)])
        window = StepResult(at, 0.0, passed, checks, value, delivered)
        progress.write("  recovering: " + describe_step(window, args.quota))
        if window.correct(args.quota):
            return True
        if time.monotonic() + args.step > deadline:
            return False


def step_outages(chain: Chain, probe, arrivals: ArrivalLog, progress: TimeProgress, args,
                 at: float, outages: List[float], outage_steps: List[StepResult]):
    """Up the interruption ladder at `at` Hz until a step is incorrect (appended to
    `outage_steps`): the mux cuts the stream, then restores it."""
    for outage in outages:
        if outage_steps and not outage_steps[-1].correct(args.quota):
            break
        progress.phase(f"{outage:g} s cut at {at:g} Hz: settling")
        progress.sleep(args.settle)
        progress.phase(f"{outage:g} s cut at {at:g} Hz: probing")
        passed, checks, value, delivered, silence = _watch(
            probe, arrivals, progress,
            [(outage, lambda: chain.select("__none")),
             (args.step, lambda: chain.select(chain.throttled))])
        step = StepResult(at, outage, passed, checks, value, delivered)
        outage_steps.append(step)
        progress.write("  " + describe_step(step, args.quota)
                       + f" (longest silence seen {silence:.2f} s)")
