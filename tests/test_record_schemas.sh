#!/usr/bin/env bash
# What real runs write follows the JSON Schemas the build installs (share/pneu/schemas, written by
# pneu-records from the records' descriptions): every line of pneud's events file and its summary
# (--summary-json), on the simulated bench with its designed law, with the paper's gains, with the
# in-position hold, and with a settling rule that latches a fault.
#   test_record_schemas.sh SOURCE_DIR BINARY_DIR
set -euo pipefail
src=$1 bin=$2
schemas=$bin/share/pneu/schemas
work=$(mktemp -d); trap 'rm -rf "$work"' EXIT
fail=0
# validate SCHEMA FILE WHAT [document]: each line of FILE (a JSON lines file), or FILE whole (a
# JSON document), against SCHEMA.
validate() {
  if /usr/bin/python3 - "$1" "$2" "${4:-lines}" > "$work/out" 2>&1 <<'PY'
import json, sys, jsonschema
schema = json.load(open(sys.argv[1]))
jsonschema.Draft202012Validator.check_schema(schema)
v = jsonschema.Draft202012Validator(schema)
if sys.argv[3] == "document": lines = [json.load(open(sys.argv[2]))]
else: lines = [json.loads(l) for l in open(sys.argv[2])]
refused = [(i + 1, e.message) for i, o in enumerate(lines) for e in list(v.iter_errors(o))[:1]]
for i, m in refused[:5]: print(f"line {i}: {m[:300]}")
print(f"{len(lines)} lines, {len(refused)} refused")
sys.exit(1 if refused or not lines else 0)
PY
  then echo "ok: $3: $(tail -1 "$work/out")"
  else echo "FAIL: $3 against $(basename "$1"):"; cat "$work/out"; fail=1; fi
}
run() {  # NAME pneud-arguments...
  local name=$1; shift
  "$bin/bin/pneud" --quiet --clock simulated --events "$work/$name.jsonl" --summary-json "$work/$name.json" "$@" || true
  validate "$schemas/events.schema.json" "$work/$name.jsonl" "pneud's events ($name)"
  validate "$schemas/summary.schema.json" "$work/$name.json" "pneud's summary ($name)" document
}
run sim
run paper --config "$src/config/paper.yaml"
run hold --set controller.hold.enabled=true
run fault --set controller.supervisor.settle_time_s=0.2
grep -q '"key": "controller.supervisor.settle_time_s"' "$work/fault.json" || { echo "FAIL: the fault run's summary names no fault with its key"; fail=1; }
exit $fail
