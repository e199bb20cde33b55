"""`anyscale thresholds`, what it reports (pure, no ROS): the steps and the thresholds found as
text or JSON, and freq_min, freq_opt and the tolerance written into the model's connection with
a comment block saying how they were found (every other byte of the file kept; a tolerance
that was not measured is left as it was)."""
from dataclasses import dataclass
from typing import List, Sequence

from .model_loader import read_yaml
from .model_update import (CommentBlock, NumberEdit, connection_index, update_model_text,
                           write_text_atomically)
from .thresholds_search import StepResult, Thresholds, describe_step

THRESHOLDS_PREFIX = "thresholds: "


@dataclass(frozen=True)
class ThresholdsRun:
    """One run's results: the connection, its source's rate, the probe, the steps (the rate
    steps, then the interruptions) and the thresholds that follow from them."""
    pub: str
    sub: str
    topic: str
    source_hz: float
    probe: str                      # the probe's description
    quota: float
    steps: Sequence[StepResult]
    found: Thresholds

    def as_json(self, written: bool) -> dict:
        found = self.found
        return {"connection": f"{self.pub}:{self.sub}:{self.topic}",
                "source_hz": round(self.source_hz, 3), "probe": self.probe,
                "quota": self.quota,
                "steps": [{"rate_hz": s.rate_hz, "outage_s": s.outage_s, "passed": s.passed,
                           "checks": s.checks, "value_mean": s.value_mean,
                           "delivered_hz": round(s.delivered_hz, 3),
                           "correct": s.correct(self.quota)} for s in self.steps],
                "freq_min": found.freq_min, "freq_opt": found.freq_opt,
                "tolerance": found.tolerance,
                "tolerance_is_lower_bound": found.tolerance_is_lower_bound,
                "tolerance_unmeasured": found.tolerance_unmeasured,
                "freq_min_is_upper_bound": found.freq_min_is_upper_bound, "written": written}

    def text_lines(self, model_path: str, written: bool) -> List[str]:
        return ([f"{self.pub} -> {self.sub} on {self.topic}: source {self.source_hz:.2f} Hz; "
                 f"probe {self.probe}"]
                + ["  " + describe_step(s, self.quota) for s in self.steps]
                + [summary_line(self.found),
                   f"{model_path}: " + ("freq_min, freq_opt and tolerance written, with how "
                                        "they were found" if written
                                        else "not changed (--dry-run)")])


def summary_line(found: Thresholds) -> str:
    low = " (every rate tried was correct: it may be lower)" if found.freq_min_is_upper_bound \
        else ""
    if found.tolerance is None:
        tolerance = f"tolerance not measured: {found.tolerance_unmeasured or 'no interruption'}"
    else:
        tol = " (every interruption tried was correct: at least this)" \
            if found.tolerance_is_lower_bound else ""
        tolerance = f"tolerance {found.tolerance:g} s{tol}"
    return f"freq_min {found.freq_min:g} Hz{low}, freq_opt {found.freq_opt:g} Hz, {tolerance}"


def write_into_model(path: str, run: ThresholdsRun, when: str):
    """freq_min, freq_opt and tolerance into the connection's item in the model file at `path`,
    with a comment block above it; `when` is the time the block names."""
    with open(path, encoding="utf-8") as f:
        text = f.read()
    index = connection_index(read_yaml(path), run.pub, run.sub, run.topic)
    item = ("connections", index)
    numbers = [NumberEdit(item + ("freq_min",), run.found.freq_min),
               NumberEdit(item + ("freq_opt",), run.found.freq_opt)]
    if run.found.tolerance is not None:     # not measured: the model's own value stays
        numbers.append(NumberEdit(item + ("tolerance",), run.found.tolerance))
    lines = (f"{when} by `anyscale thresholds`: {run.topic} ({run.source_hz:.2f} Hz) through "
             f"topic_tools throttle into {run.sub}; probe {run.probe}, correct when "
             f"{run.quota:.0%} of its checks pass;", summary_line(run.found))
    comments = [CommentBlock(item, THRESHOLDS_PREFIX, lines)]
    write_text_atomically(path, update_model_text(text, numbers, comments, path))
