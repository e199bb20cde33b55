"""What the decision node learned of its nodes' CPU costs, written back into the model on
request: the file the decision node writes (~learned_costs_out) and `anyscale profile MODEL
--from-run FILE`, which puts its figures into the model's cpu_usage in place (model_update.py),
so that the next run starts from the measured cost instead of learning it again (no ROS).

A figure is the estimate when the node last ran there, not what it relaxed to since. One learned
on a saturated scale is a lower bound; one above 100 % (more than the scale has) is written as
100, the most a model may say: the node then fits only an idle scale.
"""
import datetime
import json
import math
import os
import sys
from dataclasses import dataclass
from typing import List, Optional, Sequence, Tuple

import yaml

from .cost_estimate import CostRow
from .model import ModelError, SystemModel
from .model_loader import is_finite_number, read_yaml
from .model_todos import load_model_with_todos
from .model_update import (CommentBlock, NumberEdit, node_paths, update_model_text,
                           write_text_atomically)
from .profile_plan import PROFILE_PREFIX

FILE_NAME = "learned_costs.yaml"        # in a run's directory (the test bed's)
MIN_SAMPLES = 10                        # default of --min-samples


@dataclass(frozen=True)
class LearnedCost:
    node: str
    scale: str
    model_percent: float        # the run's model said
    measured_percent: float     # % of the scale's capacity, when the node last ran there
    samples: int
    lower_bound: bool           # learned on a saturated scale: at least this
    capacity_cores: float       # the scale's capacity then (its quota, else its cores)


def dump_learned(rows: Sequence[CostRow], model_path: str, when: datetime.datetime) -> str:
    """The learned-costs file's text: the rows with at least one sample."""
    costs = [{"node": r.node, "scale": r.scale, "model_percent": round(r.model, 2),
              "measured_percent": round(r.measured, 2), "samples": r.samples,
              "lower_bound": r.lower_bound,
              "capacity_cores": round(r.capacity_cores, 3)
              if math.isfinite(r.capacity_cores) else None}
             for r in rows if r.samples > 0 and math.isfinite(r.measured)]
    head = ("# CPU costs the AnyScale decision node learned while its nodes ran (% of each "
            "scale's capacity).\n# Into the model with: anyscale profile MODEL --from-run "
            "THIS_FILE\n")
    return head + yaml.safe_dump({"model": model_path,
                                  "written": when.isoformat(timespec="seconds"),
                                  "costs": costs}, sort_keys=False)


def learned_path(path: str) -> str:
    """`path`, or the learned-costs file in it if it is a run's directory."""
    return os.path.join(path, FILE_NAME) if os.path.isdir(path) else path


def load_learned(path: str) -> Tuple[str, List[LearnedCost]]:
    """(when written, the costs) of a learned-costs file; ModelError names file and key."""
    data = read_yaml(path)
    if not isinstance(data, dict) or not isinstance(data.get("costs"), list):
        raise ModelError(path, "costs", "expected a learned-costs file (~learned_costs_out of "
                                        "the decision node) with a list `costs`")
    out = []
    for n, item in enumerate(data["costs"]):
        key = f"costs[{n}]"
        if not isinstance(item, dict):
            raise ModelError(path, key, f"expected a mapping, got {type(item).__name__}")
        for field, ok in (("node", lambda v: isinstance(v, str) and v),
                          ("scale", lambda v: isinstance(v, str) and v),
                          ("model_percent", is_finite_number),
                          ("measured_percent", lambda v: is_finite_number(v) and v >= 0),
                          ("samples", lambda v: isinstance(v, int) and not isinstance(v, bool)
                           and v >= 0),
                          ("lower_bound", lambda v: isinstance(v, bool))):
            if not ok(item.get(field)):
                raise ModelError(path, f"{key}.{field}", f"missing or invalid: "
                                                         f"{item.get(field)!r}")
        cores = item.get("capacity_cores")
        out.append(LearnedCost(item["node"], item["scale"], float(item["model_percent"]),
                               float(item["measured_percent"]), item["samples"],
                               item["lower_bound"],
                               float(cores) if is_finite_number(cores) else math.nan))
    return str(data.get("written", "?")), out


@dataclass(frozen=True)
class Applied:
    cost: LearnedCost
    written: Optional[float]    # the cpu_usage written; None: skipped
    why: str                    # what was written, or why it was skipped


