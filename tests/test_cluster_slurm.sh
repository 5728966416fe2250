#!/usr/bin/env bash
# A real Slurm (Debian 12's slurm-wlm 22.05) brought up by this test on this host alone, without
# systemd: munged with a key of its own, slurmctld and slurmd on 127.0.0.1 and free ports, every
# file in a temporary directory, each daemon started here and stopped by its PID. Through it,
# tools/cluster/slurm-sweep.sh runs the 200-step sweep as a job array of 4 shards and a dependent
# merge job; the merged files must equal the unsharded sweep's byte for byte, its summary line for
# line (issue 33). Prints the sweep's wall time from submission to the merge's end. With
# EMPTY_PIPELINES > 0 (bench/slurm_overhead.sh; timing belongs in benchmarks, not in ctest) it then
# times Slurm's own cost: that many runs of the same pipeline with empty tasks, from submission to
# its end, and the median run per task.
# Skips (77), saying why, only when the daemons are not installed or munged cannot start here.
#   test_cluster_slurm.sh BINARY_DIR SOURCE_DIR [EMPTY_PIPELINES]   (default 0)
set -euo pipefail
bin=$1/bin
src=$2
empty_pipelines=${3:-0}
[[ $empty_pipelines =~ ^[0-9]+$ ]] || { echo "usage: $0 BINARY_DIR SOURCE_DIR [EMPTY_PIPELINES]" >&2; exit 2; }
fail() { echo "FAIL: $*"; exit 1; }
skip() { echo "SKIP: $*"; exit 77; }
for tool in munged munge unmunge slurmctld slurmd sbatch squeue sinfo scontrol setpriv; do
  command -v "$tool" > /dev/null || skip "$tool is not installed (scripts/deps installs slurm-wlm and munge)"
done
[ "$(id -u)" = 0 ] || skip "a single-host Slurm with SlurmUser=root needs root (this runs as $(id -un))"

