"""The paper's evaluation on the two-scale test bed (issue 13), the logic of
scripts/run_evaluation.py: baseline runs with every node on the robot, AnyScale on the coverage
link with four seeds of the WiFi variation (the paper's four tests), the same with the
paper_local and the optimal allocator, and the best case with the network everywhere. Each run
is scripts/run_testbed.py, the main job's code, at the calibrated CPU quotas. Then the table
beside the paper's figures (evaluation.txt/.md/.csv), Fig. 5 and Fig. 6 (PNG), all in --out.

Resumable: a run whose directory in --out already holds a record.json is not run again, its
record is read. A full office-floor run takes 8-10 minutes with its set-up, so the 15 runs take
about 2.5 hours; the machine should be left to them. Root; run with the workspace sourced:
    sudo -E /usr/bin/python3 scripts/run_evaluation.py --out results/evaluation
    sudo -E /usr/bin/python3 scripts/run_evaluation.py --runs baseline,paper --seeds 1,2
"""
import argparse
from dataclasses import dataclass
import os
import sys
import time
from typing import List, Optional, Sequence

import yaml

from anyscale_core.characterisation import characterise
from anyscale_core.model import ModelError
from anyscale_core.model_loader import load_model
from anyscale_nav_demo.occupancy_map import MapError, load_map

from .bench_runs import latest_record, run_logged, start_on_the_testbed
from .demo_run import nav_demo_path
from .evaluation_figures import (RunFigures, configurations_along_path, run_figures,
                                 truth_in_window)
from .evaluation_plots import draw_fig5, draw_fig6
from .evaluation_table import format_markdown, format_table, write_csv
from .link_shaper import coverage_grid, coverage_model_from_grid
from .testbed_record import TestbedRecord

ALLOCATORS = ("paper", "paper_local", "optimal")
# No migration: the link is down throughout, so every node stays on the robot.
BASELINE_SCHEDULE = "[[0, 0]]"
# The network everywhere: the best rate of the WiFi model (54 Mbit/s PHY, half usable) always.
BEST_CASE_SCHEDULE = "[[0, 27]]"
EXIT_CODE_FILE = "exit_code"


@dataclass(frozen=True)
class PlannedRun:
    key: str            # its directory under --out and its name in --runs
    kind: str           # baseline, best_case, or the allocator of a seeded test
    seed: int
    title: str          # its name in the table and the figures
    argv: List[str]     # run_testbed.py's link and allocator options


def evaluation_plan(seeds: Sequence[int], baseline_runs: int = 2) -> List[PlannedRun]:
    """The baseline runs first (gains are measured against their mean), the seeded tests
    allocator by allocator, the best case last."""
    plan = [PlannedRun("baseline" if k == 1 else f"baseline-{k}", "baseline", 0,
                       "baseline (no migration)" + (f", run {k}" if k > 1 else ""),
                       ["--link", "schedule", "--schedule", BASELINE_SCHEDULE])
            for k in range(1, baseline_runs + 1)]
    for allocator in ALLOCATORS:
        name = "AnyScale" if allocator == "paper" else f"AnyScale {allocator}"
        plan += [PlannedRun(f"{allocator}-seed{s}", allocator, s, f"{name}, seed {s}",
                            ["--link", "coverage", "--seed", str(s), "--allocator", allocator])
                 for s in seeds]
    plan.append(PlannedRun("best_case", "best_case", 0, "best case (network everywhere)",
                           ["--link", "schedule", "--schedule", BEST_CASE_SCHEDULE]))
    return plan


def select_runs(plan: Sequence[PlannedRun], wanted: Optional[str]) -> List[PlannedRun]:
    """The runs named in `wanted` (comma-separated keys or kinds: "baseline,paper",
    "optimal-seed2"), all if None; ValueError names an unknown one."""
    if wanted is None:
        return list(plan)
    names = [w.strip() for w in wanted.split(",") if w.strip()]
    known = {r.key for r in plan} | {r.kind for r in plan}
    unknown = [n for n in names if n not in known]
    if unknown or not names:
        raise ValueError(f"--runs: unknown {', '.join(unknown) or 'empty list'}; expected keys "
                         f"or kinds among: {', '.join(sorted(known))}")
    return [r for r in plan if r.key in names or r.kind in names]


