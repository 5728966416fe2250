#!/usr/bin/env bash
# The Debian package as an admin meets it. CPack builds it from this build tree; then, in a
# throw-away copy-on-write copy of this machine's root (an overlay in a private mount namespace,
# so nothing is installed here), dpkg installs it, its units verify, pneud checks the installed
# /etc/pneu/bench.yaml with the unit's own command line, an admin edits that file, and two newer
# versions are installed over it: one shipping the same examples (dpkg keeps the edit silently)
# and one shipping a changed bench.yaml (the edit is kept, the new one beside it as
# .dpkg-dist). Removing keeps the configurations, purging removes them.
#   test_deb_package.sh SOURCE_DIR BINARY_DIR
# Exits 77 (ctest: skipped) with the reason when the machine cannot do it: not root, no
# unshare/overlayfs, no dpkg.
set -u
src=$1 bin=$2
skip() { echo "SKIPPED: $*" >&2; exit 77; }
[ "$(id -u)" -eq 0 ] || skip "installing a package, even in an overlay, needs root"
left_out=$(sed -nE 's/^(PNEU_WITH_[A-Z_]+):BOOL=OFF$/\1/p' "$bin/CMakeCache.txt" | tr '\n' ' ')
[ -z "$left_out" ] || skip "built with ${left_out% } off: the package tested is the whole one"
for tool in cpack dpkg dpkg-deb unshare chroot; do
  command -v "$tool" > /dev/null || skip "$tool is missing"
done
if ! unshare -m true 2> /dev/null; then
  # Inside a chroot whose root is not a mount point (a fresh root made with debootstrap), the
  # new namespace's mounts cannot be made private, and an overlay mounted there could show on the
  # host: the test does not run there rather than risk it.
  if ! mountpoint -q /; then skip "/ is not a mount point (a chroot): no private mount namespace to install in"; fi
  skip "unshare -m is not permitted here"
fi

work=$(mktemp -d /var/tmp/pneu-deb.XXXXXX)
trap 'rm -rf "$work"' EXIT
mkdir -p "$work/pkg" "$work/ovl"

# The package, then two newer versions repacked from it: 0.1.1 as is, 0.1.2 with a changed
# shipped bench.yaml (its md5sum updated, as a rebuild would).
(cd "$bin" && cpack -G DEB -B "$work/pkg" > "$work/cpack.log" 2>&1) || { cat "$work/cpack.log"; echo "FAIL: cpack"; exit 1; }
deb=$(ls "$work"/pkg/pneu_*.deb)
version=$(dpkg-deb -f "$deb" Version)
repack() {  # NEW_VERSION [change-bench]
  local tree="$work/tree-$1"
  dpkg-deb -R "$deb" "$tree"
  sed -i "s/^Version: .*/Version: $1/" "$tree/DEBIAN/control"
  if [ "${2:-}" = change-bench ]; then
    echo "# a line the newer version ships" >> "$tree/etc/pneu/bench.yaml"
    local sum; sum=$(cd "$tree" && md5sum etc/pneu/bench.yaml)
    sed -i "s|^[0-9a-f]*  etc/pneu/bench.yaml\$|$sum|" "$tree/DEBIAN/md5sums"
  fi
  dpkg-deb -b "$tree" "$work/pkg/pneu_$1.deb" > /dev/null
}
repack "$version.1"
repack "$version.2" change-bench

cat > "$work/pkg/in_root.sh" <<'EOF'
set -u
version=$1 first=$2
failures=0
ok() { echo "ok: $*"; }
fail() { echo "FAIL: $*"; failures=$((failures + 1)); }
check() {  # DESCRIPTION COMMAND...
  local what=$1; shift
  if "$@" > /tmp/check.out 2>&1; then ok "$what"; else fail "$what: $(cat /tmp/check.out)"; fi
}
installed_version() { dpkg-query -W -f='${Version}' pneu 2> /dev/null; }

check "dpkg -i installs the package" dpkg -i "/pkg/$first"
check "the package is installed" test "$(dpkg-query -W -f='${Status}' pneu)" = "install ok installed"
for f in /usr/bin/pneud /usr/bin/pneu-plant /usr/bin/pneu-command /usr/bin/pneu-spy /usr/bin/pneu-dash; do
  check "$f is executable" test -x "$f"
