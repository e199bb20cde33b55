"""The system tests run on the two-scale test bed: without root, network namespaces, tc or
cgroups each of them skips, saying which is missing. Those marked `fixed_cpu_quota` judge rates
and tolerances at the bed's fixed CPU quotas, and skip on a host too slow for them
(host_speed.too_slow_for_fixed_quotas), saying how slow it was."""
import functools

import pytest

from anyscale_testbed.host_speed import idle_cpu_ms, too_slow_for_fixed_quotas
from anyscale_testbed.two_scale_testbed import missing_capabilities

MISSING = missing_capabilities()


@functools.lru_cache(maxsize=None)
def host_too_slow():
    """Read once, at the first marked test, before any bed of it loads the host (the previous
    module's bed is torn down by then)."""
    return too_slow_for_fixed_quotas(idle_cpu_ms())


@pytest.hookimpl(tryfirst=True)     # before the fixtures that would build the test bed
def pytest_runtest_setup(item):
    if MISSING:
        pytest.skip("the two-scale test bed needs " + "; ".join(MISSING))
    if item.get_closest_marker("fixed_cpu_quota") and host_too_slow():
        pytest.skip("these tests need " + host_too_slow())
