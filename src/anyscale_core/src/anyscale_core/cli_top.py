"""`anyscale top`: a live terminal view of the running system. rospy is imported only when it
runs, so that the commands on paper work without ROS installed."""
from .cli_common import add_command


def add_parsers(sub):
    top = add_command(
        sub, "top", run_top, help="live view of scales, nodes, connection rates and events",
        description="A live terminal view of the running system: every scale (CPU, memory, "
                    "link), every node and where it runs, each model connection's rate "
                    "against freq_min/freq_opt, and the last migration events. Needs a ROS "
                    "master.",
        epilog="examples:\n  anyscale top\n  anyscale top --model testbed.yaml --once"
               "\n\nexit status: 0; 1 no ROS master")
    top.add_argument("--model", metavar="MODEL",
                     help="system model YAML (default: the one the decision node publishes "
                          "as /anyscale/model)")
    top.add_argument("--once", action="store_true",
                     help="print one frame once data has arrived, then exit")
    top.add_argument("--period", type=float, default=1.0, metavar="S",
                     help="refresh period in seconds (default: 1)")


def run_top(args) -> int:
    # Imported here: check, plan and simulate must work without ROS installed.
    from . import top_view
    return top_view.run(args.model, args.once, max(args.period, 0.1))
