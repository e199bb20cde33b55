"""The closing line of scripts/run_tests.sh counts each <testcase> once, whatever the XML's
nesting (gtest's <testsuites> root repeats its suites' totals)."""
import importlib.util
import os

import pytest

SCRIPT = os.path.join(os.path.dirname(__file__), "..", "scripts", "summarize_test_results.py")
spec = importlib.util.spec_from_file_location("summarize_test_results", SCRIPT)
summarize_test_results = importlib.util.module_from_spec(spec)
spec.loader.exec_module(summarize_test_results)

GTEST = """<?xml version="1.0" encoding="UTF-8"?>
<testsuites tests="3" failures="1" disabled="0" errors="0" name="AllTests">
  <testsuite name="LeaseTable" tests="2" failures="0" errors="0">
    <testcase name="Renews" status="run" classname="LeaseTable"/>
    <testcase name="Expires" status="run" classname="LeaseTable"/>
  </testsuite>
  <testsuite name="NodeModel" tests="1" failures="1" errors="0">
    <testcase name="RefusesUnknown" status="run" classname="NodeModel">
      <failure message="expected false">node_model.cpp:12</failure>
    </testcase>
  </testsuite>
</testsuites>"""
PYTEST = """<?xml version="1.0" encoding="utf-8"?>
<testsuites><testsuite name="pytest" errors="1" failures="0" skipped="1" tests="4">
  <testcase classname="test_a" name="test_ok"/>
  <testcase classname="test_a" name="test_ok_too"/>
  <testcase classname="test_a" name="test_skip"><skipped message="needs root"/></testcase>
  <testcase classname="test_a" name="test_error"><error message="fixture broke"/></testcase>
</testsuite></testsuites>"""
ROSUNIT = """<?xml version="1.0" encoding="utf-8"?>
<testsuite errors="0" failures="0" name="unittest.suite.TestSuite" tests="1" time="5.2">
<testcase classname="__main__.HzTest" name="test_hz" time="5.2"/></testsuite>"""
ROSTEST_WRAPPER = """<?xml version="1.0" encoding="utf-8"?>
<testsuite errors="0" failures="0" name="unittest.suite.TestSuite" tests="1" time="6.8">
<testcase classname="rostest.runner.RosTest" name="testhz_scan" time="6.8"/></testsuite>"""


def write(folder, name, text):
    path = folder / name
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)


@pytest.fixture
def results(tmp_path):
    write(tmp_path, "pkg/gtest-test_core.xml", GTEST)
    write(tmp_path, "pytest/pytest.xml", PYTEST)
    write(tmp_path, "pkg/rosunit-hz_scan.xml", ROSUNIT)
    write(tmp_path, "pkg/rostest-test_hz_scan.xml", ROSTEST_WRAPPER)
    return tmp_path


def test_each_testcase_counts_once_whatever_the_nesting(results, capsys):
    counts = summarize_test_results.summarize(str(results))
    # gtest 3 (not 6: its <testsuites> root repeats the totals), pytest 4, rosunit 1, wrapper 1
    assert (counts.passed, counts.failed, counts.skipped) == (6, 2, 1)
    out = capsys.readouterr().out
    assert "gtest-test_core.xml: 1 of 3 failed" in out
    assert "pytest.xml: 1 of 4 failed" in out


def test_each_failed_case_is_named_with_its_message(results, capsys):
    summarize_test_results.summarize(str(results))
    out = capsys.readouterr().out
    assert "    NodeModel.RefusesUnknown: expected false node_model.cpp:12" in out
    assert "    test_a.test_error: fixture broke" in out
    assert "test_ok" not in out


def test_the_closing_line_and_exit_status(results, capsys):
    assert summarize_test_results.main([str(results)]) == 1
    assert capsys.readouterr().out.splitlines()[-1] == "6 passed, 2 failed, 1 skipped"


def test_all_passing_exits_zero(tmp_path, capsys):
    write(tmp_path, "pkg/rosunit-hz_scan.xml", ROSUNIT)
    assert summarize_test_results.main([str(tmp_path)]) == 0
    assert capsys.readouterr().out.splitlines()[-1] == "1 passed, 0 failed, 0 skipped"


def test_an_unreadable_result_file_is_a_failure(tmp_path, capsys):
    write(tmp_path, "pkg/rosunit-cut.xml", ROSUNIT[:80])
    assert summarize_test_results.main([str(tmp_path)]) == 1
    out = capsys.readouterr().out
    assert "rosunit-cut.xml: unreadable result file" in out
    assert out.splitlines()[-1] == "0 passed, 1 failed, 0 skipped"


def test_a_missing_folder_is_named(tmp_path, capsys):
    assert summarize_test_results.main([str(tmp_path / "nowhere")]) == 2
    assert "no such folder" in capsys.readouterr().err


def test_a_disabled_gtest_counts_as_skipped(tmp_path, capsys):
    write(tmp_path, "pkg/gtest-test_core.xml", """<?xml version="1.0" encoding="UTF-8"?>
<testsuites tests="2" disabled="1" name="AllTests"><testsuite name="LeaseTable" tests="2">
  <testcase name="Renews" status="run" classname="LeaseTable"/>
  <testcase name="DISABLED_Slow" status="notrun" classname="LeaseTable"/>
</testsuite></testsuites>""")
    counts = summarize_test_results.summarize(str(tmp_path))
    assert (counts.passed, counts.failed, counts.skipped) == (1, 0, 1)


def test_system_tests_not_run_get_a_line_of_their_own(tmp_path, capsys):
    write(tmp_path, "pytest/pytest.xml", """<?xml version="1.0" encoding="utf-8"?>
<testsuites><testsuite name="pytest" tests="3">
  <testcase classname="t" name="test_bed"><skipped message="SYSTEM TEST NOT RUN: this machine
lacks root"/></testcase>
  <testcase classname="t" name="test_other"><skipped message="needs the study"/></testcase>
  <testcase classname="t" name="test_ok"/>
</testsuite></testsuites>""")
    assert summarize_test_results.main([str(tmp_path)]) == 0
    out = capsys.readouterr().out.strip().splitlines()
    assert out[-2].startswith("SYSTEM TEST NOT RUN: 1 system tests skipped"), out
    assert out[-1] == "1 passed, 0 failed, 2 skipped"
