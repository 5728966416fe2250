#!/usr/bin/env bash
# Installs the independent Foxglove client's npm packages (package.json, package-lock.json: pinned)
# into DEST with npm ci, for test_dash_live.sh foxglove. Exits 77 (ctest: skipped), saying why,
# when npm is missing or its registry cannot be reached.
#   npm_ci.sh SOURCE_DIR DEST
set -u
src=$1
dest=$2
command -v npm >/dev/null || { echo "SKIPPED: npm is missing (scripts/deps installs nodejs)"; exit 77; }
mkdir -p "$dest"
cp "$src/package.json" "$src/package-lock.json" "$dest/"
if ! out=$(cd "$dest" && timeout 60 npm ping 2>&1); then
  echo "SKIPPED: the npm registry cannot be reached (npm ping: $(tail -1 <<<"$out")); the Foxglove client is not tested"
  exit 77
fi
cd "$dest" && timeout 300 npm ci --no-audit --no-fund || { echo "FAIL: npm ci in $dest"; exit 1; }
