"""`anyscale check` and `anyscale plan`: a system model on paper, no ROS needed. check validates
and characterises it; plan makes one decision of an allocator from the all-on-master start."""
import json
from typing import List

from .allocators import ALLOCATORS, DEFAULT_ALLOCATOR, AllocationContext, make_allocator
from .characterisation import Characterisation, characterise, count_mappings
from .cli_common import add_command
from .constraints import DynamicState, load_state, required_bandwidth, violations
from .cost import perf
from .model import ModelError
from .model_loader import load_model


def add_parsers(sub):
    check = add_command(
        sub, "check", run_check, help="validate a system model and characterise it",
        description="Validate a system model (YAML) and print its critical, pinned and "
                    "migratable nodes and the number of allowed mappings before and after "
                    "pruning.",
        epilog="example:\n  anyscale check $(rospack find anyscale_nav_demo)/config/"
               "testbed.yaml\n\nexit status: 0 valid; 2 invalid (one line naming the file, the "
               "key and what was\nexpected)")
    check.add_argument("model", metavar="MODEL", help="system model YAML file")

    plan = add_command(
        sub, "plan", run_plan, help="one allocation decision from the all-on-master start",
        description="Run one decision of an allocator from the paper's initial configuration "
                    "(every node on the master scale) and print the mapping, its Perf (Eq. 1) "
                    "and whether it satisfies the constraints.",
        epilog="examples:\n  anyscale plan testbed.yaml\n"
               "  echo 'bandwidth_mbps: 3' > weak.yaml; anyscale plan testbed.yaml --state "
               "weak.yaml --json\n  anyscale plan testbed.yaml --solver optimal\n\n"
               "exit status: 0 planned; 2 a bad model, state file or solver (one line)")
    plan.add_argument("model", metavar="MODEL", help="system model YAML file")
    plan.add_argument("--state", metavar="STATE",
                      help="YAML with the dynamic parameters: bandwidth_mbps (default: the "
                           "network's maximum), scale_load {scale: %%} (default 0), link_up "
                           "{remote scale: bool} (default true)")
    plan.add_argument("--solver", default=DEFAULT_ALLOCATOR, metavar="NAME",
                      help=f"allocator: {', '.join(sorted(ALLOCATORS))} (default: "
                           f"{DEFAULT_ALLOCATOR})")
    plan.add_argument("--json", action="store_true",
                      help='print {"mapping": {node: scale}, "perf": float, "feasible": bool, '
                           '"solver": str}')


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
