#!/usr/bin/python3
"""No public header outside config/ includes the root configuration (pneu/config/config.hpp),
directly or through the headers it includes: each component takes its own parameters
(<component>/params, pneu/config/describe.hpp for the vocabulary), and code that needs the whole
configuration takes it by reference, declared, not included. A public header is one under an
include/ directory of the source tree. Prints each offender with the chain of includes that
reaches the root configuration; exit 1 if there is one.
    test_public_headers.py SOURCE_DIR
"""
import os
import re
import sys

ROOT = "pneu/config/config.hpp"
src = sys.argv[1]
include_dirs = []
headers = []
for dirpath, dirnames, filenames in os.walk(src):
    dirnames[:] = [d for d in dirnames if d not in (".git", "build") and not d.startswith("build")]
    if os.path.basename(dirpath) == "include":
        include_dirs.append(dirpath)
for inc in include_dirs:
    for dirpath, _, filenames in os.walk(inc):
        for f in filenames:
            if f.endswith(".hpp"):
                headers.append((os.path.relpath(os.path.join(dirpath, f), inc), os.path.join(dirpath, f)))
by_name = {}
for name, path in headers:
    by_name.setdefault(name, path)
include_re = re.compile(r'^\s*#\s*include\s+"(pneu/[^"]+)"', re.M)


def chain_to_root(name, seen):
    """The include chain from `name` to the root configuration, or None."""
    if name == ROOT:
        return [name]
    if name in seen or name not in by_name:
        return None
    seen.add(name)
    with open(by_name[name], encoding="utf-8") as f:
        for inc in include_re.findall(f.read()):
            rest = chain_to_root(inc, seen)
            if rest:
                return [name] + rest
    return None


offenders = 0
checked = 0
for name, path in sorted(headers):
    rel = os.path.relpath(path, src)
    if rel.startswith("config" + os.sep):
        continue
    checked += 1
    chain = chain_to_root(name, set())
    if chain:
        offenders += 1
        print(f"FAIL: {rel} includes the root configuration: {' -> '.join(chain)}")
if ROOT not in by_name:
    print(f"FAIL: {ROOT} not found under {src}: the check would prove nothing")
    sys.exit(1)
print(f"{checked} public headers outside config/, {offenders} reaching {ROOT}")
sys.exit(1 if offenders else 0)
