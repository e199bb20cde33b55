"""`anyscale thresholds`, the pure part: the rates and interruptions to try, the probe's verdict
on each step, and freq_min, freq_opt and the tolerance that follow from them.

The paper found Table I by hand: feed the subscriber less and less, see where it stops working.
This does the same, step by step, with topic_tools throttle. The rate ladder goes down from the
source's own rate in the steps throttle can deliver (source / k, see rate_ladder; the
subscriber's state after a failed step is suspect: AMCL lost at 1 Hz stays lost when the rate
comes back, so the ladder stops at the first failure rather than trying lower rates on a broken
system); the interruptions go up from short to long, each after the stream has run at freq_opt
again, and stop at the first failure for the same reason. After a failed rate step they are
tried only once the subscriber works again at freq_opt (a probe window correct within
--recover); else the tolerance is not measured rather than judged on a broken system.

A probe gives, per step, how many of its checks passed: a topic probe one check per message
(the condition, a Python expression over `m` as in `rostopic echo --filter`), a script probe
one check per run (exit 0 passes, 1 fails). A step is correct when at least `quota` of its
checks passed (and there was at least one). Its score, for freq_opt, is the mean of the topic
probe's `--value` expression where one is given (lower is better: an error), else the share of
passed checks (higher is better).

- freq_min: the lowest rate such that it and every rate above it tried were correct.
- freq_opt: the lowest correct rate whose score is within `improvement` (relative) of the best
  score of any correct rate: above it the probe no longer improves.
- tolerance: the longest interruption such that it and every shorter one tried were correct;
  0 when even the shortest failed (a critical connection).
Nothing here talks to ROS (thresholds_ros.py and thresholds_chain_ros.py do).
"""
import math
from dataclasses import dataclass
from typing import Callable, List, Optional, Sequence, Tuple

from .model import ModelError

# The source's rate divided by these: 10 Hz gives 10, 5, 3.33, 2.5, 2, 1.67, 1.25, 1 Hz.
DEFAULT_DIVISORS = (1, 2, 3, 4, 5, 6, 8, 10)
DEFAULT_OUTAGES_S = (0.5, 1.0, 2.0, 3.0, 5.0, 8.0)


def compile_condition(text: str, what: str) -> Callable[[object], object]:
    """A Python expression over the message `m` (rostopic's --filter convention), compiled
    once; a syntax error is a ModelError naming the option."""
    try:
        code = compile(text, f"<{what}>", "eval")
    except SyntaxError as e:
        raise ModelError(what, "", f"not a Python expression over m: {e.msg}: {text!r}") \
            from None

    def evaluate(m):
        return eval(code, {"__builtins__": __builtins__, "math": math}, {"m": m})  # noqa: S307
    return evaluate


class ProbeBroken(ModelError):
    """The probe itself failed (its expression raised, its script crashed): no verdict."""


def check_message(condition: Callable, value: Optional[Callable], message,
                  what: str) -> Tuple[bool, Optional[float]]:
    """(passed, value) of one probe message; ProbeBroken when an expression raises."""
    try:
        passed = bool(condition(message))
        number = float(value(message)) if value is not None else None
    except Exception as e:  # noqa: BLE001 - any error of the user's expression: one line
        raise ProbeBroken(what, "", f"raised {type(e).__name__}: {e}") from None
    return passed, number


def summarise_checks(checks: Sequence[Tuple[bool, Optional[float]]]
                     ) -> Tuple[int, int, Optional[float]]:
    """(passed, checks, mean value or None) of a step's (passed, value) checks."""
    values = [v for _, v in checks if v is not None]
    return (sum(1 for ok, _ in checks if ok), len(checks),
            sum(values) / len(values) if values else None)


def rate_and_longest_silence(start: float, arrivals: Sequence[float], end: float
                             ) -> Tuple[float, float]:
    """(messages per second, longest silence in s) of the receipt times `arrivals` within
    [start, end]: what the subscriber got, and the interruption as it saw it."""
    edges = [start, *arrivals, end]
    gaps = [b - a for a, b in zip(edges, edges[1:])]
    return len(arrivals) / max(end - start, 1e-9), max(gaps)


@dataclass(frozen=True)
class StepResult:
    """One step: the stream at `rate_hz`, or interrupted for `outage_s` (then rate_hz is the
    rate around the interruption)."""
    rate_hz: float
    outage_s: float                 # 0 for a rate step
    passed: int
    checks: int
    value_mean: Optional[float]     # mean of --value over the checks, when given
    delivered_hz: float             # what the subscriber actually received

    def correct(self, quota: float) -> bool:
        return self.checks > 0 and self.passed >= quota * self.checks - 1e-9

    @property
    def pass_share(self) -> float:
        return self.passed / self.checks if self.checks else 0.0


def rate_ladder(source_hz: float, rates: Optional[Sequence[float]] = None) -> List[float]:
    """The rates to try, highest first: source_hz / k for the default divisors, or for each of
    `rates` the nearest source_hz / k. topic_tools throttle drops every message that comes
    sooner than 1/rate after the last one it passed, so from a periodic source it delivers only
    source/k (a 10 Hz laser throttled to 8 Hz gives 5 Hz): the ladder names what it delivers."""
    if not source_hz > 0:
        raise ModelError("source", "", f"expected a source rate > 0, got {source_hz:g}")
    divisors = DEFAULT_DIVISORS if not rates else [max(1, round(source_hz / r)) for r in rates
                                                   if r > 0]
    if not divisors:
        raise ModelError("--rates", "", "expected at least one rate > 0")
    return sorted({round(source_hz / k, 2) for k in divisors}, reverse=True)


