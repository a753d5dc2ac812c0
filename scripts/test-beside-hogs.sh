#!/usr/bin/env bash
# Runs the full test suite N times in a row (default 5) beside two CPU hogs (a busy loop on
# each core), as issue 19 asks of the suite: it must pass on a loaded host. Prints each run's
# wall time and result; the logs go to target/hog-runs/run-K.log.
# Usage: bash scripts/test-beside-hogs.sh [N]
set -uo pipefail
cd "$(dirname "$0")/.."
runs="${1:-5}"
mkdir -p target/hog-runs
hogs=()
for _ in 1 2; do
  (while :; do :; done) &
  hogs+=("$!")
done
trap 'kill "${hogs[@]}" 2>/dev/null' EXIT
failed=0
for k in $(seq 1 "$runs"); do
  start=$(date +%s)
  if bash scripts/test.sh > "target/hog-runs/run-$k.log" 2>&1; then result=passed; else result=FAILED; failed=$((failed + 1)); fi
  end=$(date +%s)
  summary=$(grep -E "^ +Summary" "target/hog-runs/run-$k.log" | tail -n 1 | sed 's/^ *//')
  echo "run $k: $result in $((end - start)) s ($summary)"
done
echo "$((runs - failed)) of $runs runs passed beside two CPU hogs"
[ "$failed" = 0 ]
