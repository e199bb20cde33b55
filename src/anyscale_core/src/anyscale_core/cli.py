"""The `anyscale` command line: check a model, plan one decision, watch a running system (top),
draft a model from a running graph (model draft), measure its nodes' CPU (profile) and a
connection's thresholds (thresholds), and the commands other packages register (cli_plugins:
the Fig. 7 study's `simulate`).

This module assembles the parser from the sub-command modules (each adds its parsers and
carries its commands out) and turns their errors into one line. Errors in the user's files are
printed as one line naming the file and key, exit status 2; so is bad usage.
"""
import argparse
import os
import sys
from typing import List, Optional

from . import cli_check_plan, cli_model_draft, cli_profile, cli_thresholds, cli_top
from .cli_common import EXIT_USAGE, OneLineParser
from .cli_plugins import KNOWN_ELSEWHERE, add_plugin_parsers, registered_modules
from .model import ModelError

# In the order `anyscale --help` lists them (check, plan, top, model, profile, thresholds),
# then the registered commands.
COMMAND_MODULES = (cli_check_plan, cli_top, cli_model_draft, cli_profile, cli_thresholds)


def build_parser(plugins=None) -> argparse.ArgumentParser:
    parser = OneLineParser(
        prog="anyscale",
        description="AnyScale: decide where the nodes of a ROS system run (paper: AnyScale "
                    "computing for ROS).")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    for module in COMMAND_MODULES:
        module.add_parsers(sub)
    add_plugin_parsers(sub, registered_modules() if plugins is None else plugins)
    parser.command_names = frozenset(sub.choices)
    return parser


def main(argv: Optional[List[str]] = None, plugins=None) -> int:
    """plugins: the registered (package, module) pairs; None: as `rospack plugins` lists them."""
    parser = build_parser(plugins)
    argv = sys.argv[1:] if argv is None else argv
    command = argv[0] if argv else ""
    if command in KNOWN_ELSEWHERE and command not in parser.command_names:
        print(f"anyscale {command}: needs the package {KNOWN_ELSEWHERE[command]}; build or "
              f"install it beside anyscale_core", file=sys.stderr)
        return EXIT_USAGE
    args = parser.parse_args(argv)
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
