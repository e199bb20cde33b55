"""`anyscale model draft`: a first system model drafted from the running ROS graph, with TODO
where a human must decide. rospy is imported only when it runs."""
import os
import sys

from .cli_common import add_command
from .model import ModelError


def add_parsers(sub):
    model = sub.add_parser("model", help="write system models: `anyscale model draft`",
                           description="Commands that write system models.")
    model_sub = model.add_subparsers(dest="model_command", metavar="MODEL_COMMAND")
    model_sub.required = True
    draft = add_command(
        model_sub, "draft", run_model_draft,
        help="draft a model YAML from the running ROS graph",
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
    draft.set_defaults(command="model draft")


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
