#!/usr/bin/env bash
# Slurm's own cost per task: the single-host Slurm 22.05 of tests/test_cluster_slurm.sh (munged,
# slurmctld and slurmd on 127.0.0.1, brought up in a temporary directory and stopped by PID), the
# test's 200-step sweep through it as 4 shards and a merge, then RUNS (default 5) pipelines of 4
# empty tasks and their dependent merge, each timed from submission to its end; the median run
# over its 5 tasks is the overhead per task. Root only (SlurmUser=root), as the test.
#
#   bench/slurm_overhead.sh [BUILD_DIR] [RUNS]        (BUILD_DIR defaults to build)
set -euo pipefail
here=$(cd "$(dirname "$0")/.." && pwd)
build=$(cd "${1:-$here/build}" && pwd)
runs=${2:-5}
[[ $runs =~ ^[1-9][0-9]*$ ]] || { echo "usage: $0 [BUILD_DIR] [RUNS >= 1]" >&2; exit 2; }
exec bash "$here/tests/test_cluster_slurm.sh" "$build" "$here" "$runs"