def parse_seeds(text: str) -> List[int]:
    try:
        seeds = [int(s) for s in text.split(",") if s.strip()]
    except ValueError:
        raise ValueError(f"--seeds: expected integers separated by commas, got {text!r}") from None
    if not seeds or any(s < 1 for s in seeds) or len(set(seeds)) != len(seeds):
        raise ValueError(f"--seeds: expected distinct integers >= 1 (0 is the unseeded model), "
                         f"got {text!r}")
    return seeds


def parse_args(argv, default_out: str):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter,
                                epilog=__doc__.split("\n\n", 1)[1])
    p.add_argument("--world", default="office_floor",
                   help="office_floor (default), small_loop (the CI smoke test's)")
    p.add_argument("--seeds", default="1,2,3,4", help="the WiFi variation's seeds (1,2,3,4)")
    p.add_argument("--baseline-runs", type=int, default=2, metavar="N",
                   help="baseline runs, whose mean the gains are measured against (2): its time "
                        "to complete varies from run to run")
    p.add_argument("--runs", default=None, metavar="NAMES",
                   help="only these runs: keys (baseline, baseline-2, paper-seed1, "
                        "paper_local-seed2, optimal-seed3, best_case) or kinds (baseline, "
                        "paper, paper_local, optimal, best_case), comma-separated (default: all)")
    p.add_argument("--duration", type=float, default=0.0,
                   help="end each run after this many seconds (default: when the loop is done)")
    p.add_argument("--out", default=default_out, help=f"results directory ({default_out})")
    args = p.parse_args(argv)
    if args.baseline_runs < 1:
        p.error(f"--baseline-runs: expected at least 1, got {args.baseline_runs}")
    try:
        args.plan = evaluation_plan(parse_seeds(args.seeds), args.baseline_runs)
        args.selected = select_runs(args.plan, args.runs)
    except ValueError as e:
        p.error(str(e))
    if args.duration < 0:
        p.error(f"--duration: expected seconds >= 0, got {args.duration:g}")
    return args


def amcl_bandwidth_mbps(model_path: str) -> float:
    """What AMCL moves over the link when it runs apart from the robot (its input and output
    connections in the system model)."""
    ch = characterise(load_model(model_path))
    return ch.bandwidth_of_node(ch.node_index("amcl"))


def recorded_exit_code(run_dir: str) -> int:
    try:
        with open(os.path.join(run_dir, EXIT_CODE_FILE)) as f:
            return int(f.read().strip())
    except (OSError, ValueError):
        return 0            # recorded before exit codes were kept: the record is what counts


def run_one(run: PlannedRun, args, run_testbed: str, run_dir: str) -> int:
    code = run_logged([sys.executable, run_testbed, "--world", args.world,
                       "--duration", str(args.duration), "--out", run_dir] + run.argv, run_dir)
    with open(os.path.join(run_dir, EXIT_CODE_FILE), "w") as f:
        f.write(f"{code}\n")
    return code


def collect(plan: Sequence[PlannedRun], out: str, amcl_mbps: float) -> List[RunFigures]:
    """The figures of every planned run recorded in `out`, in plan order."""
    figures = []
    for run in plan:
        run_dir = os.path.join(out, run.key)
        rec = latest_record(run_dir)
        if rec is not None:
            figures.append(run_figures(run.title, run.kind, run.seed,
                                       recorded_exit_code(run_dir), rec, amcl_mbps))
    return figures


