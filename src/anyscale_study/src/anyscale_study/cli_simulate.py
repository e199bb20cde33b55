"""`anyscale simulate`: the paper's Fig. 7 study as a sub-command of the `anyscale` CLI,
registered in this package's package.xml (<anyscale_core cli="anyscale_study.cli_simulate"/>),
so anyscale_core never imports the study."""
from anyscale_core.cli_common import add_command

from . import simulation_report


def add_parsers(sub):
    parser = add_command(sub, "simulate", simulation_report.main, raw=False,
                         help="the paper's Fig. 7 simulation study (package anyscale_study)",
                         description="Simulate the paper's generalised test bed (Fig. 7) and "
                                     "compare the heuristic, the exact optimum and the best "
                                     "case with no migration.")
    simulation_report.add_arguments(parser)
