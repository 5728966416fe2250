#!/usr/bin/env bash
# pneu-identify (issue 15, offline): from pneud's trajectory of an ordinary run it writes a
# configuration pneud loads; a record that cannot identify the bench is refused naming what is
# missing (exit 2), as is one lacking a column; nothing is written then.
#   test_pneu_identify_cli.sh BINARY_DIR SOURCE_DIR
set -euo pipefail
bin=$1/bin
tmp=$(mktemp -d); trap 'rm -rf "$tmp"' EXIT
fail() { echo "FAIL: $*"; exit 1; }

"$bin/pneud" --quiet --trajectory "$tmp/run.csv" --set hal.sim.plant.friction.static_negative_n=-55 \
  --set controller.predictor.horizon_s=9
"$bin/pneu-identify" --trajectory "$tmp/run.csv" --out "$tmp/id.yaml" > "$tmp/out.txt" || fail "identified from an ordinary run"
cat "$tmp/out.txt"
# The bench's -55 N to within 0.05 N (its breakaways bracket it to about 0.1 N).
awk '$1 == "plant.friction.static_negative_n" && $2 == -50 && ($3 + 55 < 0.05 && $3 + 55 > -0.05) { ok = 1 }
     END { exit !ok }' "$tmp/out.txt" || fail "F_S- identified from the run's restarts"
grep -qE '^plant.friction.static_positive_n .*no breakaway in the positive direction' "$tmp/out.txt" \
  || fail "F_S+ reported not identified: the run restarts one way"
"$bin/pneud" --config "$tmp/id.yaml" --check-config > /dev/null || fail "the written configuration loads"
# The parameter table first (after the line saying what it was identified from), the evidence after.
[ "$(sed -n 2p "$tmp/out.txt" | cut -c1-10)" = "parameter " ] || fail "the parameter table leads the report"
table=$(grep -n '^parameter ' "$tmp/out.txt" | cut -d: -f1); evidence=$(grep -n '^evidence: ' "$tmp/out.txt" | cut -d: -f1)
[ "$table" -lt "$evidence" ] || fail "the evidence (line $evidence) comes after the table (line $table)"
# The header: when, by what, from which record, the fit; then the source's text.
head -1 "$tmp/id.yaml" | grep -qE '^# identified [0-9-]+ [0-9:]+ UTC by pneu-identify [^:]+: pneu-identify --trajectory ' \
  || fail "the header says when and by what: $(head -1 "$tmp/id.yaml")"
grep -qF "# from the trajectory $tmp/run.csv: " "$tmp/id.yaml" || fail "the header names the record"
grep -q '^# the fit: ' "$tmp/id.yaml" || fail "the header gives the fit's residual"
grep -qE '^ +static_negative_n: -5[0-9.]+ .*# identified [0-9-]+: -5[0-9.]+ \+- [0-9.e-]+ \(was -50\)$' "$tmp/id.yaml" \
  || fail "F_S- replaced in place, its sigma beside it"

# From a configuration file with comments (--config), its text and comments are kept.
"$bin/pneu-identify" --quiet --trajectory "$tmp/run.csv" --config "$2/config/sim.yaml" --out "$tmp/commented.yaml" \
  || fail "identified with --config"
grep -qF '# pneu default configuration: the in-process simulated bench' "$tmp/commented.yaml" \
  || fail "sim.yaml's comments kept"

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
