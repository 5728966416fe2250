#!/usr/bin/env bash
# The LCM types in every language lcm-gen writes that this machine can build, each .lcm file on its
# own (so a failure names the file), and the jar lcm-spy uses decoding a log pneud recorded.
#   test_lcmtypes.sh SOURCE_DIR BINARY_DIR c|cpp|java|python|jar
# c, cpp: the generated code compiles with warnings as errors (C: but the unused parameters lcm-gen
#   writes in its array clean-up functions).
# java: javac accepts it (a field named after a Java keyword, like `final`, is an error).
# python: the module imports, and a message encodes, decodes and encodes again to the same bytes.
# jar: pneud and pneu-command write LCM logs (to LCM's file:// provider; pneud on the simulated
#   clock) and tests/DecodeLcmLog.java decodes every message of them with lcm-spy's own type lookup.
set -euo pipefail
src=$1 bin=$2 lang=$3
work=$(mktemp -d); trap 'rm -rf "$work"' EXIT
# The .lcm files here, and those pneu-records wrote from the records' descriptions (state_t,
# event_t, prediction_t, health_t, identification_t).
types=("$src"/lcmtypes/*.lcm)
for t in state_t event_t prediction_t health_t identification_t; do
  [ -f "$bin/share/pneu/lcmtypes/$t.lcm" ] || { echo "FAIL: no $t.lcm in $bin/share/pneu/lcmtypes (pneu-records)"; exit 1; }
  types+=("$bin/share/pneu/lcmtypes/$t.lcm")
done
lcm_jar=/usr/share/java/lcm.jar
fail=0
say() { echo "$1: $2"; [ "$1" = ok ] || fail=1; }

for lcm in "${types[@]}"; do
  [ "$lang" = jar ] && break
  name=$(basename "$lcm" .lcm)
  out="$work/$lang/$name"
  mkdir -p "$out"
  case $lang in
    c)
      lcm-gen -c --c-cpath "$out" --c-hpath "$out" "$lcm" > /dev/null
      if gcc -std=c11 -Wall -Wextra -Wno-unused-parameter -Werror $(pkg-config --cflags lcm) -I"$out" -c "$out"/*.c -o "$out/$name.o" \
           2> "$out/err"; then say ok "$name.lcm in C"; else say FAIL "$name.lcm in C: $(cat "$out/err")"; fi ;;
    cpp)
      lcm-gen -x --cpp-hpath "$out" "$lcm" > /dev/null
      header=$(cd "$out" && find . -name "$name.hpp" | head -1)
      printf '#include "%s"\nint main() { %s m{}; return m.getEncodedSize() > 0 ? 0 : 1; }\n' \
        "${header#./}" "$(sed -n 's/^package \(.*\);/\1/p' "$lcm")::$name" > "$out/use.cpp"
      if g++ -std=c++20 -Wall -Wextra -Werror -fno-strict-aliasing $(pkg-config --cflags lcm) -I"$out" \
           -c "$out/use.cpp" -o "$out/use.o" 2> "$out/err"; then say ok "$name.lcm in C++"
      else say FAIL "$name.lcm in C++: $(cat "$out/err")"; fi ;;
    java)
      lcm-gen -j --jpath "$out/src" "$lcm" > /dev/null
      mkdir -p "$out/classes"
      if javac -Xlint:all,-cast -Werror -cp "$lcm_jar" -d "$out/classes" $(find "$out/src" -name '*.java') \
           2> "$out/err"; then say ok "$name.lcm in Java"; else say FAIL "$name.lcm in Java: $(cat "$out/err")"; fi ;;
    python)
      lcm-gen -p --ppath "$out" "$lcm" > /dev/null
      package=$(sed -n 's/^package \(.*\);/\1/p' "$lcm")
      if /usr/bin/python3 - "$out" "$package" "$name" > "$out/err" 2>&1 <<'EOF'
import importlib, sys
sys.path.insert(0, sys.argv[1])
cls = getattr(importlib.import_module(f"{sys.argv[2]}.{sys.argv[3]}"), sys.argv[3])
message = cls()
data = message.encode()
again = cls.decode(data).encode()
assert again == data, "decode then encode changed the bytes"
assert cls._get_packed_fingerprint() == data[:8], "the message does not start with its fingerprint"
EOF
      then say ok "$name.lcm in Python"; else say FAIL "$name.lcm in Python: $(cat "$out/err")"; fi ;;
    *) echo "unknown language $lang" >&2; exit 2 ;;
  esac
done

if [ "$lang" = jar ]; then
  log="$work/run.lcm"
  "$bin/bin/pneud" --quiet --duration 3 --set telemetry.in_simulated_time=true \
    --set "telemetry.lcm_url=file://$log?mode=w"
  commands="$work/commands.lcm"
  "$bin/bin/pneu-command" --no-wait --lcm-url "file://$commands?mode=w" set-point 0.1
  # lcm-spy's class path (pneu-spy): LCM's jar, jchart2d's, ours.
  decode() { java -cp "$lcm_jar:/usr/share/java/jchart2d.jar:$bin/share/java/pneu_lcmtypes.jar" \
                  "$src/tests/DecodeLcmLog.java" "$@"; }
  decode "$log" PNEU_STATE PNEU_EVENT PNEU_PREDICTION PNEU_HEALTH && say ok "the jar decodes pneud's log" \
    || say FAIL "the jar does not decode pneud's log"
  decode "$commands" PNEU_COMMAND && say ok "the jar decodes pneu-command's log" \
    || say FAIL "the jar does not decode pneu-command's log"
fi
exit $fail
