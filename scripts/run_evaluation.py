#!/usr/bin/python3
"""The paper's evaluation on the two-scale test bed (by default per seed a baseline run, then at
once its AnyScale test, gains measured side by side; the other allocators' tests, best case;
the table beside the paper's, Fig. 5 and Fig. 6): the logic is anyscale_testbed.evaluation_run;
results go to results/evaluation/ of this workspace.

Root, with the workspace sourced; options: --help.
"""
import os
import sys

try:
    from anyscale_testbed.evaluation_run import main
except ImportError as e:
    sys.exit(f"{os.path.basename(__file__)}: {e}: source this workspace first "
             "(source devel/setup.bash; scripts/setup.sh installs and builds it)")

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

if __name__ == "__main__":
    sys.exit(main(os.path.join(ROOT, "results", "evaluation"),
                  os.path.join(ROOT, "scripts", "run_testbed.py")))
