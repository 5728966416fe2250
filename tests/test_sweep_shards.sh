#!/usr/bin/env bash
# pneu-sweep --shard K/N and pneu-sweep merge (issue 33): a sweep cut in 1, 2, 4 and 7 shards and
# merged gives the unsharded sweep's stops and scenarios files byte for byte, its summary line for
# line and its --summary-json member for member (the wall time and threads aside: the merge's are
# the shards' summed, and its wall line says so); the merge says which shards it took; a shard run
# again alone after a failure merges the same; a missing, duplicated or foreign shard (other seed,
# steps, options, configuration or N), or a file that is no shard, is refused, naming it.
#   test_sweep_shards.sh BINARY_DIR default|identified
#     default:    the 200-step sweep of the shipped configuration, and the refusals
#     identified: --steps 40 --bench-spread 0.2 --identify (each bench its own, identified first)
#     atlas:      --design lhs --steps 40 --bench-spread 0.3 --bench-spool-lag-s 0.001:0.004 (an
#                 atlas's Latin hypercube); a Monte-Carlo shard of the same options is refused
set -euo pipefail
sweep=$1/bin/pneu-sweep
mode=$2
tmp=$(mktemp -d); trap 'rm -rf "$tmp"' EXIT
fail() { echo "FAIL: $*"; exit 1; }
case $mode in
  default) options=(--steps 200) ;;
  identified) options=(--steps 40 --bench-spread 0.2 --identify) ;;
  atlas) options=(--design lhs --steps 40 --bench-spread 0.3 --bench-spool-lag-s 0.001:0.004) ;;
  *) fail "unknown mode $mode" ;;
esac

# The summary less its wall-time line and the "wrote" lines (their paths differ).
summary_lines() { grep -v -e '^  [0-9.]* s wall ' -e '^  wrote ' "$1"; }
# The --summary-json less wall_s and jobs, its members sorted.
summary_json() {
  /usr/bin/python3 -c 'import json, sys; d = json.load(open(sys.argv[1])); d.pop("wall_s"); d.pop("jobs"); print(json.dumps(d, sort_keys=True, indent=1))' "$1"
}

echo "== unsharded: ${options[*]}"
"$sweep" "${options[@]}" --quiet --out "$tmp/whole.csv" --scenarios-out "$tmp/whole_scenarios.csv" \
  --summary-json "$tmp/whole.json" > "$tmp/whole.txt"
cat "$tmp/whole.txt"
stops=$(($(wc -l < "$tmp/whole.csv") - 1))
[ "$stops" -ge 20 ] || fail "not vacuous: the sweep has stops to merge (got $stops)"
if [ "$mode" != default ]; then
  [ "$mode" != identified ] || grep -q '^scenario,.*identified_static_positive_n' "$tmp/whole_scenarios.csv" \
    || fail "--identify's columns are there"
  # The benches differ from one another (--bench-spread): each shard must carry its own.
  [ "$(cut -d, -f16 "$tmp/whole_scenarios.csv" | sort -u | wc -l)" -gt 10 ] || fail "not vacuous: the benches differ"
fi

for n in 1 2 4 7; do
  echo "== $n shards"
  shards=()
  for k in $(seq "$n"); do
    "$sweep" "${options[@]}" --shard "$k/$n" --out "$tmp/s$n-$k.csv" > "$tmp/s$n-$k.txt" 2> "$tmp/s$n-$k.err"
    [ -s "$tmp/s$n-$k.csv.shard" ] || fail "shard $k/$n wrote its shard file beside its --out"
    grep -qE "^pneu-sweep shard $k/$n: [0-9]+/[0-9]+ scenarios, [0-9.]+ s, [0-9.]+ scenarios/s" "$tmp/s$n-$k.err" \
      || fail "shard $k/$n reports its progress on stderr: $(cat "$tmp/s$n-$k.err")"
    shards+=("$tmp/s$n-$k.csv")
  done
  grep -qE 'about [0-9]+ s left \(ends [0-9:]{8} UTC\)' "$tmp/s$n-1.err" || [ "$n" -gt 1 ] \
    || fail "the progress says the time left and the estimated end: $(cat "$tmp/s$n-1.err")"
  # Any order: the last first.
  order=("${shards[@]:$((n - 1))}" "${shards[@]:0:$((n - 1))}")
  "$sweep" merge --out "$tmp/m$n.csv" --scenarios-out "$tmp/m$n-scenarios.csv" --summary-json "$tmp/m$n.json" \
    "${order[@]}" > "$tmp/m$n.txt" 2> "$tmp/m$n.err"
  cat "$tmp/m$n.err"
  [ "$(grep -c '^pneu-sweep merge: took shard ' "$tmp/m$n.err")" = "$n" ] || fail "the merge names the $n shards it took"
  grep -q "^pneu-sweep merge: took shard $n/$n from $tmp/s$n-$n.csv.shard: " "$tmp/m$n.err" || fail "... each with its file"
  cmp "$tmp/whole.csv" "$tmp/m$n.csv" || fail "$n shards: the stops file differs from the unsharded sweep's"
  cmp "$tmp/whole_scenarios.csv" "$tmp/m$n-scenarios.csv" || fail "$n shards: the scenarios file differs"
  diff <(summary_lines "$tmp/whole.txt") <(summary_lines "$tmp/m$n.txt") || fail "$n shards: the summary differs"
  grep -qE "^  [0-9.]+ s wall summed over $n shards \(each on up to [0-9]+ threads\)" "$tmp/m$n.txt" \
    || fail "the merged summary says its wall time is the shards' summed"
  diff <(summary_json "$tmp/whole.json") <(summary_json "$tmp/m$n.json") || fail "$n shards: the --summary-json differs"
