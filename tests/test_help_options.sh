#!/usr/bin/env bash
# Every pneu program takes -h as --help (the same text, exit 0), and an unknown option's error
# points to the program's --help (exit 2).
#
# usage: test_help_options.sh BIN_DIR
set -u
bin=$1
failures=0
fail() {
  echo "FAIL: $*" >&2
  failures=$((failures + 1))
}
for p in pneud pneu-plant pneu-sweep "pneu-sweep merge" pneu-identify pneu-command pneu-log2csv "pneu-plant simulate" "pneu-plant serve" \
         "pneu-plant tune" "pneu-plant null-flow" "pneu-plant characterize-valve" pneu-dash; do
  read -r -a cmd <<<"$p"
  if [ "$p" = pneu-dash ] && [ ! -e "$bin/pneu-dash" ]; then
    echo "note: pneu-dash is not built (PNEU_WITH_DASH=OFF)"
    continue
  fi
  [ -x "$bin/${cmd[0]}" ] || { fail "$bin/${cmd[0]} is missing: build it first"; continue; }
  cmd[0]=$bin/${cmd[0]}
  short=$("${cmd[@]}" -h 2>&1); short_rc=$?
  long=$("${cmd[@]}" --help 2>&1); long_rc=$?
  if [ "$short_rc" -ne 0 ] || [ "$long_rc" -ne 0 ] || [ "$short" != "$long" ] || [ -z "$long" ]; then
    fail "$p -h (exit $short_rc) is not $p --help (exit $long_rc): $(printf '%s' "$short" | head -2)"
  else
    echo "ok: $p -h is --help"
  fi
  [ "${cmd[0]}" = "$bin/pneu-plant" ] && [ ${#cmd[@]} -eq 1 ] && continue  # its first word is a command
  err=$("${cmd[@]}" --no-such-option 2>&1 >/dev/null); rc=$?
  if [ "$rc" -ne 2 ] || ! grep -qF -- "unknown option --no-such-option (see $p --help)" <<<"$err"; then
    fail "$p --no-such-option: exit $rc, '$err'"
  else
    echo "ok: $p --no-such-option points to $p --help"
  fi
done
[ "$failures" -eq 0 ] || exit 1
echo PASSED
