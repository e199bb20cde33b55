"""What the `anyscale` sub-commands share: the parser whose usage errors are one line with exit
status 2, adding a sub-command with its help in one call, the option types with their one-line
errors, and the checks and help text common to the commands that drive the agents."""
import argparse
import os

from .model import ModelError

EXIT_USAGE = 2

RUNNING_AGENTS = ("It needs a ROS master, the agent of every scale it uses, and no decision "
                  "node\n(on the demo: `roslaunch anyscale_nav_demo robot.launch decision:=false` "
                  "on the robot,\n`roslaunch anyscale_nav_demo laptop.launch` on the laptop). ")


class OneLineParser(argparse.ArgumentParser):
    """Bad usage is one line and exit status 2, like a bad file: argparse's default prints the
    whole usage block first. Sub-command parsers are of this class too (add_subparsers makes
    them of the parent's class)."""

    def error(self, message):
        self.exit(EXIT_USAGE, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def add_command(sub, name: str, run, help: str, raw: bool = True,
                **kwargs) -> argparse.ArgumentParser:
    """The sub-command `name` of the sub-parsers `sub`, carried out by run(args). raw: its
    description and epilog are printed as written (their own line breaks)."""
    formatter = argparse.RawDescriptionHelpFormatter if raw else argparse.HelpFormatter
    parser = sub.add_parser(name, help=help, formatter_class=formatter, **kwargs)
    parser.set_defaults(run=run)
    return parser


def positive(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not 0 < value <= 86400:
        raise argparse.ArgumentTypeError(f"expected a number in (0, 86400], got {text}")
    return value


def number_list(text: str):
    try:
        values = [float(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected numbers separated by commas, got {text!r}") \
            from None
    if not values or any(not 0 < v <= 86400 for v in values):
        raise argparse.ArgumentTypeError(f"expected numbers in (0, 86400], got {text!r}")
    return values


def add_seconds(parser, flag: str, default: float, help: str):
    """An option of seconds in (0, 86400], its default named at the end of its help."""
    parser.add_argument(flag, type=positive, default=default, metavar="S",
                        help=f"{help} (default: {default:g})")


def add_start_timeout(parser: argparse.ArgumentParser):
    add_seconds(parser, "--start-timeout", 60.0, "how long a node may take to register")


def require_model_file(path: str):
    if not os.path.isfile(path):
        raise ModelError(path, "", "no such file")
