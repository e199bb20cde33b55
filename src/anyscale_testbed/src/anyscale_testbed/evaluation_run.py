"""The paper's evaluation on the two-scale test bed (issue 13), the logic of
scripts/run_evaluation.py: baseline runs with every node on the robot, AnyScale on the coverage
link with four seeds of the WiFi variation (the paper's four tests), the same with the
paper_local and the optimal allocator, and the best case with the network everywhere. Each run
is scripts/run_testbed.py, the main job's code, at the calibrated CPU quotas. Then the table
beside the paper's figures (evaluation.txt/.md/.csv), Fig. 5 and Fig. 6 (PNG), all in --out.

Order (--order). paired (the default): for each seed N a baseline run, pairN-baseline, then at
once the AnyScale test pairN-paper; then the other allocators' tests and the best case. Each
test's gain is measured against its own pair's baseline as well as against the mean of all
baselines: this machine is a shared VM whose speed drifts over hours and days (baselines of
different days took 361-583 s; AMCL at home ran at 2 Hz one day, 3 Hz another under the same
quota), so only runs measured side by side give the gain. Each run's AMCL rate with every node
home is shown, flagged where it is more than 0.5 Hz off the premise's 2 Hz (premise_figures).
grouped (the order before): the baseline runs first (baseline, baseline-2, ...,
--baseline-runs), then paper-seedN, paper_local-seedN, optimal-seedN, best_case.

Resumable: a run whose directory in --out already holds the record of a run that ended is not
run again, its record is read (a run killed midway is run again). The table has every run
recorded in --out under a key of either order (the plan's first), so results recorded in the
grouped order still load. A full office-floor run
takes 8-10 minutes with its set-up, so the 17 runs of the paired order take about 2.8 hours;
the machine should be left to them. Root; run with the workspace sourced:
    sudo -E /usr/bin/python3 scripts/run_evaluation.py --out results/evaluation
    sudo -E /usr/bin/python3 scripts/run_evaluation.py --runs baseline,paper --seeds 1,2
    sudo -E /usr/bin/python3 scripts/run_evaluation.py --order grouped --baseline-runs 4
    sudo -E /usr/bin/python3 scripts/run_evaluation.py --normalise-cpu --out results/eval_norm
"""
import argparse
from dataclasses import dataclass
import glob
import math
import os
import re
import sys
import time
from typing import Iterable, List, Optional, Sequence, Tuple

import yaml

from anyscale_core.characterisation import characterise
from anyscale_core.link_map import LinkMapError, load_link_map
from anyscale_core.model import ModelError
from anyscale_core.model_loader import load_model
from anyscale_nav_demo.occupancy_map import MapError, load_map

from .bench_runs import latest_record, run_logged, start_on_the_testbed
from .calibration_file import nav_demo_path
from .evaluation_figures import RunFigures, returns_along_path, run_figures
from .evaluation_laps import lap_figures, write_lap_report
from .evaluation_plots import draw_fig5, draw_fig6
from .evaluation_table import format_markdown, format_table, write_csv
from .path_steps import configurations_along_path, truth_in_window
from .link_shaper import coverage_grid, coverage_model_from_grid
from .premise_figures import premise_off_note
from .quota_calibration import CalibrationError
from .quota_for_the_day import (EVERY_NODE_HOME_LINK, QuotaForTheDay, calibration_markdown,
                                normalise_cpu_argv, parse_robot_cpu)
from .testbed_record import TestbedRecord

ALLOCATORS = ("paper", "paper_local", "optimal")
ORDERS = ("paired", "grouped")
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
    pair: int = 0       # the seed of the interleaved pair it belongs to; 0: none


def _baseline_argv() -> List[str]:
    return list(EVERY_NODE_HOME_LINK)


def _seeded_argv(allocator: str, seed: int) -> List[str]:
    return ["--link", "coverage", "--seed", str(seed), "--allocator", allocator]


