#!/usr/bin/env bash
# Builds the libFuzzer targets of fuzz/ with clang and runs each over a COPY of its corpus (the
# repository's corpus is never written to), after replaying fuzz/regressions/: for a bounded time,
# or for a fixed number of inputs.
#
#   fuzz/run.sh SECONDS_PER_TARGET [BUILD_DIR]                  (BUILD_DIR defaults to build/fuzz)
#   fuzz/run.sh --runs CONFIG_INPUTS COMMAND_INPUTS [BUILD_DIR]
#
# With --runs (what ctest runs), each target is given that many inputs from seed PNEU_FUZZ_SEED
# (default 1) with address-space randomisation off (setarch -R): the same work whatever else
# loads the machine, and the same inputs when run again from the same environment (the config
# loader compares stack addresses, which move with the environment's size); another seed
# explores others.
#
# Exit status: 0 when nothing was found; 1 on any crash, sanitizer report, leak, timeout, out of
# memory or contract violation (the input is left in BUILD_DIR/run/<target>/artifacts/ and named
# in the output); 77 when clang, libFuzzer or lcm-gen is not available (the reason is printed).
# Environment: PNEU_FUZZ_CXX picks the clang++ to use; PNEU_FUZZ_TIMEOUT_S (default 10) is the
# time one input may take before it counts as a hang.
set -uo pipefail

