#!/usr/bin/env bash
# The paper's figures (tools/plots/pneu_plots.py) rendered from a paper-scenario run: from
# pneud's own output and from the same run laid out as pneu-log2csv writes an LCM log. The files
# must exist, be real PNG/SVG of a sensible size, carry what the figures are about (areas, curve,
# one stop marker per stop), and bad input must be refused with exit code 2. The third figure
# (Fig. 13: a sticking phase against its forecasts) needs the trajectory's forecast columns: it is
# drawn from pneud's output, skipped with a note from the LCM CSVs and from an older trajectory.
# An LCM log's figures name its date and the configuration drawn (tests/check_plot_figures.py;
# runs of every kind: test_plots_runs.sh); the stability map names what it was computed on.
# Usage: test_plots.sh BUILD_BIN_DIR SOURCE_DIR   (exit 77: skipped, saying why)
set -euo pipefail
bin=$1
src=$2
. "$src/tests/plots_preamble.sh"  # py, tool, check, the skip, fail, PATH, tmp
trap 'rm -rf "$tmp"' EXIT

# The configuration as this build's pneud sees it (the source tree's sim.yaml may be newer than
# the binaries); the run and both figures use it.
"$bin/pneud" --set telemetry.enabled=false --check-config > "$tmp/config.yaml"
"$bin/pneud" --config "$tmp/config.yaml" --quiet --events "$tmp/events.jsonl" --trajectory "$tmp/traj.csv"
stops=$(grep -c '"event":"stop"' "$tmp/events.jsonl")
[ "$stops" -ge 2 ] || fail "the paper run has $stops stops"

check_figure() {  # DIR STEM: STEM.png and STEM.svg, real and of a sensible size
  local png="$1/$2.png" svg="$1/$2.svg" size w h
  [ -s "$png" ] || fail "$png missing"
  [ -s "$svg" ] || fail "$svg missing"
  [ "$(head -c 8 "$png" | od -An -tx1 | tr -d ' \n')" = "89504e470d0a1a0a" ] || fail "$png is not a PNG"
  size=$(stat -c %s "$png")
  [ "$size" -gt 20000 ] || fail "$png is only $size bytes"
  # IHDR: width and height, big-endian, at bytes 16..23.
  read -r w h < <(od -An -tu1 -j16 -N8 "$png" | awk '{print $1*16777216+$2*65536+$3*256+$4, $5*16777216+$6*65536+$7*256+$8}')
  [ "$w" -ge 800 ] && [ "$w" -le 3000 ] && [ "$h" -ge 600 ] && [ "$h" -le 3000 ] || fail "$png is ${w}x${h}"
  grep -q "<svg" "$svg" || fail "$svg has no <svg>"
  ! grep -q "<dc:date>" "$svg" || fail "$svg carries a date (not reproducible)"
}

check_figures() {  # DIR NAME
  local dir=$1 name=$2 f
  for f in "${name}_time" "${name}_plane"; do
    check_figure "$dir" "$f"
  done
  grep -q "no-restarting area" "$dir/${name}_plane.svg" || fail "the plane figure lacks the no-restarting area"
  grep -q "stop area" "$dir/${name}_plane.svg" || fail "the plane figure lacks the stop area"
  grep -q "null-flow curve" "$dir/${name}_plane.svg" || fail "the plane figure lacks the null-flow curve"
  grep -q "forecast restart, linearized" "$dir/${name}_time.svg" || fail "the time figure lacks the linearized forecasts"
  grep -q "forecast restart, nonlinear" "$dir/${name}_time.svg" || fail "the time figure lacks the nonlinear forecasts"
  grep -q "actual restart" "$dir/${name}_time.svg" || fail "the time figure lacks the actual restarts"
  # Each stop is numbered in the time figure's zoom: the labels 1..N are there.
  for ((i = 1; i <= stops; i++)); do
    grep -q ">$i</text>" "$dir/${name}_time.svg" || fail "the time figure lacks the label of stop $i"
  done
}

# 1. pneud's output; pneu-plant found on PATH.
"$py" "$tool" --trajectory "$tmp/traj.csv" --events "$tmp/events.jsonl" --config "$tmp/config.yaml" \
  --out-dir "$tmp/out" --name paper || fail "pneu_plots.py failed on pneud's output"
