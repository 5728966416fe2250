#!/usr/bin/env python3
"""The configuration reference, docs/configuration.md, generated from one source: the shipped
configurations. The keys and their values are what pneud reads from each file (`pneud
--check-config`); the meaning of each key is its comment in config/sim.yaml (else hil.yaml, else
bench.yaml); for an optional key, the value the loader takes when it is left out is what
`pneud --check-config` prints for the file without it.

  tools/docs/config_reference.py --pneud build/bin/pneud --out docs/configuration.md
  tools/docs/config_reference.py --pneud build/bin/pneud --check docs/configuration.md

--check (ctest ConfigurationReferenceIsCurrent) fails when the page is not what the shipped files
generate, when a key pneud prints for a shipped file is missing from the page, when a key has no
comment anywhere, or when the loader refuses a number of a key for being out of range while the
key's comment states no range. Exit 0 when all is well, 1 otherwise, 77 without PyYAML.
"""

import argparse
import difflib
import os
import re
import subprocess
import sys
import tempfile

try:
    import yaml
except ImportError:  # Debian: python3-yaml (scripts/deps)
    print("config_reference.py: skipped: PyYAML (python3-yaml) is not installed")
    sys.exit(77)

ROOT = os.path.normpath(os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", ".."))
# The shipped files, in the order their comments are taken; sim.yaml is the default bench.
FILES = [("sim", "config/sim.yaml"), ("hil", "config/hil.yaml"), ("bench", "config/bench.yaml")]
# A comment states a range when it holds one of these (">= 0", "in [1, 20000]", "1..247",
# "!= 0", "inside the stroke", "must contain the stroke", "1 | 2").
RANGE_MARKER = re.compile(r"[<>]|\bin [\[(]|\d\.\.\d|!=|\binside\b|\bwithin\b|\bmust\b|\d \| \d")


def fail(message):
    print("config_reference.py: " + message, file=sys.stderr)
    sys.exit(1)


def normal(path):
    """A key path with list indexes dropped: a.list[3].b -> a.list[].b."""
    return re.sub(r"\[\d+\]", "[]", path)


# ------------------------------------------------------------------------------------------------
# The shipped files: each key's comment, by normalised path


def comments_of(text):
    """({path: comment}, header, {path}) of a YAML text: the comment on a key's line (the first key
    of that line owns it), continued by the comment-only lines below it that are indented further
    than the key; the file's header (the comment lines before the first key); every key path."""
    lines = text.split("\n")
    owners = {}  # line -> (path, column) of the first key on it

    def walk(node, path):
        if isinstance(node, yaml.MappingNode):
            for key, value in node.value:
                child = key.value if not path else path + "." + key.value
                line, column = key.start_mark.line, key.start_mark.column
                if line not in owners or column < owners[line][1]:
                    owners[line] = (child, column)
                paths.add(normal(child))
                walk(value, child)
        elif isinstance(node, yaml.SequenceNode):
            for i, item in enumerate(node.value):
                walk(item, "%s[%d]" % (path, i))

    paths = set()
    walk(yaml.compose(text), "")
    comments = {}
    for line, (path, column) in owners.items():
        hash_at = lines[line].find(" #")
        if hash_at < 0:
            continue
        parts = [lines[line][hash_at + 2:].strip()]
        for below in lines[line + 1:]:
            stripped = below.lstrip(" ")
            if not stripped.startswith("#") or len(below) - len(stripped) <= column:
                break
            parts.append(stripped[1:].strip())
        comments[normal(path)] = " ".join(p for p in parts if p)
    header = []
    for line in lines:
        if not line.startswith("#"):
            break
        header.append(line[1:].strip())
    return comments, " ".join(header), paths


# ------------------------------------------------------------------------------------------------
# What pneud reads


def check_config(pneud, config_path, overrides=()):
    args = [pneud, "--config", config_path, "--check-config"]
    for o in overrides:
        args += ["--set", o]
    return subprocess.run(args, capture_output=True, text=True)


def flow_text(node):
    """A composed node as one line of YAML flow text, scalars as pneud wrote them."""
    if isinstance(node, yaml.ScalarNode):
        if node.value == "" or node.style in ("'", '"'):
            return '"%s"' % node.value
        return node.value
    if isinstance(node, yaml.SequenceNode):
        return "[" + ", ".join(flow_text(v) for v in node.value) + "]"
    return "{" + ", ".join("%s: %s" % (k.value, flow_text(v)) for k, v in node.value) + "}"


def effective_keys(pneud, config_path):
    """[(path, kind, value text)] of everything pneud reads from the file, in its order; kind is
    'section' (a mapping), 'list' or 'value'. A list of mappings also yields the keys of its
    entries (path[].key, without values)."""
    result = check_config(pneud, config_path)
    if result.returncode != 0:
        fail("%s: pneud --check-config failed: %s" % (config_path, result.stderr.strip()))
    out = []

    def walk(node, path):
        for key, value in node.value:
            child = key.value if not path else path + "." + key.value
            if isinstance(value, yaml.MappingNode):
                out.append((child, "section", ""))
                walk(value, child)
            elif isinstance(value, yaml.SequenceNode):
                out.append((child, "list", flow_text(value)))
                for item in value.value:
                    if isinstance(item, yaml.MappingNode):
                        for k, _ in item.value:
                            entry = child + "[]." + k.value
                            if all(p != entry for p, _, _ in out):
                                out.append((entry, "entry", ""))
            else:
                out.append((child, "value", flow_text(value)))

    walk(yaml.compose(result.stdout), "")
    return out


def value_at(pneud_yaml, path):
    node = yaml.compose(pneud_yaml)
    for part in path.split("."):
        node = next(v for k, v in node.value if k.value == part)
    return flow_text(node)


def without(text, path):
    """The YAML text with the key at `path` (no list index) removed (comments are lost)."""
    data = yaml.safe_load(text)
    parent = data
    parts = path.split(".")
    for part in parts[:-1]:
        parent = parent[part]
    del parent[parts[-1]]
    return yaml.safe_dump(data, sort_keys=False)


# ------------------------------------------------------------------------------------------------
# The page


def cell(text):
    return text.replace("|", "\\|").replace("<", "&lt;")


def code(text):
    return "`" + text.replace("|", "\\|") + "`" if text != "" else ""


def build(pneud):
    texts = {name: open(os.path.join(ROOT, rel)).read() for name, rel in FILES}
    comments, headers, present = {}, {}, {}
    for name, _ in FILES:
        comments[name], headers[name], present[name] = comments_of(texts[name])
    keys = {name: effective_keys(pneud, os.path.join(ROOT, rel)) for name, rel in FILES}
    values = {name: {p: v for p, _, v in keys[name]} for name in keys}

    # Every key of every file, in pneud's order (a key sim.yaml lacks goes after the key before it).
    order, kinds = [], {}
    for name, _ in FILES:
        previous = None
        for path, kind, _ in keys[name]:
            kinds.setdefault(path, kind)
            if path not in order:
                order.insert(order.index(previous) + 1 if previous else len(order), path)
            previous = path

    def meaning(path):
        """(what the page says, the comment it stands on), from the first file that has the key:
        its own comment; else the same key's in the first sibling mapping that comments it ("as
        `...position.register`"); else, for a key of a list's entries, the list's ("see ...")."""
        for name, _ in FILES:
            if path not in present[name] and not any(path in values[n] for n in (name,)):
                continue
            own = comments[name]
            if path in own:
                return own[path], own[path]
            parent, _, leaf = path.rpartition(".")
            grand = parent.rpartition(".")[0]
            for sibling in order:
                if sibling.rpartition(".")[0] == grand and sibling != parent and sibling + "." + leaf in own:
                    return "as `%s.%s`" % (sibling, leaf), own[sibling + "." + leaf]
            if parent.endswith("[]") and parent[:-2] in own:
                return "see `%s`" % parent[:-2], own[parent[:-2]]
        return None, None

    def comment_text(path):
        return meaning(path)[1]

    undocumented = [p for p in order if meaning(p)[0] is None]
    if undocumented:
        fail("keys without a comment in any shipped file (comment them in config/*.yaml): " + ", ".join(undocumented))

    def when_left_out(path):
        marked = "optional" in comment_text(path)
        if kinds[path] == "entry" and meaning(path)[0].startswith("see "):
            return "required"  # in each entry of its list
        if kinds[path] in ("section", "entry"):
            return "optional" if marked else "required"
        in_a_file = [(name, rel) for name, rel in FILES if path in present[name]]
        if in_a_file and not marked:
            return "required"
        for name, rel in in_a_file:  # optional: what the loader takes without it
            with tempfile.TemporaryDirectory() as tmp:
                target = os.path.join(tmp, os.path.basename(rel))
                with open(target, "w") as f:
                    f.write(without(texts[name], path))
                result = check_config(pneud, target)
                if result.returncode != 0:
                    fail("%s without %s: pneud --check-config failed: %s" % (rel, path, result.stderr.strip()))
                return code(value_at(result.stdout.split("\n", 1)[1], path))
        for name, _ in FILES:  # in no shipped file: what the loader took is its default
            if path in values[name]:
                return code(values[name][path])
        return ""

    def elsewhere(path):
        base = values["sim"].get(path)
        shown = {}
        for name in ("hil", "bench"):
            v = values[name].get(path)
            if v is not None and v != base:
                shown.setdefault(v, []).append(name)
        return "; ".join("%s: %s" % (", ".join(names), code(v)) for v, names in shown.items())

    out = []
    w = out.append
    w("# Configuration reference")
    w("")
    w("<!-- Generated by tools/docs/config_reference.py from config/sim.yaml, hil.yaml and bench.yaml")
    w("     and pneud --check-config: edit the comments of those files, not this page. -->")
    w("")
    w("Every key pneud and pneu-plant read, with its value in each shipped file, what the loader")
    w("takes when an optional key is left out, and its meaning (unit, valid range where the loader")
    w("checks one). SI units, named in the keys (`_m`, `_pa`, `_kg`, `_s`, `_v`, `_n` ...);")
    w("pressures are absolute. Every key is required unless marked optional, unknown keys are refused")
    w("(a misspelt one is named with the key it stands for), and a value out of its range is refused")
    w("with the key path and the reason before anything runs (exit code 2). `--set KEY=VALUE`")
    w("overrides a key by its dotted path; `pneud --check-config` prints the effective configuration.")
    w("The symbols (`M`, `S_P`, `p_S`, `F_S+`, `K_y` ...) are those of [the model](model.md).")
    w("")
    w("This page is generated from the comments of the shipped files by")
    w("`tools/docs/config_reference.py --pneud build/bin/pneud --out docs/configuration.md`; ctest")
    w("(`ConfigurationReferenceIsCurrent`) fails when it is stale.")
    w("")
    w("## The shipped files")
    w("")
    for name, rel in FILES:
        first = re.match(r"(.*?\.)(\s|$)", headers[name])
        w("- [`%s`](../%s): %s" % (rel, rel, cell(first.group(1) if first else headers[name])))
    w("")
    w("In the tables: the value in `sim.yaml` (the default, embedded in the programs), the values of")
    w("`hil.yaml` and `bench.yaml` where they differ from it, and the value taken when the key is left")
    w("out (\"required\": refused). Numbers are written as pneud prints them.")

    def heading(path):
        depth = path.count(".") + 1
        w("")
        w("%s `%s`" % ("##" if depth == 1 else "###", path))
        text, _ = meaning(path)
        if text:
            w("")
            w(cell(text) + ("" if text.endswith(".") else "."))

    def section_of(path):
        """The heading a key's row goes under: its nearest ancestor mapping of depth 1 or 2."""
        parts = normal(path).replace("[]", "").split(".")
        return ".".join(parts[:min(2, len(parts) - 1)])

    headings = [p for p in order if kinds[p] == "section" and p.count(".") <= 1]
    for section in headings:
        heading(section)
        rows = [p for p in order if p not in headings and section_of(p) == section]
        if not rows:
            continue
        w("")
        w("| key | sim.yaml | hil.yaml, bench.yaml | left out | meaning |")
        w("|---|---|---|---|---|")
        for path in rows:
            kind = kinds[path]
            if kind in ("section", "entry"):
                shown_value, others = "", ""
            else:
                shown_value = code(values["sim"][path]) if path in values["sim"] else "—"
                others = elsewhere(path)
            w("| %s | %s | %s | %s | %s |" % (code(path), shown_value, others, when_left_out(path), cell(meaning(path)[0])))
    w("")
    return "\n".join(out), order, kinds, comment_text, values


# ------------------------------------------------------------------------------------------------
# The checks


def listed_keys(page):
    return set(re.findall(r"^\| `([^`]+)` \|", page, re.M)) | set(re.findall(r"^#+ `([^`]+)`", page, re.M))


def unstated_ranges(pneud, order, kinds, comment_text, values):
    """Numeric keys the loader refuses as out of range while their comment states no range."""
    problems = []
    for path in order:
        if kinds[path] != "value" or "[]" in path:
            continue
        name = next((n for n, _ in FILES if path in values[n]), None)
        try:
            float(values[name][path])
        except ValueError:
            continue
        if values[name][path] in ("true", "false"):
            continue
        rel = dict(FILES)[name]
        for probe in ("-9999999999", "9999999999"):  # integers: the integer keys take them too
            result = check_config(pneud, os.path.join(ROOT, rel), ["%s=%s" % (path, probe)])
            reason = result.stderr.partition("config: %s: " % path)[2]
            refused_here = result.returncode == 2 and "must" in reason
            if refused_here and not RANGE_MARKER.search(comment_text(path)):
                problems.append("%s = %s is refused (%s) but its comment states no range" %
                                (path, probe, result.stderr.strip().split("config: ", 1)[-1]))
                break
    return problems


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--pneud", required=True, help="the built pneud")
    group = parser.add_mutually_exclusive_group(required=True)
    group.add_argument("--out", help="write the page here")
    group.add_argument("--check", help="check this page")
    args = parser.parse_args()
    page, order, kinds, comment_text, values = build(args.pneud)
    if args.out:
        with open(args.out, "w") as f:
            f.write(page)
        return 0
    problems = []
    with open(args.check) as f:
        committed = f.read()
    if committed != page:
        diff = difflib.unified_diff(committed.splitlines(), page.splitlines(), args.check, "generated", lineterm="", n=1)
        problems.append("%s is stale; regenerate it with tools/docs/config_reference.py --out. Difference:\n%s" %
                        (args.check, "\n".join(list(diff)[:60])))
    listed = listed_keys(committed)
    for name, rel in FILES:
        for path, kind, _ in effective_keys(args.pneud, os.path.join(ROOT, rel)):
            if normal(path) not in listed:
                problems.append("%s: key %s (pneud --check-config) is missing from %s" % (rel, path, args.check))
    problems += unstated_ranges(args.pneud, order, kinds, comment_text, values)
    for p in problems:
        print("FAIL: " + p)
    print("%d keys; %s" % (len(order), "%d problems" % len(problems) if problems else "the reference is current"))
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
