"""When the test bed's tests run, and what a machine that cannot run them reports
(system_test_gate.py and the conftest.py files): the slow-day mode for a host's reading, an
emulated slower host, the one loud summary line of the tests that did not run, and
ANYSCALE_REQUIRE_SYSTEM_TESTS=1 turning each of them into a failure (an error in its set-up)
(pytest in pytest, with the capability check faked). No root needed."""
import os

import pytest

from anyscale_testbed.host_speed import REFERENCE_IDLE_MS
from anyscale_testbed.system_test_gate import (EMULATE_ENV, MAX_HOST_FACTOR, NOT_RUN,
                                               REQUIRE_ENV, HostMode, host_mode, required,
                                               summary_line, too_slow)

pytest_plugins = "pytester"

HERE = os.path.dirname(os.path.abspath(__file__))


def test_a_host_runs_the_mode_of_its_own_reading():
    assert host_mode(REFERENCE_IDLE_MS, {}) == HostMode(REFERENCE_IDLE_MS, 1.0)
    assert host_mode(7.0, {}).factor == 1.0                 # faster: nothing scaled
    slow = host_mode(45.0, {})                              # a slow day's reading
    assert slow.factor == pytest.approx(45.0 / REFERENCE_IDLE_MS) and slow.slowdown == 1.0
    assert slow.argv() == ["--host-factor", f"{slow.factor:.3f}"]


def test_an_emulated_host_is_slowed_down_from_this_ones_own_reading():
    mode = host_mode(REFERENCE_IDLE_MS / 2, {EMULATE_ENV: "4.5"})   # twice as fast as the day
    assert mode.factor == 4.5 and mode.slowdown == pytest.approx(9.0)
    assert mode.argv() == ["--host-factor", "4.500", "--emulate-slow-host", "9.000"]
    assert "EMULATING" in mode.describe()
    # a host already slower than the one to emulate is not slowed down further
    assert host_mode(REFERENCE_IDLE_MS * 5, {EMULATE_ENV: "4.5"}).slowdown == 1.0
    for bad in ("fast", "0.5", "nan"):
        with pytest.raises(ValueError, match=EMULATE_ENV):
            host_mode(10.0, {EMULATE_ENV: bad})


def test_only_a_host_slower_than_the_mode_covers_is_too_slow():
    assert too_slow(HostMode(40.0, MAX_HOST_FACTOR)) is None
    why = too_slow(HostMode(80.0, MAX_HOST_FACTOR + 0.5))
    assert "80.0 ms" in why and f"{MAX_HOST_FACTOR:g} x" in why


def test_the_summary_names_how_many_and_each_reason_once():
    line = summary_line(["no root", "no root", "too slow"])
    assert line.startswith("SYSTEM TESTS SKIPPED: 3 ")
    assert "no root (2)" in line and "too slow (1)" in line and REQUIRE_ENV in line
    assert required({REQUIRE_ENV: "1"}) and not required({}) and not required({REQUIRE_ENV: "0"})


CONFTEST_FAKING = """
import anyscale_testbed.two_scale_testbed as bed
bed.missing_capabilities = lambda need_cgroups=True: {missing!r}
path = {path!r}
exec(compile(open(path).read(), path, "exec"))
"""

TESTS = """
import pytest

@pytest.mark.fixed_cpu_quota
def test_at_fixed_quotas(slow_host_argv):
    assert slow_host_argv

def test_of_outcomes():
    pass
"""


@pytest.fixture
def suite(pytester):
    """The test bed's conftest files around two system tests, the capability check faked."""
    def make(missing):
        pytester.makeini("[pytest]\nmarkers =\n    fixed_cpu_quota: at fixed quotas\n")
        pytester.makeconftest(CONFTEST_FAKING.format(missing=missing,
                                                     path=os.path.join(HERE, "conftest.py")))
        system = pytester.path / "system"
        system.mkdir(exist_ok=True)
        (system / "conftest.py").write_text(CONFTEST_FAKING.format(
            missing=missing, path=os.path.join(HERE, "system", "conftest.py")))
        (system / "test_bed.py").write_text(TESTS)
        return pytester
    return make


def test_a_machine_without_root_skips_them_with_one_loud_line(suite, monkeypatch):
    monkeypatch.delenv(REQUIRE_ENV, raising=False)
    result = suite(["root (faked)"]).runpytest_subprocess("-rs")
    result.assert_outcomes(skipped=2)
    loud = [line for line in result.outlines if line.startswith("SYSTEM TESTS SKIPPED")]
    assert len(loud) == 1 and "SKIPPED: 2 " in loud[0] and "root (faked)" in loud[0], loud
    assert NOT_RUN in result.stdout.str()


def test_with_the_release_check_a_machine_without_root_fails_them(suite, monkeypatch):
    monkeypatch.setenv(REQUIRE_ENV, "1")
    result = suite(["root (faked)"]).runpytest_subprocess()
    result.assert_outcomes(errors=2)        # a test that fails in its set-up is an error
    assert result.ret != 0
    assert f"{REQUIRE_ENV}=1, and {NOT_RUN}this machine lacks root (faked)" in result.stdout.str()
    assert "SYSTEM TESTS SKIPPED" not in result.stdout.str()


def test_a_host_slower_than_the_mode_skips_only_the_fixed_quota_tests(suite, monkeypatch):
    monkeypatch.delenv(REQUIRE_ENV, raising=False)
    monkeypatch.setenv(EMULATE_ENV, str(MAX_HOST_FACTOR + 1))
    result = suite([]).runpytest_subprocess("-rs")
    result.assert_outcomes(passed=1, skipped=1)
    assert "beyond the slow-day mode's" in result.stdout.str()
    monkeypatch.setenv(REQUIRE_ENV, "1")
    suite([]).runpytest_subprocess().assert_outcomes(passed=1, errors=1)