def choose(model: SystemModel, costs: Sequence[LearnedCost], min_samples: int,
           nodes: Optional[Sequence[str]] = None) -> List[Applied]:
    """Which learned costs go into the model, and why the others do not."""
    out = []
    for c in costs:
        node = model.node(c.node) if c.node in model.node_names else None
        if nodes and c.node not in nodes:
            continue
        if node is None:
            out.append(Applied(c, None, f"no node {c.node} in {model.source}"))
        elif c.scale not in node.cpu_usage:
            out.append(Applied(c, None, f"{c.node} has no cpu_usage for {c.scale}"))
        elif c.samples < min_samples:
            out.append(Applied(c, None, f"{c.samples} samples, fewer than {min_samples}"))
        else:
            value = round(min(c.measured_percent, 100.0), 1)
            bound = "at least " if c.lower_bound else ""
            over = (f"; more than the scale has, written as the model's most, {value:g} %"
                    if c.measured_percent > 100.0 else "")
            out.append(Applied(c, value, f"{bound}{c.measured_percent:.1f} % learned from "
                                         f"{c.samples} reports"
                                         + (" on a saturated scale" if c.lower_bound else "")
                                         + over))
    return out


def learned_edits(tree, applied: Sequence[Applied], source: str, written: str,
                  when: datetime.datetime) -> Tuple[List[NumberEdit], List[CommentBlock]]:
    """The cpu_usage edits and the comment blocks (profile's: a later profile replaces them)."""
    index = node_paths(tree)
    numbers, by_node = [], {}
    for a in applied:
        if a.written is None:
            continue
        numbers.append(NumberEdit(("nodes", index[a.cost.node], "cpu_usage", a.cost.scale),
                                  a.written))
        capacity = (f", scale capacity {a.cost.capacity_cores:g} cores"
                    if math.isfinite(a.cost.capacity_cores) else "")
        by_node.setdefault(a.cost.node, []).append(
            f"cpu_usage {a.cost.scale} {a.written:g} % ({a.why}{capacity}; the model said "
            f"{a.cost.model_percent:g})")
    comments = [CommentBlock(("nodes", index[node]), PROFILE_PREFIX, tuple(
        [f"{when:%Y-%m-%d %H:%M} by `anyscale profile --from-run {source}`: the decision "
         f"node's live estimates of a run written {written}"] + lines))
        for node, lines in by_node.items()]
    return numbers, comments


def run_from_run(model_path: str, source: str, nodes: Optional[Sequence[str]],
                 min_samples: int, dry_run: bool, as_json: bool) -> int:
    """`anyscale profile MODEL --from-run FILE`: ModelError (one line, exit 2) on bad input."""
    model = load_model_with_todos(model_path).model
    unknown = [n for n in nodes or () if n not in model.node_names]
    if unknown:
        raise ModelError("--nodes", "", f"not in {model_path}: {', '.join(unknown)}")
    path = learned_path(source)
    if not os.path.isfile(path):
        raise ModelError(source, "", f"no learned-costs file there (the decision node writes "
                                     f"one with ~learned_costs_out; a test-bed run keeps it "
                                     f"as {FILE_NAME} in its directory)")
    written, costs = load_learned(path)
    applied = choose(model, costs, min_samples, nodes)
    changed = [a for a in applied if a.written is not None]
    if changed and not dry_run:
        with open(model_path, encoding="utf-8") as f:
            text = f.read()
        numbers, comments = learned_edits(read_yaml(model_path), applied, path, written,
                                          datetime.datetime.now())
        write_text_atomically(model_path, update_model_text(text, numbers, comments,
                                                            model_path))
    done = bool(changed) and not dry_run
    if as_json:
        print(json.dumps({"model": model_path, "from": path, "learned_at": written,
                          "costs": [{"node": a.cost.node, "scale": a.cost.scale,
                                     "model_percent": a.cost.model_percent,
                                     "learned_percent": a.cost.measured_percent,
                                     "samples": a.cost.samples,
                                     "lower_bound": a.cost.lower_bound,
                                     "cpu_usage": a.written, "why": a.why} for a in applied],
                          "written": done}, indent=2))
        return 0
    print(f"{'NODE':<16} {'SCALE':<10} {'MODEL':>7} {'LEARNED':>9} {'WRITTEN':>8}  WHY")
    for a in applied:
        learned = ("≥" if a.cost.lower_bound else "") + f"{a.cost.measured_percent:.1f}"
        print(f"{a.cost.node:<16} {a.cost.scale:<10} {a.cost.model_percent:>7g} {learned:>9} "
              f"{'-' if a.written is None else format(a.written, 'g'):>8}  {a.why}")
    print(f"{model_path}: " + (f"cpu_usage written for {len(changed)} node and scale pairs, "
                               f"with where they were learned" if done else
                               "not changed (--dry-run)" if dry_run and changed else
                               "not changed (nothing learned enough to write)"),
          file=sys.stderr)
    return 0
