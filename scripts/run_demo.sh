#!/usr/bin/env bash
# The main job: sets up the workspace, then shows AnyScale deciding on the paper's test bed:
# the model checked, one decision per network condition and allocator, and the Fig. 7 study.
# Results (CSV, PNG) go to results/.
set -o pipefail
ANYSCALE_ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ANYSCALE_ROOT" || exit 2
# shellcheck disable=SC1091
source scripts/setup.sh || exit 1
set -e

model="$(rospack find anyscale_nav_demo)/config/testbed.yaml"
states="$ANYSCALE_ROOT/build/demo_states"
mkdir -p "$states" results

echo
echo "=== The test bed's system model (paper Tables I and II)"
anyscale check "$model"

declare -A conditions=(
  [1_good_link]="bandwidth_mbps: 27"
  [2_weak_link]="bandwidth_mbps: 3"
  [3_laptop_busy]=$'bandwidth_mbps: 27\nscale_load: {laptop: 70}'
  [4_link_down]=$'link_up: {laptop: false}'
)
for name in $(printf '%s\n' "${!conditions[@]}" | sort); do
  printf '%s\n' "${conditions[$name]}" > "$states/$name.yaml"
  for solver in paper optimal; do
    echo
    echo "=== ${name#?_}: ${conditions[$name]//$'\n'/, } (solver $solver)"
    anyscale plan "$model" --state "$states/$name.yaml" --solver "$solver"
  done
done

echo
echo "=== The paper's Fig. 7 simulation"
anyscale simulate --out results/fig7 "$@"
