#!/usr/bin/env bash
# The link check itself can fail: on a small tree with one good link of each kind it passes, and each
# kind of bad link (a missing file, a missing anchor, a way out of the repository, an unlisted web
# site, a README over the limit) makes it fail naming the file and line.
#
# usage: test_markdown_link_check.sh SOURCE_DIR
set -u
check=$1/tests/check_markdown_links.py
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
failures=0
fail() {
  echo "FAIL: $*" >&2
  failures=$((failures + 1))
}
good_tree() {
  rm -rf "$tmp/repo" && mkdir -p "$tmp/repo/docs/img"
  : >"$tmp/repo/docs/img/f.png"
  printf '# Top\n\nSee [the page](docs/page.md#a-heading-with-code), ![f](docs/img/f.png), [here](#top),\n[LCM](https://lcm-proj.github.io/) and `[not a link](nowhere.md)`.\n\n```\n[nor this](gone.md)\n```\n' \
    >"$tmp/repo/README.md"
  printf '# Page\n\n## A heading with `code`\n\nBack to [the README](../README.md).\n' >"$tmp/repo/docs/page.md"
}
good_tree
out=$(/usr/bin/python3 "$check" "$tmp/repo" 2>&1) || fail "a tree whose links are all good failed: $out"
expect_failure() {  # what, the line it must print
  local out rc
  out=$(/usr/bin/python3 "$check" "$tmp/repo" 2>&1); rc=$?
  if [ "$rc" -ne 1 ] || ! grep -qF -- "$2" <<<"$out"; then
    fail "$1: exit $rc, expected 1 and '$2' in: $out"
  else
    echo "ok: $1 fails: $(grep -F -- "$2" <<<"$out" | head -1)"
  fi
}
good_tree; echo 'A [dead link](docs/gone.md).' >>"$tmp/repo/README.md"
expect_failure "a link to a missing file" "README.md:9: docs/gone.md: no such file"
good_tree; echo 'A [dead anchor](page.md#no-such-heading).' >>"$tmp/repo/docs/page.md"
expect_failure "a link to a missing anchor" "docs/page.md:6: page.md#no-such-heading: docs/page.md has no heading"
good_tree; echo 'The [team notes](../../shared/design/MODEL.md).' >>"$tmp/repo/docs/page.md"
expect_failure "a link out of the repository" "leads out of the repository"
good_tree; echo 'A [blog](http://example.com/post).' >>"$tmp/repo/README.md"
expect_failure "a link to an unlisted site" "web link to example.com"
good_tree; seq 1 5 >>"$tmp/repo/README.md"
out=$(/usr/bin/python3 "$check" "$tmp/repo" 12 2>&1); rc=$?
if [ "$rc" -ne 1 ] || ! grep -qF "README.md: 13 lines, more than 12" <<<"$out"; then
  fail "a README over the limit: exit $rc: $out"
else
  echo "ok: a README over the limit fails"
fi
[ "$failures" -eq 0 ] || exit 1
echo PASSED