check_figures "$tmp/out" paper

check_forecast_figure() {  # DIR NAME: the Fig. 13 analogue, with its curves and restarts named
  local svg="$1/$2_forecast.svg" text
  check_figure "$1" "$2_forecast"
  for text in "measured" "linearized forecast (Eq. 24/17)" "nonlinear forecast (Eq. 19)" \
              "forecast restart, linearized" "forecast restart, nonlinear" "actual restart" \
              "Brun et al. 2005, Fig. 13"; do
    grep -qF "$text" "$svg" || fail "the forecast figure $svg lacks '$text'"
  done
}
check_forecast_figure "$tmp/out" paper

# Reproducible SVG: a second rendering is byte-identical.
"$py" "$tool" --trajectory "$tmp/traj.csv" --events "$tmp/events.jsonl" --config "$tmp/config.yaml" \
  --pneu-plant "$bin/pneu-plant" --out-dir "$tmp/again" --name paper > /dev/null
cmp -s "$tmp/out/paper_plane.svg" "$tmp/again/paper_plane.svg" || fail "two renderings of the plane SVG differ"
cmp -s "$tmp/out/paper_forecast.svg" "$tmp/again/paper_forecast.svg" || fail "two renderings of the forecast SVG differ"

# --time-range slices the forecast columns with the rest: the 2.5 s phase and its restart are kept.
"$bin/pneu-plant" null-flow --config "$tmp/config.yaml" --out "$tmp/null_flow.csv"
"$py" "$tool" --trajectory "$tmp/traj.csv" --events "$tmp/events.jsonl" --config "$tmp/config.yaml" \
  --null-flow "$tmp/null_flow.csv" --time-range 1.3 4.2 --out-dir "$tmp/range" --name range > /dev/null \
  || fail "pneu_plots.py failed with --time-range"
check_forecast_figure "$tmp/range" range

# An older pneud's trajectory (no forecast columns; p_P, p_N, F where state_t says p_p, p_n,
# force): the two figures, a note, no forecast figure.
cut -d, -f1-12 "$tmp/traj.csv" | sed '1s/,p_p,p_n,force,/,p_P,p_N,F,/' > "$tmp/old.csv"
head -1 "$tmp/old.csv" | grep -q ',p_P,p_N,F,' || fail "the older trajectory's header: $(head -1 "$tmp/old.csv")"
"$py" "$tool" --trajectory "$tmp/old.csv" --events "$tmp/events.jsonl" --config "$tmp/config.yaml" \
  --null-flow "$tmp/null_flow.csv" --out-dir "$tmp/old" --name old > /dev/null 2> "$tmp/old.err" \
  || fail "pneu_plots.py failed on a trajectory without forecast columns: $(cat "$tmp/old.err")"
check_figures "$tmp/old" old
[ ! -e "$tmp/old/old_forecast.png" ] && [ ! -e "$tmp/old/old_forecast.svg" ] \
  || fail "a forecast figure was drawn from a trajectory without forecast columns"
grep -q "no forecast figure" "$tmp/old.err" || fail "no note on skipping the forecast figure: $(cat "$tmp/old.err")"

# 2. The same run as pneu-log2csv lays out an LCM log (column sets of lcmtypes/*.lcm), with a
#    null-flow curve given as a file.
"$py" - "$tmp" <<'EOF'
import csv, json, math, sys
tmp = sys.argv[1]
d = f"{tmp}/log"
import os; os.makedirs(d)
with open(f"{tmp}/traj.csv") as f, open(f"{d}/RUN1_STATE.csv", "w", newline="") as o:
    w = csv.writer(o)
    w.writerow("log_utime,utime,seq,t,y_d,y,v_hat,a_hat,p_p,p_n,force,u,stuck,mode,validity".split(","))
    for r in csv.DictReader(f):
        us = 1_700_000_000_000_000 + round(float(r["t"]) * 1e6)
        w.writerow([us + 50, us, r["seq"], r["t"], r["y_d"], r["y"], r["v_hat"], r["a_hat"], r["p_p"],
                    r["p_n"], r["force"], r["u"], r["stuck"], 1, r["validity"]])
