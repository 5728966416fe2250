#!/usr/bin/env bash
# Figures that name their run (tools/plots/pneu_plots.py): a sim run, held runs and a HIL run
# (pneud over Modbus against pneu-plant serve; hil.yaml's sensors on the sim backend in a build
# without Modbus) are drawn and checked as matplotlib objects by tests/check_plot_figures.py: the
# titles name the configuration, backend, clock, hold and date and write no time with an exponent,
# the file stems are the run's, no two stop labels overlap, the close-up stays a close-up, the holds
# and reaches are marked and the forecasts they superseded left out. Events of another run are
# refused naming both files; the trajectory alone is drawn.
# Usage: test_plots_runs.sh BUILD_BIN_DIR SOURCE_DIR MODBUS(0|1)   (exit 77: skipped, saying why)
set -euo pipefail
bin=$1
src=$2
modbus=$3
. "$src/tests/plots_preamble.sh"  # py, tool, check, the skip, fail, PATH, tmp
serve_pid=
trap '[ -z "$serve_pid" ] || kill "$serve_pid" 2> /dev/null || true; rm -rf "$tmp"' EXIT
date_re='[0-9]{8}-[0-9]{6}'  # the run's date and time in a file stem

check_figure() {  # DIR STEM: STEM.png and STEM.svg written
  [ -s "$1/$2.png" ] && [ -s "$1/$2.svg" ] || fail "$1/$2.png or .svg missing: $(ls "$1")"
}

# The configuration as this build's pneud sees it; the paper's step on it.
"$bin/pneud" --set telemetry.enabled=false --check-config > "$tmp/config.yaml"
"$bin/pneud" --config "$tmp/config.yaml" --quiet --events "$tmp/events.jsonl" --trajectory "$tmp/traj.csv"
"$bin/pneu-plant" null-flow --config "$tmp/config.yaml" --out "$tmp/null_flow.csv"

# 1. A sim run: without --name the files are named by the run, and each title says which run it is.
"$py" "$tool" --trajectory "$tmp/traj.csv" --events "$tmp/events.jsonl" --null-flow "$tmp/null_flow.csv" \
  --out-dir "$tmp/auto" > /dev/null \
  || fail "pneu_plots.py failed without --name"
ls "$tmp/auto" | grep -Eq "^config_sim_${date_re}_plane\.svg$" || fail "the files are not named by the run: $(ls "$tmp/auto")"
"$py" "$check" "$tool" --stem "config_sim_${date_re}" --title "config.yaml on the sim backend, simulated clock, hold off, run of" \
  -- --trajectory "$tmp/traj.csv" --events "$tmp/events.jsonl" --null-flow "$tmp/null_flow.csv" --out-dir "$tmp/unused" \
  || fail "the sim run's figures"

# 2. Held runs: their figures name them held, mark the holds and reaches in time and leave out the
# forecast restarts a hold or reach superseded: the run held and reaching a 0.1 mm window, and the
# run held with the default window (no reach), whose stop is held to the end of the record.
"$bin/pneud" --config "$tmp/config.yaml" --quiet --set controller.hold.enabled=true --set controller.hold.window_m=0.0001 \
  --set controller.hold.reach_m=0.005 --events "$tmp/held.jsonl" --trajectory "$tmp/held.csv" 2> /dev/null
"$py" "$check" "$tool" --held --stem "config_sim_held_${date_re}" --title "hold on (window 0.1 mm, reach 5 mm)" \
  -- --trajectory "$tmp/held.csv" --events "$tmp/held.jsonl" --null-flow "$tmp/null_flow.csv" --out-dir "$tmp/unused" \
  || fail "the held run's figures"
"$bin/pneud" --config "$tmp/config.yaml" --quiet --set controller.hold.enabled=true --events "$tmp/held5.jsonl" \
  --trajectory "$tmp/held5.csv" 2> /dev/null
"$py" "$check" "$tool" --held --title "hold on (window 0.5 mm)" \
  -- --trajectory "$tmp/held5.csv" --events "$tmp/held5.jsonl" --null-flow "$tmp/null_flow.csv" --out-dir "$tmp/unused" \
  || fail "the figures of the run held with the default window"

