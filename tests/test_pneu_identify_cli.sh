#!/usr/bin/env bash
# pneu-identify (issue 15, offline): from pneud's trajectory of an ordinary run it writes a
# configuration pneud loads; a record that cannot identify the bench is refused naming what is
# missing (exit 2), as is one lacking a column; nothing is written then.
#   test_pneu_identify_cli.sh BINARY_DIR
set -euo pipefail
bin=$1/bin
tmp=$(mktemp -d); trap 'rm -rf "$tmp"' EXIT
fail() { echo "FAIL: $*"; exit 1; }

"$bin/pneud" --quiet --trajectory "$tmp/run.csv" --set hal.sim.plant.friction.static_negative_n=-55 \
  --set controller.predictor.horizon_s=9
"$bin/pneu-identify" --trajectory "$tmp/run.csv" --out "$tmp/id.yaml" > "$tmp/out.txt" || fail "identified from an ordinary run"
cat "$tmp/out.txt"
grep -qE '^plant.friction.static_negative_n +-50 +-55\.0' "$tmp/out.txt" || fail "F_S- identified from the run's restarts"
grep -qE '^plant.friction.static_positive_n .*no breakaway in the positive direction' "$tmp/out.txt" \
  || fail "F_S+ reported not identified: the run restarts one way"
"$bin/pneud" --config "$tmp/id.yaml" --check-config > /dev/null || fail "the written configuration loads"

# Without --config, the run's own configuration, the one pneud wrote beside the trajectory, is
# the prior: what the run was given with --set is kept in the written configuration.
[ -s "$tmp/run.csv.config.yaml" ] || fail "pneud wrote no configuration beside the trajectory"
grep -qE '^ +horizon_s: 9$' "$tmp/id.yaml" || fail "the run's controller.predictor.horizon_s=9 is not kept"

# A record where the carriage never stands still: refused, naming it, nothing written.
awk -F, 'BEGIN { OFS = "," } NR == 1 { print; next } { $4 = $2 * 0.01; print }' "$tmp/run.csv" > "$tmp/sliding.csv"
status=0
"$bin/pneu-identify" --trajectory "$tmp/sliding.csv" --out "$tmp/none.yaml" 2> "$tmp/err.txt" || status=$?
cat "$tmp/err.txt"
[ "$status" = 2 ] || fail "exit 2 on a record with no sticking phase (got $status)"
grep -q 'no sticking phase' "$tmp/err.txt" || fail "says what is missing"
[ ! -e "$tmp/none.yaml" ] || fail "nothing written"

# A record without a pressure column.
cut -d, -f1-6,8- "$tmp/run.csv" > "$tmp/no_pp.csv"
status=0
"$bin/pneu-identify" --trajectory "$tmp/no_pp.csv" 2> "$tmp/err.txt" || status=$?
[ "$status" = 2 ] && grep -q 'no column p_p' "$tmp/err.txt" || fail "a missing column is named (exit $status: $(cat "$tmp/err.txt"))"
echo ok