def grouped_baseline(k: int) -> PlannedRun:
    """Baseline run k of the grouped order: baseline, baseline-2, ..."""
    return PlannedRun("baseline" if k == 1 else f"baseline-{k}", "baseline", 0,
                      "baseline (no migration)" + (f", run {k}" if k > 1 else ""),
                      _baseline_argv())


def seeded_test(allocator: str, seed: int) -> PlannedRun:
    name = "AnyScale" if allocator == "paper" else f"AnyScale {allocator}"
    return PlannedRun(f"{allocator}-seed{seed}", allocator, seed, f"{name}, seed {seed}",
                      _seeded_argv(allocator, seed))


def paired_baseline_run(seed: int) -> PlannedRun:
    """The baseline of seed `seed`'s pair, run just before its test. Not baseline-N: that key
    is the grouped order's run N, measured apart from any test."""
    return PlannedRun(f"pair{seed}-baseline", "baseline", 0,
                      f"pair {seed}: baseline (no migration)", _baseline_argv(), seed)


def paired_test(seed: int) -> PlannedRun:
    """The AnyScale test of seed `seed`'s pair, run just after its baseline."""
    return PlannedRun(f"pair{seed}-paper", "paper", seed, f"pair {seed}: AnyScale, seed {seed}",
                      _seeded_argv("paper", seed), seed)


def best_case_run() -> PlannedRun:
    return PlannedRun("best_case", "best_case", 0, "best case (network everywhere)",
                      ["--link", "schedule", "--schedule", BEST_CASE_SCHEDULE])


def grouped_plan(seeds: Sequence[int], baseline_runs: int = 2) -> List[PlannedRun]:
    """The baseline runs first (gains are measured against their mean), the seeded tests
    allocator by allocator, the best case last."""
    return ([grouped_baseline(k) for k in range(1, baseline_runs + 1)]
            + [seeded_test(a, s) for a in ALLOCATORS for s in seeds] + [best_case_run()])


def paired_plan(seeds: Sequence[int]) -> List[PlannedRun]:
    """Per seed a baseline and at once its AnyScale test (the machine's speed drifts: a gain
    is measured side by side), then the other allocators' tests, the best case last."""
    return ([run for s in seeds for run in (paired_baseline_run(s), paired_test(s))]
            + [seeded_test(a, s) for a in ALLOCATORS if a != "paper" for s in seeds]
            + [best_case_run()])


def evaluation_plan(seeds: Sequence[int], order: str = "paired",
                    baseline_runs: int = 2) -> List[PlannedRun]:
    """The runs in `order` (ORDERS); baseline_runs counts only in the grouped order."""
    if order not in ORDERS:
        raise ValueError(f"--order: expected one of {', '.join(ORDERS)}, got {order!r}")
    return paired_plan(seeds) if order == "paired" else grouped_plan(seeds, baseline_runs)


# A number as the plans write it: no 0 (the unseeded model), no leading zero.
_NUMBER = r"([1-9][0-9]*)"


def _run_and_place_of_key(key: str) -> Optional[Tuple[Tuple[int, ...], PlannedRun]]:
    """The run a key of either order names, with its place among runs loaded beside the plan:
    grouped baselines, pairs, seeded tests by allocator, the best case, each in number order."""
    found = None
    m = re.fullmatch(rf"baseline(?:-{_NUMBER})?", key)
    if m:
        k = int(m.group(1) or 1)
        found = ((0, k), grouped_baseline(k))
    m = re.fullmatch(rf"pair{_NUMBER}-(baseline|paper)", key)
    if m:
        s, is_test = int(m.group(1)), m.group(2) == "paper"
        found = ((1, s, is_test), paired_test(s) if is_test else paired_baseline_run(s))
    m = re.fullmatch(rf"({'|'.join(ALLOCATORS)})-seed{_NUMBER}", key)
    if m:
        s = int(m.group(2))
        found = ((2, ALLOCATORS.index(m.group(1)), s), seeded_test(m.group(1), s))
    if key == "best_case":
        found = ((3,), best_case_run())
    # "baseline-1" is no key: the grouped order's first run is "baseline".
    return found if found is not None and found[1].key == key else None


