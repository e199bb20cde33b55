"""The system tests run on the two-scale test bed: without root, network namespaces, tc or
cgroups each of them skips, saying which is missing."""
import pytest

from anyscale_testbed.two_scale_testbed import missing_capabilities

MISSING = missing_capabilities()


@pytest.hookimpl(tryfirst=True)     # before the fixtures that would build the test bed
def pytest_runtest_setup(item):
    if MISSING:
        pytest.skip("the two-scale test bed needs " + "; ".join(MISSING))
