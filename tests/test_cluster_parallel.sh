#!/usr/bin/env bash
# tools/cluster/parallel-sweep.sh (issue 33): GNU parallel runs the 200-step sweep's 5 shards on
# this machine's cores (and, given through --sshlogin ":", GNU parallel's name for this machine,
# the same way it takes ssh hosts), then merges them: the merged files equal the unsharded sweep's
# byte for byte, its summary line for line. A failed shard stops the run, saying so, and
# --resume-failed runs only the shards that did not succeed, then merges.
#   test_cluster_parallel.sh BINARY_DIR SOURCE_DIR
set -euo pipefail
bin=$1/bin
src=$2
fail() { echo "FAIL: $*"; exit 1; }
parallel --version 2> /dev/null | grep -q 'GNU parallel' || fail "GNU parallel is not installed (scripts/deps installs parallel)"
tmp=$(mktemp -d); trap 'rm -rf "$tmp"' EXIT
summary_lines() { grep -v -e '^  [0-9.]* s wall ' -e '^  wrote ' "$1"; }

"$bin/pneu-sweep" --steps 200 --quiet --out "$tmp/whole.csv" --scenarios-out "$tmp/whole_scenarios.csv" > "$tmp/whole.txt"
for hosts in local ssh-login; do
  echo "== 5 shards through GNU parallel ($hosts)"
  login=()
  [ "$hosts" = local ] || login=(--sshlogin :)
  "$src/tools/cluster/parallel-sweep.sh" --dir "$tmp/$hosts" --shards 5 "${login[@]}" --sweep "$bin/pneu-sweep" \
    -- --steps 200 > "$tmp/$hosts.txt" || fail "$hosts: parallel-sweep.sh failed"
  cmp "$tmp/whole.csv" "$tmp/$hosts/sweep.csv" || fail "$hosts: the merged stops file differs from the unsharded sweep's"
  cmp "$tmp/whole_scenarios.csv" "$tmp/$hosts/scenarios.csv" || fail "$hosts: the merged scenarios file differs"
  diff <(summary_lines "$tmp/whole.txt") <(summary_lines "$tmp/$hosts/summary.txt") || fail "$hosts: the merged summary differs"
  [ "$(awk 'NR > 1 && $7 == 0' "$tmp/$hosts/parallel.joblog" | wc -l)" = 5 ] || fail "$hosts: GNU parallel's job log has 5 shards done"
done

echo "== a failing shard, then --resume-failed"
# A pneu-sweep that fails on shard 3 until $tmp/fixed exists (a node lost, a time limit hit).
cat > "$tmp/flaky-sweep" <<EOF
#!/usr/bin/env bash
for a in "\$@"; do [ "\$a" = 3/5 ] && [ ! -e "$tmp/fixed" ] && { echo "flaky-sweep: shard 3 fails this time" >&2; exit 1; }; done
exec "$bin/pneu-sweep" "\$@"
EOF
chmod +x "$tmp/flaky-sweep"
status=0
"$src/tools/cluster/parallel-sweep.sh" --dir "$tmp/flaky" --shards 5 --sweep "$tmp/flaky-sweep" -- --steps 200 \
  > "$tmp/flaky.txt" 2> "$tmp/flaky.err" || status=$?
cat "$tmp/flaky.err"
[ "$status" = 1 ] || fail "a failed shard fails the run (got $status)"
grep -q 'run the same command again with --resume-failed' "$tmp/flaky.err" || fail "it says how to run again"
[ ! -e "$tmp/flaky/sweep.csv" ] || fail "nothing is merged when a shard failed"
grep -q 'shard 3 fails this time' "$tmp/flaky/shard-3.log" || fail "the shard's log says why"
before=$(stat -c %Y "$tmp/flaky/shard-1.csv.shard")
touch "$tmp/fixed"
sleep 1
"$src/tools/cluster/parallel-sweep.sh" --dir "$tmp/flaky" --shards 5 --sweep "$tmp/flaky-sweep" --resume-failed \
  -- --steps 200 > "$tmp/resumed.txt" || fail "--resume-failed failed"
[ "$(stat -c %Y "$tmp/flaky/shard-1.csv.shard")" = "$before" ] || fail "--resume-failed does not run shard 1 again"
cmp "$tmp/whole.csv" "$tmp/flaky/sweep.csv" || fail "resumed: the merged stops file differs"
echo "ok: GNU parallel's shards merged equal the unsharded 200-step sweep; a failed shard is run again alone"