usage() { echo "usage: $0 SECONDS_PER_TARGET [BUILD_DIR] | --runs CONFIG_INPUTS COMMAND_INPUTS [BUILD_DIR]" >&2; exit 2; }
count() { [[ $1 =~ ^[0-9]+$ ]] && [ "$1" -ge 1 ] || usage; }
seconds='' runs_config='' runs_command=''
if [ "${1:-}" = --runs ]; then
  [ $# -ge 3 ] && [ $# -le 4 ] || usage
  count "$2" && count "$3"
  runs_config=$2 runs_command=$3
  shift 3
else
  [ $# -ge 1 ] && [ $# -le 2 ] || usage
  count "$1"
  seconds=$1
  shift
fi
seed=${PNEU_FUZZ_SEED:-1}
count "$seed"
here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
build=${1:-$here/../build/fuzz}
timeout_s=${PNEU_FUZZ_TIMEOUT_S:-10}

skip() { echo "fuzz/run.sh: SKIPPED: $*" >&2; exit 77; }
fail() { echo "fuzz/run.sh: FAILED: $*" >&2; exit 1; }

# --- what it needs, or a clear skip ---------------------------------------------------------------
cxx=${PNEU_FUZZ_CXX:-}
if [ -z "$cxx" ]; then
  for c in clang++ clang++-14 clang++-15 clang++-16 clang++-17 clang++-18 clang++-19; do
    if command -v "$c" >/dev/null 2>&1; then cxx=$(command -v "$c"); break; fi
  done
fi
[ -n "$cxx" ] && command -v "$cxx" >/dev/null 2>&1 || skip "clang++ not found (Debian: apt-get install clang libclang-rt-14-dev, or set PNEU_FUZZ_CXX)"
command -v cmake >/dev/null 2>&1 || skip "cmake not found"
command -v lcm-gen >/dev/null 2>&1 || skip "lcm-gen not found (Debian: liblcm-bin), needed for the command decoder's types"
probe_dir=$(mktemp -d)
trap 'rm -rf "$probe_dir"' EXIT
echo 'extern "C" int LLVMFuzzerTestOneInput(const unsigned char*, unsigned long) { return 0; }' > "$probe_dir/probe.cpp"
if ! "$cxx" -fsanitize=fuzzer,address,undefined "$probe_dir/probe.cpp" -o "$probe_dir/probe" > "$probe_dir/probe.log" 2>&1; then
  sed 's/^/  /' "$probe_dir/probe.log" >&2
  skip "$cxx cannot link -fsanitize=fuzzer,address,undefined: libFuzzer or the sanitizer runtimes are missing (Debian: libclang-rt-14-dev)"
fi

# --- build ----------------------------------------------------------------------------------------
generator=()
command -v ninja >/dev/null 2>&1 && [ ! -f "$build/CMakeCache.txt" ] && generator=(-G Ninja)
jobs=$(nproc 2>/dev/null || echo 2)
start=$(date +%s)
mkdir -p "$build" || fail "cannot create $build"
cmake -S "$here" -B "$build" "${generator[@]}" -DCMAKE_CXX_COMPILER="$cxx" -DCMAKE_BUILD_TYPE=RelWithDebInfo > "$build/configure.log" 2>&1 \
  || { cat "$build/configure.log" >&2; fail "configuring the fuzz project in $build"; }
cmake --build "$build" -j "$jobs" || fail "building the fuzz targets in $build"
echo "fuzz/run.sh: built in $(( $(date +%s) - start )) s with $cxx"

# --- run ------------------------------------------------------------------------------------------
export UBSAN_OPTIONS=${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}
export ASAN_OPTIONS=${ASAN_OPTIONS:-detect_leaks=1}
failures=()

# run_target NAME CORPUS_DIR MAX_LEN INPUTS (INPUTS: with --runs)
run_target() {
  local name=$1 corpus=$2 max_len=$3 inputs=$4
  local exe=$build/pneu_fuzz_$name work=$build/run/$name
  rm -rf "$work" && mkdir -p "$work/corpus" "$work/artifacts" || { failures+=("$name: cannot prepare $work"); return; }
  cp -R "$here/corpus/$corpus/." "$work/corpus/"
  # The shipped configurations as they are now (the committed copies may lag behind the schema).
  [ "$name" = config ] && cp "$here"/../config/*.yaml "$work/corpus/"
  # libFuzzer exits 77 on a crash by default: that is ctest's skip code, so every failure is 1.
  local common=(-error_exitcode=1 -timeout_exitcode=1 -timeout="$timeout_s" -rss_limit_mb=2048
                -max_len="$max_len" -artifact_prefix="$work/artifacts/")
  [ -f "$here/$corpus.dict" ] && common+=(-dict="$here/$corpus.dict")

  # Known crashers first, one by one: deterministic, whatever the fuzzing below happens to find.
  local regressions=()
  if [ -d "$here/regressions/$corpus" ]; then
    while IFS= read -r -d '' f; do regressions+=("$f"); done < <(find "$here/regressions/$corpus" -type f -print0 | sort -z)
  fi
  if [ ${#regressions[@]} -gt 0 ]; then
    if ! "$exe" "${common[@]}" "${regressions[@]}" > "$work/regressions.log" 2>&1; then
      tail -n 60 "$work/regressions.log" >&2
      failures+=("$name: a regression input of fuzz/regressions/$corpus/ fails (log: $work/regressions.log)")
    else
      echo "fuzz/run.sh: $name: ${#regressions[@]} regression input(s) pass"
    fi
  fi

  local bound=(-max_total_time="$seconds") fixed=()
  if [ -z "$seconds" ]; then
    bound=(-runs="$inputs" -seed="$seed")
    # Without address-space randomisation the same seed gives the same inputs in the same
    # environment (comparisons of addresses steer the mutations); where setarch cannot, the count
    # is still fixed.
    setarch "$(uname -m)" -R true 2>/dev/null && fixed=(setarch "$(uname -m)" -R)
    echo "fuzz/run.sh: $name: fuzzing $inputs inputs from seed $seed${fixed[*]:+ (setarch -R)} over a copy of fuzz/corpus/$corpus/"
  else
    echo "fuzz/run.sh: $name: fuzzing for $seconds s over a copy of fuzz/corpus/$corpus/"
  fi
  "${fixed[@]}" "$exe" "${common[@]}" "${bound[@]}" -print_final_stats=1 "$work/corpus" > "$work/fuzz.log" 2>&1
  local rc=$?
  grep -E '^#[0-9]+[[:space:]]+(INITED|DONE)' "$work/fuzz.log" | sed "s/^/fuzz\/run.sh: $name: /"
  grep -E '^stat::(number_of_executed_units|average_exec_per_sec|peak_rss_mb)' "$work/fuzz.log" | sed "s/^/fuzz\/run.sh: $name: /"
  if [ $rc -ne 0 ]; then
    tail -n 80 "$work/fuzz.log" >&2
    local found
    found=$(find "$work/artifacts" -type f | head -n 5 | tr '\n' ' ')
    failures+=("$name: libFuzzer exited $rc; input: ${found:-none written} (log: $work/fuzz.log)")
  fi
}

run_target config config 16384 "$runs_config"
run_target command command 512 "$runs_command"

if [ ${#failures[@]} -gt 0 ]; then
  for f in "${failures[@]}"; do echo "fuzz/run.sh: FAILED: $f" >&2; done
  exit 1
fi
if [ -n "$seconds" ]; then
  echo "fuzz/run.sh: no finding in $seconds s per target"
else
  echo "fuzz/run.sh: no finding in $runs_config config and $runs_command command inputs"
fi
exit 0
