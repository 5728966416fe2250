#!/usr/bin/env bash
# The test suite while the machine is busy: RUNS times (default 3) `ctest -j<cores>` over BUILD_DIR
# while as many busy loops as cores run beside it (what `stress-ng --cpu <cores>` does), and says,
# run by run, how many tests passed and which failed. Extra arguments go to ctest (e.g.
# `-LE 'idle|soak'` for the set that must hold under load; see docs/development.md, "The test suite").
#
#   bench/ctest_under_load.sh BUILD_DIR [RUNS] [-- CTEST_ARGS...]
#
# Exit 0 when every run passed. Each run's ctest output stays in OUT_DIR (default a temporary
# directory, printed).
set -euo pipefail

build=${1:?usage: ctest_under_load.sh BUILD_DIR [RUNS] [-- CTEST_ARGS...]}
shift
runs=3
if [[ $# -gt 0 && $1 != -- ]]; then runs=$1; shift; fi
[[ $# -gt 0 && $1 == -- ]] && shift
out=${OUT_DIR:-$(mktemp -d /tmp/pneu_ctest_load.XXXXXX)}
mkdir -p "$out"
cores=$(nproc)

busy=()
stop_busy() { for pid in "${busy[@]}"; do kill "$pid" 2>/dev/null || true; done; }
trap stop_busy EXIT
for ((i = 0; i < cores; ++i)); do
  (while :; do :; done) &
  busy+=($!)
done
echo "ctest under load: $cores busy loops (pids ${busy[*]}), $runs runs of ctest -j$cores $*; output in $out"

failed_runs=0
for ((r = 1; r <= runs; ++r)); do
  start=$(date +%s)
  if ctest --test-dir "$build" -j"$cores" --output-on-failure "$@" >"$out/run$r.txt" 2>&1; then verdict=passed
  else verdict=FAILED; failed_runs=$((failed_runs + 1)); fi
  summary=$(grep -E '^[0-9]+% tests passed' "$out/run$r.txt" || echo "no summary (see $out/run$r.txt)")
  echo "run $r: $verdict in $(( $(date +%s) - start )) s: $summary"
  grep -E '^\s+[0-9]+ - .*\((Failed|Timeout|SEGFAULT|Subprocess aborted|Exception)' "$out/run$r.txt" || true
done
echo "load average at the end: $(cut -d' ' -f1-3 /proc/loadavg)"
[[ $failed_runs -eq 0 ]]
