#!/usr/bin/env bash
# Issue 15: a 200-step sweep on benches drawn +-20 % around the model (friction, conductances, dead
# volumes; a valve null offset within +-0.1 V), each identified first by pneud's identification run
# (pneu-sweep --identify), with ideal sensors and with hil.yaml's. After identification:
#   - the nonlinear forecast made at the stop is within 2 % (ideal) / 5 % (hil.yaml) of the sticking
#     time on at least 95 % of the restarts after 0.5 s or more, and within 10 % on all of them;
#   - the restart/no-restart verdict is wrong on under 1 % of the judged stops;
#   - the identified stiction is within 2 % (ideal) / 5 % (hil.yaml) of each bench's, and p_null(u)
#     within 5 kPa over |u| < 1 V.
# The relaxation method (made again only, from each phase's own pressures and the identified
# stiction, no valve model) runs alongside: half-way, within 5 % on at least 90 % of those restarts
# (measured 54 of 55 ideal, 69 of 69 hil.yaml).
# Issue 28 (ideal-thermal, hil-thermal): the same on benches with the physics every real cylinder
# has, each drawn a thermal time constant of 0.5 to 3 s at mid-stroke and a spool lag of 0 to 5
# ms besides, identified from a model that has both terms (at 1 s and 2 ms), on 60 steps (100
# with hil.yaml's sensors, whose noise makes fewer stops judged: 22 long restarts there, 9 on 60;
# docs/results.md gives the 200-step figures and their command); also: the
# model fits every bench (its residual within twice what the sensors' noise explains) and at
# least 95 % of the parameters published that the bench has too lie within 3 of their sigmas of
# it. unmodelled-thermal: the same benches identified from a model without either term are
# reported as not fitting, every one (20 steps).
# Every scenario is counted: those whose identification failed, or whose gains could not be
# designed on the identified model, are listed by the summary and must stay few (<= 2 %).
# The figures are read from the sweep's data: its --summary-json (tests/sweep_summary.py) and its
# CSV files, not from the summary's sentences.
#   test_sweep_identified.sh BINARY_DIR ideal|hil|ideal-thermal|hil-thermal|unmodelled-thermal SOURCE_DIR
set -euo pipefail
sweep=$1/bin/pneu-sweep
kind=$2
src=$3
tmp=$(mktemp -d); trap 'rm -rf "$tmp"' EXIT
fail() { echo "FAIL: $*"; exit 1; }
# summary KEY...: members of the sweep's --summary-json, one a line.
summary() { /usr/bin/python3 "$(dirname "$0")/sweep_summary.py" "$tmp/summary.json" "$@"; }
steps=200; methods="nonlinear, relaxation"; thermal=0
case "$kind" in
  *-thermal) steps=60; methods="nonlinear"; thermal=1
             bench_physics=(--bench-thermal-s 0.5:3 --bench-spool-lag-s 0:0.005) ;;
esac
[ "$kind" = hil-thermal ] && steps=100
[ "$kind" = unmodelled-thermal ] && steps=20
args=(--steps "$steps" --bench-spread 0.2 --identify --quiet --set "controller.predictor.methods=[$methods]"
      --out "$tmp/stops.csv" --scenarios-out "$tmp/scenarios.csv" --summary-json "$tmp/summary.json")
[ "$thermal" = 1 ] && args+=("${bench_physics[@]}")
case "$kind" in
  ideal-thermal|hil-thermal)
    args+=(--set plant.thermal.heat_transfer_w_per_m2_k=25.72 --set plant.valve.spool_time_constant_s=0.002) ;;
esac
most=2; stiction=2
if [ "$kind" = hil ] || [ "$kind" = hil-thermal ]; then
  # hil.yaml's in-position hold off: the restarts judged here are those it prevents.
  args+=(--config "$src/config/hil.yaml" --set hal.backend=sim --set controller.hold.enabled=false)
  most=5; stiction=5
fi
"$sweep" "${args[@]}" > "$tmp/summary.txt"
cat "$tmp/summary.txt"

# Identified and run, and failed (each listed with its reason).
[ "$(summary scenarios)" = "$steps" ] || fail "the summary counts $(summary scenarios) scenarios, not $steps"
identified=$(summary identification.identified_and_run)
failed=$(/usr/bin/python3 -c 'import json, sys; print(len(json.load(open(sys.argv[1]))["identification"]["failed"]))' "$tmp/summary.json")
[ $((identified + failed)) = "$steps" ] || fail "every scenario is counted ($identified identified, $failed failed)"

