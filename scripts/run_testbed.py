#!/usr/bin/python3
"""The navigation demo on the two-scale test bed with AnyScale deciding (the main job's run):
the logic is anyscale_testbed.demo_run; results go to results/testbed/ of this workspace.

Run with the workspace sourced (scripts/run_demo.sh does that); options: --help.
"""
import os
import sys

from anyscale_testbed.demo_run import main

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

if __name__ == "__main__":
    sys.exit(main(os.path.join(ROOT, "results", "testbed")))
