#!/usr/bin/env bash
# A pneu-sweep cut in shards on a Slurm cluster: one job array of N shards (pneu-sweep --shard K/N)
# and a merge job that starts once every shard has succeeded (afterok), writing the whole sweep's
# files into DIR. See docs/cluster.md.
#
#   slurm-sweep.sh --dir DIR (--shards N | --shard-minutes M --scenario-cpu-s S) [--partition P]
#                  [--time MINUTES] [--cpus-per-task C] [--sweep PATH] [--sbatch-option OPT]...
#                  [--wait] -- PNEU-SWEEP-OPTIONS...
#
#   --dir DIR           where the batch scripts, the shards, their logs and the merged sweep go:
#                       on a file system every compute node sees (it is made absolute)
#   --shards N          the number of shards; or, sized from the sweep:
#   --shard-minutes M   ... about M minutes of work per shard, each scenario taking
#   --scenario-cpu-s S  ... S seconds of one core (docs/cluster.md gives measured figures):
#                       N = ceil(steps * S / (60 * M * C))
#   --partition P       the partition (default: the cluster's default)
#   --time MINUTES      each shard's time limit (default: 3 M + 5 when sized, else 60)
#   --cpus-per-task C   cores per shard, its --jobs (default 1)
#   --sweep PATH        the pneu-sweep binary, on a path every node sees (default: the one on PATH)
#   --sbatch-option OPT passed to both sbatch calls (e.g. --account=lab, --qos=short)
#   --wait              return when the merge job has ended, with its exit status
#
# DIR then holds shard.sbatch and merge.sbatch (submitted as they are), shard-K.csv and its shard
# file shard-K.csv.shard, shard-K.log (the shard's progress and summary), and once merged
# sweep.csv, scenarios.csv, summary.json, summary.txt and merge.log. A shard that failed is run
# again alone, then the merge: sbatch --array=K DIR/shard.sbatch; sbatch DIR/merge.sbatch
set -euo pipefail
usage() { sed -n '6,24p' "$0" | sed 's/^# \{0,1\}//' >&2; exit 2; }
dir="" shards="" minutes="" cpu_s="" partition="" time_min="" cpus=1 sweep="" wait_flag=() extra=()
while [ $# -gt 0 ]; do
  case $1 in
    --dir) dir=$2; shift 2 ;;
    --shards) shards=$2; shift 2 ;;
    --shard-minutes) minutes=$2; shift 2 ;;
    --scenario-cpu-s) cpu_s=$2; shift 2 ;;
    --partition) partition=$2; shift 2 ;;
    --time) time_min=$2; shift 2 ;;
    --cpus-per-task) cpus=$2; shift 2 ;;
    --sweep) sweep=$2; shift 2 ;;
    --sbatch-option) extra+=("$2"); shift 2 ;;
    --wait) wait_flag=(--wait); shift ;;
    --) shift; break ;;
    -h|--help) usage ;;
    *) echo "slurm-sweep.sh: unknown option $1" >&2; usage ;;
  esac
done
options=("$@")
[ -n "$dir" ] || { echo "slurm-sweep.sh: --dir DIR is needed" >&2; usage; }
command -v sbatch > /dev/null || { echo "slurm-sweep.sh: no sbatch on PATH (is this a Slurm login node?)" >&2; exit 2; }
sweep=${sweep:-$(command -v pneu-sweep || true)}
[ -x "$sweep" ] || { echo "slurm-sweep.sh: no pneu-sweep binary (--sweep PATH)" >&2; exit 2; }
sweep=$(realpath "$sweep")
[[ $cpus =~ ^[1-9][0-9]*$ ]] || { echo "slurm-sweep.sh: --cpus-per-task must be a whole number >= 1" >&2; exit 2; }

# The sweep's number of scenarios, as pneu-sweep reads it (default 200).
steps=200
for ((i = 0; i < ${#options[@]}; ++i)); do
  case ${options[i]} in
    --steps) steps=${options[i + 1]} ;;
    --steps=*) steps=${options[i]#--steps=} ;;
    --shard|--shard=*|--out|--out=*|--jobs|--jobs=*)
      echo "slurm-sweep.sh: ${options[i]} is set per shard by this script" >&2; exit 2 ;;
  esac
done
if [ -z "$shards" ]; then
  [ -n "$minutes" ] && [ -n "$cpu_s" ] || { echo "slurm-sweep.sh: give --shards N, or --shard-minutes and --scenario-cpu-s" >&2; exit 2; }
  shards=$(awk -v n="$steps" -v s="$cpu_s" -v m="$minutes" -v c="$cpus" \
    'BEGIN { k = n * s / (60 * m * c); k = (k == int(k)) ? k : int(k) + 1; if (k < 1) k = 1; if (k > n) k = n; print k }')
  time_min=${time_min:-$(awk -v m="$minutes" 'BEGIN { printf "%d", 3 * m + 5 }')}
fi
time_min=${time_min:-60}
[[ $shards =~ ^[1-9][0-9]*$ ]] || { echo "slurm-sweep.sh: --shards must be a whole number >= 1" >&2; exit 2; }

mkdir -p "$dir"
dir=$(realpath "$dir")
quoted_options=$(printf ' %q' "${options[@]}")
header() {  # header JOB-NAME OUTPUT
  echo "#!/bin/bash"
  echo "#SBATCH --job-name=$1"
  echo "#SBATCH --output=$2"
  echo "#SBATCH --ntasks=1"
  echo "#SBATCH --cpus-per-task=$cpus"
  echo "#SBATCH --time=$time_min"
  [ -z "$partition" ] || echo "#SBATCH --partition=$partition"
  echo "set -euo pipefail"
}
{
  header pneu-sweep-shard "$dir/shard-%a.log"
  echo "# Shard K of $shards (K: the array index) of: pneu-sweep$quoted_options"
  echo "k=\$SLURM_ARRAY_TASK_ID"
  echo "exec $(printf '%q' "$sweep")$quoted_options --shard \"\$k/$shards\" --jobs $cpus --out $(printf '%q' "$dir")/shard-\$k.csv"
} > "$dir/shard.sbatch"
{
  header pneu-sweep-merge "$dir/merge.log"
  echo "# The $shards shards merged into the sweep's files."
  printf 'exec %q merge --out %q --scenarios-out %q --summary-json %q' "$sweep" "$dir/sweep.csv" "$dir/scenarios.csv" \
    "$dir/summary.json"
  for k in $(seq "$shards"); do printf ' %q' "$dir/shard-$k.csv"; done
  printf ' > %q\n' "$dir/summary.txt"
} > "$dir/merge.sbatch"

array=$(sbatch --parsable "${extra[@]}" --array="1-$shards" "$dir/shard.sbatch")
array=${array%%;*}
echo "slurm-sweep.sh: $steps scenarios in $shards shards (${cpus} cores each, ${time_min} min limit): job array $array"
echo "slurm-sweep.sh: the merge waits for every shard (afterok:$array); the sweep lands in $dir"
set +e
merge=$(sbatch --parsable "${wait_flag[@]}" "${extra[@]}" --dependency="afterok:$array" --kill-on-invalid-dep=yes \
  "$dir/merge.sbatch")
status=$?
set -e
echo "slurm-sweep.sh: merge job ${merge%%;*}"
exit $status
