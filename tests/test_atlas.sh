#!/usr/bin/env bash
# The restart-risk atlas (issue 33): pneu-sweep --design lhs|grid draws each scenario's set point
# and bench tolerances (friction, dead volumes, valve null offset, and the spool lag when its range
# is given) and writes them in the scenarios file; and tools/plots/atlas.py turns atlases into maps
# that count every scenario.
#   test_atlas.sh BINARY_DIR SOURCE_DIR drawing|plots   (exit 77: skipped, saying why)
#     drawing: a Latin hypercube puts exactly one scenario in each stratum of each dimension, all
#              friction values of a bench by one factor, both dead volumes by one; a grid holds
#              each combination of its levels once; both are the same for a seed and differ for
#              another; bad --design / --grid-levels are refused. (Sharded and merged: the shard
#              test's atlas mode.)
#     plots:   on planted files whose answer is known, the per-bin counts and probabilities; on
#              two small atlases (hold off, hold on), every scenario counted in every axis's bins
#              and every judged stop and restart once; the figures are PNGs of a modest size;
#              bad input exits 2.
set -euo pipefail
sweep=$1/bin/pneu-sweep
src=$2
mode=$3
py=/usr/bin/python3
tmp=$(mktemp -d); trap 'rm -rf "$tmp"' EXIT
fail() { echo "FAIL: $*"; exit 1; }

case $mode in
drawing)
  short=(--duration 1.2 --step-time 0.2 --tail 0 --quiet)
  # The model's own values: a Monte-Carlo sweep without --bench-spread runs the model's bench.
  "$sweep" --steps 1 "${short[@]}" --out "$tmp/nominal.csv" --scenarios-out "$tmp/nominal_scenarios.csv" > /dev/null
  lhs=(--design lhs --steps 12 --bench-spread 0.2 --bench-spool-lag-s 0.001:0.005)
  "$sweep" "${lhs[@]}" "${short[@]}" --out "$tmp/lhs.csv" --scenarios-out "$tmp/lhs_scenarios.csv" > "$tmp/lhs.txt"
  grep -q 'an atlas (lhs) of set point x bench friction and dead volumes +-20 %, null offset within +-0.1 V, spool lag' \
    "$tmp/lhs.txt" || fail "the summary says the design: $(head -1 "$tmp/lhs.txt")"
  # Each dimension's values, in strata of its range: one scenario per stratum, and the bench's
  # friction values all by one factor, both dead volumes by one.
  "$py" - "$tmp/nominal_scenarios.csv" "$tmp/lhs_scenarios.csv" 12 lhs <<'EOF' || fail "the Latin hypercube's coverage"
import csv, sys
nominal = next(csv.DictReader(open(sys.argv[1])))
rows = list(csv.DictReader(open(sys.argv[2])))
n = int(sys.argv[3])
assert len(rows) == n, f"{len(rows)} scenarios, not {n}"
f = lambda r, c: float(r[c])
def factor(r, c): return f(r, c) / f(nominal, c)
for r in rows:
    k = factor(r, "bench_static_positive_n")
    for c in ("bench_coulomb_positive_n", "bench_static_negative_n", "bench_coulomb_negative_n", "bench_viscous_n_s_per_m"):
        assert abs(factor(r, c) / k - 1) < 1e-12, f"scenario {r['scenario']}: {c} not by the friction factor"
    assert abs(factor(r, "bench_dead_volume_n_m3") / factor(r, "bench_dead_volume_p_m3") - 1) < 1e-12, "dead volumes alike"
    for c in ("bench_max_conductance_m3_per_s_pa", "bench_leak_conductance_in_m3_per_s_pa"):
        assert f(r, c) == f(nominal, c), f"{c} stays the model's"
    assert abs(f(r, "y0_m") - f(r, "y_d_m")) >= 0.005, "the step is at least --min-step-m"