def run_of_key(key: str) -> Optional[PlannedRun]:
    """The run a key of either order names (baseline-3, paper-seed2, pair2-baseline, ...);
    None for any other name."""
    found = _run_and_place_of_key(key)
    return found[1] if found else None


def runs_to_collect(plan: Sequence[PlannedRun], recorded_keys: Iterable[str]) -> List[PlannedRun]:
    """The plan, then every other run recorded under a key of either order (results recorded
    in the grouped order load in the paired one and the other way round)."""
    planned = {r.key for r in plan}
    others = [found for found in map(_run_and_place_of_key, set(recorded_keys) - planned)
              if found is not None]
    return list(plan) + [run for _, run in sorted(others, key=lambda f: f[0])]


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
    p.add_argument("--order", choices=ORDERS, default="paired",
                   help="paired (default): per seed a baseline, then at once its AnyScale test "
                        "(the machine's speed drifts; a gain is measured side by side); "
                        "grouped: the baseline runs first, then the tests (the order before)")
    p.add_argument("--baseline-runs", type=int, default=None, metavar="N",
                   help="with --order grouped: baseline runs, whose mean the gains are measured "
                        "against (2): its time to complete varies from run to run")
    p.add_argument("--runs", default=None, metavar="NAMES",
                   help="only these runs: keys (paired: pair1-baseline, pair1-paper; grouped: "
                        "baseline, baseline-2, paper-seed1; both: paper_local-seed2, "
                        "optimal-seed3, best_case) or kinds (baseline, paper, paper_local, "
                        "optimal, best_case), comma-separated (default: all)")
    p.add_argument("--duration", type=float, default=0.0,
                   help="end each run after this many seconds (default: when the loop is done)")
    p.add_argument("--normalise-cpu", action="store_true",
                   help="each run with run_testbed.py --normalise-cpu: the CPU quotas follow the "
                        "host's speed (a shared VM's drifts, and with it AMCL's rate at a fixed "
                        "quota, every node home: 3.18-1.77 Hz in 7 runs), so that the baselines "
                        "and the tests run on the same emulated robot; see run_testbed.py "
                        "--help; relative to the host's speed at which each quota was found "
                        "(--robot-cpu auto: its calibration run's). Off by default. Runs already "
                        "recorded in --out are not run again, with it or without: give it a "
                        "new --out")
    p.add_argument("--robot-cpu", default="auto", metavar="CORES|auto",
                   help="the robot's CPU quota in cores for every run; auto (default): before "
                        "each pair (paired order) or before the runs (grouped), short runs "
                        "with every node home find the quota at which AMCL runs at the "
                        "premise's 2 Hz today (quota_calibration.py; about 2 minutes per run, "
                        "1-3 runs), kept in DIR/<pair>-calibration/calibration.json")
    p.add_argument("--laps", type=int, default=1, metavar="N",
                   help="each run drives its loop N times (run_testbed.py --loops): the link "
                        "map the decision node learns on lap 1 serves lap 2; the table then "
                        "also has each lap apart (default 1)")
    p.add_argument("--no-forecast", action="store_true",
                   help="the AnyScale tests with run_testbed.py --no-forecast: the reactive "
                        "rules only, to compare")
    p.add_argument("--link-map", default=None, metavar="FILE|DIR",
                   help="each AnyScale test starts from this link map: a file, or an earlier "
                        "evaluation's --out, where each test starts from the map its namesake "
                        "saved (DIR/KEY/*/link_map.yaml); default: an empty map")
    p.add_argument("--out", default=default_out, help=f"results directory ({default_out})")
    args = p.parse_args(argv)
    if not 1 <= args.laps <= 20:
        p.error(f"--laps: expected 1 to 20, got {args.laps}")
    if args.link_map is not None and not os.path.isdir(args.link_map):
        try:
            load_link_map(args.link_map)
        except LinkMapError as e:
            p.error(f"--link-map: {e}")
    try:
        args.robot_cpu = parse_robot_cpu(args.robot_cpu)
    except ValueError as e:
        p.error(str(e))
    if args.baseline_runs is not None and args.order == "paired":
        p.error("--baseline-runs: only with --order grouped (paired: a baseline per seed, run "
                "just before its test)")
    if args.baseline_runs is not None and args.baseline_runs < 1:
        p.error(f"--baseline-runs: expected at least 1, got {args.baseline_runs}")
    try:
        args.plan = evaluation_plan(parse_seeds(args.seeds), args.order,
                                    args.baseline_runs or 2)
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