ev = [json.loads(l) for l in open(f"{tmp}/events.jsonl")]
with open(f"{d}/RUN1_EVENT.csv", "w", newline="") as o, open(f"{d}/RUN1_PREDICTION.csv", "w", newline="") as p:
    we, wp = csv.writer(o), csv.writer(p)
    we.writerow("log_utime,utime,kind,kind_name,t,stop,y,force,y_d,direction,seq,text".split(","))
    wp.writerow(("log_utime,utime,t,stop,t_stop,update,method,method_name,will_restart,direction,"
                 "t_restart,u_star,equilibrium_force,p_p_equilibrium,p_n_equilibrium,tau_p,tau_n,"
                 "min_margin,horizon_reached,force,stop_forecast_force").split(","))
    for e in ev:
        us = 1_700_000_000_000_000 + round(e["t"] * 1e6)
        k = e["event"]
        if k == "start":
            name = "restart" if e["restart"] else "start"
            we.writerow([us, us, 2 if e["restart"] else 1, name, e["t"], e["stop"], e["y"], "",
                         e["y_d"], e["direction"], 0, 'left rest, "quoted", with a comma\nand a newline'])
        elif k == "stop":
            we.writerow([us, us, 3, "stop", e["t"], e["stop"], e["y"], e["force"], e["y_d"], 0, 0, ""])
        elif k == "end":
            we.writerow([us, us, 7, "end", e["t"], 0, "", "", "", 0, 0, ""])
        elif k in ("prediction", "reforecast"):  # the stop's forecast is update 0
            m = e["method"]
            wp.writerow([us, us, e["t"], e["stop"], e["t_stop"], e.get("update", 0),
                         1 if m == "linearized" else 2, m, int(e["will_restart"]), e["direction"],
                         "" if e["t_restart"] is None else e["t_restart"], e.get("u_star", ""),
                         e.get("equilibrium_force", ""), "", "", e.get("tau_p", ""),
                         e.get("tau_n", ""), e["min_margin"], int(e["horizon_reached"]),
                         e.get("force", ""), e.get("stop_forecast_force", "")])
EOF
"$py" "$tool" --log-csv "$tmp/log" --prefix RUN1_ --config "$tmp/config.yaml" \
  --null-flow "$tmp/null_flow.csv" --out-dir "$tmp/out_lcm" --name lcm > "$tmp/lcm.out" 2> "$tmp/lcm.err" \
  || fail "pneu_plots.py failed on the LCM CSVs: $(cat "$tmp/lcm.err")"
check_figures "$tmp/out_lcm" lcm
# An LCM log is dated by its first STATE message (utime 1700000000 s) and names the --config drawn.
"$py" "$check" "$tool" --stem "config_sim_20231114-221320" \
  --title "config.yaml (--config: the run recorded none) on the sim backend, simulated clock, hold off, run of 2023-11-14 22:13 UTC" \
  -- --log-csv "$tmp/log" --prefix RUN1_ --config "$tmp/config.yaml" --null-flow "$tmp/null_flow.csv" --out-dir "$tmp/unused" \
  2> /dev/null || fail "the LCM run's figures"
# Only the stops' forecasts (update 0) are the forecasts; the re-forecasts are not.
predictions=$(grep -c '"event":"prediction"' "$tmp/events.jsonl")
reforecasts=$(grep -c '"event":"reforecast"' "$tmp/events.jsonl")
[ "$reforecasts" -gt 0 ] || fail "the paper run has no re-forecasts"
grep -q " $predictions forecasts, $reforecasts re-forecasts;" "$tmp/lcm.out" \
  || fail "the LCM forecasts are not $predictions forecasts and $reforecasts re-forecasts: $(cat "$tmp/lcm.out")"
# The STATE channel carries no forecast columns: no forecast figure, a note saying why.
[ ! -e "$tmp/out_lcm/lcm_forecast.png" ] && [ ! -e "$tmp/out_lcm/lcm_forecast.svg" ] \
  || fail "a forecast figure was drawn from the LCM CSVs"
grep -q "no forecast figure: the LCM STATE channel" "$tmp/lcm.err" || fail "no note on the forecast figure: $(cat "$tmp/lcm.err")"

