#!/usr/bin/env python3
"""The simulated bench's integration steps against a fine reference: each long sticking phase
(>= --min-sticking-s, a restart) of a reference sweep matched, in the same scenario, with the stop
confirmed within 10 ms of it in each other sweep; the relative difference of the sticking times,
and how many found no match (a stop made or lost by the step: the stops whose force lands a hair
inside the stiction band are sensitive to anything).
  plant_step_accuracy.py REFERENCE.csv LABEL=SWEEP.csv...
"""
import argparse
import csv


def load(path):
    return list(csv.DictReader(open(path)))


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("reference")
    parser.add_argument("others", nargs="+", metavar="LABEL=SWEEP.csv")
    parser.add_argument("--min-sticking-s", type=float, default=0.5)
    args = parser.parse_args()
    reference = [r for r in load(args.reference)
                 if r["outcome"] == "restart" and float(r["sticking_s"]) >= args.min_sticking_s]
    print("| steps | long sticks | not matched | rel. error p50 | p90 | max |")
    print("|---|---|---|---|---|---|")
    for item in args.others:
        label, _, path = item.partition("=")
        by_scenario = {}
        for row in load(path):
            by_scenario.setdefault(row["scenario"], []).append(row)
        errors, unmatched = [], 0
        for r in reference:
            t_stop = float(r["t_stop_s"])
            match = [q for q in by_scenario.get(r["scenario"], []) if abs(float(q["t_stop_s"]) - t_stop) < 0.01]
            if not match or match[0]["outcome"] != "restart":
                unmatched += 1
                continue
            errors.append(abs(float(match[0]["sticking_s"]) - float(r["sticking_s"])) / float(r["sticking_s"]))
        errors.sort()
        if errors:
            p = lambda q: errors[min(len(errors) - 1, int(q * len(errors)))]
            print("| %s | %d | %d | %.1e | %.1e | %.1e |" % (label, len(reference), unmatched, p(0.5), p(0.9), errors[-1]))
        else:
            print("| %s | %d | %d | - | - | - |" % (label, len(reference), unmatched))


if __name__ == "__main__":
    main()
