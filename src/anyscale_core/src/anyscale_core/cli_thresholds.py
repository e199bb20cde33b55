"""`anyscale thresholds`: a connection's freq_min, freq_opt and tolerance measured on the running
system, the paper's offline search (thresholds_ros.py with thresholds_chain_ros.py, imported
only when it runs)."""
from .cli_common import (RUNNING_AGENTS, add_command, add_seconds, add_start_timeout,
                         number_list, require_model_file)
from .model import ModelError


def add_parsers(sub):
    add_thresholds_parser(sub)


def add_thresholds_parser(sub):
    th = add_command(
        sub, "thresholds", run_thresholds,
        help="find a connection's freq_min, freq_opt and tolerance with a correctness probe",
        description="Find freq_min, freq_opt and the tolerance of one connection of MODEL "
                    "(paper, Table I), as\nthe paper did by hand: feed the subscriber less and "
                    "less and watch whether it still\nworks.\n\n"
                    "The subscriber is restarted by this command with its input remapped to "
                    "TOPIC_throttle,\nwhich `topic_tools throttle messages TOPIC RATE "
                    "TOPIC_throttle` feeds. Step by step,\nhighest rate first (the source's "
                    "rate divided by 1, 2, 3, 4, 5, 6, 8, 10: what throttle\ncan deliver from a "
                    "periodic source; or the nearest of those to --rates), the stream\nruns "
                    "--settle seconds, then the probe is watched for --step seconds.\nThen, at "
                    "freq_opt, the stream is cut for each of --outages seconds (shortest\n"
                    "first), and the probe is watched from the cut until "
                    "--step seconds after it. A step is\ncorrect when at least --quota of the "
                    "probe's checks pass. Each ladder stops at its first\nincorrect step "
                    "(the subscriber's state is suspect after it). After an incorrect rate\n"
                    "step the stream runs at freq_opt again and the probe is watched, --step "
                    "seconds at a\ntime, until a window is correct; the interruptions are "
                    "judged only on a subscriber\nthat recovered within --recover seconds "
                    "(AMCL lost at 1 Hz may stay lost), else the\ntolerance is reported as "
                    "not measured and left as it is in MODEL.\n\n"
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
    add_seconds(th, "--probe-period", 1.0, "with --probe-script: seconds between runs")
    th.add_argument("--rates", type=number_list, metavar="HZ,...",
                    help="rates to try, each taken as the nearest source rate / k (default: "
                         "the source's rate / 1, 2, 3, 4, 5, 6, 8, 10)")
    th.add_argument("--outages", type=number_list, metavar="S,...",
                    help="interruptions to try, s (default: 0.5,1,2,3,5,8)")
    add_seconds(th, "--settle", 5.0, "seconds at a new rate, or after an interruption's "
                                     "recovery, before the probe counts")
    add_seconds(th, "--step", 20.0, "seconds the probe is watched per step")
    add_seconds(th, "--recover", 60.0, "after an incorrect rate step: seconds the subscriber "
                                       "has to work again at freq_opt before the "
                                       "interruptions")
    th.add_argument("--quota", type=float, default=0.95, metavar="SHARE",
                    help="share of the probe's checks that must pass (default: 0.95)")
    th.add_argument("--improvement", type=float, default=0.1, metavar="SHARE",
                    help="a higher rate improves the score by more than this share of the "
                         "best, or it does not count (default: 0.1)")
    add_start_timeout(th)
    th.add_argument("--dry-run", action="store_true", help="do not write MODEL")
    th.add_argument("--json", action="store_true",
                    help="print {connection, source_hz, probe, steps: [{rate_hz, outage_s, "
                         "passed, checks, value_mean, delivered_hz, correct}], freq_min, "
                         "freq_opt, tolerance, tolerance_is_lower_bound, "
                         "freq_min_is_upper_bound, written}")


def run_thresholds(args) -> int:
    require_model_file(args.model)
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
