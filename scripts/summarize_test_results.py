#!/usr/bin/python3
"""Sums the JUnit XML results of every runner (gtest, rostest, pytest) under a folder.

catkin_test_results does the same walk but prints its own format; the project's CI wants one
closing line "N passed, N failed, N skipped", so this reuses catkin's reader and formats it.
Exits 1 if anything failed or errored.
"""
import sys

from catkin.test_results import test_results2


def main(argv):
    if len(argv) != 2:
        print("usage: summarize_test_results.py RESULTS_DIR", file=sys.stderr)
        return 2
    total = errors = failures = skipped = 0
    for name, (tests, errs, fails, skips) in sorted(test_results2(argv[1], show_verbose=False,
                                                                   show_all=True).items()):
        total, errors, failures, skipped = (total + tests, errors + errs, failures + fails,
                                            skipped + skips)
        if errs or fails:
            print(f"  FAILED: {name}: {errs} errors, {fails} failures")
    failed = errors + failures
    print(f"{total - failed - skipped} passed, {failed} failed, {skipped} skipped")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
