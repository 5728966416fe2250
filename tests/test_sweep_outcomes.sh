#!/usr/bin/env bash
# pneu-sweep reports every scenario (issue 14): each gets an outcome (settled, never-settled,
# end-stop, fault), --scenarios-out writes one row per scenario, the summary's counts add up to
# the number of scenarios and agree with the rows, and --strict fails, saying why, when any
# scenario does not settle. With the paper's gains the mid-stroke scenarios never settle, and the
# settling rules checked alongside would latch the oscillation fault on each of them; with the
# shipped default (the designed schedule) every scenario of the 200-step sweep settles, --strict
# passes, and supervised no fault latches.
# The figures are read from the sweep's data: its --summary-json (tests/sweep_summary.py) and its
# CSV files, not from the summary's sentences.
#   test_sweep_outcomes.sh BINARY_DIR
set -euo pipefail
sweep=$1/bin/pneu-sweep
tmp=$(mktemp -d); trap 'rm -rf "$tmp"' EXIT
fail() { echo "FAIL: $*"; exit 1; }
nonlinear=(--set "controller.predictor.methods=[nonlinear]")  # the forecasts held to their criteria
paper=(--set controller.law.gains=fixed)  # config/paper.yaml's law: the paper's gains

# column NAME FILE: the values of a column of a CSV file with a header, one a line.
column() { awk -F, -v name="$1" 'NR == 1 { for (i = 1; i <= NF; ++i) if ($i == name) c = i; next } { print $c }' "$2"; }
# summary FILE KEY...: members of a --summary-json, one a line.
summary() { /usr/bin/python3 "$(dirname "$0")/sweep_summary.py" "$@"; }

echo "== the paper's gains: 40 scenarios"
status=0
"$sweep" --steps 40 --quiet --strict "${paper[@]}" "${nonlinear[@]}" --out "$tmp/stops.csv" --scenarios-out "$tmp/scenarios.csv" \
  --summary-json "$tmp/summary.json" > "$tmp/summary.txt" 2> "$tmp/err.txt" || status=$?
cat "$tmp/summary.txt" "$tmp/err.txt"
[ "$status" = 1 ] || fail "--strict exits 1 when scenarios do not settle (got $status)"
grep -qE '^pneu-sweep: strict: [0-9]+ of 40 scenarios did not settle \([0-9]+ never settled' "$tmp/err.txt" \
  || fail "--strict says why"
[ "$(summary "$tmp/summary.json" methods.nonlinear.outside_criteria methods.linearized.outside_criteria | tr '\n' ' ')" = "0 0 " ] \
  || fail "the nonlinear forecasts are all within their criteria"
grep -q 'forecasts outside' "$tmp/err.txt" && fail "--strict names no forecast outside its criteria"

[ "$(head -1 "$tmp/scenarios.csv")" = "scenario,y0_m,y_d_m,friction_scale,gain_scale,outcome,settle_time_s,final_error_m,fault_cause,fault_after_s,stops,restarts,at_rest_at_end,last_second_swing_m,oscillation_rule_after_s,bench_static_positive_n,bench_coulomb_positive_n,bench_static_negative_n,bench_coulomb_negative_n,bench_viscous_n_s_per_m,bench_max_conductance_m3_per_s_pa,bench_leak_conductance_in_m3_per_s_pa,bench_leak_conductance_out_m3_per_s_pa,bench_dead_volume_p_m3,bench_dead_volume_n_m3,bench_null_offset_v,bench_heat_transfer_w_per_m2_k,bench_thermal_time_constant_s,bench_spool_time_constant_s,in_window_after_s,hold_after_s,restarts_after_hold" ] \
  || fail "the scenarios file's header: $(head -1 "$tmp/scenarios.csv")"
[ "$(column scenario "$tmp/scenarios.csv" | tr '\n' ' ')" = "$(seq 0 39 | tr '\n' ' ')" ] || fail "one row per scenario, in order"
read -r settled never end_stop faults <<< "$(summary "$tmp/summary.json" outcomes.settled.count outcomes.never_settled.count \
  outcomes.end_stop.count outcomes.fault.count | tr '\n' ' ')"
[ $((settled + never + end_stop + faults)) = 40 ] || fail "the counts add up to the scenarios: $settled + $never + $end_stop + $faults"
for outcome in settled never-settled end-stop fault; do
  rows=$(column outcome "$tmp/scenarios.csv" | grep -cx -- "$outcome" || true)
  case $outcome in settled) want=$settled ;; never-settled) want=$never ;; end-stop) want=$end_stop ;; fault) want=$faults ;; esac
  [ "$rows" = "$want" ] || fail "$outcome: $rows rows, the summary says $want"
