#!/usr/bin/env bash
# Issue 16: the in-position hold on 200-step sweeps (controller.hold.enabled=true). On each sweep:
#   - no restart after the hold began: no breakaway of the plant that takes the carriage beyond
#     the stop detector's motion band (the set point does not change after the step, nothing
#     pushes), counted per scenario in the scenarios file's restarts_after_hold;
#   - no fault;
#   - the hold began in most scenarios (those at rest within its window).
# With the 0.5 mm window alone the final error is not the issue's (measured, in docs/results.md): that
# takes reaching the window.
# reach: the default sweep reaching a 0.1 mm window (controller.hold.reach_m): besides, the final
# error's p90 within 0.1 mm (measured 0.088 mm); the time to come to rest within the window, p90,
# no more than 0.3 s over the same sweep's without the hold (measured 0.978 s against 0.943 s),
# and on the scenarios the baseline brings there (tools/sweep/paired_window_times.py: 0.829 s
# against 0.942 s); the forecasts under the hold's commands: none a restart while held within the
# window, and every reach's breakaway forecast within 1 ms of the start seen (measured 0.5 ms at
# worst).
# The figures are read from the sweep's data: its --summary-json (tests/sweep_summary.py) and its
# CSV files, not from the summary's sentences.
#   test_sweep_hold.sh BINARY_DIR default|hil|spread|identified|reach SOURCE_DIR
set -euo pipefail
sweep=$1/bin/pneu-sweep
kind=$2
src=$3
tmp=$(mktemp -d); trap 'rm -rf "$tmp"' EXIT
fail() { echo "FAIL: $*"; exit 1; }
# summary FILE KEY...: members of a --summary-json, one a line.
summary() { /usr/bin/python3 "$(dirname "$0")/sweep_summary.py" "$@"; }
args=(--steps 200 --quiet --set controller.hold.enabled=true --set "controller.predictor.methods=[nonlinear]"
      --out "$tmp/stops.csv" --scenarios-out "$tmp/scenarios.csv" --summary-json "$tmp/summary.json")
case "$kind" in
  default) ;;
  hil) args+=(--config "$src/config/hil.yaml" --set hal.backend=sim) ;;
  spread) args+=(--friction-spread 0.3 --gain-spread 0.3) ;;
  identified) args+=(--bench-spread 0.2 --identify) ;;
  reach) args+=(--set controller.hold.window_m=0.0001 --set controller.hold.reach_m=0.005) ;;
  *) fail "unknown sweep $kind" ;;
esac
"$sweep" "${args[@]}" > "$tmp/summary.txt"
cat "$tmp/summary.txt"

# The scenarios file: restarts_after_hold, hold_after_s and fault_cause by their header's names.
read -r rows held restarts faults < <(awk -F, '
  NR == 1 { for (i = 1; i <= NF; ++i) col[$i] = i; next }
  $col["outcome"] != "identification_failed" {
    ++rows
    if ($col["hold_after_s"] != "") ++held
    restarts += $col["restarts_after_hold"]
    if ($col["fault_cause"] != "") ++faults
  }
  END { print rows + 0, held + 0, restarts + 0, faults + 0 }' "$tmp/scenarios.csv")
[ "$rows" -ge 196 ] || fail "scenarios run: $rows of 200"
[ "$restarts" = 0 ] || fail "$restarts restarts after the hold began"
[ "$faults" = 0 ] || fail "$faults faults"
awk -v h="$held" -v n="$rows" 'BEGIN { exit !(h >= 0.7 * n) }' || fail "the hold began in $held of $rows scenarios only"
# The summary's figures say what the scenarios file does.
[ "$(summary "$tmp/summary.json" hold.enabled hold.began hold.restarts_after hold.scenarios_restarted_after | tr '\n' ' ')" \
  = "1 $held 0 0 " ] || fail "the summary says what the scenarios file does"
if [ "$kind" = reach ]; then
  p90=$(awk -F, 'NR == 1 { for (i = 1; i <= NF; ++i) col[$i] = i; next } { print $col["final_error_m"] * 1000 }' \
        "$tmp/scenarios.csv" | sort -g | awk '{ v[NR] = $1 } END { pos = 0.9 * (NR - 1); i = int(pos); f = pos - i; print v[i + 1] * (1 - f) + v[i + 2] * f }')
  awk -v p="$p90" 'BEGIN { exit !(p <= 0.1) }' || fail "final error p90 $p90 mm (need 0.1 mm)"
  echo "final error p90 $p90 mm"
  # The time to come to rest within the 0.1 mm window, p90 over those that came.
  into_p90() {
    [ "$(summary "$1" in_window.window_m)" = 0.0001 ] || fail "$1: the window is not 0.1 mm"
    summary "$1" in_window.after_s.p90
  }
  base_args=("${args[@]/#$tmp\/scenarios.csv/$tmp/baseline.csv}")
  base_args=("${base_args[@]/#$tmp\/summary.json/$tmp/baseline.json}")
  "$sweep" "${base_args[@]}" --set controller.hold.enabled=false > "$tmp/baseline.txt"
  with=$(into_p90 "$tmp/summary.json"); without=$(into_p90 "$tmp/baseline.json")
  awk -v a="$with" -v b="$without" 'BEGIN { exit !(a != "" && b != "" && a <= b + 0.3) }' \
    || fail "p90 into the window $with s with the hold, $without s without"
  echo "into the window, p90: $with s with the hold, $without s without"
  # The same scenarios side by side (tools/sweep/paired_window_times.py): the baseline's p90 as
  # the sweep gives it, and the hold's on those scenarios no later than 0.3 s after it.
  paired=$(/usr/bin/python3 "$src/tools/sweep/paired_window_times.py" "$tmp/baseline.csv" "$tmp/scenarios.csv")
  echo "$paired"
  p_base=$(echo "$paired" | grep "^paired on .*baseline.csv:" | grep -o 'p90 [0-9.]*' | cut -d' ' -f2)
  awk -v a="$p_base" -v b="$without" 'BEGIN { exit !(a != "" && (a - b) ^ 2 < 0.002 ^ 2) }' \
    || fail "the paired tool's baseline p90 $p_base s is not the sweep's, $without s"
  p_with=$(echo "$paired" | grep "^paired on .*scenarios.csv:" | grep -o 'p90 [0-9.]*' | cut -d' ' -f2)
  awk -v a="$p_with" -v b="$p_base" 'BEGIN { exit !(a != "" && b != "" && a <= b + 0.3) }' \
    || fail "paired p90 into the window $p_with s with the hold, $p_base s without"
  # The forecasts under the hold's commands: none a restart while held within the window; each
  # reach's breakaway forecast within 1 ms of the start seen.
  read -r held_forecasts held_restarts <<< "$(summary "$tmp/summary.json" hold.held_forecasts hold.held_restart_forecasts | tr '\n' ' ')"
  [ "$held_restarts" = 0 ] || fail "$held_restarts of $held_forecasts forecasts made while held within the window a restart"
  read -r reaches within_1_ms <<< "$(summary "$tmp/summary.json" hold.reach_forecast_error_ms.count hold.reach_forecasts_within_1_ms | tr '\n' ' ')"
  [ "$within_1_ms" = "$reaches" ] || fail "a reach's breakaway forecast more than 1 ms off: $within_1_ms of $reaches within 1 ms"
  [ "$reaches" -gt 0 ] || fail "no reach"
fi
echo "ok: $kind: the hold began in $held of $rows scenarios, no restart after it began, no fault"
