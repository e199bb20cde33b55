"""`anyscale profile`: each node's cpu_usage and memory_mb measured on every scale that may run
it through the AnyScale agents (profile_ros.py, imported only when it runs), or taken from what
a decision node learned (--from-run), written into the model in place."""
from .cli_common import (RUNNING_AGENTS, add_command, add_seconds, add_start_timeout,
                         require_model_file)
from .model import ModelError


def add_parsers(sub):
    add_profile_parser(sub)


def add_profile_parser(sub):
    profile = add_command(
        sub, "profile", run_profile,
        help="measure each node's cpu_usage and memory_mb on every scale that may run it, into "
             "the model",
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
               "--nodes amcl,ar_recognition\n"
               "  anyscale profile my_robot.yaml --from-run results/testbed/RUN/   # what a run "
               "learned\n\n"
               "--from-run FILE writes instead the CPU costs the decision node learned in a run "
               "(the file\nof its ~learned_costs_out, or a test-bed run's directory holding "
               "learned_costs.yaml),\nwithout the agents: each node and scale learned from at "
               "least --min-samples reports.\n\n"
               "exit status: 0 done; 2 bad input, no master, a decision node running, an agent "
               "missing,\na node that fails to start (one line on standard error); 130 "
               "interrupted.")
    profile.add_argument("model", metavar="MODEL", help="system model YAML file (updated in "
                                                        "place unless --dry-run)")
    profile.add_argument("--nodes", metavar="A,B", default="",
                         help="measure only these nodes (default: every node of the model)")
    add_seconds(profile, "--warmup", 10.0, "seconds after a node's start before its window")
    add_seconds(profile, "--window", 30.0, "seconds of samples per window")
    add_seconds(profile, "--lease", 10.0, "lease of each node it starts: they end this long "
                                          "after the command dies")
    add_start_timeout(profile)
    profile.add_argument("--from-run", metavar="FILE", default=None,
                         help="write what the decision node learned in a run (its "
                              "~learned_costs_out file, or a run directory holding "
                              "learned_costs.yaml) instead of measuring; --warmup, --window, "
                              "--lease and --start-timeout do not apply")
    profile.add_argument("--min-samples", type=int, default=10, metavar="N",
                         help="with --from-run: a figure learned from fewer reports is not "
                              "written (default: 10)")
    profile.add_argument("--dry-run", action="store_true", help="measure, print, do not write "
                                                                "MODEL")
    profile.add_argument("--json", action="store_true",
                         help="print the figures as JSON: {model, measured_at, warmup_s, "
                              "window_s, measurements: [{node, scale, cpu_usage, "
                              "cpu_percent_of_one_core, cpu_sd, samples, capacity_cores, quota, "
                              "rss_mb, window_s, output_rates_hz}], memory_mb: {node: MB}, "
                              "not_measured, written}")


def run_profile(args) -> int:
    require_model_file(args.model)
    nodes = [n.strip() for n in args.nodes.split(",") if n.strip()] or None
    if args.from_run is not None:
        if args.min_samples < 1:
            raise ModelError("--min-samples", "", f"expected a count >= 1, got "
                                                  f"{args.min_samples}")
        from .learned_costs import run_from_run
        return run_from_run(args.model, args.from_run, nodes, args.min_samples, args.dry_run,
                            args.json)
    # Imported here: check, plan and simulate must work without ROS installed.
    from . import profile_ros
    return profile_ros.run(args.model, nodes, args.warmup, args.window, args.lease,
                           args.start_timeout, args.dry_run, args.json)