ys = [f(r, "y_d_m") for r in rows]
dims = {
    "set point": ([(y + 0.23) / 0.46 for y in ys]),  # the default stroke: targets over [-0.23, 0.23] m
    "friction": [(factor(r, "bench_static_positive_n") - 0.8) / 0.4 for r in rows],
    "dead volume": [(factor(r, "bench_dead_volume_p_m3") - 0.8) / 0.4 for r in rows],
    "null offset": [(f(r, "bench_null_offset_v") - f(nominal, "bench_null_offset_v") + 0.1) / 0.2 for r in rows],
    "spool lag": [(f(r, "bench_spool_time_constant_s") - 0.001) / 0.004 for r in rows],
}
for name, unit in dims.items():
    strata = sorted(int(u * n) for u in unit)
    assert all(0 <= u < 1 for u in unit), f"{name}: outside its range: {unit}"
    assert strata == list(range(n)), f"{name}: not one scenario per stratum: {strata}"
# Not the same permutation in every dimension.
assert len({tuple(sorted(range(n), key=lambda i: v[i])) for v in dims.values()}) > 1, "the dimensions shuffled alike"
print("lhs coverage ok")
EOF
  [ "$(awk -F, 'NR > 1' "$tmp/lhs_scenarios.csv" | wc -l)" = 12 ] || fail "12 scenario rows"

  echo "== determinism: the same seed draws the same atlas, another seed another"
  "$sweep" "${lhs[@]}" "${short[@]}" --jobs 1 --out "$tmp/again.csv" --scenarios-out "$tmp/again_scenarios.csv" > /dev/null
  cmp "$tmp/lhs_scenarios.csv" "$tmp/again_scenarios.csv" || fail "the same seed, the same scenarios file"
  cmp "$tmp/lhs.csv" "$tmp/again.csv" || fail "the same seed, the same stops file"
  "$sweep" "${lhs[@]}" "${short[@]}" --seed 2 --out "$tmp/seed2.csv" --scenarios-out "$tmp/seed2_scenarios.csv" > /dev/null
  ! cmp -s <(cut -d, -f3,16,24,26,29 "$tmp/lhs_scenarios.csv") <(cut -d, -f3,16,24,26,29 "$tmp/seed2_scenarios.csv") \
    || fail "another seed, another atlas"

  echo "== a grid: each combination of the levels once"
  "$sweep" --design grid --grid-levels 3x2x2x1 --bench-spread 0.2 "${short[@]}" --out "$tmp/grid.csv" \
    --scenarios-out "$tmp/grid_scenarios.csv" > /dev/null
  "$py" - "$tmp/nominal_scenarios.csv" "$tmp/grid_scenarios.csv" <<'EOF' || fail "the grid's combinations"
import csv, sys
nominal = next(csv.DictReader(open(sys.argv[1])))
rows = list(csv.DictReader(open(sys.argv[2])))
key = lambda r: (round(float(r["y_d_m"]), 9), round(float(r["bench_static_positive_n"]) / float(nominal["bench_static_positive_n"]), 9),
                 round(float(r["bench_dead_volume_p_m3"]) / float(nominal["bench_dead_volume_p_m3"]), 9),
                 round(float(r["bench_null_offset_v"]) - float(nominal["bench_null_offset_v"]), 9))
