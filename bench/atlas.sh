#!/usr/bin/env bash
# The restart-risk atlas at scale (issue 33): SCENARIOS scenarios (default 20,000), half without
# the in-position hold and half with it, each half a Latin hypercube over set point x bench
# tolerances (friction and dead volumes +-30 %, valve null offset +-0.15 V, spool lag 0-4 ms) run
# through tools/cluster/parallel-sweep.sh in SHARDS shards on this machine's cores, merged; then
# tools/plots/atlas.py draws the maps. Prints each half's wall time and CPU time (user + system of
# all its processes), and the scenarios per core-second: scenarios / (wall x cores), and
# scenarios / CPU seconds.
#   bench/atlas.sh [--scenarios N] [--shards S] [--dir DIR] [--img-dir DIR] [--seed S]
# Defaults: 20000 scenarios, 8 shards per half, DIR build/atlas, the maps in DIR/img (docs/img to
# publish them). Needs build/bin/pneu-sweep, GNU parallel, /usr/bin/python3 with matplotlib.
set -euo pipefail
cd "$(dirname "$0")/.."
root=$PWD
scenarios=20000 shards=8 dir=build/atlas img="" seed=1
while [ $# -gt 0 ]; do
  case $1 in
    --scenarios) scenarios=$2; shift 2 ;;
    --shards) shards=$2; shift 2 ;;
    --dir) dir=$2; shift 2 ;;
    --img-dir) img=$2; shift 2 ;;
    --seed) seed=$2; shift 2 ;;
    *) sed -n '2,11p' "$0" | sed 's/^# \{0,1\}//' >&2; exit 2 ;;
  esac
done
img=${img:-$dir/img}
[ -x build/bin/pneu-sweep ] || { echo "build pneu-sweep first (cmake --build build --target pneu-sweep)" >&2; exit 1; }
[ $((scenarios % 2)) = 0 ] || { echo "--scenarios must be even (two halves)" >&2; exit 2; }
half=$((scenarios / 2))
cores=$(nproc)
design=(--design lhs --steps "$half" --seed "$seed" --bench-spread 0.3 --bench-spool-lag-s 0:0.004)
echo "bench/atlas.sh: $scenarios scenarios ($half hold off, $half hold on), $shards shards each, $cores cores," \
  "$(git rev-parse --short HEAD)$(git diff --quiet HEAD -- . ':!docs' || echo +), $(date -u '+%Y-%m-%d %H:%M UTC')"
echo "  pneu-sweep ${design[*]} --set controller.hold.enabled=false|true"
total_wall=0 total_cpu=0
for hold in false true; do
  out=$dir/hold-$hold
  rm -rf "$out"
  mkdir -p "$dir"
  # The half's wall time, and the CPU time of all its processes (bash's times: the children's).
  start=$(date +%s.%N)
  read -r user0 sys0 < <(awk '{print $14 + $16, $15 + $17}' /proc/$$/stat)
  ( tools/cluster/parallel-sweep.sh --dir "$out" --shards "$shards" --sweep build/bin/pneu-sweep \
      -- "${design[@]}" --set controller.hold.enabled=$hold > /dev/null 2> "$out.err" ) \
    || { cat "$out.err" >&2; exit 1; }
  end=$(date +%s.%N)
  read -r user1 sys1 < <(awk '{print $14 + $16, $15 + $17}' /proc/$$/stat)
  ticks=$(getconf CLK_TCK)
  awk -v s="$start" -v e="$end" -v u="$((user1 - user0))" -v y="$((sys1 - sys0))" -v t="$ticks" -v n="$half" \
      -v c="$cores" -v h="$hold" 'BEGIN {
    wall = e - s; cpu = (u + y) / t
    printf "  hold %-5s: %d scenarios in %.1f s wall, %.1f s CPU: %.1f scenarios per core-second of wall (x %d cores), %.1f per CPU second\n",
      h, n, wall, cpu, n / (wall * c), c, n / cpu
  }'
  total_wall=$(awk -v a="$total_wall" -v s="$start" -v e="$end" 'BEGIN { print a + e - s }')
  total_cpu=$(awk -v a="$total_cpu" -v u="$((user1 - user0))" -v y="$((sys1 - sys0))" -v t="$ticks" 'BEGIN { print a + (u + y) / t }')
done
awk -v w="$total_wall" -v u="$total_cpu" -v n="$scenarios" -v c="$cores" 'BEGIN {
  printf "  all: %d scenarios in %.1f s wall, %.1f s CPU: %.1f scenarios per core-second of wall (x %d cores), %.1f per CPU second\n",
    n, w, u, n / (w * c), c, n / u
}'
/usr/bin/python3 tools/plots/atlas.py --run "hold off=$dir/hold-false" --run "hold on=$dir/hold-true" \
  --out-dir "$img" --summary-json "$dir/atlas.json"
