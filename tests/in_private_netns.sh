#!/usr/bin/env bash
# Runs a command inside a private network namespace with only loopback up and multicast routed to
# it, so LCM datagrams of the test never reach a real interface. Exits 77 (ctest: skipped) with a
# reason when the namespace cannot be made.
set -u
if [ "$(id -u)" -ne 0 ]; then
  echo "SKIPPED: a private network namespace needs root (unshare -n); LCM multicast is not tested here" >&2
  exit 77
fi
if ! unshare -n true 2>/dev/null; then
  echo "SKIPPED: unshare -n is not permitted on this machine; LCM multicast is not tested here" >&2
  exit 77
fi
exec unshare -n bash -c 'set -e; ip link set lo up; ip route add 224.0.0.0/4 dev lo; exec "$@"' netns "$@"
