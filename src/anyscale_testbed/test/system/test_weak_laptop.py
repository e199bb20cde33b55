"""System test of learning from placements that fail (issue 40) on the two-scale test bed (root:
network namespaces, tc, cgroups; conftest.py skips without them): a laptop whose CPU quota is too
small for AMCL and AR recognition together at their optimal rates. Without learning, AMCL went
out on the model's 36 %, came home for its rate and went out again about every T; with it, the
decision node learns each node's cost on the laptop and backs the move off, so each goes out a
few times at most, and every Δ holds. The link is a fixed good one (scheduled), so no return is
the link's doing.

One run of the small loop serves every test here; the first test checks that the laptop sent a
node home for its rate or CPU, so that the others test what they claim."""
import glob
import os
import subprocess
import sys

import pytest

from anyscale_testbed.calibration_file import quota_cores
from anyscale_testbed.testbed_record import OTHER_RETURN, TestbedRecord, kind_of_move

# Judges AMCL's rate on a starved laptop and the outputs' Δ at fixed quotas (conftest.py skips
# on a host too slow for them).
pytestmark = pytest.mark.fixed_cpu_quota

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", "..", "..", ".."))
DURATION_S = 100.0
HYSTERESIS_S = 10.0
# A laptop this small gives AMCL alone its optimal rate but not beside AR recognition (the
# calibration file's 0.9 cores do); one much smaller (0.12) starves the laptop's agent too, whose
# rate monitor then sees silences that are its own.
LAPTOP_CPU_CORES = 0.3
MOST_MOVES_OUT = 3          # issue 40: at most 3 moves of a node out; one every ~T+10 s would be 5


@pytest.fixture(scope="module")
def run(tmp_path_factory, slow_host_argv, host_factor):
    out = tmp_path_factory.mktemp("weak_laptop")
    robot_cpu, _ = quota_cores(None, None)
    done = subprocess.run(
        [sys.executable, os.path.join(ROOT, "scripts", "run_testbed.py"), "--world",
         "small_loop", "--link", "schedule", "--schedule", "[[0, 27]]", "--loops", "5",
         "--duration", str(DURATION_S), "--hysteresis", str(HYSTERESIS_S),
         "--robot-cpu", str(robot_cpu), "--laptop-cpu", str(LAPTOP_CPU_CORES),
         "--out", str(out)] + slow_host_argv,
        capture_output=True, text=True, timeout=DURATION_S + 180 * host_factor)
    records = glob.glob(str(out / "*" / "record.json"))
    assert done.returncode == 0 and records, done.stdout[-3000:] + done.stderr[-3000:]
    print(done.stdout)      # the run's own account, shown with -s or on failure
    return TestbedRecord.load(records[0])


OFFLOADED = ("amcl", "ar_recognition")   # the nodes the model lets out to the laptop


def moves(rec, node, kind):
    return [e for e in rec.events if e.node == node and e.kind == kind and e.success]


def account(rec):
    """The offloaded nodes' moves, short enough for CI's one-line failure summary."""
    return [(e.node, round(e.t, 1), e.kind, e.reason[:60]) for e in rec.events
            if e.node in OFFLOADED and e.kind in ("migrate", "migrate_back")]


def test_the_laptop_is_too_small_for_amcl_and_ar_recognition(run):
    """The premise: a node went out and was sent home for its rate or CPU on the laptop at
    least once (else the run tests nothing). AMCL alone fits the laptop at its rate; AMCL
    and AR recognition together do not, so either may be the one sent home."""
    returns = [e for node in OFFLOADED for e in moves(run, node, "migrate_back")
               if kind_of_move(e) == OTHER_RETURN and not e.reason.startswith("bandwidth")]
    assert returns, account(run)


@pytest.mark.parametrize("node", OFFLOADED)
def test_a_node_goes_out_a_few_times_at_most(run, node):
    out = moves(run, node, "migrate")
    assert len(out) <= MOST_MOVES_OUT, account(run)


def test_amcl_went_out(run):
    assert moves(run, "amcl", "migrate"), account(run)


def test_the_learned_cost_on_the_laptop_is_above_the_models(run):
    """Each node sent home for its rate or CPU there is learned to cost more than the model says."""
    assert run.cost_estimates, "no /anyscale/cost_estimates recorded"
    laptop = {c["node"]: c for c in run.cost_estimates if c["scale"] == "laptop"}
    sent_home = {e.node for node in OFFLOADED for e in moves(run, node, "migrate_back")
                 if kind_of_move(e) == OTHER_RETURN}
    assert sent_home, account(run)
    for node in sent_home:
        assert node in laptop and laptop[node]["live_percent"] > laptop[node]["model_percent"], \
            (node, laptop.get(node))


def test_every_output_kept_its_tolerance(run):
    assert not run.violations, [(v.topic, round(v.silence_s, 2), v.cause)
                                for v in run.violations]
