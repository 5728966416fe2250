#!/usr/bin/env bash
# The systemd units of systemd/: `systemd-analyze verify` accepts them without a single warning,
# pneud's (and pneu-dash's) command line in the unit is one the freshly built program accepts with the example bench
# configuration, the unit lets pneud reach the I/O module of that configuration, and the
# sandbox's exposure (`systemd-analyze security --offline=true`) stays at or below what was
# measured with systemd 252. Exits 77 (ctest: skipped) with a reason without systemd-analyze.
#
# usage: test_systemd_units.sh SOURCE_DIR BIN_DIR
#
# The units name /usr/bin/pneud and /usr/bin/pneu-plant, which do not exist before
# `cmake --install`: verify runs on copies whose ExecStart= points at BIN_DIR instead, so it also
# checks that those binaries are there and executable. verify does not resolve User=/Group=
# (it accepts User=pneu whether the user exists or not), so a missing `pneu` user is only reported.
set -u

# Figures measured with systemd 252 (Debian 12); a newer systemd may score differently.
readonly MAX_EXPOSURE_PNEUD=1.5
readonly MAX_EXPOSURE_PLANT=0.9
readonly MAX_EXPOSURE_DASH=1.0

if [ $# -ne 2 ]; then
  echo "usage: $0 SOURCE_DIR BIN_DIR" >&2
  exit 2
fi
src=$1
bin=$2
units=$src/systemd

if ! command -v systemd-analyze >/dev/null 2>&1; then
  echo "SKIPPED: systemd-analyze is not installed (Debian package systemd); the units are not checked" >&2
  exit 77
fi
if ! systemd-analyze security --help 2>/dev/null | grep -q -- '--offline'; then
  echo "SKIPPED: this systemd-analyze has no 'security --offline' (systemd < 250); the units are not checked" >&2
  exit 77
fi

failures=0
fail() {
  echo "FAIL: $*" >&2
  failures=$((failures + 1))
}

for b in pneud pneu-plant; do
  [ -x "$bin/$b" ] || fail "$bin/$b is missing: build it first"
done
[ "$failures" -eq 0 ] || exit 1
# pneu-dash.service: checked when pneu-dash was built (-DPNEU_WITH_DASH=ON, the default).
unit_list=(pneud.service pneu-plant-hil.service)
if [ -x "$bin/pneu-dash" ]; then
  unit_list+=(pneu-dash.service)
else
  echo "note: $bin/pneu-dash is not built (PNEU_WITH_DASH=OFF): pneu-dash.service is not checked"
fi

work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
chmod 755 "$work"

# 1. verify, on copies pointing at the built binaries; any output at all is a failure (verify
#    exits 0 on unknown keys, unparsable system calls and the like: it only prints them).
for u in "${unit_list[@]}"; do
  grep -q '^ExecStart=/usr/bin/' "$units/$u" || fail "$u: ExecStart= does not start with /usr/bin/"
  sed "s#^ExecStart=/usr/bin/#ExecStart=$bin/#" "$units/$u" >"$work/$u"
  if ! diff -q <(grep -v '^ExecStart=' "$units/$u") <(grep -v '^ExecStart=' "$work/$u") >/dev/null; then
    fail "$u: the copy differs from the unit beyond ExecStart="
  fi
done
out=$(cd "$work" && systemd-analyze verify --man=no "${unit_list[@]/#/./}" 2>&1)
rc=$?
if [ "$rc" -ne 0 ] || [ -n "$out" ]; then
  fail "systemd-analyze verify (exit $rc):"
  printf '%s\n' "$out" >&2
else
  echo "systemd-analyze verify: ${unit_list[*]} accepted, no warning"
fi

# 2. pneud's command line from the unit, with the installed configuration path mapped to the
#    example in the source tree, validated by the built pneud (--check-config opens no device).
cmdline=$(sed -n 's#^ExecStart=/usr/bin/pneud ##p' "$units/pneud.service")
[ -n "$cmdline" ] || fail "pneud.service: no ExecStart=/usr/bin/pneud line"
read -r -a args <<<"${cmdline//\/etc\/pneu\//$src/config/}"
if ! check=$("$bin/pneud" "${args[@]}" --check-config 2>&1); then
  fail "pneud rejects the unit's command line (${args[*]}):"
  printf '%s\n' "$check" | tail -5 >&2
fi

# 3. The I/O module's address of the example bench configuration is let through IPAddressAllow=.
host=$(sed -n 's/^ *host: *\([0-9.]*\).*/\1/p' "$src/config/bench.yaml" | head -1)
if [ -z "$host" ]; then
  fail "config/bench.yaml: no hal.modbus.host address found"
elif ! grep -E '^IPAddressAllow=' "$units/pneud.service" | grep -qw -- "$host"; then
  fail "pneud.service: IPAddressAllow= does not let in the I/O module of config/bench.yaml ($host)"
fi

# 3b. The unit has no supplementary group (exposure): the example bench's module must then be on
#     Modbus TCP; a serial one (rtu) needs `SupplementaryGroups=dialout` for its port.
transport=$(sed -n 's/^ *transport: *\([a-z]*\).*/\1/p' "$src/config/bench.yaml" | head -1)
if [ "$transport" = rtu ] && ! grep -q '^SupplementaryGroups=.*dialout' "$units/pneud.service"; then
  fail "config/bench.yaml speaks Modbus RTU but pneud.service has no SupplementaryGroups=dialout for the serial port"
fi

# 4. Exposure, from the "Overall exposure level for X: N.N ..." line.
exposure_at_most() {  # unit max
  local line level
  line=$(systemd-analyze security --offline=true "$units/$1" 2>&1 | grep 'Overall exposure level')
  level=$(printf '%s\n' "$line" | sed -n 's/.*Overall exposure level for [^:]*: *\([0-9][0-9.]*\).*/\1/p')
  if [ -z "$level" ]; then
    fail "$1: no exposure level in the output of systemd-analyze security"
  elif awk -v l="$level" -v m="$2" 'BEGIN { exit !(l > m) }'; then
    fail "$1: exposure $level is above $2 (systemd-analyze security --offline=true $units/$1)"
  else
    echo "$1: exposure $level (at most $2)"
  fi
}
exposure_at_most pneud.service "$MAX_EXPOSURE_PNEUD"
exposure_at_most pneu-plant-hil.service "$MAX_EXPOSURE_PLANT"
if [ -x "$bin/pneu-dash" ]; then
  exposure_at_most pneu-dash.service "$MAX_EXPOSURE_DASH"
  # Its command line, with the installed configuration mapped to the example, checked by the
  # built pneu-dash (--check-config: the options and the configuration read, nothing served).
  dash_cmd=$(sed -n 's#^ExecStart=/usr/bin/pneu-dash ##p' "$units/pneu-dash.service")
  read -r -a dash_args <<<"${dash_cmd//\/etc\/pneu\//$src/config/}"
  if ! check=$("$bin/pneu-dash" "${dash_args[@]}" --check-config 2>&1); then
    fail "pneu-dash rejects the unit's command line (${dash_args[*]}):"
    printf '%s\n' "$check" | tail -5 >&2
  fi
fi

if ! getent passwd pneu >/dev/null 2>&1; then
  echo "note: no user 'pneu' on this machine; verify does not check User=, but pneud.service would fail to start (status 217/USER) until it is created (systemd/README.md)"
fi

[ "$failures" -eq 0 ] || exit 1
echo "PASSED"
