"""`anyscale thresholds`, the ROS part: the subscriber fed through topic_tools throttle and mux,
the probe watched step by step, the results from thresholds_search.py written into the model.

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
import json
import os
import shlex
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
from typing import Dict, List, Optional

from .agent_session_ros import AgentSession, SessionError
from .model import ModelError
from .model_draft_ros import RateCounter, system_state
from .model_loader import read_yaml
from .model_todos import load_model_with_todos, parse_connection_spec
from .model_update import (CommentBlock, NumberEdit, connection_index, update_model_text,
                           write_text_atomically)
from .profile_plan import format_duration
from .progress import TimeProgress
from .thresholds_search import (ProbeBroken, StepResult, Thresholds, check_message,
                                compile_condition, describe_step, next_step, outage_ladder,
                                predict_seconds, rate_ladder, subscriber_remaps,
                                throttle_argument, thresholds)

CALLER = "/anyscale_thresholds"
THROTTLE_NODE = "anyscale_thresholds_throttle"
MUX_NODE = "anyscale_thresholds_mux"
SOURCE_COUNT_S = 3.0
SET_UP_ESTIMATE_S = 15.0      # bringing the system up and the subscriber's restart
PROBE_TOPIC_WAIT_S = 15.0
STOP_GRACE_S = 5.0
THRESHOLDS_PREFIX = "thresholds: "


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


class OwnProcess:
    """A process this command starts, in its own process group, its output in a log file."""

    def __init__(self, name: str, argv: List[str], log_dir: str):
        self.name = name
        self.log_path = os.path.join(log_dir, f"{name}.log")
        with open(self.log_path, "ab") as log:
            self.proc = subprocess.Popen(argv, stdout=log, stderr=subprocess.STDOUT,
                                         stdin=subprocess.DEVNULL, start_new_session=True)

    def alive(self) -> bool:
        return self.proc.poll() is None

    def log_tail(self, lines: int = 3) -> str:
        try:
            with open(self.log_path, errors="replace") as f:
                tail = [x.rstrip() for x in f.readlines()[-lines:] if x.strip()]
        except OSError:
            return ""
        return " | ".join(tail)

    def stop(self):
        """SIGINT to the group, SIGKILL after STOP_GRACE_S; reaped either way."""
        if self.proc.poll() is None:
            try:
                os.killpg(self.proc.pid, signal.SIGINT)
                self.proc.wait(timeout=STOP_GRACE_S)
            except subprocess.TimeoutExpired:
                os.killpg(self.proc.pid, signal.SIGKILL)
                self.proc.wait()
            except ProcessLookupError:
                self.proc.wait()


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
        end = time.monotonic()
        edges = [self._start] + self._times + [end]
        gaps = [b - a for a, b in zip(edges, edges[1:])]
        return len(self._times) / max(end - self._start, 1e-9), max(gaps)

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
        values = [v for _, v in checks if v is not None]
        return (sum(1 for ok, _ in checks if ok), len(checks),
                sum(values) / len(values) if values else None)

    def check_broken(self):
        with self._lock:
            if self._broken is not None:
                raise self._broken

    def unregister(self):
        if self._sub is not None:
            self._sub.unregister()


class ScriptProbe:
    """The user's command, run once every `period_s` while open: exit 0 passes, 1 fails, any
    other exit (or no exit within the timeout) breaks the probe."""

    def __init__(self, command: str, period_s: float):
        try:
            self.argv = shlex.split(command)
        except ValueError as e:
            raise ModelError("--probe-script", "", f"cannot split {command!r}: {e}") from None
        if not self.argv:
            raise ModelError("--probe-script", "", "empty command")
        exe = self.argv[0]
        if not (shutil.which(exe) or (os.sep in exe and os.access(exe, os.X_OK))):
            raise ModelError("--probe-script", "", f"{exe}: not an executable (give a path or "
                                                   "a command on PATH)")
        self.description = f"script `{command}` every {period_s:g} s"
        self.period_s = period_s
        self.timeout_s = max(10.0, 5 * period_s)
        self._lock = threading.Lock()
        self._results: List[bool] = []
        self._broken: Optional[ProbeBroken] = None
        self._stop = threading.Event()
        self._thread: Optional[threading.Thread] = None
        self.env: Dict[str, str] = dict(os.environ)

    def connect(self, tick):
        pass

    def _loop(self):
        while not self._stop.is_set():
            started = time.monotonic()
            try:
                run = subprocess.run(self.argv, capture_output=True, text=True,
                                     timeout=self.timeout_s, env=self.env)
            except subprocess.TimeoutExpired:
                self._fail(f"no exit within {self.timeout_s:g} s")
                return
            except OSError as e:
                self._fail(f"cannot run: {e.strerror}")
                return
            if run.returncode not in (0, 1):
                last = (run.stderr.strip().splitlines() or [""])[-1]
                self._fail(f"exit status {run.returncode} (0 = correct, 1 = not)"
                           + (f": {last}" if last else ""))
                return
            with self._lock:
                self._results.append(run.returncode == 0)
            self._stop.wait(max(0.0, self.period_s - (time.monotonic() - started)))

    def _fail(self, why: str):
        with self._lock:
            self._broken = ProbeBroken("--probe-script", "", f"{self.argv[0]}: {why}")

    def open(self):
        with self._lock:
            self._results = []
        self._stop.clear()
        self._thread = threading.Thread(target=self._loop, daemon=True, name="probe script")
        self._thread.start()

    def close(self):
        self._stop.set()
        if self._thread is not None:
            self._thread.join(self.timeout_s + 1)
        self.check_broken()
        with self._lock:
            return sum(self._results), len(self._results), None

    def check_broken(self):
        with self._lock:
            if self._broken is not None:
                raise self._broken

    def unregister(self):
        self._stop.set()


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
    import rosgraph
    loaded = load_model_with_todos(args.model)
    model = loaded.model
    pub, sub, topic = parse_connection_spec(model, args.connection)
    probe = (TopicProbe(args.probe, args.condition, args.value) if args.probe
             else ScriptProbe(args.probe_script, args.probe_period))
    outages = outage_ladder(args.outages)
    session = AgentSession(model, CALLER, start_timeout_s=args.start_timeout)
    log_dir = tempfile.mkdtemp(prefix="anyscale-thresholds-")
    chain = Chain(topic, log_dir)
    say = (lambda line: print(line, file=sys.stderr, flush=True))
    progress: Optional[TimeProgress] = None
    counter = arrivals = None
    rate_steps: List[StepResult] = []
    outage_steps: List[StepResult] = []
    try:
        session.open(sorted(set(session.home.values())))
        session.bring_home()
        instance = model.instance_name(pub, session.home[pub])
        counter = RateCounter([topic])
        time.sleep(1.0)          # the counter's connection comes up
        counter.open()
        time.sleep(SOURCE_COUNT_S)
        source = counter.close().get((topic, instance))
        counter.unregister()
        counter = None
        if source is None or source.hz <= 0:
            raise SessionError(args.connection, "", f"no message on {topic} from {instance} in "
                                                    f"{SOURCE_COUNT_S:g} s")
        ladder = rate_ladder(source.hz, args.rates)
        predicted = predict_seconds(len(ladder), outages, args.settle, args.step,
                                    SET_UP_ESTIMATE_S)
        say(f"anyscale thresholds: {pub} -> {sub} on {topic}, source {source.hz:.2f} Hz; rates "
            f"{', '.join(f'{r:g}' for r in ladder)} Hz, then interruptions of "
            f"{', '.join(f'{d:g}' for d in outages)} s; probe {probe.description}; at most "
            f"{format_duration(predicted)}")
        progress = TimeProgress(predicted)
        session.tick = progress.tick
        progress.phase(f"restarting {sub} fed through throttle")
        with session._lock:          # the hand-off the session keeps (AMCL's last pose)
            overrides = dict(session._handoff.get(sub, {}))
        chain.start_mux()
        chain.set_rate(source.hz, ladder[0])
        session.stop(sub, session.home[sub])
        chain.start_subscriber(model, sub, session.home[sub], overrides)
        master = rosgraph.Master(CALLER)
        wait_subscribed(master, model.instance_name(sub, session.home[sub]), chain.fed, chain.subscriber, args.start_timeout,
                        progress.tick)
        chain.select(chain.throttled)
        arrivals = ArrivalLog(chain.fed)
        probe.connect(progress.tick)

        while True:
            rate = next_step(ladder, rate_steps, args.quota)
            if rate is None:
                break
            progress.phase(f"{rate:g} Hz: settling")
            if rate_steps:
                chain.set_rate(source.hz, rate)
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
        found = thresholds(rate_steps, [], args.quota, args.improvement)
        at = found.freq_opt
        if not rate_steps[-1].correct(args.quota):
            # Known limit: a stateful subscriber (AMCL) may still be lost from the failed step;
            # a fresh start would need a state to start from that is not stale.
            progress.write(f"  warning: the interruptions follow an incorrect step at "
                           f"{rate_steps[-1].rate_hz:g} Hz; if {sub} keeps state, give --rates "
                           "that stop above its failure to judge them on a working subscriber")
        chain.set_rate(source.hz, at)
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
        found = thresholds(rate_steps, outage_steps, args.quota, args.improvement)
    finally:
        for listener in (counter, arrivals, probe):
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

    written = False
    if not args.dry_run:
        written = _write(args.model, pub, sub, topic, found, source.hz, probe.description,
                         args.quota)
    report = {"connection": f"{pub}:{sub}:{topic}", "source_hz": round(source.hz, 3),
              "probe": probe.description, "quota": args.quota,
              "steps": [{"rate_hz": s.rate_hz, "outage_s": s.outage_s, "passed": s.passed,
                         "checks": s.checks, "value_mean": s.value_mean,
                         "delivered_hz": round(s.delivered_hz, 3),
                         "correct": s.correct(args.quota)} for s in rate_steps + outage_steps],
              "freq_min": found.freq_min, "freq_opt": found.freq_opt,
              "tolerance": found.tolerance,
              "tolerance_is_lower_bound": found.tolerance_is_lower_bound,
              "freq_min_is_upper_bound": found.freq_min_is_upper_bound, "written": written}
    if args.json:
        print(json.dumps(report, indent=2))
        return 0
    print(f"{pub} -> {sub} on {topic}: source {source.hz:.2f} Hz; probe {probe.description}")
    for s in rate_steps + outage_steps:
        print("  " + describe_step(s, args.quota))
    print(summary_line(found))
    print(f"{args.model}: " + ("freq_min, freq_opt and tolerance written, with how they were "
                               "found" if written else "not changed (--dry-run)"))
    return 0


def summary_line(found: Thresholds) -> str:
    low = " (every rate tried was correct: it may be lower)" if found.freq_min_is_upper_bound \
        else ""
    tol = " (every interruption tried was correct: at least this)" \
        if found.tolerance_is_lower_bound else ""
    return (f"freq_min {found.freq_min:g} Hz{low}, freq_opt {found.freq_opt:g} Hz, tolerance "
            f"{found.tolerance:g} s{tol}")


def _write(path: str, pub: str, sub: str, topic: str, found: Thresholds, source_hz: float,
           probe: str, quota: float) -> bool:
    import datetime
    with open(path, encoding="utf-8") as f:
        text = f.read()
    index = connection_index(read_yaml(path), pub, sub, topic)
    item = ("connections", index)
    numbers = [NumberEdit(item + ("freq_min",), found.freq_min),
               NumberEdit(item + ("freq_opt",), found.freq_opt),
               NumberEdit(item + ("tolerance",), found.tolerance)]
    lines = (f"{datetime.datetime.now():%Y-%m-%d %H:%M} by `anyscale thresholds`: {topic} "
             f"({source_hz:.2f} Hz) through topic_tools throttle into {sub}; probe {probe}, "
             f"correct when {quota:.0%} of its checks pass;", summary_line(found))
    comments = [CommentBlock(item, THRESHOLDS_PREFIX, lines)]
    write_text_atomically(path, update_model_text(text, numbers, comments, path))
    return True
