"""`anyscale thresholds`, the rospy run: the source's rate measured, the subscriber restarted
behind the chain, then down the rate ladder and up the interruption ladder step by step, to the
thresholds found. The chain (throttle, mux, the remapped subscriber), the arrival log and the
topic probe are thresholds_chain_ros.py; the ladders and verdicts thresholds_search.py, the
script probe script_probe.py, the report and the model edit thresholds_report.py (all pure, no
ROS).

Everything started here is in its own process group and ended at the end, also on an error or
Ctrl-C; the agent then starts the subscriber at home again if it ran before.
"""
import datetime
import json
import sys
import tempfile
import time
from typing import List, Optional

from .agent_session_ros import AgentSession, SessionError
from .model_draft_ros import RateCounter
from .model_todos import load_model_with_todos, parse_connection_spec
from .profile_plan import format_duration
from .progress import TimeProgress
from .script_probe import ScriptProbe
from .thresholds_chain_ros import ArrivalLog, Chain, TopicProbe, wait_subscribed
from .thresholds_report import ThresholdsRun, write_into_model
from .thresholds_search import (StepResult, describe_step, next_step, outage_ladder,
                                predict_seconds, rate_ladder, thresholds)

CALLER = "/anyscale_thresholds"
SOURCE_COUNT_S = 3.0
SET_UP_ESTIMATE_S = 15.0      # bringing the system up and the subscriber's restart


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
