#!/usr/bin/env bash
# A pneu-sweep cut in shards run by GNU parallel, on this machine's cores or on other hosts over
# ssh (--sshlogin), then merged into the whole sweep's files in DIR. See docs/cluster.md.
#
#   parallel-sweep.sh --dir DIR --shards N [--jobs-per-shard J] [--sshlogin LOGINS]
#                     [--sweep PATH] [--resume-failed] -- PNEU-SWEEP-OPTIONS...
#
#   --dir DIR            the shards, their logs, GNU parallel's job log and the merged sweep
#                        (with --sshlogin: a path every host sees, e.g. on NFS; it is made absolute)
#   --shards N           the number of shards
#   --jobs-per-shard J   each shard's threads (pneu-sweep --jobs; default 1): GNU parallel runs as
#                        many shards at once on each host as it has cores, divided by J
#   --sshlogin LOGINS    GNU parallel's --sshlogin: "host1,4/user@host2,:" (":" is this machine);
#                        pneu-sweep and the configuration must be at the same paths on every host
#   --sweep PATH         the pneu-sweep binary (default: the one on PATH)
#   --resume-failed      run only the shards that failed or did not run last time (GNU parallel's
#                        job log, DIR/parallel.joblog), then merge
#
# DIR then holds shard-K.csv, its shard file shard-K.csv.shard and shard-K.log (its progress and
# summary), and sweep.csv, scenarios.csv, summary.json and summary.txt (the merge's summary).
set -euo pipefail
usage() { sed -n '5,19p' "$0" | sed 's/^# \{0,1\}//' >&2; exit 2; }
dir="" shards="" per_shard=1 sshlogin="" sweep="" resume=()
while [ $# -gt 0 ]; do
  case $1 in
    --dir) dir=$2; shift 2 ;;
    --shards) shards=$2; shift 2 ;;
    --jobs-per-shard) per_shard=$2; shift 2 ;;
    --sshlogin) sshlogin=$2; shift 2 ;;
    --sweep) sweep=$2; shift 2 ;;
    --resume-failed) resume=(--resume-failed); shift ;;
    --) shift; break ;;
    -h|--help) usage ;;
    *) echo "parallel-sweep.sh: unknown option $1" >&2; usage ;;
  esac
done
options=("$@")
[ -n "$dir" ] || { echo "parallel-sweep.sh: --dir DIR is needed" >&2; usage; }
[[ $shards =~ ^[1-9][0-9]*$ ]] || { echo "parallel-sweep.sh: --shards N (a whole number >= 1) is needed" >&2; exit 2; }
[[ $per_shard =~ ^[1-9][0-9]*$ ]] || { echo "parallel-sweep.sh: --jobs-per-shard must be a whole number >= 1" >&2; exit 2; }
parallel --version 2>/dev/null | grep -q 'GNU parallel' \
  || { echo "parallel-sweep.sh: needs GNU parallel (Debian: apt-get install parallel)" >&2; exit 2; }
sweep=${sweep:-$(command -v pneu-sweep || true)}
[ -x "$sweep" ] || { echo "parallel-sweep.sh: no pneu-sweep binary (--sweep PATH)" >&2; exit 2; }
sweep=$(realpath "$sweep")
for o in "${options[@]}"; do
  case $o in --shard|--shard=*|--out|--out=*|--jobs|--jobs=*)
    echo "parallel-sweep.sh: $o is set per shard by this script" >&2; exit 2 ;;
  esac
done
mkdir -p "$dir"
dir=$(realpath "$dir")

hosts=()
[ -z "$sshlogin" ] || hosts=(--sshlogin "$sshlogin")
# Each shard: its own log; --halt soon,fail=1 starts no more shards after the first failure (run
# again with --resume-failed). The command is quoted once for the shell GNU parallel starts (locally or
# over ssh).
command="$(printf '%q ' "$sweep" "${options[@]}") --shard {}/$shards --jobs $per_shard --out $(printf '%q' "$dir")/shard-{}.csv \
> $(printf '%q' "$dir")/shard-{}.log 2>&1"
start=$(date +%s.%N)
parallel --halt soon,fail=1 --joblog "$dir/parallel.joblog" "${resume[@]}" "${hosts[@]}" -j "$((100 / per_shard))%" \
  "$command" ::: $(seq "$shards") || {
  echo "parallel-sweep.sh: a shard failed (its log: $dir/shard-K.log; GNU parallel's job log: $dir/parallel.joblog)." >&2
  echo "parallel-sweep.sh: run the same command again with --resume-failed to run only what failed." >&2
  exit 1
}
shard_files=()
for k in $(seq "$shards"); do shard_files+=("$dir/shard-$k.csv"); done
"$sweep" merge --out "$dir/sweep.csv" --scenarios-out "$dir/scenarios.csv" --summary-json "$dir/summary.json" \
  "${shard_files[@]}" > "$dir/summary.txt"
cat "$dir/summary.txt"
awk -v s="$start" -v e="$(date +%s.%N)" -v n="$shards" \
  'BEGIN { printf "parallel-sweep.sh: %d shards run and merged in %.1f s wall\n", n, e - s }' >&2