done
[ "$never" -ge 10 ] || fail "not vacuous: the paper's gains leave the mid-stroke scenarios unsettled (got $never)"
[ "$settled" -ge 10 ] || fail "not vacuous: near the ends they settle (got $settled)"
[ "$faults" = 0 ] || fail "unsupervised, no fault latches"
# Each row: settled ones have a settle time and a final error within the stroke; never-settled
# ones no settle time, a wide swing to the end, and the settling rules would latch on each within
# 2 s of the step.
awk -F, 'NR > 1 {
  if ($6 == "settled" && ($7 == "" || $7 < 0 || $7 > 13 || $8 == "" || $8 > 0.5)) { print "settled row " $0; bad = 1 }
  if ($6 == "never-settled" && ($7 != "" || $14 < 0.02 || $15 == "" || $15 > 2.0)) { print "never-settled row " $0; bad = 1 }
  if ($8 == "" || $11 == "" || $12 == "" || $13 == "") { print "incomplete row " $0; bad = 1 }
} END { exit bad }' "$tmp/scenarios.csv" || fail "rows"
# numbers N FILE KEY...: each member a number (not null), one a line; N of them.
numbers() { local n=$1; shift; [ "$(summary "$@" | grep -cE '^-?[0-9.]+(e-?[0-9]+)?$')" = "$n" ]; }
[ "$(summary "$tmp/summary.json" settle_time_s.count)" = "$settled" ] &&
  numbers 4 "$tmp/summary.json" settle_time_s.p50 settle_time_s.p90 settle_time_s.p99 settle_time_s.max \
  || fail "settle time percentiles over the settled ones"
[ "$(summary "$tmp/summary.json" final_error_m.count)" = "$settled" ] && numbers 1 "$tmp/summary.json" final_error_m.p50 \
  || fail "final error percentiles"
numbers 4 "$tmp/summary.json" outcomes.never_settled.y0_min_m outcomes.never_settled.y0_max_m \
  outcomes.never_settled.y_d_min_m outcomes.never_settled.y_d_max_m || fail "where the unsettled ones lie"
[ "$(summary "$tmp/summary.json" settling_rules.checked_alongside outcomes.never_settled.settling_rules_would_latch | tr '\n' ' ')" \
  = "1 $never " ] && numbers 1 "$tmp/summary.json" outcomes.settled.settling_rules_would_latch \
  || fail "the settling rules checked alongside latch on every never-settled scenario"

echo "== --strict-forecasts: the forecasts only"
"$sweep" --steps 40 --quiet --strict-forecasts "${paper[@]}" "${nonlinear[@]}" --out "$tmp/stops2.csv" > /dev/null \
  || fail "--strict-forecasts passes with every nonlinear forecast within its criteria"
cmp -s "$tmp/stops.csv" "$tmp/stops2.csv" || fail "the outcomes change nothing of the per-stop CSV"

echo "== --supervised: a fault is an outcome, named"
"$sweep" --steps 40 --quiet --supervised "${paper[@]}" --out "$tmp/stops3.csv" --scenarios-out "$tmp/supervised.csv" \
  --summary-json "$tmp/summary3.json" > "$tmp/summary3.txt"
cat "$tmp/summary3.txt"
osc=$(column fault_cause "$tmp/supervised.csv" | grep -cx oscillation || true)
[ "$osc" -ge "$never" ] || fail "every scenario that never settled latches the oscillation fault ($osc < $never)"
[ "$(summary "$tmp/summary3.json" faults_by_cause.oscillation)" = "$osc" ] || fail "the summary names the causes"
awk -F, 'NR > 1 && $6 == "fault" && ($9 == "" || $10 == "") { print; bad = 1 } END { exit bad }' "$tmp/supervised.csv" \
  || fail "a fault row names its cause and time"

echo "== the shipped default, the designed schedule: all 200 scenarios settle, --strict passes, no fault"
"$sweep" --steps 200 --quiet --strict "${nonlinear[@]}" --out "$tmp/stops4.csv" \
  --scenarios-out "$tmp/designed.csv" --summary-json "$tmp/summary4.json" > "$tmp/summary4.txt" \
  || { cat "$tmp/summary4.txt"; fail "--strict on the default"; }
cat "$tmp/summary4.txt"
[ "$(summary "$tmp/summary4.json" outcomes.settled.count)" = 200 ] || fail "200 settled"
[ "$(summary "$tmp/summary4.json" settling_rules.checked_alongside outcomes.settled.settling_rules_would_latch | tr '\n' ' ')" \
  = "1 0 " ] || fail "no false oscillation fault"
"$sweep" --steps 200 --quiet --supervised --out "$tmp/stops5.csv" --scenarios-out "$tmp/designed5.csv" \
  --summary-json "$tmp/summary5.json" > "$tmp/summary5.txt"
[ "$(summary "$tmp/summary5.json" outcomes.fault.count)" = 0 ] || { cat "$tmp/summary5.txt"; fail "supervised, no fault latches"; }
[ "$(column outcome "$tmp/designed5.csv" | grep -cx settled)" = 200 ] || fail "supervised, 200 rows settled"

echo "== --bench-spread: each scenario a bench of its own, the controller's model unchanged"
"$sweep" --steps 40 --quiet --bench-spread 0.2 --out "$tmp/bench.csv" --scenarios-out "$tmp/bench_sc.csv" \
  --summary-json "$tmp/bench.json" > "$tmp/bench.txt"
[ "$(summary "$tmp/bench.json" setting.bench_spread setting.bench_null_offset_within_v | tr '\n' ' ')" = "0.2 0.1 " ] \
  || fail "the summary names the bench spread"
