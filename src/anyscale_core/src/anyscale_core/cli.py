"""The `anyscale` command line: check a model, plan one decision, run the Fig. 7 simulation,
watch a running system (top), draft a model from a running graph (model draft), measure its
nodes' CPU (profile) and a connection's thresholds (thresholds).

Errors in the user's files are printed as one line naming the file and key, exit status 2.
`simulate` lives in the anyscale_study package, which a robot does not need: it is imported
only when the command runs, and where it is missing the command says what to install.
"""
import argparse
import json
import os
import sys
from typing import List, Optional

from .allocators import ALLOCATORS, AllocationContext, make_allocator
from .characterisation import Characterisation, characterise, count_mappings
from .constraints import DynamicState, load_state, required_bandwidth, violations
from .cost import perf
from .model import ModelError
from .model_loader import load_model

EXIT_USAGE = 2


class OneLineParser(argparse.ArgumentParser):
    """Bad usage is one line and exit status 2, like a bad file: argparse's default prints the
    whole usage block first. Sub-command parsers are of this class too (add_subparsers makes
    them of the parent's class)."""

    def error(self, message):
        self.exit(EXIT_USAGE, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def build_parser() -> argparse.ArgumentParser:
    parser = OneLineParser(
        prog="anyscale",
        description="AnyScale: decide where the nodes of a ROS system run (paper: AnyScale "
                    "computing for ROS).")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True

    check = sub.add_parser("check", help="validate a system model and characterise it",
                           description="Validate a system model (YAML) and print its critical, "
                                       "pinned and migratable nodes and the number of allowed "
                                       "mappings before and after pruning.")
    check.formatter_class = argparse.RawDescriptionHelpFormatter
    check.epilog = ("example:\n  anyscale check $(rospack find anyscale_nav_demo)/config/"
                    "testbed.yaml\n\nexit status: 0 valid; 2 invalid (one line naming the "
                    "file, the key and what was\nexpected)")
    check.add_argument("model", metavar="MODEL", help="system model YAML file")
    check.set_defaults(run=run_check)

    plan = sub.add_parser("plan", help="one allocation decision from the all-on-master start",
                          description="Run one decision of an allocator from the paper's "
                                      "initial configuration (every node on the master scale) "
                                      "and print the mapping, its Perf (Eq. 1) and whether it "
                                      "satisfies the constraints.")
    plan.formatter_class = argparse.RawDescriptionHelpFormatter
    plan.epilog = ("examples:\n  anyscale plan testbed.yaml\n"
                   "  echo 'bandwidth_mbps: 3' > weak.yaml; anyscale plan testbed.yaml --state "
                   "weak.yaml --json\n  anyscale plan testbed.yaml --solver optimal\n\n"
                   "exit status: 0 planned; 2 a bad model, state file or solver (one line)")
    plan.add_argument("model", metavar="MODEL", help="system model YAML file")
    plan.add_argument("--state", metavar="STATE",
                      help="YAML with the dynamic parameters: bandwidth_mbps (default: the "
                           "network's maximum), scale_load {scale: %%} (default 0), link_up "
                           "{remote scale: bool} (default true)")
    plan.add_argument("--solver", default="paper", metavar="NAME",
                      help=f"allocator: {', '.join(sorted(ALLOCATORS))} (default: paper)")
    plan.add_argument("--json", action="store_true",
                      help='print {"mapping": {node: scale}, "perf": float, "feasible": bool, '
                           '"solver": str}')
    plan.set_defaults(run=run_plan)

    # Its options are the study's own (anyscale_study.simulation_report.add_arguments): main()
    # hands them over unparsed and run_simulate parses them once the package is known to be there.
    simulate = sub.add_parser("simulate", help="the paper's Fig. 7 simulation study "
                                               "(package anyscale_study)", add_help=False)
    simulate.set_defaults(run=run_simulate)

    top = sub.add_parser("top", help="live view of scales, nodes, connection rates and events",
                         description="A live terminal view of the running system: every "
                                     "scale (CPU, memory, link), every node and where it runs, "
                                     "each model connection's rate against freq_min/freq_opt, "
                                     "and the last migration events. Needs a ROS master.")
    top.formatter_class = argparse.RawDescriptionHelpFormatter
    top.epilog = ("examples:\n  anyscale top\n  anyscale top --model testbed.yaml --once"
                  "\n\nexit status: 0; 1 no ROS master")
    top.add_argument("--model", metavar="MODEL",
                     help="system model YAML (default: the one the decision node publishes "
                          "as /anyscale/model)")
    top.add_argument("--once", action="store_true",
                     help="print one frame once data has arrived, then exit")
    top.add_argument("--period", type=float, default=1.0, metavar="S",
                     help="refresh period in seconds (default: 1)")
    top.set_defaults(run=run_top)

    model = sub.add_parser("model", help="write system models: `anyscale model draft`",
                           description="Commands that write system models.")
    model_sub = model.add_subparsers(dest="model_command", metavar="MODEL_COMMAND")
    model_sub.required = True
    draft = model_sub.add_parser(
        "draft", help="draft a model YAML from the running ROS graph",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description="Draft a system model from the running ROS graph: every node (package, "
                    "executable,\nargs and remaps read from /proc/PID/cmdline for nodes on this "
                    "machine), every\nconnection (publisher, subscriber, topic) with the rate and "
                    "bytes/s counted here for\n--seconds as a first freq_opt and bandwidth_mbps, "
                    "and TODO at every value a human must\ndecide (freq_min, tolerance, pinned "
                    "drivers, scales, cpu_usage). /rosout and AnyScale's\nown nodes are left out. "
                    "Once the TODOs are filled, `anyscale check OUTPUT` accepts it.",
        epilog="example:\n  roslaunch my_robot robot.launch &\n"
               "  anyscale model draft my_robot.yaml --seconds 10\n"
               "  $EDITOR my_robot.yaml      # replace every TODO\n"
               "  anyscale check my_robot.yaml")
    draft.add_argument("output", metavar="OUTPUT",
                       help="model YAML to write ('-': standard output); an existing file is "
                            "kept unless --force")
    draft.add_argument("--seconds", type=float, default=5.0, metavar="N",
                       help="how long to count each connection's messages (default: 5)")
    draft.add_argument("--force", action="store_true", help="overwrite OUTPUT if it exists")
    draft.set_defaults(run=run_model_draft, command="model draft")
    add_profile_parser(sub)
    add_thresholds_parser(sub)
    return parser


def _positive(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not 0 < value <= 86400:
        raise argparse.ArgumentTypeError(f"expected a number in (0, 86400], got {text}")
    return value


def _number_list(text: str):
    try:
        values = [float(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected numbers separated by commas, got {text!r}") \
            from None
    if not values or any(not 0 < v <= 86400 for v in values):
        raise argparse.ArgumentTypeError(f"expected numbers in (0, 86400], got {text!r}")
    return values


RUNNING_AGENTS = ("It needs a ROS master, the agent of every scale it uses, and no decision "
                  "node\n(on the demo: `roslaunch anyscale_nav_demo robot.launch decision:=false` "
                  "on the robot,\n`roslaunch anyscale_nav_demo laptop.launch` on the laptop). ")


def add_profile_parser(sub):
    profile = sub.add_parser(
        "profile", help="measure each node's cpu_usage and memory_mb on every scale that may "
                        "run it, into the model",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description="Measure the CPU usage (paper, Table II) and memory of the model's nodes "
                    "with the AnyScale\nagents, and write them into MODEL.\n\n"
                    "Every node of the model that does not run yet is started where the paper "
                    "starts it (its\npinned scale, else the master). A first window measures "
                    "every node there. Then each\nmigratable node in turn is moved alone to "
                    "each other scale with a cpu_usage key (memory\npermitting) and measured "
                    "there while the rest of the system runs at home. A window is\n--warmup "
                    "seconds of settling, then --window seconds of the agents' /proc samples "
                    "(the\nnode's process group, as the agents report it at run time). "
                    "cpu_usage is the mean\nin % of the scale's capacity: its cgroup CPU quota "
                    "where it has one, else all its cores\n(the unit of the model and of the "
                    "agents' scale load); memory_mb the largest RSS seen\non any scale. Each "
                    "node gets a comment block in MODEL saying when and how it was\nmeasured; "
                    "the rest of the file (comments, order, style) is kept as it is. TODOs in\n"
                    "numeric fields (a fresh `anyscale model draft`) are accepted.\n\n"
                    + RUNNING_AGENTS + "Nodes it starts run under a lease,\nso they end "
                    "even if the command is killed; at the end it stops what it started and "
                    "starts\nagain at home what it found running. The predicted time is "
                    "printed first, then a\nprogress bar (on a terminal).",
        epilog="examples:\n"
               "  anyscale profile my_robot.yaml\n"
               "  anyscale profile my_robot.yaml --nodes amcl --window 60 --dry-run --json\n"
               "  anyscale profile $(rospack find anyscale_nav_demo)/config/testbed.yaml "
               "--nodes amcl,ar_recognition\n\n"
               "exit status: 0 done; 2 bad input, no master, a decision node running, an agent "
               "missing,\na node that fails to start (one line on standard error); 130 "
               "interrupted.")
    profile.add_argument("model", metavar="MODEL", help="system model YAML file (updated in "
                                                        "place unless --dry-run)")
    profile.add_argument("--nodes", metavar="A,B", default="",
                         help="measure only these nodes (default: every node of the model)")
    profile.add_argument("--warmup", type=_positive, default=10.0, metavar="S",
                         help="seconds after a node's start before its window (default: 10)")
    profile.add_argument("--window", type=_positive, default=30.0, metavar="S",
                         help="seconds of samples per window (default: 30)")
    profile.add_argument("--lease", type=_positive, default=10.0, metavar="S",
                         help="lease of each node it starts: they end this long after the "
                              "command dies (default: 10)")
    profile.add_argument("--start-timeout", type=_positive, default=60.0, metavar="S",
                         help="how long a node may take to register (default: 60)")
    profile.add_argument("--dry-run", action="store_true", help="measure, print, do not write "
                                                                "MODEL")
    profile.add_argument("--json", action="store_true",
                         help="print the figures as JSON: {model, measured_at, warmup_s, "
                              "window_s, measurements: [{node, scale, cpu_usage, "
                              "cpu_percent_of_one_core, cpu_sd, samples, capacity_cores, quota, "
                              "rss_mb, window_s, output_rates_hz}], memory_mb: {node: MB}, "
                              "not_measured, written}")
    profile.set_defaults(run=run_profile)


def add_thresholds_parser(sub):
    th = sub.add_parser(
        "thresholds", help="find a connection's freq_min, freq_opt and tolerance with a "
                           "correctness probe",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description="Find freq_min, freq_opt and the tolerance of one connection of MODEL "
                    "(paper, Table I), as\nthe paper did by hand: feed the subscriber less and "
                    "less and watch whether it still\nworks.\n\n"
                    "The subscriber is restarted by this command with its input remapped to "
                    "TOPIC_throttle,\nwhich `topic_tools throttle messages TOPIC RATE "
                    "TOPIC_throttle` feeds. Step by step,\nhighest rate first (the source's "
                    "rate times 1, 0.8, 0.6, 0.5, 0.4, 0.3, 0.2, 0.1, or\n--rates), the "
                    "stream runs --settle seconds, then the probe is watched for --step\n"
                    "seconds. Then, at freq_opt, the stream is cut for each of --outages "
                    "seconds (shortest\nfirst), and the probe is watched from the cut until "
                    "--step seconds after it. A step is\ncorrect when at least --quota of the "
                    "probe's checks pass. Each ladder stops at its first\nincorrect step "
                    "(the subscriber's state is suspect after it).\n\n"
                    "The probe is a topic and a condition (--probe TOPIC --condition EXPR: one "
                    "check per\nmessage; EXPR is Python over the message m, as in "
                    "`rostopic echo --filter`; --value EXPR\nadds a number to minimise, e.g. "
                    "an error), or a script (--probe-script CMD: run once\nevery "
                    "--probe-period seconds, exit 0 = correct, 1 = not; any other exit stops "
                    "the run).\n\n"
                    "Reported: freq_min, the lowest rate that stays correct; freq_opt, the "
                    "lowest correct rate\nwhose score (the mean --value, else the share of "
                    "passed checks) is within --improvement\nof the best: above it the probe "
                    "no longer improves; the tolerance, the longest\ninterruption that stays "
                    "correct (0: critical). They are written into the connection in\nMODEL "
                    "with a comment, unless --dry-run.\n\n" + RUNNING_AGENTS +
                    "The subscriber runs on this\nmachine, unconstrained. At the end it is "
                    "started again by its agent as it was.",
        epilog="examples:\n"
               "  anyscale thresholds testbed.yaml --connection laser:amcl:/scan \\\n"
               "      --probe /amcl_error --condition 'm.data < 0.3' --value m.data\n"
               "  anyscale thresholds relay.yaml --connection talker:relay:/chatter \\\n"
               "      --probe-script './listener_ok.sh' --rates 10,5,2 --outages 1,2 --json\n\n"
               "exit status: 0 done; 2 bad input (an unknown connection, a probe that never "
               "passes at\nthe full rate or that breaks, no master, a missing agent, a node "
               "that fails to start);\n130 interrupted.")
    th.add_argument("model", metavar="MODEL", help="system model YAML file")
    th.add_argument("--connection", required=True, metavar="PUB:SUB:TOPIC",
                    help="the connection, as in the model: publisher:subscriber:topic")
    probe = th.add_mutually_exclusive_group(required=True)
    probe.add_argument("--probe", metavar="TOPIC", help="probe topic (one check per message)")
    probe.add_argument("--probe-script", metavar="CMD",
                       help="probe command line (split like a shell's, run without one)")
    th.add_argument("--condition", metavar="EXPR",
                    help="with --probe: Python expression over the message m that is true "
                         "when correct")
    th.add_argument("--value", metavar="EXPR",
                    help="with --probe: a number per message to minimise (e.g. an error); "
                         "freq_opt is where its mean stops improving")
    th.add_argument("--probe-period", type=_positive, default=1.0, metavar="S",
                    help="with --probe-script: seconds between runs (default: 1)")
    th.add_argument("--rates", type=_number_list, metavar="HZ,...",
                    help="rates to try (default: the source's rate x 1, 0.8, ..., 0.1)")
    th.add_argument("--outages", type=_number_list, metavar="S,...",
                    help="interruptions to try, s (default: 0.5,1,2,3,5,8)")
    th.add_argument("--settle", type=_positive, default=5.0, metavar="S",
                    help="seconds at a new rate, or after an interruption's recovery, before "
                         "the probe counts (default: 5)")
    th.add_argument("--step", type=_positive, default=20.0, metavar="S",
                    help="seconds the probe is watched per step (default: 20)")
    th.add_argument("--quota", type=float, default=0.95, metavar="SHARE",
                    help="share of the probe's checks that must pass (default: 0.95)")
    th.add_argument("--improvement", type=float, default=0.1, metavar="SHARE",
                    help="a higher rate improves the score by more than this share of the "
                         "best, or it does not count (default: 0.1)")
    th.add_argument("--start-timeout", type=_positive, default=60.0, metavar="S",
                    help="how long a node may take to register (default: 60)")
    th.add_argument("--dry-run", action="store_true", help="do not write MODEL")
    th.add_argument("--json", action="store_true",
                    help="print {connection, source_hz, probe, steps: [{rate_hz, outage_s, "
                         "passed, checks, value_mean, delivered_hz, correct}], freq_min, "
                         "freq_opt, tolerance, tolerance_is_lower_bound, "
                         "freq_min_is_upper_bound, written}")
    th.set_defaults(run=run_thresholds)


def run_check(args) -> int:
    model = load_model(args.model)
    ch = characterise(model)
    print(f"{args.model}: valid. {len(model.scales)} scales, {len(model.nodes)} nodes, "
          f"{len(model.connections)} connections; network {model.network.technology}, "
          f"{model.network.max_bandwidth_mbps:g} Mbit/s")
    for s in model.scales:
        role = "master" if s.master else "remote"
        print(f"  scale {s.name:<12} {role:<6} {s.cores} x {s.cpu_ghz:g} GHz, "
              f"{s.memory_mb:g} MB, alpha {s.alpha:g}")
    master = model.master.name
    critical = [n for n, c in zip(ch.node_names, ch.critical) if c]
    pinned = [n.name for n in model.nodes if n.pinned and n.name not in critical]
    print(f"critical nodes ({len(critical)}, pinned to {master}): {', '.join(critical) or '-'}")
    print(f"pinned nodes ({len(pinned)}): " + (", ".join(
        f"{n} -> {model.node(n).pinned}" for n in pinned) or "-"))
    migratable = [i for i in range(ch.num_nodes) if ch.migratable[i]]
    print(f"migratable nodes ({len(migratable)}):" + ("" if migratable else " -"))
    for i in migratable:
        scales = ", ".join(f"{ch.scale_names[k]} {ch.cpu[i, k]:g} %"
                           for k in range(ch.num_scales) if ch.allowed[i, k])
        print(f"  {ch.node_names[i]:<16} CPU {scales}; moves {ch.bandwidth_of_node(i):g} Mbit/s "
              f"when remote")
    count = count_mappings(ch)
    after_memory = ("not counted (too many to enumerate)" if count.after_memory is None
                    else f"{count.after_memory}")
    print(f"mappings: {count.before_pruning} before pruning, {count.after_pinning} after "
          f"pinning, {after_memory} after memory")
    return 0


def run_plan(args) -> int:
    model = load_model(args.model)
    state = load_state(args.state, model) if args.state else DynamicState.nominal(model)
    try:
        allocator = make_allocator(args.solver)
    except ValueError as e:
        raise ModelError("--solver", "", str(e)) from None
    ch = characterise(model)
    start = ch.initial_mapping()
    decision = allocator.decide(ch, start, state, AllocationContext())
    broken = violations(ch, decision.assign, state)
    result = {"mapping": ch.as_dict(decision.assign), "perf": perf(ch, decision.assign),
              "feasible": not broken, "solver": allocator.name}
    if args.json:
        print(json.dumps(result, indent=2))
        return 0
    print_plan(ch, state, start, decision, result, [v.message for v in broken])
    return 0


def print_plan(ch: Characterisation, state: DynamicState, start, decision, result,
               broken: List[str]):
    links = ", ".join(f"{s} {'up' if state.link_up.get(s, True) else 'down'}"
                      for s in ch.scale_names if s != ch.scale_names[ch.master]) or "-"
    loads = ", ".join(f"{s} {state.scale_load.get(s, 0.0):g} %" for s in ch.scale_names)
    print(f"solver {result['solver']}; bandwidth {state.bandwidth_mbps:g} Mbit/s; "
          f"links {links}; background load {loads}")
    reasons = {m.node: m.reason for m in decision.moves}
    shown = [i for i in range(ch.num_nodes) if ch.migratable[i] or i in reasons]
    width = max((len(ch.node_names[i]) for i in shown), default=0)
    for i in shown:
        name, where = ch.node_names[i], ch.scale_names[decision.assign[i]]
        if i in reasons:
            print(f"  {name:<{width}}  {ch.scale_names[start[i]]} -> {where}  ({reasons[i]})")
        else:
            print(f"  {name:<{width}}  stays on {where}")
    print(f"  ({ch.num_nodes - len(shown)} critical or pinned nodes stay where they are)")
    base = perf(ch, start)
    gain = (result["perf"] / base - 1) * 100 if base > 0 else 0.0
    print(f"Perf (Eq. 1): {base:g} -> {result['perf']:g} ({gain:+.1f} %)")
    print(f"bandwidth across scales: {required_bandwidth(ch, decision.assign):g} of "
          f"{state.bandwidth_mbps:g} Mbit/s")
    print("feasible: yes" if result["feasible"] else "feasible: NO: " + "; ".join(broken))


SIMULATE_DESCRIPTION = ("Simulate the paper's generalised test bed (Fig. 7) and compare the "
                        "heuristic, the exact optimum and the best case with no migration.")


def run_simulate(args) -> int:
    try:
        from anyscale_study import simulation_report
    except ModuleNotFoundError as e:
        if e.name != "anyscale_study":
            raise
        print("anyscale simulate: needs the package anyscale_study (the paper's Fig. 7 study); "
              "build or install it beside anyscale_core", file=sys.stderr)
        return EXIT_USAGE
    parser = argparse.ArgumentParser(prog="anyscale simulate", description=SIMULATE_DESCRIPTION)
    simulation_report.add_arguments(parser)
    return simulation_report.main(parser.parse_args(args.options))


def run_top(args) -> int:
    # Imported here: check, plan and simulate must work without ROS installed.
    from . import top_view
    return top_view.run(args.model, args.once, max(args.period, 0.1))


def run_model_draft(args) -> int:
    if not 0 < args.seconds <= 3600:
        raise ModelError("--seconds", "", f"expected seconds in (0, 3600], got {args.seconds:g}")
    if args.output != "-" and os.path.exists(args.output) and not args.force:
        raise ModelError(args.output, "", "exists; give --force to overwrite it")
    # Imported here: check, plan and simulate must work without ROS installed.
    from .model_draft import draft_model
    from .model_draft_ros import collect_snapshot
    text = draft_model(collect_snapshot(args.seconds))
    if args.output == "-":
        sys.stdout.write(text)
        return 0
    try:
        # "x" refuses a file that appeared while the graph was counted.
        with open(args.output, "w" if args.force else "x", encoding="utf-8") as f:
            f.write(text)
    except FileExistsError:
        raise ModelError(args.output, "", "exists; give --force to overwrite it") from None
    except OSError as e:
        raise ModelError(args.output, "", f"cannot write: {e.strerror}") from None
    print(f"{args.output}: drafted; replace every TODO, then: anyscale check {args.output}",
          file=sys.stderr)
    return 0


def _require_model_file(path: str):
    if not os.path.isfile(path):
        raise ModelError(path, "", "no such file")


def run_profile(args) -> int:
    _require_model_file(args.model)
    nodes = [n.strip() for n in args.nodes.split(",") if n.strip()] or None
    # Imported here: check, plan and simulate must work without ROS installed.
    from . import profile_ros
    return profile_ros.run(args.model, nodes, args.warmup, args.window, args.lease,
                           args.start_timeout, args.dry_run, args.json)


def run_thresholds(args) -> int:
    _require_model_file(args.model)
    if args.probe and not args.condition:
        raise ModelError("--probe", "", "needs --condition EXPR (true when correct)")
    if args.probe_script and (args.condition or args.value):
        raise ModelError("--condition/--value", "", "go with --probe TOPIC, not --probe-script")
    if not 0 < args.quota <= 1:
        raise ModelError("--quota", "", f"expected a share in (0, 1], got {args.quota:g}")
    if not 0 <= args.improvement < 1:
        raise ModelError("--improvement", "", f"expected a share in [0, 1), got "
                                              f"{args.improvement:g}")
    from . import thresholds_ros
    return thresholds_ros.run(args)


def main(argv: Optional[List[str]] = None) -> int:
    parser = build_parser()
    args, study_options = parser.parse_known_args(argv)
    if args.command == "simulate":
        args.options = study_options
    elif study_options:
        parser.error("unrecognized arguments: " + " ".join(study_options))
    try:
        return args.run(args)
    except ModelError as e:
        print(f"anyscale {args.command}: error: {e}", file=sys.stderr)
        return EXIT_USAGE
    except KeyboardInterrupt:
        print(f"anyscale {args.command}: interrupted", file=sys.stderr)
        return 130