# 3. Bad input is refused with exit code 2 and a message naming the problem.
expect_refusal() {  # WHAT PATTERN ARGS...
  local what=$1 pattern=$2 rc=0
  shift 2
  "$py" "$tool" "$@" --out-dir "$tmp/bad" > "$tmp/bad.out" 2> "$tmp/bad.err" || rc=$?
  [ "$rc" -eq 2 ] || fail "$what: exit code $rc, expected 2"
  grep -q -- "$pattern" "$tmp/bad.err" || fail "$what: the message does not say '$pattern': $(cat "$tmp/bad.err")"
}
expect_refusal "a missing trajectory" "no such file" --trajectory "$tmp/nothing.csv" \
  --events "$tmp/events.jsonl" --config "$tmp/config.yaml" --null-flow "$tmp/null_flow.csv"
cut -d, -f1-8 "$tmp/traj.csv" > "$tmp/short.csv"
expect_refusal "a trajectory without force, u, stuck" "missing column(s) force, u, stuck" --trajectory "$tmp/short.csv" \
  --events "$tmp/events.jsonl" --config "$tmp/config.yaml" --null-flow "$tmp/null_flow.csv"
expect_refusal "a missing log directory" "no such directory" --log-csv "$tmp/nowhere" \
  --config "$tmp/config.yaml" --null-flow "$tmp/null_flow.csv"
expect_refusal "a wrong prefix" "PNEU_STATE.csv" --log-csv "$tmp/log" \
  --config "$tmp/config.yaml" --null-flow "$tmp/null_flow.csv"
expect_refusal "both inputs" "not both" --log-csv "$tmp/log" --trajectory "$tmp/traj.csv" \
  --events "$tmp/events.jsonl"
[ ! -e "$tmp/bad" ] || [ -z "$(ls -A "$tmp/bad")" ] || fail "a refused run left files in its --out-dir"

# 4. The stability map (tools/plots/stability_map.py) from pneu-plant tune's map: both laws drawn,
# a missing map and a map without its columns refused with exit code 2.
map_tool="$src/tools/plots/stability_map.py"
"$bin/pneu-plant" tune --config "$src/config/paper.yaml" --step-mm 25 --csv "$tmp/map.csv" > /dev/null
"$py" "$map_tool" --map "$tmp/map.csv" --out "$tmp/stability_map" > /dev/null || fail "stability_map.py failed"
check_figure "$tmp" stability_map
grep -q "paper's fixed gains" "$tmp/stability_map.svg" || fail "the map draws no fixed-gain line"
grep -q "designed schedule" "$tmp/stability_map.svg" || fail "the map draws no schedule line"
grep -qF "Stability map of Eq. 4 over the stroke (the map map.csv of pneu-plant tune --csv)" "$tmp/stability_map.svg" \
  || fail "the map's title does not name its map"
# Computed by the tool on a configuration with --set: the title names both, the fixed gains are
# named by their values, not as the paper's.
"$py" "$map_tool" --config "$src/config/paper.yaml" --set controller.law.position_gain_v_per_m=60 --step-mm 25 \
  --pneu-plant "$bin/pneu-plant" --out "$tmp/map60" > /dev/null || fail "stability_map.py failed with --set"
grep -qF "(pneu-plant tune on paper.yaml --set controller.law.position_gain_v_per_m=60, every 25 mm)" "$tmp/map60.svg" \
  || fail "the map's title does not name its configuration and --set"
grep -qF "fixed gains (60 V/m, 1.5 V/(m/s)" "$tmp/map60.svg" || fail "the map's fixed gains are not named by their values"
! grep -q "paper's fixed gains" "$tmp/map60.svg" || fail "gains of 60 V/m named the paper's"
rc=0; "$py" "$map_tool" --map "$tmp/nothing.csv" --out "$tmp/none" 2> "$tmp/map.err" || rc=$?
[ "$rc" -eq 2 ] && grep -q "no such file" "$tmp/map.err" || fail "a missing map: exit $rc, $(cat "$tmp/map.err")"
cut -d, -f1-3 "$tmp/map.csv" > "$tmp/short_map.csv"
rc=0; "$py" "$map_tool" --map "$tmp/short_map.csv" --out "$tmp/none" 2> "$tmp/map.err" || rc=$?
[ "$rc" -eq 2 ] && grep -q "missing column(s)" "$tmp/map.err" || fail "a map without columns: exit $rc, $(cat "$tmp/map.err")"