tmp=$(mktemp -d /tmp/pneu-slurm.XXXXXX)
chmod 700 "$tmp"
pids=()
cleanup() {
  # The jobs' step daemons (slurmstepd) first end, reporting to slurmd: each has a socket in the
  # spool directory while it lives (10 s at most). Then every daemon this test started, by its
  # PID, slurmd and slurmctld before munged; then the directory.
  for _ in $(seq 100); do
    [ -z "$(find "$tmp/spool" -type s 2> /dev/null)" ] && break
    sleep 0.1
  done
  for ((i = ${#pids[@]} - 1; i >= 0; --i)); do kill "${pids[i]}" 2> /dev/null || true; done
  for pid in "${pids[@]}"; do
    for _ in $(seq 50); do kill -0 "$pid" 2> /dev/null || break; sleep 0.1; done
    kill -9 "$pid" 2> /dev/null || true
  done
  # Whatever is left of this Slurm (a step daemon still ending) has this test's SLURM_CONF in its
  # environment: given 5 s to end, then ended by its PID.
  # (Unset here first: the commands this loop runs must not carry it.)
  local conf=$tmp/slurm.conf ours=() environ
  unset SLURM_CONF
  for _ in $(seq 50); do
    ours=()
    for environ in /proc/[0-9]*/environ; do
      grep -qzx "SLURM_CONF=$conf" "$environ" 2> /dev/null && { environ=${environ%/environ}; ours+=("${environ#/proc/}"); }
    done
    [ ${#ours[@]} = 0 ] && break
    sleep 0.1
  done
  [ ${#ours[@]} = 0 ] || kill -9 "${ours[@]}" 2> /dev/null || true
  rm -rf "$tmp"
}
trap cleanup EXIT
logs() { for f in "$tmp"/log/*; do echo "---- $f"; tail -n 20 "$f"; done; }

mkdir -p "$tmp/munge" "$tmp/log" "$tmp/state" "$tmp/spool" "$tmp/run"
chmod 700 "$tmp/munge"
echo "== munged, with a key of its own"
head -c 1024 /dev/urandom > "$tmp/munge/munge.key"
chmod 400 "$tmp/munge/munge.key"
socket=$tmp/munge/munge.socket
# Each daemon in the foreground, a child of this script that dies with it (--pdeathsig: should
# ctest kill the script on a timeout, no daemon is left behind).
daemon() { setpriv --pdeathsig TERM "$@" & pids+=($!); }
daemon munged --foreground --force --key-file="$tmp/munge/munge.key" --socket="$socket" \
  --pid-file="$tmp/munge/munged.pid" --seed-file="$tmp/munge/munged.seed" --log-file="$tmp/log/munged.log" \
  > "$tmp/log/munged.out" 2>&1
for _ in $(seq 100); do
  [ -S "$socket" ] && break
  kill -0 "${pids[0]}" 2> /dev/null \
    || skip "munged cannot start here: $(cat "$tmp/log/munged.out" "$tmp/log/munged.log" 2> /dev/null | tail -n 3)"
  sleep 0.1
done
munge -S "$socket" -n | unmunge -S "$socket" > /dev/null \
  || skip "munged cannot encode and decode a credential here: $(tail -n 3 "$tmp/log/munged.log" "$tmp/log/munged.out")"

# Two free TCP ports on 127.0.0.1; slurmctld's host is this host's short name (slurmctld checks
# it), reached at 127.0.0.1: no name resolution needed.
read -r ctld_port slurmd_port < <(/usr/bin/python3 -c '
import socket
s = [socket.socket() for _ in range(2)]
for x in s: x.bind(("127.0.0.1", 0))
print(*[x.getsockname()[1] for x in s])')
host=$(hostname -s)
node=pneunode
export SLURM_CONF=$tmp/slurm.conf
cat > "$SLURM_CONF" <<EOF
ClusterName=pneutest
SlurmctldHost=$host(127.0.0.1)
SlurmctldPort=$ctld_port
SlurmdPort=$slurmd_port
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
CredType=cred/munge
AuthInfo=socket=$socket
StateSaveLocation=$tmp/state
SlurmdSpoolDir=$tmp/spool
SlurmctldPidFile=$tmp/slurmctld.pid
SlurmdPidFile=$tmp/slurmd.pid
SlurmctldLogFile=$tmp/log/slurmctld.log
SlurmdLogFile=$tmp/log/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
MpiDefault=none
ReturnToService=2
SchedulerType=sched/builtin
MinJobAge=600
NodeName=$node NodeAddr=127.0.0.1 NodeHostname=$host CPUs=$(nproc) State=UNKNOWN
PartitionName=pneu Nodes=$node Default=YES MaxTime=60 State=UP
EOF
echo "== slurmctld and slurmd (node $node at 127.0.0.1, controller $host at 127.0.0.1:$ctld_port)"
daemon slurmctld -D -i -f "$SLURM_CONF" > "$tmp/log/slurmctld.out" 2>&1
daemon slurmd -D -f "$SLURM_CONF" -N "$node" > "$tmp/log/slurmd.out" 2>&1
up=0
for _ in $(seq 300); do
  if [ "$(sinfo -h -n "$node" -o %t 2> /dev/null)" = idle ]; then up=1; break; fi
  for pid in "${pids[@]}"; do kill -0 "$pid" 2> /dev/null || { logs; fail "a Slurm daemon ended while starting"; }; done
  sleep 0.1
done
[ "$up" = 1 ] || { logs; fail "the node is not idle within 30 s: $(sinfo 2>&1)"; }
sinfo

# wait_for JOB: until Slurm has ended the job (polled every 0.1 s; MinJobAge keeps its record),
# then its state.
wait_for() {
  local state
  for _ in $(seq 6000); do
    state=$(scontrol show job -o "$1" 2> /dev/null | grep -o 'JobState=[A-Z_]*' | head -n 1 | cut -d= -f2)
    case $state in PENDING|RUNNING|CONFIGURING|COMPLETING|"") sleep 0.1 ;; *) echo "$state"; return ;; esac
  done
  echo TIMEOUT
}

echo "== the 200-step sweep: 4 shards and the merge through Slurm"
submitted=$(date +%s.%N)
"$src/tools/cluster/slurm-sweep.sh" --dir "$tmp/run" --shards 4 --partition pneu --time 10 --cpus-per-task 1 \
  --sweep "$bin/pneu-sweep" -- --steps 200 > "$tmp/submit.txt" 2>&1 || { cat "$tmp/submit.txt"; logs; fail "the submission failed"; }
cat "$tmp/submit.txt"
merge_job=$(sed -n 's/^slurm-sweep.sh: merge job \([0-9]*\)$/\1/p' "$tmp/submit.txt")
[ -n "$merge_job" ] || fail "the script names the merge job"
state=$(wait_for "$merge_job")
ended=$(date +%s.%N)
[ "$state" = COMPLETED ] || { logs; tail -n 5 "$tmp"/run/*.log; fail "the merge job ended $state"; }
cat "$tmp/run/merge.log"
for k in 1 2 3 4; do
  grep -q "^pneu-sweep shard $k/4: 50/50 scenarios" "$tmp/run/shard-$k.log" || fail "shard $k/4's log shows its progress to the end"
done

echo "== the same sweep unsharded"
"$bin/pneu-sweep" --steps 200 --quiet --out "$tmp/whole.csv" --scenarios-out "$tmp/whole_scenarios.csv" > "$tmp/whole.txt"
cmp "$tmp/whole.csv" "$tmp/run/sweep.csv" || fail "the merged stops file differs from the unsharded sweep's"
cmp "$tmp/whole_scenarios.csv" "$tmp/run/scenarios.csv" || fail "the merged scenarios file differs"
summary_lines() { grep -v -e '^  [0-9.]* s wall ' -e '^  wrote ' "$1"; }
diff <(summary_lines "$tmp/whole.txt") <(summary_lines "$tmp/run/summary.txt") || fail "the merged summary differs"
[ "$(grep -c '^pneu-sweep merge: took shard ' "$tmp/run/merge.log")" = 4 ] || fail "the merge names the 4 shards it took"

# What Slurm costs: the sweep's wall from submission to the merge's end against the work its
# shards did.
work=$(awk '/ s wall on / { s += $1 } END { printf "%.2f", s }' "$tmp"/run/shard-*.log)
awk -v s="$submitted" -v e="$ended" -v w="$work" 'BEGIN {
  printf "slurm: the 200-step sweep in 4 shards and the merge: %.1f s from submission to the merge'"'"'s end; the shards'"'"' own work %.2f s (summed, on 2 cores)\n", e - s, w }'
# And, asked for (bench/slurm_overhead.sh), the same pipeline with no work (4 empty tasks and their
# dependent merge): Slurm's own cost alone.
if [ "$empty_pipelines" -gt 0 ]; then
  echo "== Slurm's overhead"
  empties=()
  for ((run = 1; run <= empty_pipelines; ++run)); do
    t0=$(date +%s.%N)
    array=$(sbatch --parsable --array=1-4 --output=/dev/null --wrap true)
    merge=$(sbatch --parsable --dependency="afterok:$array" --output=/dev/null --wrap true)
    [ "$(wait_for "$merge")" = COMPLETED ] || fail "an empty pipeline's merge did not complete"
    empties+=("$(awk -v s="$t0" -v e="$(date +%s.%N)" 'BEGIN { printf "%.2f", e - s }')")
  done
  echo "slurm: 4 empty tasks and their dependent merge, from submission to the end, $empty_pipelines runs: ${empties[*]} s"
  median=$(printf '%s\n' "${empties[@]}" | sort -n | sed -n "$(( (empty_pipelines + 1) / 2 ))p")
  awk -v m="$median" 'BEGIN { printf "slurm: overhead per task: %.2f s (the median run, %.2f s, over its 5 tasks, on 2 cores)\n", m / 5, m }'
fi
echo "ok: 4 shards and the merge through Slurm equal the unsharded 200-step sweep"