keys = [key(r) for r in rows]
assert len(rows) == 12 and len(set(keys)) == 12, f"{len(rows)} scenarios, {len(set(keys))} distinct"
levels = [sorted({k[d] for k in keys}) for d in range(4)]
assert [len(l) for l in levels] == [3, 2, 2, 1], levels
assert levels[0] == [round(-0.23 + 0.46 * (j + 0.5) / 3, 9) for j in range(3)], f"set points in the middle of each level: {levels[0]}"
assert levels[1] == [0.9, 1.1] and levels[2] == [0.9, 1.1] and levels[3] == [0.0], levels
assert keys[0][0] < keys[1][0] < keys[2][0] and keys[0][1:] == keys[2][1:], "the set point varies fastest"
print("grid ok")
EOF

  echo "== refusals"
  refused() {
    local want=$1 status=0
    shift
    "$sweep" "$@" --quiet --out "$tmp/refused.csv" > "$tmp/refused.txt" 2>&1 || status=$?
    [ "$status" = 2 ] && grep -qF -- "$want" "$tmp/refused.txt" || fail "$* is refused saying '$want': $(cat "$tmp/refused.txt")"
  }
  refused "--design must be mc, lhs or grid (got 'sobol')" --design sobol
  refused "--grid-levels must be 4 whole numbers >= 1 joined by 'x'" --design grid
  refused "--grid-levels must be 5 whole numbers >= 1 joined by 'x', one per dimension (set point, friction, dead volume, null offset, spool lag) (got '2x2x2x2')" \
    --design grid --grid-levels 2x2x2x2 --bench-spool-lag-s 0.001:0.002
  refused "(got '2x0x2x2')" --design grid --grid-levels 2x0x2x2
  refused "--steps 10 is not the grid's 16 scenarios" --design grid --grid-levels 2x2x2x2 --steps 10
  refused "--grid-levels goes with --design grid" --design lhs --grid-levels 2x2x2x2
  echo "ok: the atlas's drawing"
  ;;

plots)
  if ! "$py" -c "import matplotlib, numpy" 2> /dev/null; then
    echo "SKIPPED: $py lacks matplotlib or numpy (Debian packages python3-matplotlib, python3-numpy)" >&2
    exit 77
  fi
  atlas=("$py" "$src/tools/plots/atlas.py")
  echo "== planted files: the counts and probabilities known"
  mkdir -p "$tmp/planted"
  cat > "$tmp/planted/scenarios.csv" <<'EOF'
scenario,y_d_m,outcome,final_error_m,bench_static_positive_n,bench_dead_volume_p_m3
0,-0.1,settled,0.000010,10,1e-6
1,-0.1,never-settled,0.002,20,1e-6
2,0.1,fault,0.1,10,1e-6
3,0.1,identification_failed,,20,1e-6
EOF
  cat > "$tmp/planted/sweep.csv" <<'EOF'
scenario,outcome,sticking_s
0,restart,0.5
0,stuck_to_end,11
1,setpoint_changed,0.1
2,restart,2.0
2,plant_not_at_rest,0.3
EOF
  "${atlas[@]}" --run planted="$tmp/planted" --bins 2 --out-dir "$tmp/planted_img" --summary-json "$tmp/planted.json" \
    > "$tmp/planted.txt" || fail "atlas.py on the planted files: $(cat "$tmp/planted.txt")"
  "$py" - "$tmp/planted.json" <<'EOF' || fail "the planted atlas's figures"
