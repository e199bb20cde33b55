#!/usr/bin/python3
"""The fault soak (root, issue 15): the navigation demo on the small loop, on the two-scale test
bed with AnyScale deciding, while a seeded schedule injects faults one at a time: link flaps of
1-5 s and bandwidth steps, kill -9 of the laptop's and of the robot's agent, kill -9 of the
decision node (roslaunch restarts it), SIGSTOP/SIGCONT of the laptop's agent for 1-4 s, SIGSEGV
of a managed node, and a restart of roscore (robot.launch's master keeper gives the new master
the parameters and registrations the old one held). After each fault it checks the invariants
(one instance of each node, none on a scale the mapping does not place it on once leases ran
out, in /proc and in the master's lists, critical and pinned nodes never moved, every Δ kept,
critical topics included; at the end nothing left behind and no
growth of the agents' and the decision node's memory and file descriptors) and prints a table
per fault kind (count, worst recovery, violations); CSV and Markdown copies and the raw samples
go to --out. The logic is anyscale_testbed.soak_run (orchestration), fault_schedule and
soak_invariants (pure). Run with the workspace sourced:
    sudo -E /usr/bin/python3 tests/bench/bench_fault_soak.py --minutes 10 --seed 1
    /usr/bin/python3 tests/bench/bench_fault_soak.py --minutes 10 --seed 1 --dry-run
    /usr/bin/python3 tests/bench/bench_fault_soak.py --judge results/bench_fault_soak/DATE
"""
import os
import sys

try:
    from anyscale_testbed.soak_run import main
except ImportError as e:
    sys.exit(f"{os.path.basename(__file__)}: {e}: source this workspace first "
             "(source devel/setup.bash; scripts/setup.sh installs and builds it)")

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

if __name__ == "__main__":
    sys.exit(main(ROOT))