# 3. Events of another run are refused, naming both files: the held run's over the paper run's
# trajectory (their configurations differ), and, with no configuration beside them, the paper
# run's over the held trajectory (their rests differ).
expect_mismatch() {  # TRAJECTORY EVENTS PATTERN
  local rc=0
  "$py" "$tool" --trajectory "$1" --events "$2" --null-flow "$tmp/null_flow.csv" --out-dir "$tmp/mismatch" \
    > /dev/null 2> "$tmp/mismatch.err" || rc=$?
  [ "$rc" -eq 2 ] || fail "events of another run: exit code $rc, expected 2"
  grep -qF -- "--events $2 does not belong to --trajectory $1: $3" "$tmp/mismatch.err" \
    || fail "events of another run: $(cat "$tmp/mismatch.err")"
  [ ! -e "$tmp/mismatch" ] || fail "events of another run: figures written"
}
expect_mismatch "$tmp/traj.csv" "$tmp/held.jsonl" "their effective configurations differ"
cp "$tmp/events.jsonl" "$tmp/bare.jsonl"
expect_mismatch "$tmp/held.csv" "$tmp/bare.jsonl" "the trajectory comes to rest"

# The trajectory alone: the figures without stops, restarts or holds, and a note for the forecast one.
"$py" "$tool" --trajectory "$tmp/held.csv" --null-flow "$tmp/null_flow.csv" --out-dir "$tmp/alone" --name alone \
  > /dev/null 2> "$tmp/alone.err" || fail "the trajectory alone is refused: $(cat "$tmp/alone.err")"
check_figure "$tmp/alone" alone_time
check_figure "$tmp/alone" alone_plane
grep -q "no forecast figure: no --events" "$tmp/alone.err" || fail "no note without --events: $(cat "$tmp/alone.err")"

# 4. A HIL run: pneud's modbus backend against pneu-plant serve on a free loopback port for 3 s of
# real time (the link's and the loop's timing faults off: the machine's load is not the subject),
# its title naming hil.yaml, the modbus backend and the real clock, its times (the first tick a
# few microseconds after 0) without an exponent. Without the modbus backend in this build,
# hil.yaml's sensors on the sim backend.
hil="$src/config/hil.yaml"
if [ "$modbus" = 1 ]; then
  port=$("$py" -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')
  "$bin/pneu-plant" serve --config "$hil" --set "hal.modbus.port=$port" --duration 10 --quiet \
    > "$tmp/serve.out" 2>&1 &
  serve_pid=$!
  for _ in $(seq 100); do (exec 3<> "/dev/tcp/127.0.0.1/$port") 2> /dev/null && break; sleep 0.05; done
  rc=0
  "$bin/pneud" --config "$hil" --set "hal.modbus.port=$port" --set telemetry.enabled=false \
    --set controller.movement_test.enabled=false --set hal.modbus.response_timeout_s=0.5 \
    --set hal.modbus.max_sample_age_s=0.5 --set controller.comms_fault_after_s=2 \
    --set controller.supervisor.overruns_in_a_row=0 --set controller.supervisor.max_tick_interval_s=0 \
    --duration 3 --quiet --events "$tmp/hil.jsonl" --trajectory "$tmp/hil.csv" 2> "$tmp/hil.err" || rc=$?
  kill "$serve_pid" 2> /dev/null || true
  wait "$serve_pid" 2> /dev/null || true
  serve_pid=
  [ "$rc" -eq 0 ] || fail "the HIL run failed (exit $rc): $(cat "$tmp/hil.err")"
  hil_title="hil.yaml on the modbus backend, real clock, hold on (window 0.2 mm, reach 5 mm), run of"
  hil_stem="hil_modbus_held_${date_re}"
else
  "$bin/pneud" --config "$hil" --set hal.backend=sim --set controller.clock=simulated --set telemetry.enabled=false \
    --quiet --events "$tmp/hil.jsonl" --trajectory "$tmp/hil.csv" 2> "$tmp/hil.err" \
    || fail "the run on hil.yaml's sensors failed: $(cat "$tmp/hil.err")"
  hil_title="hil.yaml on the sim backend, simulated clock, hold on (window 0.2 mm, reach 5 mm), run of"
  hil_stem="hil_sim_held_${date_re}"
fi
"$py" "$check" "$tool" --stem "$hil_stem" --title "$hil_title" \
  -- --trajectory "$tmp/hil.csv" --events "$tmp/hil.jsonl" --out-dir "$tmp/unused" || fail "the HIL run's figures"

echo "plots of runs: a sim, two held and a $([ "$modbus" = 1 ] && echo "Modbus" || echo "hil.yaml sensors") run named" \
     "by their run, holds marked, labels apart; events of another run refused; the trajectory alone drawn"
