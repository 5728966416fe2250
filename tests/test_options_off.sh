#!/usr/bin/env bash
# Every build option off at once (PNEU_WITH_MODBUS, PNEU_WITH_GPIOD, PNEU_WITH_LCM,
# PNEU_WITH_LCM_JAVA, PNEU_WITH_DASH, PNEU_BUILD_TESTS, PNEU_BUILD_BENCHMARKS): the project configures and builds
# into BINARY_DIR/options-off with the generator, compiler, launcher, build type and warnings of
# BINARY_DIR; the binaries run, and what the build left out is refused saying so (pneu-plant serve,
# pneud on the modbus backend, with GPIO lines, with --require-telemetry), nothing driven.
# Every library and program is built and linked there; an object whose compile is word for word
# BINARY_DIR's, reading the same files, is copied from BINARY_DIR instead of compiled a second time
# (tests/reuse_identical_objects.py says when exactly; the build log names each object compiled and
# why). PNEU_OPTIONS_OFF_COMPILE_ALL=1 compiles every object again.
# Usage: test_options_off.sh SOURCE_DIR BINARY_DIR CXX BUILD_TYPE WERROR GENERATOR [LAUNCHER]
set -euo pipefail
src=$1
out=$2/options-off
fail() { echo "FAIL: $*"; exit 1; }

options=(-DPNEU_WITH_MODBUS=OFF -DPNEU_WITH_GPIOD=OFF -DPNEU_WITH_LCM=OFF -DPNEU_WITH_LCM_JAVA=OFF -DPNEU_WITH_DASH=OFF
         -DPNEU_BUILD_TESTS=OFF -DPNEU_BUILD_BENCHMARKS=OFF)
same=(-G "$6" -DCMAKE_CXX_COMPILER="$3" -DCMAKE_BUILD_TYPE="$4" -DPNEU_WERROR="$5")
launcher=${7:-}
if [ "${PNEU_OPTIONS_OFF_COMPILE_ALL:-0}" != 1 ]; then
  launcher="/usr/bin/python3;$src/tests/reuse_identical_objects.py;$2;$out${launcher:+;$launcher};--"
fi
[ -n "$launcher" ] && same+=(-DCMAKE_CXX_COMPILER_LAUNCHER="$launcher")
echo "== configure: ${options[*]}"
cmake -S "$src" -B "$out" "${same[@]}" "${options[@]}" >/dev/null || fail "configuring with every option off"
# On every core: in the suite it runs beside a real-clock test, which mostly waits.
echo "== build ($(nproc) jobs)"
start=$(date +%s)
rm -f "$out/objects.log"
cmake --build "$out" -j "$(nproc)" >"$out/build.log" 2>&1 || { tail -40 "$out/build.log"; fail "building with every option off"; }
echo "built in $(($(date +%s) - start)) s"
if [ -f "$out/objects.log" ]; then
  echo "objects compiled: $(grep -c '^compiled' "$out/objects.log"), copied from $2 (the same compile): $(grep -c '^reused' "$out/objects.log")"
  grep '^compiled' "$out/objects.log" | cut -c1-300 || true
fi

bin=$out/bin
for b in pneud pneu-plant pneu-sweep; do [ -x "$bin/$b" ] || fail "$b was not built"; done
for b in pneu-command pneu-log2csv pneu-dash bench_controller bare_loop test_controller; do
  [ ! -e "$bin/$b" ] || fail "$b was built with its option off"
done

tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
# Refused: exit code 2, the message on stderr, no output file.
expect_refused() {  # MESSAGE COMMAND...
  local message=$1 code=0
  shift
  (cd "$tmp" && "$@" >"$tmp/out" 2>"$tmp/err") || code=$?
  [ "$code" = 2 ] || fail "$* exited with $code, not 2: $(cat "$tmp/err")"
  grep -qF -- "$message" "$tmp/err" || fail "$*: expected '$message' on stderr, got: $(cat "$tmp/err")"
  [ ! -e "$tmp/events.jsonl" ] || fail "$* left an events file behind"
  echo "ok: refused: $(cat "$tmp/err")"
}
expect_refused "serve: this pneu-plant was built without libmodbus" \
  "$bin/pneu-plant" serve --config "$src/config/hil.yaml" --duration 0.1
expect_refused "hal.backend: this pneud was built without the modbus backend" \
  "$bin/pneud" --config "$src/config/hil.yaml" --duration 0.1 --events events.jsonl
expect_refused "hal.gpio.enabled: this pneud was built without libgpiod" \
  "$bin/pneud" --config "$src/config/bench.yaml" --set hal.backend=sim --duration 0.1 --events events.jsonl
expect_refused "--require-telemetry: this pneud was built without LCM" \
  "$bin/pneud" --clock real --duration 0.1 --require-telemetry --events events.jsonl

# What it has runs: the paper scenario on the simulated clock, the plant, a short sweep; on the
# real clock, with telemetry configured, it says telemetry is off.
"$bin/pneud" --quiet --events "$tmp/events.jsonl" || fail "pneud on the sim backend"
grep -q '"event":"stop"' "$tmp/events.jsonl" || fail "pneud's paper run recorded no stop"
"$bin/pneud" --clock real --duration 0.1 --quiet 2>"$tmp/err" || fail "pneud on the real clock: $(cat "$tmp/err")"
grep -qF "warning: telemetry off: this pneud was built without LCM" "$tmp/err" ||
  fail "pneud on the real clock did not say telemetry is off: $(cat "$tmp/err")"
"$bin/pneu-plant" null-flow --out "$tmp/null.csv" || fail "pneu-plant null-flow"
"$bin/pneu-sweep" --steps 2 --quiet --out "$tmp/sweep.csv" || fail "pneu-sweep"
echo "PASS"