# 5. The in-position hold (issue 16): the default run held and reaching a 0.1 mm window; the plane
# figure draws the held path, the hold's target line and where each hold and reach began.
"$bin/pneud" --config "$tmp/config.yaml" --quiet --set controller.hold.enabled=true --set controller.hold.window_m=0.0001 \
  --set controller.hold.reach_m=0.005 --events "$tmp/held.jsonl" --trajectory "$tmp/held.csv"
grep -q '"event":"hold_start".*"reach":0' "$tmp/held.jsonl" || fail "the held run never held within the window"
"$py" "$tool" --trajectory "$tmp/held.csv" --events "$tmp/held.jsonl" --config "$tmp/config.yaml" \
  --null-flow "$tmp/null_flow.csv" --out-dir "$tmp/held" --name held > /dev/null || fail "pneu_plots.py failed on the held run"
check_figure "$tmp/held" held_plane
for text in "trajectory, held" "the hold's target: x - y = (F_S+ + F_S-) / 2 = -2.5 N" "hold began" "reach began"; do
  grep -qF "$text" "$tmp/held/held_plane.svg" || fail "the held run's plane figure lacks '$text'"
done

# 6. A run made with --set is drawn with the run's values: the tool reads the effective
# configuration pneud wrote beside the trajectory (T.csv.config.yaml), not a YAML file that lacks
# the override, even when given one with --config (it says so). Without the run's own (an older
# pneud), --config is drawn, and the recorded force disagreeing with it is told.
"$bin/pneud" --config "$tmp/config.yaml" --quiet --duration 3 --set plant.geometry.bore_diameter_m=0.04 \
  --events "$tmp/bore.jsonl" --trajectory "$tmp/bore.csv"
[ -s "$tmp/bore.csv.config.yaml" ] || fail "no effective configuration beside the trajectory"
"$py" "$tool" --trajectory "$tmp/bore.csv" --events "$tmp/bore.jsonl" --out-dir "$tmp/bore" --name bore \
  > /dev/null 2> "$tmp/bore.err" || fail "pneu_plots.py failed on the --set run: $(cat "$tmp/bore.err")"
! grep -q "is it the run's configuration" "$tmp/bore.err" || fail "drawn with other values than the run's: $(cat "$tmp/bore.err")"
"$py" "$tool" --trajectory "$tmp/bore.csv" --events "$tmp/bore.jsonl" --config "$tmp/config.yaml" \
  --out-dir "$tmp/bore_file" --name bore > /dev/null 2> "$tmp/bore_file.err" || fail "pneu_plots.py failed with --config"
! grep -q "is it the run's configuration" "$tmp/bore_file.err" || fail "--config drawn over the run's own: $(cat "$tmp/bore_file.err")"
grep -qF "drawing the run's own effective configuration $tmp/bore.csv.config.yaml, not --config $tmp/config.yaml" \
  "$tmp/bore_file.err" || fail "no note on drawing the run's own configuration: $(cat "$tmp/bore_file.err")"
mkdir "$tmp/older" && cp "$tmp/bore.csv" "$tmp/bore.jsonl" "$tmp/older/"
"$py" "$tool" --trajectory "$tmp/older/bore.csv" --events "$tmp/older/bore.jsonl" --config "$tmp/config.yaml" \
  --out-dir "$tmp/older/out" --name bore > /dev/null 2> "$tmp/older.err" || fail "pneu_plots.py failed on a run without its configuration"
grep -q "is it the run's configuration" "$tmp/older.err" || fail "a configuration without the --set is not noticed"

echo "plots: $stops stops; paper_time, paper_plane and paper_forecast (PNG and SVG) from pneud's output," \
     "the first two from LCM CSVs and from a trajectory without forecast columns; the stability map; a held run's plane;" \
     "a --set run drawn with its effective configuration; bad input refused; the LCM run and the map named"
