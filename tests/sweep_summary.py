#!/usr/bin/python3
"""Members of pneu-sweep's --summary-json, for the sweep's shell tests.

    sweep_summary.py SUMMARY.json KEY [KEY ...]

Prints each KEY's value on a line of its own, a KEY naming nested members with dots
(methods.nonlinear.long_within.2_percent); null as an empty line, true / false as 1 / 0. A KEY the
summary lacks is an error (exit 1, naming it).
"""
import json
import sys

summary = json.load(open(sys.argv[1]))
for path in sys.argv[2:]:
    value = summary
    for key in path.split('.'):
        if not isinstance(value, dict) or key not in value:
            sys.exit(f"sweep_summary.py: {sys.argv[1]} has no {path}")
        value = value[key]
    if isinstance(value, bool):
        value = int(value)
    print('' if value is None else value)
