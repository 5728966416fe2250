#!/usr/bin/env bash
# What a run writes, pinned byte for byte: a change of structure must leave it as it is. Each mode
# runs a program and compares its outputs with tests/pinned/ (text files, so a real change shows
# as a readable diff; the 1.7 MB trajectory by its SHA-256):
#   paper          pneud on the paper's step: the events file and the trajectory, with the
#                  embedded sim.yaml (its designed law) and with config/paper.yaml (the paper's
#                  gains)
#   sweep          pneu-sweep --steps 200: its CSV and its summary (the wall-time and path lines
#                  left out)
#   check-config   pneud --check-config on each shipped configuration
# A change meant to alter them: rerun with PNEU_UPDATE_PINNED=1 to rewrite tests/pinned/, and say
# in the commit what changed and why.
#   test_pinned_outputs.sh SOURCE_DIR BINARY_DIR paper|sweep|check-config
set -euo pipefail
src=$1 bin=$2/bin mode=$3
pinned=$src/tests/pinned
work=$(mktemp -d); trap 'rm -rf "$work"' EXIT
failures=0
same() {  # PINNED_NAME PRODUCED_FILE
  if [ "${PNEU_UPDATE_PINNED:-}" = 1 ]; then cp "$2" "$pinned/$1"; echo "updated: $1"; return; fi
  if diff -u "$pinned/$1" "$2" > "$work/diff"; then echo "same: $1"
  else echo "FAIL: $1 differs from what is pinned:"; head -40 "$work/diff"; failures=$((failures + 1)); fi
}
case $mode in
  paper)
    "$bin/pneud" --quiet --events "$work/events.jsonl" --trajectory "$work/trajectory.csv"
    same paper_events.jsonl "$work/events.jsonl"
    (cd "$work" && sha256sum trajectory.csv) > "$work/trajectory.sha256"
    same paper_trajectory.sha256 "$work/trajectory.sha256"
    "$bin/pneud" --quiet --config "$src/config/paper.yaml" --events "$work/paper_gains_events.jsonl" \
      --trajectory "$work/paper_gains_trajectory.csv"
    same paper_gains_events.jsonl "$work/paper_gains_events.jsonl"
    (cd "$work" && sha256sum paper_gains_trajectory.csv) > "$work/paper_gains_trajectory.sha256"
    same paper_gains_trajectory.sha256 "$work/paper_gains_trajectory.sha256" ;;
  sweep)
    "$bin/pneu-sweep" --steps 200 --quiet --out "$work/sweep.csv" > "$work/summary.full"
    grep -v -E '^  [0-9.]+ s wall on |^  wrote ' "$work/summary.full" > "$work/summary.txt"
    same sweep_200_summary.txt "$work/summary.txt"
    (cd "$work" && sha256sum sweep.csv) > "$work/sweep.sha256"
    same sweep_200.sha256 "$work/sweep.sha256" ;;
  check-config)
    for name in sim paper hil bench; do
      "$bin/pneud" --check-config --config "$src/config/$name.yaml" > "$work/$name.yaml"
      same "check_config_$name.yaml" "$work/$name.yaml"
    done ;;
  *) echo "unknown mode $mode" >&2; exit 2 ;;
esac
exit $((failures > 0))