def run_argv(run: PlannedRun, args, run_testbed: str, run_dir: str,
             robot_cpu: Optional[float] = None, found_at_ms: Optional[float] = None) -> List[str]:
    """run_testbed.py's command line for one planned run; its link options last. robot_cpu:
    the robot's quota (None: the calibration file's); found_at_ms: the host speed it was found
    at (with --normalise-cpu, the reference the quotas follow from)."""
    quota = ["--robot-cpu", f"{robot_cpu:g}"] if robot_cpu is not None else []
    return ([sys.executable, run_testbed, "--world", args.world, "--duration", str(args.duration),
             "--out", run_dir] + quota + normalise_cpu_argv(args.normalise_cpu, found_at_ms)
            + (["--loops", str(args.laps)] if args.laps > 1 else [])
            + link_map_argv(run, args) + run.argv)


def link_map_argv(run: PlannedRun, args) -> List[str]:
    """An AnyScale test's link forecast options: --no-forecast, and the map it starts from
    (--link-map: a file, or the one its namesake saved in an earlier evaluation's directory;
    none there: an empty map, said so)."""
    if run.kind not in ALLOCATORS:
        return []
    out = ["--no-forecast"] if args.no_forecast else []
    if args.link_map is None:
        return out
    path = args.link_map
    if os.path.isdir(path):
        saved = sorted(glob.glob(os.path.join(path, run.key, "*", "link_map.yaml")))
        if not saved:
            print(f"evaluation: {run.key}: no link map in {path}/{run.key}/; starting from an "
                  "empty one", flush=True)
            return out
        path = saved[-1]
    return out + ["--link-map", path]


def run_one(run: PlannedRun, args, run_testbed: str, run_dir: str,
            robot_cpu: Optional[float] = None, found_at_ms: Optional[float] = None) -> int:
    code = run_logged(run_argv(run, args, run_testbed, run_dir, robot_cpu, found_at_ms), run_dir)
    with open(os.path.join(run_dir, EXIT_CODE_FILE), "w") as f:
        f.write(f"{code}\n")
    return code


def calibration_key(run: PlannedRun) -> str:
    """The calibration a run is made at: its pair's, or the one before the unpaired runs."""
    return f"pair{run.pair}-calibration" if run.pair else "calibration"


def collect(runs: Sequence[PlannedRun], out: str, amcl_mbps: float,
            laps: int = 1) -> List[RunFigures]:
    """The figures of every one of `runs` recorded in `out`, in their order."""
    figures = []
    for run in runs:
        run_dir = os.path.join(out, run.key)
        rec = latest_record(run_dir)
        if rec is not None:
            figures.append(figures_of(run, recorded_exit_code(run_dir), rec, amcl_mbps, laps))
    return figures


def figures_of(run: PlannedRun, code: int, rec: TestbedRecord, amcl_mbps: float,
               laps: int = 1) -> RunFigures:
    """A recorded run's figures, lap by lap too when it drove more than one."""
    figures = run_figures(run.title, run.kind, run.seed, code, rec, amcl_mbps, pair=run.pair)
    if laps > 1:
        figures.laps = lap_figures(rec, laps, amcl_mbps)
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
                           configurations_along_path(rec), returns_along_path(rec)))
    draw_fig5(os.path.join(out, "fig5_paths.png"), occ.occupied, occ.data < 0, occ.resolution,
              occ.origin[:2], panels, coverage)
    draw_fig6(os.path.join(out, "fig6_time_and_omega.png"),
              [(f.name, f.row.path_time_s, f.mean_omega_deg_s) for f in figures])


