#!/usr/bin/env bash
# The sweep's throughput, scenarios per core-second, of this tree's build against a baseline's, in
# the same run pair (issue 33's "Throughput": at least 1.5x the baseline's for the default sweep and
# 3x for the identified ones). The baseline (a commit, default `main`) is checked out as a detached
# git worktree under build/bench-base/ and only its pneu-sweep is built there (kept for the next
# run). Each case runs pneu-sweep --jobs 1, the two builds alternating, REPS times each; the figure
# is the median of the CPU times (user + system of the child) of the repetitions.
#   bench/sweep_throughput.sh [BASE_COMMIT [REPS [CASES...]]]
# CASES (default all): default identified identified-hil identified-thermal identified-thermal-hil
# Issue 33's baseline, "today's build" when it was filed, is db797b5 (its thermal cases cannot run there).
# Needs this tree's build/bin/pneu-sweep built (cmake --build build --target pneu-sweep).
# PNEU_BASE_SWEEP=PATH: a pneu-sweep already built at BASE_COMMIT, used in place of building one.
set -euo pipefail
cd "$(dirname "$0")/.."
root=$PWD
base_commit=${1:-main}
reps=${2:-3}
shift $(($# > 2 ? 2 : $#))
base_sha=$(git rev-parse --verify "$base_commit^{commit}")
base=$root/build/bench-base
base_sweep=${PNEU_BASE_SWEEP:-$base/src/build/bin/pneu-sweep}
if [ -n "${PNEU_BASE_SWEEP:-}" ]; then
  :  # a pneu-sweep already built at BASE_COMMIT (say, the main tree's build of it)
elif [ ! -x "$base/src/build/bin/pneu-sweep" ] || [ "$(git -C "$base/src" rev-parse HEAD 2>/dev/null)" != "$base_sha" ]; then
  if [ -d "$base/src" ]; then
    git -C "$base/src" checkout -q --detach "$base_sha"
  else
    mkdir -p "$base"
    git worktree add -q --detach "$base/src" "$base_sha"
  fi
  launcher=()
  command -v ccache >/dev/null && launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache)
  cmake -S "$base/src" -B "$base/src/build" -G Ninja -DCMAKE_BUILD_TYPE=Release "${launcher[@]}" >/dev/null
  cmake --build "$base/src/build" -j2 --target pneu-sweep >/dev/null
fi
[ -x build/bin/pneu-sweep ] || { echo "build this tree's pneu-sweep first (cmake --build build --target pneu-sweep)" >&2; exit 1; }
# The base reads its own tree's configuration files (a key added since would be refused there).
base_config=$(mktemp -d)
trap 'rm -rf "$base_config"' EXIT
git archive "$base_sha" config | tar -x -C "$base_config"
/usr/bin/python3 "$root/bench/sweep_throughput.py" --base "$base_sweep" --base-source "$base_config" \
  --base-name "$(git rev-parse --short "$base_sha")" --new "$root/build/bin/pneu-sweep" \
  --new-name "$(git rev-parse --short HEAD)$(git diff --quiet HEAD -- . ':!docs' || echo +)" \
  --source "$root" --reps "$reps" "$@"
