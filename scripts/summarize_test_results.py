#!/usr/bin/python3
"""Sums the JUnit XML results of every runner (gtest, rostest, pytest) under a folder into the
closing line "N passed, N failed, N skipped" that CI reads; exits 1 if anything failed.

Each `<testcase>` element counts once, wherever it sits: gtest nests its `<testsuite>`s under
a `<testsuites>` root whose totals repeat theirs, and catkin's own reader
(catkin.test_results.test_results2) adds both, counting every gtest twice. A case with a
`<failure>` or `<error>` child failed, one with a `<skipped>` child (or gtest's
status="notrun") was skipped.

A rostest run leaves two files: `rosunit-NAME.xml` with the test node's own cases, and the
wrapper `rostest-*.xml` with one case per test node of the launch. The wrapper's case is a test
of its own and counts: it passes when the launch came up and the test node ran to its end and
wrote results, whatever those results say (rostest.runner), and fails when the node did not
launch, timed out or left no results, which no rosunit file then reports.
"""
import argparse
import os
import sys
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from typing import List


# The prefix of a skip that says this machine cannot run a system test (no root, namespaces or
# cgroups; anyscale_testbed.system_test_gate.NOT_RUN): such skips get a loud line of their own.
NOT_RUN = "SYSTEM TEST NOT RUN"


@dataclass
class Counts:
    passed: int = 0
    failed: int = 0
    skipped: int = 0
    not_run: int = 0            # of the skipped, the system tests this machine cannot run

    def add(self, other: "Counts"):
        self.passed += other.passed
        self.failed += other.failed
        self.skipped += other.skipped
        self.not_run += other.not_run

    @property
    def total(self) -> int:
        return self.passed + self.failed + self.skipped


def count_cases(root: ET.Element) -> Counts:
    """The outcome of every <testcase> under `root`, each counted once."""
    counts = Counts()
    for case in root.iter("testcase"):
        children = {child.tag for child in case}
        if children & {"failure", "error"}:
            counts.failed += 1
        elif "skipped" in children or case.get("status") == "notrun":
            counts.skipped += 1     # gtest marks a DISABLED_ test status="notrun"
            skip = case.find("skipped")
            text = "" if skip is None else (skip.get("message") or "") + (skip.text or "")
            counts.not_run += NOT_RUN in text
        else:
            counts.passed += 1
    return counts


def failures(root: ET.Element, limit: int = 600) -> List[str]:
    """'case: message' of each failed <testcase> under `root`, the message cut to `limit`
    characters: CI shows only this summary of a rostest or gtest, whose logs it does not keep."""
    out = []
    for case in root.iter("testcase"):
        for child in case:
            if child.tag in ("failure", "error"):
                text = " ".join(((child.get("message") or "") + " " + (child.text or "")).split())
                name = ".".join(filter(None, (case.get("classname"), case.get("name"))))
                out.append(f"{name}: {text[:limit]}")
                break
    return out


def result_files(folder: str) -> List[str]:
    return sorted(os.path.join(d, f) for d, _, files in os.walk(folder)
                  for f in files if f.endswith(".xml"))


def summarize(folder: str) -> Counts:
    """Counts of every result file under `folder`; prints a FAILED line per file that has a
    failure (with each failed case's message), or that cannot be read (which counts as one
    failure: a runner that crashed while writing its results must not pass silently)."""
    total = Counts()
    for path in result_files(folder):
        name = os.path.relpath(path, folder)
        try:
            root = ET.parse(path).getroot()
            counts = count_cases(root)
        except ET.ParseError as e:
            print(f"  FAILED: {name}: unreadable result file ({e})")
            total.failed += 1
            continue
        if counts.failed:
            print(f"  FAILED: {name}: {counts.failed} of {counts.total} failed")
            for line in failures(root):
                print(f"    {line}")
        total.add(counts)
    return total


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(
        description="Sum the JUnit XML results under a folder into one line "
                    "'N passed, N failed, N skipped' (each <testcase> once).")
    parser.add_argument("results_dir", help="folder searched for *.xml result files")
    args = parser.parse_args(argv)
    if not os.path.isdir(args.results_dir):
        print(f"summarize_test_results.py: no such folder: {args.results_dir}", file=sys.stderr)
        return 2
    total = summarize(args.results_dir)
    if total.not_run:
        print(f"  {NOT_RUN}: {total.not_run} system tests skipped because this machine cannot "
              f"run them (their reasons in the log; ANYSCALE_REQUIRE_SYSTEM_TESTS=1 fails them)")
    print(f"{total.passed} passed, {total.failed} failed, {total.skipped} skipped")
    return 1 if total.failed else 0


if __name__ == "__main__":
    sys.exit(main())
