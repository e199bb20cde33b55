"""The `anyscale` command line: check a model, plan one decision, run the Fig. 7 simulation,
watch a running system (top), draft a model from a running graph (model draft), measure its
nodes' CPU (profile) and a connection's thresholds (thresholds).

This module assembles the parser from the sub-command modules in COMMAND_MODULES (each adds its
parsers and carries its commands out) and turns their errors into one line. Errors in the
user's files are printed as one line naming the file and key, exit status 2; so is bad usage.
"""
import argparse
import os
import sys
from typing import List, Optional

from . import cli_check_plan, cli_profile_thresholds, cli_simulate, cli_top_draft
from .cli_common import EXIT_USAGE, OneLineParser
from .model import ModelError

# In the order `anyscale --help` lists them: check, plan, simulate, top, model, profile,
# thresholds.
COMMAND_MODULES = (cli_check_plan, cli_simulate, cli_top_draft, cli_profile_thresholds)


def build_parser() -> argparse.ArgumentParser:
    parser = OneLineParser(
        prog="anyscale",
        description="AnyScale: decide where the nodes of a ROS system run (paper: AnyScale "
                    "computing for ROS).")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    for module in COMMAND_MODULES:
        module.add_parsers(sub)
    return parser


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
    except BrokenPipeError:
        # The reader went away (`anyscale check M | head`): as other commands do, end quietly.
        # stdout points at /dev/null so that the interpreter's last flush does not raise again.
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 141
