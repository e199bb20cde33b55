"""The system tests run on the two-scale test bed. Without root, network namespaces, tc or
cgroups each of them does not run (../conftest.py: a loud line in the summary, or a failure
with ANYSCALE_REQUIRE_SYSTEM_TESTS=1). Those marked `fixed_cpu_quota` judge rates and tolerances
at the bed's CPU quotas: they run in the slow-day mode for this host's speed (`slow_host_argv`,
anyscale_testbed/slow_host.py), and not at all on a host slower than that mode covers.
ANYSCALE_EMULATED_HOST_FACTOR=F emulates a host F times slower than the reference day."""
import functools
import os

import pytest

from anyscale_testbed.host_speed import idle_cpu_ms
from anyscale_testbed.system_test_gate import NOT_RUN, host_mode, too_slow
from anyscale_testbed.two_scale_testbed import missing_capabilities

MISSING = missing_capabilities()


@functools.lru_cache(maxsize=None)
def this_host():
    """Read once, at the first marked test, before any bed of it loads the host (the previous
    module's bed is torn down by then). ValueError for a bad ANYSCALE_EMULATED_HOST_FACTOR."""
    mode = host_mode(idle_cpu_ms(), os.environ)
    print(f"\n[system tests] {mode.describe()}")
    return mode


@pytest.hookimpl(tryfirst=True)     # before the fixtures that would build the test bed
def pytest_runtest_setup(item):
    if MISSING:
        pytest.skip(NOT_RUN + "this machine lacks " + "; ".join(MISSING))
    if item.get_closest_marker("fixed_cpu_quota"):
        why = too_slow(this_host())
        if why:
            pytest.skip(NOT_RUN + why)


@pytest.fixture(scope="session")
def slow_host_argv():
    """run_testbed.py's (and bench_fault_soak.py's) options for this host's speed."""
    return this_host().argv()


@pytest.fixture(scope="session")
def host_factor():
    """How many times slower than the reference day the tests run as (1: not slower)."""
    return this_host().factor
