#!/usr/bin/python3
"""The navigation demo on the two-scale test bed with AnyScale deciding (the main job's run):
the logic is anyscale_testbed.demo_run; results go to results/testbed/ of this workspace.

Run with the workspace sourced (scripts/run_demo.sh does that); options: --help.
"""
import os
import sys

try:
    from anyscale_testbed.demo_run import main
except ImportError as e:
    sys.exit(f"{os.path.basename(__file__)}: {e}: source this workspace first "
             "(source devel/setup.bash; scripts/setup.sh installs and builds it)")

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

if __name__ == "__main__":
    sys.exit(main(os.path.join(ROOT, "results", "testbed"), os.path.abspath(__file__)))