"$sweep" --steps 40 --quiet --out "$tmp/nobench.csv" --scenarios-out "$tmp/nobench_sc.csv" > /dev/null
[ "$(cut -d, -f1-3 "$tmp/bench_sc.csv")" = "$(cut -d, -f1-3 "$tmp/nobench_sc.csv")" ] || fail "the same scenarios (y0, y_d) as without it"
# Without it every bench is the model (sim.yaml): F_S+ 45, F_C+ 35, F_S- -50, F_C- -38, sigma 60,
# C_max 1.6e-8, leaks 8e-10 and 1.28e-9, dead volumes 1e-5, no null offset.
awk -F, 'NR > 1 && ($16 != 45 || $17 != 35 || $18 != -50 || $19 != -38 || $20 != 60 || $21 != 1.6e-08 || $22 != 8e-10 ||
                    $23 != 1.28e-09 || $24 != 1e-05 || $25 != 1e-05 || $26 != 0) { print; bad = 1 } END { exit bad }' \
  "$tmp/nobench_sc.csv" || fail "without --bench-spread the bench is the model"
# With it each value within +-20 % of the model's, each Coulomb level within its stiction bound, the
# null offset within +-0.1 V, and the values drawn, not all alike.
awk -F, 'function off(v, m) { return m > 0 ? v < m * 0.8 - 1e-12 || v > m * 1.2 + 1e-12 : off(-v, -m) }
  NR > 1 { if (off($16, 45) || off($18, -50) || off($20, 60) || off($21, 1.6e-8) || off($22, 8e-10) ||
               off($23, 1.28e-9) || off($24, 1e-5) || off($25, 1e-5) || $17 > $16 || $19 < $18 ||
               $26 < -0.1 || $26 > 0.1) { print; bad = 1 }
           distinct[$16] = 1; if ($26 != 0) offsets++ }
  END { n = 0; for (k in distinct) n++; if (n < 30 || offsets < 30) { print "too alike: " n " " offsets; bad = 1 }; exit bad }' \
  "$tmp/bench_sc.csv" || fail "the drawn benches"
"$sweep" --steps 4 --quiet --bench-spread 1 --out "$tmp/x.csv" 2> "$tmp/err.txt" && fail "--bench-spread 1 accepted"
grep -q -- "--bench-spread must be in \[0, 1)" "$tmp/err.txt" || fail "--bench-spread 1 refused saying why"

echo "== --online: the stops on a side the bench had broken away to after 0.5 s or more stuck"
"$sweep" --steps 40 --quiet --bench-spread 0.2 --online "${nonlinear[@]}" --out "$tmp/online.csv" \
  --summary-json "$tmp/online.json" > "$tmp/online.txt"
cat "$tmp/online.txt"
# side_broken_away_slowly is 1 exactly where the forecast's side (the restart's, or for "no restart"
# the side the force relaxes towards) is that of an earlier stop of the scenario that ended, after
# 0.5 s or more stuck, with the plant breaking away (a restart: its row's outcome, or while learning,
# a later stop of the scenario follows it), in that direction; the plant's own truth, row by row.
awk -F, 'NR == 1 { for (i = 1; i <= NF; ++i) c[$i] = i; next }
  { sc = $c["scenario"]; outcome = $c["outcome"]; slow = $c["side_broken_away_slowly"]
    if (slow != 0 && slow != 1) { print "not 0 or 1: " $0; bad = 1 }
    # The previous row of the scenario, if it restarted after >= 0.5 s, opens its side.
    if (sc == last_sc && last_slow_restart) open[sc, last_dir] = 1
    side = $c["nl_will_restart"] == 1 ? $c["nl_direction"] : ($c["equilibrium_force_n"] > $c["force_n"] ? 1 : -1)
    # (A force already at its equilibrium to the CSV digits relaxes towards neither side it shows.)
    tie = $c["nl_will_restart"] != 1 && $c["equilibrium_force_n"] == $c["force_n"]
    if (!tie && slow != ((sc, side) in open ? 1 : 0)) { print "wrong: " $0; bad = 1 }
    ones += slow
    last_sc = sc; last_dir = $c["direction"]
    last_slow_restart = $c["sticking_s"] >= 0.5 && (outcome == "restart" || outcome == "before_learning") }
  END { if (ones < 10) { print "too few stops on such a side: " ones; bad = 1 }; exit bad }' \
  "$tmp/online.csv" || fail "side_broken_away_slowly, row by row"
# The summary counts the judged ones among them.
judged_slow=$(awk -F, 'NR == 1 { for (i = 1; i <= NF; ++i) c[$i] = i; next }
  $c["side_broken_away_slowly"] == 1 && $c["nl_verdict"] != "not_judged" { n++ } END { print n + 0 }' "$tmp/online.csv")
[ "$(summary "$tmp/online.json" setting.online methods.nonlinear.online_slow_side.stops | tr '\n' ' ')" = "1 $judged_slow " ] \
  || fail "the summary counts the $judged_slow judged stops on a slowly broken-away side"
echo "all well"
