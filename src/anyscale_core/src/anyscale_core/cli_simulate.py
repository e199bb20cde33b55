"""`anyscale simulate`: the paper's Fig. 7 study. It lives in the anyscale_study package, which
a robot does not need: it is imported only when the command runs, and where it is missing the
command says what to install (exit status 2)."""
import argparse
import sys

from .cli_common import EXIT_USAGE, add_command

SIMULATE_DESCRIPTION = ("Simulate the paper's generalised test bed (Fig. 7) and compare the "
                        "heuristic, the exact optimum and the best case with no migration.")


def add_parsers(sub):
    # Its options are the study's own (anyscale_study.simulation_report.add_arguments): main()
    # hands them over unparsed and run_simulate parses them once the package is known to be there.
    add_command(sub, "simulate", run_simulate, raw=False, add_help=False,
                help="the paper's Fig. 7 simulation study (package anyscale_study)")


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
