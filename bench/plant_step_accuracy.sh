#!/usr/bin/env bash
# How much the simulated bench's integration steps change what the sweep measures: the default
# 200-step sweep for SEEDS (default 1 2 3) with a fine reference step (10 us sliding and stuck), the
# shipped steps (config/sim.yaml: plant.max_step_s sliding, plant.max_stuck_step_s stuck) and
# 0.2 ms for both; each long sticking phase's time against the reference's
# (bench/plant_step_accuracy.py). Needs build/bin/pneu-sweep.
#   bench/plant_step_accuracy.sh [SEEDS...]
set -euo pipefail
cd "$(dirname "$0")/.."
sweep=$PWD/build/bin/pneu-sweep
seeds=("$@")
[ ${#seeds[@]} -gt 0 ] || seeds=(1 2 3)
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
for seed in "${seeds[@]}"; do
  run() { "$sweep" --steps 200 --seed "$seed" --quiet --out "$work/$1_$seed.csv" "${@:2}" >/dev/null; }
  run reference --set plant.max_step_s=1e-5 --set plant.max_stuck_step_s=1e-5
  run shipped
  run fixed_0.2ms --set plant.max_step_s=2e-4 --set plant.max_stuck_step_s=2e-4
  echo "seed $seed:"
  /usr/bin/python3 bench/plant_step_accuracy.py "$work/reference_$seed.csv" \
    "shipped (sliding $(grep -Po '^  max_step_s: \K\S+' config/sim.yaml) s, stuck $(grep -Po '^  max_stuck_step_s: \K\S+' config/sim.yaml) s)=$work/shipped_$seed.csv" \
    "0.2 ms both=$work/fixed_0.2ms_$seed.csv"
done