import json, sys
d = json.load(open(sys.argv[1]))
assert [a["column"] for a in d["axes"]] == ["y_d_m", "bench_static_positive_n"], d["axes"]  # the dead volume does not vary
r = d["runs"][0]
assert r["scenarios"] == 4 and r["stops"] == 5, r
assert r["outcomes"] == {"settled": 1, "end-stop": 0, "never-settled": 1, "fault": 1, "identification_failed": 1}, r["outcomes"]
assert r["stops_by_fate"] == {"restart": 2, "stuck_to_end": 1, "setpoint_changed": 1, "plant_not_at_rest": 1}, r["stops_by_fate"]
setpoint, friction = r["axes"]
b = setpoint["bins"]
assert [x["scenarios"] for x in b] == [2, 2], b
assert [x["judged_stops"] for x in b] == [2, 1] and [x["restarts"] for x in b] == [1, 1], b
assert [x["restart_probability"] for x in b] == [0.5, 1.0], b
assert b[0]["outcomes"]["never-settled"] == 1 and b[1]["outcomes"]["identification_failed"] == 1, b
assert b[1]["final_error_p50_m"] == 0.1, b  # the one that did not run has no final error
b = friction["bins"]
assert [x["scenarios"] for x in b] == [2, 2] and [x["judged_stops"] for x in b] == [3, 0], b
assert b[0]["restart_probability"] == 2 / 3 and b[1]["restart_probability"] is None, b
assert b[0]["sticking_p50_s"] == 1.25, b
print("planted ok")
EOF
  grep -q "planted: 4 scenarios (settled 1, end-stop 0, never-settled 1, fault 1, not run (identification failed) 1), 5 stops" \
    "$tmp/planted.txt" || fail "it says what it counted: $(cat "$tmp/planted.txt")"

  echo "== two small atlases, hold off and hold on"
  small=(--design lhs --steps 24 --bench-spread 0.3 --bench-spool-lag-s 0.001:0.004 --duration 6 --quiet)
  for hold in false true; do
    mkdir -p "$tmp/hold-$hold"
    "$sweep" "${small[@]}" --set controller.hold.enabled=$hold --out "$tmp/hold-$hold/sweep.csv" \
      --scenarios-out "$tmp/hold-$hold/scenarios.csv" > /dev/null
  done
  "${atlas[@]}" --run "hold off=$tmp/hold-false" --run "hold on=$tmp/hold-true" --bins 4 --prefix small \
    --out-dir "$tmp/img" --summary-json "$tmp/small.json" > "$tmp/small.txt" || fail "atlas.py: $(cat "$tmp/small.txt")"
  cat "$tmp/small.txt"
  "$py" - "$tmp/small.json" "$tmp/hold-false" "$tmp/hold-true" <<'EOF' || fail "every scenario counted"
import csv, json, sys
d = json.load(open(sys.argv[1]))
assert [a["column"] for a in d["axes"]] == ["y_d_m", "bench_static_positive_n", "bench_dead_volume_p_m3",
                                            "bench_null_offset_v", "bench_spool_time_constant_s"], d["axes"]
for run, where in zip(d["runs"], sys.argv[2:]):
    scenarios = list(csv.DictReader(open(where + "/scenarios.csv")))
    stops = list(csv.DictReader(open(where + "/sweep.csv")))
    judged = sum(s["outcome"] in ("restart", "stuck_to_end") for s in stops)
    restarts = sum(s["outcome"] == "restart" for s in stops)
    assert judged > 0 and run["scenarios"] == len(scenarios) == 24 and sum(run["outcomes"].values()) == 24, run
    for axis in run["axes"]:
        bins = axis["bins"]
        assert axis["unplaced"] == 0 and sum(b["scenarios"] for b in bins) == 24, (run["label"], axis)
        assert sum(sum(b["outcomes"].values()) for b in bins) == 24, axis
        assert sum(b["judged_stops"] for b in bins) == judged and sum(b["restarts"] for b in bins) == restarts, axis
print("counted ok")
EOF
  for f in small_profiles small_restart_map small_final_error_map small_sticking; do
    png="$tmp/img/$f.png"
    [ "$(head -c 8 "$png" | od -An -tx1 | tr -d ' \n')" = "89504e470d0a1a0a" ] || fail "$png is not a PNG"
    read -r w h < <(od -An -tu1 -j16 -N8 "$png" | awk '{print $1*16777216+$2*65536+$3*256+$4, $5*16777216+$6*65536+$7*256+$8}')
    [ "$w" -ge 500 ] && [ "$w" -le 2000 ] && [ "$h" -ge 300 ] && [ "$h" -le 2000 ] || fail "$png is ${w}x${h}"
  done

  echo "== bad input"
  status=0
  cut -d, -f1,2 "$tmp/planted/scenarios.csv" > "$tmp/planted/short.csv"
  "${atlas[@]}" --run "x=$tmp/planted/sweep.csv,$tmp/planted/short.csv" --out-dir "$tmp/bad" > "$tmp/bad.txt" 2>&1 || status=$?
  [ "$status" = 2 ] && grep -q "lacks the column(s) outcome, final_error_m" "$tmp/bad.txt" || fail "a missing column: $(cat "$tmp/bad.txt")"
  echo "ok: the atlas's maps"
  ;;
*) fail "unknown mode $mode" ;;
esac