done

echo "== a shard run again alone (after a failure) merges the same"
rm "$tmp/s4-3.csv" "$tmp/s4-3.csv.shard"
"$sweep" "${options[@]}" --shard 3/4 --quiet --out "$tmp/s4-3.csv" > /dev/null
"$sweep" merge --out "$tmp/again.csv" "$tmp"/s4-{1,2,3,4}.csv > /dev/null 2>&1
cmp "$tmp/whole.csv" "$tmp/again.csv" || fail "the shard run again merges to the same file"

if [ "$mode" = atlas ]; then
  "$sweep" "${options[@]:2}" --shard 4/4 --quiet --out "$tmp/mc.csv" > /dev/null
  status=0
  "$sweep" merge --out "$tmp/refused.csv" "$tmp"/s4-{1,2,3}.csv "$tmp/mc.csv" > "$tmp/refused.txt" 2>&1 || status=$?
  [ "$status" = 2 ] && grep -q "another sweep than .*: design=0, where the first has design=1" "$tmp/refused.txt" \
    || fail "a Monte-Carlo shard is refused from an atlas's merge: $(cat "$tmp/refused.txt")"
fi
[ "$mode" = default ] || { echo "ok: $mode: 1, 2, 4 and 7 shards merged equal the unsharded sweep"; exit 0; }
# refused WANT ARGS...: the merge exits 2, saying WANT (an extended regular expression).
refused() {
  local want=$1 status=0
  shift
  "$sweep" merge --out "$tmp/refused.csv" "$@" > "$tmp/refused.txt" 2>&1 || status=$?
  [ "$status" = 2 ] || fail "merge $* exits 2 (got $status): $(cat "$tmp/refused.txt")"
  grep -qE -- "$want" "$tmp/refused.txt" || fail "merge $* says '$want': $(cat "$tmp/refused.txt")"
  [ ! -e "$tmp/refused.csv" ] || fail "a refused merge writes no --out"
  echo "refused: $(cat "$tmp/refused.txt")"
}
echo "== refusals"
refused "shards missing: 3/4 \(of $tmp/s4-1.csv.shard's sweep\)" "$tmp"/s4-{1,2,4}.csv
refused "shards missing: 2/4, 3/4, 4/4" "$tmp/s4-1.csv"
refused "shard 2/4 is given twice: $tmp/s4-2.csv.shard and $tmp/s4-2.csv.shard" "$tmp"/s4-{1,2,2,3,4}.csv
cp "$tmp/s4-2.csv.shard" "$tmp/copy.shard"
refused "shard 2/4 is given twice: $tmp/s4-2.csv.shard and $tmp/copy.shard" "$tmp"/s4-{1,2,3,4}.csv "$tmp/copy.shard"
refused "$tmp/s2-2.csv.shard is shard 2/2, of another cut than $tmp/s4-1.csv.shard \(1/4\)" "$tmp"/s4-{1,2,3,4}.csv "$tmp/s2-2.csv"
"$sweep" "${options[@]}" --seed 2 --shard 4/4 --quiet --out "$tmp/seed2.csv" > /dev/null
refused "$tmp/seed2.csv.shard is a shard of another sweep than $tmp/s4-1.csv.shard: seed=2, where the first has seed=1" \
  "$tmp"/s4-{1,2,3}.csv "$tmp/seed2.csv"
"$sweep" "${options[@]}" --duration 11 --shard 4/4 --quiet --out "$tmp/duration.csv" > /dev/null
refused "another sweep than .*: duration_s=11, where the first has duration_s=12" "$tmp"/s4-{1,2,3}.csv "$tmp/duration.csv"
"$sweep" --steps 201 --shard 4/4 --quiet --out "$tmp/steps.csv" > /dev/null
refused "another sweep than .*: steps=201, where the first has steps=200" "$tmp"/s4-{1,2,3}.csv "$tmp/steps.csv"
"$sweep" "${options[@]}" --set controller.hold.enabled=true --shard 4/4 --quiet --out "$tmp/config.csv" > /dev/null
"$sweep" "${options[@]}" --set controller.stop_detector.hold_s=0.004 --shard 4/4 --quiet --out "$tmp/config2.csv" > /dev/null
refused "$tmp/config2.csv.shard is a shard of another sweep than .*: another configuration \(fingerprint [0-9a-f]{16}" \
  "$tmp"/s4-{1,2,3}.csv "$tmp/config2.csv"
refused "another sweep than .*: hold_enabled=1, where the first has hold_enabled=0" \
  "$tmp"/s4-{1,2,3}.csv "$tmp/config.csv"
refused "the shard file $tmp/whole.csv.shard is not a shard file|cannot read the shard file $tmp/whole.csv.shard" "$tmp/whole.csv"
printf 'hello\n' > "$tmp/other.csv.shard"
refused "the shard file $tmp/other.csv.shard is not a shard file" "$tmp/other.csv"
head -n 6 "$tmp/s4-4.csv.shard" > "$tmp/cut.csv.shard"
refused "the shard file $tmp/cut.csv.shard ends before its scenarios" "$tmp"/s4-{1,2,3}.csv "$tmp/cut.csv"
refused "no shard named" 
status=0; "$sweep" --steps 4 --shard 5/4 --out "$tmp/x.csv" > "$tmp/bad.txt" 2>&1 || status=$?
[ "$status" = 2 ] && grep -q -- "--shard must be K/N with whole numbers 1 <= K <= N (got '5/4')" "$tmp/bad.txt" \
  || fail "--shard 5/4 is refused: $(cat "$tmp/bad.txt")"
echo "ok: $mode: 1, 2, 4 and 7 shards merged equal the unsharded sweep; the refusals name the shard"
