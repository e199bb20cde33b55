#!/usr/bin/env bash
# Builds the workspace and runs every test: gtest and rostest (catkin run_tests; rostest
# needs the package a .test file belongs to, so rostests live in packages), and pytest on
# every package and tests/. Ends with one line
# "N passed, N failed, N skipped" summing all runners; exits non-zero on any failure.
set -o pipefail
ANYSCALE_ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ANYSCALE_ROOT" || exit 2
# shellcheck disable=SC1091
source scripts/setup.sh || { echo "0 passed, 1 failed"; exit 1; }

results="$ANYSCALE_ROOT/build/test_results"
logs="$ANYSCALE_ROOT/build/test_logs"
rm -rf "$results" "$logs"
mkdir -p "$results" "$logs"
export ROS_TEST_RESULTS_DIR="$results"   # where rostest/rosunit write their XML
export ROS_HOME="$ANYSCALE_ROOT/build/ros_home"
status=0

echo "== gtest and rostest of the packages (make run_tests)"
make -C build -j1 run_tests > "$logs/run_tests.log" 2>&1 \
  || { status=1; tail -n 40 "$logs/run_tests.log"; }

echo "== pytest"
/usr/bin/python3 -m pytest -q -rs -p no:cacheprovider --durations=15 --junitxml="$results/pytest/pytest.xml" \
  src tests 2>&1 | tee "$logs/pytest.log" | tail -n 45
rc=${PIPESTATUS[0]}
# exit 5: nothing collected, not a failure in itself
[ "$rc" -eq 0 ] || [ "$rc" -eq 5 ] || status=1

echo "== summary"
/usr/bin/python3 "$ANYSCALE_ROOT/scripts/summarize_test_results.py" "$results" || status=1
exit $status