def progress_summary(done: RunFigures) -> str:
    """A finished run's line; AMCL's rate at home says at once whether the machine still runs
    the premise."""
    off = premise_off_note(done.amcl_hz_home)
    home = (f", AMCL {done.amcl_hz_home:.2f} Hz at home" + (f" ({off})" if off else "")
            if math.isfinite(done.amcl_hz_home) else "")
    return (f"time to complete {done.row.path_time_s:.0f} s, {done.row.migrations} migrations, "
            f"{len(done.row.violations)} violations{home}")


def recorded_keys(out: str) -> List[str]:
    """The run directories in `out` (collect reads only those that hold a record)."""
    return [d for d in os.listdir(out) if os.path.isdir(os.path.join(out, d))]


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
    quotas = QuotaForTheDay(run_testbed, args.world, out, args.robot_cpu)
    print(f"evaluation: {len(todo)} runs on {args.world}; results in {out}", flush=True)
    try:
        for k, run in enumerate(todo, 1):
            run_dir = os.path.join(out, run.key)
            if latest_record(run_dir) is not None:
                print(f"[{k}/{len(todo)}] {run.key}: recorded already, not run again", flush=True)
                continue
            robot_cpu = quotas.quota(calibration_key(run))
            found_at_ms = quotas.found_at_ms(calibration_key(run))
            at = f", robot {robot_cpu:g} cores" if robot_cpu is not None else ""
            print(f"[{k}/{len(todo)}] {run.key}: {run.title}{at}, log {run_dir}/console.log",
                  flush=True)
            began = time.monotonic()
            code = run_one(run, args, run_testbed, run_dir, robot_cpu, found_at_ms)
            rec = latest_record(run_dir)
            done = figures_of(run, code, rec, amcl_mbps) if rec else None
            summary = progress_summary(done) if done else "no record"
            print(f"[{k}/{len(todo)}] {run.key}: done in {time.monotonic() - began:.0f} s, "
                  f"exit {code}: {summary}", flush=True)
    except CalibrationError as e:
        print(f"evaluation: {e}; the table has the runs recorded so far", flush=True)
    except KeyboardInterrupt:
        print("evaluation: interrupted; the table has the runs recorded so far", flush=True)
    loaded = runs_to_collect(args.plan, recorded_keys(out))
    figures = collect(loaded, out, amcl_mbps, args.laps)
    if not figures:
        print("evaluation: no run recorded, no table", flush=True)
        return 1
    write_outputs(out, args.world, loaded, figures)
    return 0


def write_outputs(out: str, world: str, plan: Sequence[PlannedRun], figures: List[RunFigures]):
    text = format_table(figures)
    print(text, flush=True)
    with open(os.path.join(out, "evaluation.txt"), "w") as f:
        f.write(text + "\n")
    calibrations = calibration_markdown(out)
    if calibrations:
        print(calibrations, flush=True)
    with open(os.path.join(out, "evaluation.md"), "w") as f:
        f.write(format_markdown(figures, f"The paper's evaluation on the test bed ({world})"))
        f.write(calibrations)
    write_csv(os.path.join(out, "evaluation.csv"), figures)
    for line in write_lap_report(out, figures):
        print(line, flush=True)
    try:
        draw_figures(out, world, plan, figures)
    except (OSError, MapError, KeyError, yaml.YAMLError) as e:
        print(f"evaluation: figures not drawn: {e}", flush=True)
    print(f"evaluation: {out}/evaluation.md, evaluation.csv, fig5_paths.png, "
          f"fig6_time_and_omega.png", flush=True)