# The model fits (its pressure residual within twice what the noise explains) on how many.
fits=$(summary identification.fits)
if [ "$kind" = unmodelled-thermal ]; then
  [ "$identified" -gt 0 ] || fail "no bench was identified"
  [ "$fits" = 0 ] || fail "a model without the benches' heat exchange is reported as fitting $fits of $identified"
  # ... and so is each bench's row: identified_model_fits 0.
  not_fitting=$(awk -F, 'NR == 1 { for (i = 1; i <= NF; ++i) if ($i == "identified_model_fits") c = i; next }
                         $c == "0" { ++n } END { print n + 0 }' "$tmp/scenarios.csv")
  [ "$not_fitting" = "$identified" ] || fail "$not_fitting of $identified rows say the model does not fit"
  echo "ok: $kind: the model fits none of the $identified benches identified"
  exit 0
fi
[ "$failed" -le $((steps / 50)) ] || fail "$failed scenarios failed identification or design"
if [ "$thermal" = 1 ]; then
  [ "$fits" = "$identified" ] || fail "the model fits $fits of $identified benches"
  read -r inside published <<< "$(summary identification.within_3_sigma identification.published | tr '\n' ' ')"
  awk -v i="$inside" -v p="$published" 'BEGIN { exit !(p > 0 && i >= 0.95 * p) }' ||
    fail "$inside of $published parameters published within 3 sigma of the bench (need 95 %)"
  [ "$(summary identification.heat_transfer_error_percent.count)" -gt 0 ] || fail "the heat transfer's error is reported"
  [ "$(summary identification.spool_lag_error_ms.count)" -gt 0 ] || fail "the spool lag's error is reported"
  # Every scenario settles, no fault.
  [ "$(summary outcomes.settled.count outcomes.never_settled.count outcomes.end_stop.count outcomes.fault.count | tr '\n' ' ')" \
    = "$steps 0 0 0 " ] || fail "every scenario settles with no fault"
fi
# Each failure listed with its reason: "scenario I: reason", a scenario of the sweep, each once.
/usr/bin/python3 -c '
import json, re, sys
failed = json.load(open(sys.argv[1]))["identification"]["failed"]
indices = [int(m.group(1)) for m in (re.fullmatch(r"scenario (\d+): .+", f) for f in failed) if m]
sys.exit(len(indices) != len(failed) or len(set(indices)) != len(indices) or any(i >= int(sys.argv[2]) for i in indices))' \
  "$tmp/summary.json" "$steps" || fail "each failure is listed with its reason"
[ "$(tail -n +2 "$tmp/scenarios.csv" | grep -c ',identification_failed,')" = "$failed" ] || fail "each failure has its row"

# The identified stiction's error against each bench, and p_null(u)'s over |u| < 1 V.
for side in positive negative; do
  max=$(summary identification.static_${side}_error_percent.max)
  awk -v m="$max" -v l="$stiction" 'BEGIN { exit !(m != "" && m <= l) }' || fail "F_S $side identified within $stiction % (max $max %)"
done
null_max=$(summary identification.null_pressure_error_pa.max)
awk -v m="$null_max" 'BEGIN { exit !(m != "" && m <= 5000) }' || fail "p_null(u) within 5 kPa (max $null_max Pa)"

# The nonlinear forecasts made at the stop: the long restarts within 2 / 5 / 10 %, and the verdicts.
nl=methods.nonlinear
read -r w2 w5 w10 n wrong judged <<< "$(summary $nl.long_within.2_percent $nl.long_within.5_percent $nl.long_within.10_percent \
  $nl.long_error_percent.count $nl.false_restart $nl.judged | tr '\n' ' ')"
wrong=$((wrong + $(summary $nl.missed_restart)))
[ "$n" -ge 20 ] || fail "enough long restarts to judge ($n)"
within=$w2; [ "$most" = 5 ] && within=$w5
awk -v w="$within" -v n="$n" 'BEGIN { exit !(w >= 0.95 * n) }' || fail "$within of $n long restarts within $most % (need 95 %)"
[ "$w10" = "$n" ] || fail "$w10 of $n long restarts within 10 % (need all)"
awk -v w="$wrong" -v s="$judged" 'BEGIN { exit !(w < 0.01 * s) }' || fail "verdict wrong on $wrong of $judged stops (need under 1 %)"
if [ "$thermal" = 1 ]; then
  echo "ok: $kind: $within of $n within $most %, $w10 within 10 %, verdict wrong $wrong of $judged; the model fits $fits of $identified; $inside of $published published within 3 sigma; $failed of $steps not run"
  exit 0
fi
# The relaxation method's forecasts made again half-way of the long restarts: within 5 %.
read -r rn r5 <<< "$(summary methods.relaxation.halfway.restarts methods.relaxation.halfway.within.5_percent | tr '\n' ' ')"
[ "$rn" -ge 20 ] || fail "enough long restarts for the relaxation method ($rn)"
awk -v w="$r5" -v n="$rn" 'BEGIN { exit !(w >= 0.9 * n) }' || fail "relaxation half-way: $r5 of $rn within 5 % (need 90 %)"
echo "ok: $kind: $within of $n within $most %, $w10 within 10 %, verdict wrong $wrong of $judged; $failed of 200 not run; relaxation half-way $r5 of $rn within 5 %"