done
for f in /usr/lib/systemd/system/pneud.service /usr/lib/systemd/system/pneu-plant-hil.service \
         /usr/lib/systemd/system/pneu-dash.service /usr/share/pneu/dash/index.html \
         /usr/lib/udev/rules.d/60-pneu-gpio.rules /usr/lib/sysusers.d/pneu.conf \
         /usr/share/java/pneu_lcmtypes.jar /usr/share/doc/pneu/README.md /etc/pneu/bench.yaml; do
  check "$f is installed" test -s "$f"
done
check "postinst created the system user pneu" sh -c 'getent passwd pneu | grep -q ":/nonexistent:/usr/sbin/nologin$"'
check "and its group, which the udev rule gives the GPIO chip" sh -c 'getent group pneu && grep -q "GROUP=\"pneu\"" /usr/lib/udev/rules.d/60-pneu-gpio.rules'
check "the configurations are conffiles" sh -c \
  'for f in sim hil bench; do dpkg-query -W -f="\${Conffiles}" pneu | grep -q " /etc/pneu/$f.yaml "; done'
if command -v systemd-analyze > /dev/null; then
  check "systemd-analyze verify accepts the installed units without a word" sh -c \
    'out=$(systemd-analyze verify /usr/lib/systemd/system/pneud.service /usr/lib/systemd/system/pneu-plant-hil.service /usr/lib/systemd/system/pneu-dash.service 2>&1) && [ -z "$out" ] || { echo "$out"; exit 1; }'
else
  fail "systemd-analyze is missing (the package depends on systemd)"
fi
# The unit's own command line, with --check-config: the installed pneud accepts the installed file.
cmd=$(sed -n 's/^ExecStart=//p' /usr/lib/systemd/system/pneud.service)
check "pneud --check-config on /etc/pneu/bench.yaml (the unit's command line)" sh -c "$cmd --check-config"

# An admin edits the bench's configuration; newer versions are installed over it.
echo "# the admin's edit: this bench's module" >> /etc/pneu/bench.yaml
edited=$(sha256sum < /etc/pneu/bench.yaml)
check "a newer version ($version.1, same examples) installs" dpkg -i "/pkg/pneu_$version.1.deb"
check "it is the installed version" test "$(installed_version)" = "$version.1"
check "the admin's edit is kept, without a question" test "$(sha256sum < /etc/pneu/bench.yaml)" = "$edited"
check "nothing was set beside it" test ! -e /etc/pneu/bench.yaml.dpkg-dist
check "a newer version ($version.2, a changed bench.yaml) installs keeping the admin's file" \
  dpkg -i --force-confdef --force-confold "/pkg/pneu_$version.2.deb"
check "it is the installed version" test "$(installed_version)" = "$version.2"
check "the admin's edit is kept" test "$(sha256sum < /etc/pneu/bench.yaml)" = "$edited"
check "the new shipped bench.yaml is beside it as .dpkg-dist" grep -q "a line the newer version ships" /etc/pneu/bench.yaml.dpkg-dist

check "dpkg -r removes it" dpkg -r pneu
check "the binaries are gone" test ! -e /usr/bin/pneud
check "the configurations stay until purge" test -e /etc/pneu/bench.yaml
check "dpkg -P purges it" dpkg -P pneu
check "the configurations are gone" test ! -e /etc/pneu/bench.yaml
echo "$failures failures"
exit $((failures > 0))
EOF

# Inside a private mount namespace: an overlay over this root, written to a tmpfs that goes
# with the namespace.
unshare -m --propagation private bash -s "$work" "$version" "$(basename "$deb")" <<'EOF'
set -eu
work=$1 version=$2 first=$3
mount -t tmpfs tmpfs "$work/ovl"
mkdir -p "$work/ovl/upper" "$work/ovl/work" "$work/ovl/root"
root=$work/ovl/root
if ! mount -t overlay overlay -o "lowerdir=/,upperdir=$work/ovl/upper,workdir=$work/ovl/work" "$root" 2> "$work/ovl/err"; then
  echo "SKIPPED: overlayfs is not available: $(cat "$work/ovl/err")" >&2
  exit 77
fi
mount -t proc proc "$root/proc"
mount --rbind /sys "$root/sys"
mount --rbind /dev "$root/dev"
mkdir -p "$root/pkg"
mount --bind "$work/pkg" "$root/pkg"
mount -t tmpfs tmpfs "$root/tmp"
mount -t tmpfs tmpfs "$root/run"
chroot "$root" /usr/bin/env -i PATH=/usr/sbin:/usr/bin:/sbin:/bin DEBIAN_FRONTEND=noninteractive \
  bash /pkg/in_root.sh "$version" "$first"
EOF