def draw_figures(out: str, world: str, plan: Sequence[PlannedRun], figures: List[RunFigures]):
    """Fig. 5 from the AnyScale tests' records (all runs if there is none), Fig. 6 from the
    figures."""
    with open(nav_demo_path("maps", f"{world}_world.yaml")) as f:
        occ = load_map(nav_demo_path("maps", yaml.safe_load(f)["map"]))
    coverage = None
    wifi_path = nav_demo_path("config", f"wifi_{world}.yaml")
    if os.path.exists(wifi_path):
        with open(wifi_path) as f:
            wifi = yaml.safe_load(f)
        model = coverage_model_from_grid(occ.width, occ.height, occ.resolution, occ.origin[0],
                                         occ.origin[1], occ.data.ravel().tolist(),
                                         (wifi["access_point_x"], wifi["access_point_y"]))
        coverage = coverage_grid(model, 0.5)
    tests = [r for r in plan if r.kind == "paper"] or list(plan)
    panels = []
    for run in tests:
        rec: Optional[TestbedRecord] = latest_record(os.path.join(out, run.key))
        if rec is not None and len(rec.truth) > 1:
            panels.append((run.title, truth_in_window(rec)[:, 1:3],
                           configurations_along_path(rec)))
    draw_fig5(os.path.join(out, "fig5_paths.png"), occ.occupied, occ.data < 0, occ.resolution,
              occ.origin[:2], panels, coverage)
    draw_fig6(os.path.join(out, "fig6_time_and_omega.png"),
              [(f.name, f.row.path_time_s, f.mean_omega_deg_s) for f in figures])


def main(default_out: str, run_testbed: str, argv=None) -> int:
    args = parse_args(argv, default_out)
    start_on_the_testbed("run_evaluation")
    try:
        amcl_mbps = amcl_bandwidth_mbps(nav_demo_path("config", "testbed.yaml"))
    except (ModelError, ValueError) as e:
        print(f"run_evaluation: the system model: {e}", file=sys.stderr)
        return 1
    out = os.path.abspath(args.out)
    os.makedirs(out, exist_ok=True)
    todo = args.selected
    print(f"evaluation: {len(todo)} runs on {args.world}; results in {out}", flush=True)
    try:
        for k, run in enumerate(todo, 1):
            run_dir = os.path.join(out, run.key)
            if latest_record(run_dir) is not None:
                print(f"[{k}/{len(todo)}] {run.key}: recorded already, not run again", flush=True)
                continue
            print(f"[{k}/{len(todo)}] {run.key}: {run.title}, log {run_dir}/console.log",
                  flush=True)
            began = time.monotonic()
            code = run_one(run, args, run_testbed, run_dir)
            rec = latest_record(run_dir)
            done = (run_figures(run.title, run.kind, run.seed, code, rec, amcl_mbps)
                    if rec else None)
            summary = (f"time to complete {done.row.path_time_s:.0f} s, {done.row.migrations} "
                       f"migrations, {len(done.row.violations)} violations" if done
                       else "no record")
            print(f"[{k}/{len(todo)}] {run.key}: done in {time.monotonic() - began:.0f} s, "
                  f"exit {code}: {summary}", flush=True)
    except KeyboardInterrupt:
        print("evaluation: interrupted; the table has the runs recorded so far", flush=True)
    figures = collect(args.plan, out, amcl_mbps)
    if not figures:
        print("evaluation: no run recorded, no table", flush=True)
        return 1
    write_outputs(out, args.world, args.plan, figures)
    return 0


def write_outputs(out: str, world: str, plan: Sequence[PlannedRun], figures: List[RunFigures]):
    text = format_table(figures)
    print(text, flush=True)
    with open(os.path.join(out, "evaluation.txt"), "w") as f:
        f.write(text + "\n")
    with open(os.path.join(out, "evaluation.md"), "w") as f:
        f.write(format_markdown(figures, f"The paper's evaluation on the test bed ({world})"))
    write_csv(os.path.join(out, "evaluation.csv"), figures)
    try:
        draw_figures(out, world, plan, figures)
    except (OSError, MapError, KeyError, yaml.YAMLError) as e:
        print(f"evaluation: figures not drawn: {e}", flush=True)
    print(f"evaluation: {out}/evaluation.md, evaluation.csv, fig5_paths.png, "
          f"fig6_time_and_omega.png", flush=True)
