"""The tests that need the two-scale test bed (root, network namespaces, tc, cgroups) skip only
where this machine cannot run them, with a reason that starts with system_test_gate.NOT_RUN.
Such skips are counted into one loud line of pytest's summary; with
ANYSCALE_REQUIRE_SYSTEM_TESTS=1 each of them fails instead (a release check)."""
import os

import pytest

from anyscale_testbed.system_test_gate import NOT_RUN, REQUIRE_ENV, required, summary_line

NOT_RUN_REASONS = []


def skip_reason(report):
    """The reason of a skipped report ("" for any other): pytest keeps (path, line, text)."""
    if not report.skipped or not isinstance(report.longrepr, tuple):
        return ""
    return report.longrepr[2].split("Skipped: ", 1)[-1]


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item, call):
    outcome = yield
    report = outcome.get_result()
    reason = skip_reason(report)
    if not reason.startswith(NOT_RUN):
        return
    if required(os.environ):
        report.outcome = "failed"
        report.longrepr = f"{REQUIRE_ENV}=1, and {reason}"
    else:
        NOT_RUN_REASONS.append(reason[len(NOT_RUN):])


def pytest_terminal_summary(terminalreporter):
    if NOT_RUN_REASONS:
        terminalreporter.write_line(summary_line(NOT_RUN_REASONS), red=True, bold=True)
