#!/usr/bin/python3
"""Every link of every Markdown file in the repository leads somewhere, and the README stays short.

usage: check_markdown_links.py SOURCE_DIR [MAX_README_LINES]

For each .md file under SOURCE_DIR (skipping build trees, hidden folders and node_modules), outside
code blocks and code spans:
- a relative link or image (`[text](path#anchor)`, `![alt](path)`, `[label]: path`, `href=`/`src=`)
  names a file or folder that exists inside the repository, and its anchor is a heading (or an
  `<a id=...>`) of the Markdown file it names, spelt as GitHub spells heading anchors;
- no link leaves the repository (`../shared` and the like: the docs must stand alone);
- a web link (http, https) goes to one of the stable sites listed below, and no other scheme is
  used (ws://, file:// ... belong in code spans, where they are examples, not links).
Then `wc -l README.md` is at most MAX_README_LINES (300).
Prints every problem as FILE:LINE: ...; exit 0 when there is none, 1 otherwise, 2 on bad usage.
"""
import os
import re
import sys
import unicodedata
from urllib.parse import unquote, urlsplit

# Web sites a link may point to: projects' own stable homes and the archive this project builds from.
ALLOWED_HOSTS = {
    "github.com",            # upstream projects (libmodbus, foxglove/ws-protocol ...)
    "lcm-proj.github.io",    # LCM's documentation
    "www.debian.org",
    "packages.debian.org",
    "doi.org",               # the paper
    "docs.foxglove.dev",
    "prometheus.io",
    "systemd.io",
    "www.freedesktop.org",   # systemd's manual pages
    "man7.org",
    "libmodbus.org",
    "127.0.0.1",             # not the web: a page a program of this project serves on this host
}
SKIP_DIRS = {"node_modules", "__pycache__"}


def markdown_files(root):
    for dirpath, dirnames, filenames in os.walk(root):
        dirnames[:] = sorted(d for d in dirnames
                             if not d.startswith(".") and not d.startswith("build") and d not in SKIP_DIRS)
        for name in sorted(filenames):
            if name.endswith(".md"):
                yield os.path.join(dirpath, name)


FENCE = re.compile(r"^\s{0,3}(```+|~~~+)")


def prose_lines(text):
    """(line number, line with its code spans blanked, line) outside fenced code blocks."""
    fence = None
    for number, line in enumerate(text.split("\n"), 1):
        m = FENCE.match(line)
        if m:
            marker = m.group(1)
            if fence is None:
                fence = marker[0] * len(marker)
                continue
            if marker.startswith(fence):
                fence = None
                continue
        if fence is not None:
            continue
        yield number, re.sub(r"(`+)(.+?)\1", lambda s: " " * len(s.group(0)), line), line


def slug(heading):
    """The anchor GitHub gives a heading: markup dropped, lower case, punctuation out, spaces to '-'."""
    text = re.sub(r"!?\[([^\]]*)\]\([^)]*\)", r"\1", heading)  # a link's text stays
    text = re.sub(r"<[^>]+>", "", text)                         # inline HTML goes
    text = text.strip().lower()
    kept = []
    for ch in text:
        if ch in " -_" or ch.isalnum() or unicodedata.category(ch).startswith("M"):
            kept.append(ch)
    return "".join(kept).replace(" ", "-")


def anchors(path, cache={}):
    if path not in cache:
        found, seen = set(), {}
        with open(path, encoding="utf-8") as f:
            text = f.read()
        for _, _, line in prose_lines(text):
            m = re.match(r"^\s{0,3}#{1,6}\s+(.*?)\s*#*\s*$", line)
            if m:
                base = slug(m.group(1))
                n = seen.get(base, 0)
                seen[base] = n + 1
                found.add(base if n == 0 else f"{base}-{n}")
        for m in re.finditer(r"<a\s+(?:id|name)=\"([^\"]+)\"", text):
            found.add(m.group(1))
        cache[path] = found
    return cache[path]


LINK = re.compile(r"!?\[(?:[^\[\]]|\[[^\]]*\])*\]\(\s*<?([^)\s>]*)>?(?:\s+\"[^\"]*\")?\s*\)")
REFERENCE = re.compile(r"^\s{0,3}\[[^\]]+\]:\s*<?(\S+?)>?(?:\s+.*)?$")
AUTOLINK = re.compile(r"<((?:https?|ftp|ws|wss|file)://[^>\s]+)>")
HTML = re.compile(r"(?:href|src)=\"([^\"]+)\"")


def targets(line):
    for pattern in (LINK, AUTOLINK, HTML):
        for m in pattern.finditer(line):
            yield m.group(1)
    m = REFERENCE.match(line)
    if m:
        yield m.group(1)


def check_target(root, md, target):
    """None when the target is good, else what is wrong with it."""
    if not target:
        return "empty link"
    parts = urlsplit(target)
    if parts.scheme in ("http", "https"):
        if parts.hostname not in ALLOWED_HOSTS:
            return f"web link to {parts.hostname}, not one of the stable sites this check allows"
        return None
    if parts.scheme or target.startswith("//"):
        return f"a {parts.scheme or 'network'} link: only files of the repository and listed web sites"
    path, anchor = unquote(parts.path), unquote(parts.fragment)
    if path.startswith("/"):
        return "an absolute path: link relative to the file"
    resolved = os.path.normpath(os.path.join(os.path.dirname(md), path)) if path else md
    inside = os.path.relpath(resolved, root)
    if inside == ".." or inside.startswith(".." + os.sep):
        return f"{target} leads out of the repository ({inside}): the docs must stand alone"
    if not os.path.exists(resolved):
        return f"{target}: no such file ({inside})"
    if anchor:
        if not resolved.endswith(".md") or os.path.isdir(resolved):
            return f"{target}: an anchor into a file that is not Markdown"
        if anchor not in anchors(resolved):
            return f"{target}: {os.path.relpath(resolved, root)} has no heading with the anchor #{anchor}"
    return None


def main(argv):
    if len(argv) not in (2, 3):
        print(__doc__, file=sys.stderr)
        return 2
    root = os.path.abspath(argv[1])
    max_lines = int(argv[2]) if len(argv) == 3 else 300
    problems, files, links = [], 0, 0
    for md in markdown_files(root):
        files += 1
        with open(md, encoding="utf-8") as f:
            text = f.read()
        for number, line, _ in prose_lines(text):
            for target in targets(line):
                links += 1
                why = check_target(root, md, target)
                if why:
                    problems.append(f"{os.path.relpath(md, root)}:{number}: {why}")
    readme = os.path.join(root, "README.md")
    with open(readme, encoding="utf-8") as f:
        readme_lines = f.read().count("\n")
    if readme_lines > max_lines:
        problems.append(f"README.md: {readme_lines} lines, more than {max_lines}: move the detail to docs/")
    for p in problems:
        print(p)
    print(f"{files} Markdown files, {links} links checked; README.md {readme_lines} lines (at most {max_lines}); "
          f"{len(problems)} problem(s)")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