def throttle_argument(source_hz: float, rate_hz: float) -> float:
    """The rate to give topic_tools throttle for it to pass every k-th message of a periodic
    source (rate_hz = source_hz / k): its minimum interval is set halfway between k-1 and k
    source intervals, so jitter neither lets the (k-1)-th through nor holds back the k-th. At
    k = 1 it is set far above the source, passing every message."""
    k = max(1, round(source_hz / rate_hz))
    return source_hz * 20 if k == 1 else source_hz / (k - 0.5)


def outage_ladder(outages: Optional[Sequence[float]] = None) -> List[float]:
    ladder = sorted({float(d) for d in (outages or DEFAULT_OUTAGES_S) if d > 0})
    if not ladder:
        raise ModelError("--outages", "", "expected at least one duration > 0")
    return ladder


def next_step(ladder: Sequence[float], results: Sequence[StepResult], quota: float
              ) -> Optional[float]:
    """The next rung of `ladder` to try, or None: all tried, or the last one failed."""
    if results and not results[-1].correct(quota):
        return None
    return ladder[len(results)] if len(results) < len(ladder) else None


def _better(a: float, b: float, lower_is_better: bool) -> bool:
    return a < b if lower_is_better else a > b


def _within(score: float, best: float, improvement: float, lower_is_better: bool) -> bool:
    """`score` is within `improvement` (a share of the best) of `best`."""
    slack = improvement * abs(best) if best else improvement
    return score <= best + slack if lower_is_better else score >= best - slack


@dataclass(frozen=True)
class Thresholds:
    freq_min: Optional[float]
    freq_opt: Optional[float]
    tolerance: Optional[float]
    tolerance_is_lower_bound: bool      # every interruption tried was correct
    freq_min_is_upper_bound: bool       # every rate tried was correct: it may be lower still
    tolerance_unmeasured: str = ""      # why no interruption was tried, if none was


def score_of(step: StepResult) -> float:
    return step.value_mean if step.value_mean is not None else step.pass_share


def find_rates(results: Sequence[StepResult], quota: float, improvement: float
               ) -> Tuple[Optional[float], Optional[float], bool]:
    """(freq_min, freq_opt, every rate correct) from the rate steps (any order)."""
    by_rate = sorted(results, key=lambda r: r.rate_hz, reverse=True)
    correct: List[StepResult] = []
    for step in by_rate:
        if not step.correct(quota):
            break
        correct.append(step)
    if not correct:
        return None, None, False
    lower_is_better = all(s.value_mean is not None for s in correct)
    scores = [score_of(s) for s in correct]
    best = scores[0]
    for s in scores[1:]:
        if _better(s, best, lower_is_better):
            best = s
    good = [s.rate_hz for s, sc in zip(correct, scores)
            if _within(sc, best, improvement, lower_is_better)]
    return correct[-1].rate_hz, min(good), len(correct) == len(by_rate)


def find_tolerance(results: Sequence[StepResult], quota: float) -> Tuple[Optional[float], bool]:
    """(tolerance, every interruption correct) from the interruption steps; None if none."""
    if not results:
        return None, False
    longest = 0.0
    ordered = sorted(results, key=lambda r: r.outage_s)
    for step in ordered:
        if not step.correct(quota):
            return longest, False
        longest = step.outage_s
    return longest, True


def thresholds(rate_steps: Sequence[StepResult], outage_steps: Sequence[StepResult],
               quota: float, improvement: float, unmeasured: str = "") -> Thresholds:
    """`unmeasured`: why the interruptions were not tried (then the tolerance is None)."""
    freq_min, freq_opt, all_rates = find_rates(rate_steps, quota, improvement)
    tolerance, all_outages = find_tolerance(outage_steps, quota)
    return Thresholds(freq_min, freq_opt, tolerance, all_outages, all_rates,
                      unmeasured if not outage_steps else "")


def predict_seconds(rates: int, outages: Sequence[float], settle_s: float, step_s: float,
                    start_s: float, recover_s: float = 0.0) -> float:
    """At most: the set-up, every rung of both ladders (a failure ends a ladder early) and
    the wait for the subscriber to recover from an incorrect rate step."""
    return (start_s + rates * (settle_s + step_s) + recover_s
            + sum(settle_s + d + step_s for d in outages))


def subscriber_remaps(model_remaps: Sequence[Tuple[str, str]], topic: str,
                      throttled: str) -> List[str]:
    """The subscriber's remap arguments with `topic` fed from `throttled`: a model remap whose
    target is `topic` now targets `throttled`, and `topic` itself is remapped (ROS matches
    remaps on resolved names, so this also catches a topic given as an argument, as relay's).
    Remaps are not chained in ROS 1, hence both."""
    plain = topic.lstrip("/")
    out = []
    for source, target in model_remaps:
        out.append(f"{source}:={throttled if target.lstrip('/') == plain else target}")
    out.append(f"/{plain}:={throttled}")
    return out


def describe_step(step: StepResult, quota: float) -> str:
    what = (f"{step.rate_hz:g} Hz" if not step.outage_s
            else f"{step.outage_s:g} s without messages (at {step.rate_hz:g} Hz)")
    value = "" if step.value_mean is None else f", mean value {step.value_mean:.4g}"
    verdict = "correct" if step.correct(quota) else "NOT correct"
    return (f"{what}: delivered {step.delivered_hz:.2f} Hz; probe passed {step.passed} of "
            f"{step.checks}{value}: {verdict}")
