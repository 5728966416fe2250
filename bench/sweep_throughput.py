#!/usr/bin/env python3
"""Scenarios per core-second of two pneu-sweep builds, in the same run pair (bench/sweep_throughput.sh).

Each case runs both builds with --jobs 1, alternating, REPS times each; a run's cost is the CPU time
(user + system) of the child, its throughput the scenarios over that time; the medians are reported,
with the ratio new / base, and whether the two builds wrote the same scenario rows (a change meant
to leave the results alone leaves them byte for byte, or by numerical noise only). Each build reads
its own tree's configuration files (--base-source, --source). A case the base cannot run (an option
or a key it does not have yet) is reported as such, not left out.
"""
import argparse
import filecmp
import os
import resource
import statistics
import subprocess
import sys
import tempfile

THERMAL = ["--bench-thermal-s", "0.5:3", "--bench-spool-lag-s", "0:0.005",
           "--set", "plant.thermal.heat_transfer_w_per_m2_k=25.72",
           "--set", "plant.valve.spool_time_constant_s=0.002"]


def cases(src):
    hil = ["--config", os.path.join(src, "config/hil.yaml"), "--set", "hal.backend=sim"]
    identified = ["--steps", "40", "--bench-spread", "0.2", "--identify"]
    # The thermal benches as tests/test_sweep_identified.sh draws them (ideal-thermal, hil-thermal),
    # fewer steps: each identification costs seconds of a core.
    thermal = ["--steps", "8", "--bench-spread", "0.2", "--identify",
               "--set", "controller.predictor.methods=[nonlinear]"] + THERMAL
    return {
        "default": ["--steps", "200"],
        "identified": identified,
        "identified-hil": identified + hil,
        "identified-thermal": thermal,
        "identified-thermal-hil": thermal + hil,
    }


class CannotRun(Exception):
    pass


def run(binary, args, workdir, tag):
    out = os.path.join(workdir, tag + ".csv")
    scen = os.path.join(workdir, tag + "_scenarios.csv")
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    p = subprocess.run([binary, "--jobs", "1", "--quiet", "--out", out, "--scenarios-out", scen] + args,
                       stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    if p.returncode != 0:
        raise CannotRun(p.stderr.strip().splitlines()[-1] if p.stderr.strip() else f"exit {p.returncode}")
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime), scen


def steps_of(args):
    return int(args[args.index("--steps") + 1])


def main():
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--base", required=True)
    ap.add_argument("--base-name", default="base")
    ap.add_argument("--new", required=True)
    ap.add_argument("--new-name", default="new")
    ap.add_argument("--source", required=True, help="the new build's tree (its config/)")
    ap.add_argument("--base-source", required=True, help="the base's tree, or a copy of its config/ in a directory")
    ap.add_argument("--reps", type=int, default=3)
    ap.add_argument("cases", nargs="*")
    a = ap.parse_args()
    table = cases(a.source)
    base_table = cases(a.base_source)
    chosen = a.cases or list(table)
    for c in chosen:
        if c not in table:
            sys.exit(f"unknown case {c!r} (known: {', '.join(table)})")
    print(f"pneu-sweep --jobs 1, {a.reps} repetitions each, CPU time of the child (user + system); "
          f"base {a.base_name}, new {a.new_name}")
    print(f"{'case':24} {'scen':>5} {'base CPU s':>11} {'new CPU s':>10} {'base /core-s':>12} "
          f"{'new /core-s':>11} {'ratio':>6}  same rows")
    with tempfile.TemporaryDirectory() as tmp:
        for c in chosen:
            args = {"base": base_table[c], "new": table[c]}
            n = steps_of(table[c])
            times = {"base": [], "new": []}
            scen = {}
            try:
                for _ in range(a.reps):
                    for tag, binary in (("base", a.base), ("new", a.new)):
                        try:
                            t, scen[tag] = run(binary, args[tag], tmp, f"{c}_{tag}")
                        except CannotRun as e:
                            raise CannotRun(f"{tag} cannot run it: {e}")
                        times[tag].append(t)
            except CannotRun as e:
                print(f"{c:24} {n:5d}  not measured: {e}", flush=True)
                continue
            tb, tn = statistics.median(times["base"]), statistics.median(times["new"])
            same = "yes" if filecmp.cmp(scen["base"], scen["new"], shallow=False) else "no"
            print(f"{c:24} {n:5d} {tb:11.2f} {tn:10.2f} {n / tb:12.2f} {n / tn:11.2f} {tb / tn:6.2f}  {same}",
                  flush=True)


if __name__ == "__main__":
    main()
