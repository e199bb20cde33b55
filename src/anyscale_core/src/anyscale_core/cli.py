"""The `anyscale` command line: check a model, plan one decision, run the Fig. 7 simulation,
watch a running system (top), draft a model from a running graph (model draft).

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


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="anyscale",
        description="AnyScale: decide where the nodes of a ROS system run (paper: AnyScale "
                    "computing for ROS).")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True

    check = sub.add_parser("check", help="validate a system model and characterise it",
                           description="Validate a system model (YAML) and print its critical, "
                                       "pinned and migratable nodes and the number of allowed "
                                       "mappings before and after pruning.")
    check.add_argument("model", metavar="MODEL", help="system model YAML file")
    check.set_defaults(run=run_check)

    plan = sub.add_parser("plan", help="one allocation decision from the all-on-master start",
                          description="Run one decision of an allocator from the paper's "
                                      "initial configuration (every node on the master scale) "
                                      "and print the mapping, its Perf (Eq. 1) and whether it "
                                      "satisfies the constraints.")
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
    return parser


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
