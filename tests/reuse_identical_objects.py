#!/usr/bin/python3
"""Compiler launcher of the options-off build (tests/test_options_off.sh): an object whose compile
is the same as one of the main build's is taken from the main build instead of compiled again.

    reuse_identical_objects.py MAIN_BINARY_DIR OFF_BINARY_DIR [LAUNCHER...] -- COMPILER ARGS...

"The same" means: the main build's compile_commands.json holds a compile of the same object path
(relative to its binary directory), from the same directory (relative), with the same arguments
word for word apart from the object and depfile names (-o, -MF, -MT); no argument names either
binary directory (include directories there may hold different generated files); no file the
compile reads (the compiler's own -M list) lies in the options-off binary directory; and the main
build's object is newer than every one of those files and than the main build's
compile_commands.json (written at its last configure). Then the compiler would read the same
bytes with the same flags, warnings-as-errors included, and the main build already compiled them
without a diagnostic: the object is copied, with the depfile the build tool expects. Anything else
is compiled (through LAUNCHER, if given). Each decision is appended to OFF_BINARY_DIR/objects.log.
"""
import json
import os
import shlex
import shutil
import subprocess
import sys
import tempfile

PATH_OPTIONS = ("-o", "-MF", "-MT", "-MQ")


def option_value(args, option):
    for i, a in enumerate(args[:-1]):
        if a == option:
            return args[i + 1]
    return None


def without_paths(args):
    """The arguments less the object's and the depfile's (which compile_commands.json may omit)."""
    kept, skip = [], False
    for a in args:
        if skip:
            skip = False
        elif a in PATH_OPTIONS:
            skip = True
        elif a not in ("-MD", "-MMD"):
            kept.append(a)
    return kept


def inside(path, directory):
    path, directory = os.path.realpath(path), os.path.realpath(directory)
    return os.path.commonpath([path, directory]) == directory


def main_compile(main_dir, relative_object):
    """The main build's compile of this object: (its directory, its arguments), or None."""
    with open(os.path.join(main_dir, "compile_commands.json"), encoding="utf-8") as f:
        entries = json.load(f)
    for entry in entries:
        args = entry["arguments"] if "arguments" in entry else shlex.split(entry["command"])
        obj = option_value(args, "-o")
        if obj and os.path.relpath(os.path.join(entry["directory"], obj), main_dir) == relative_object:
            return entry["directory"], args
    return None


def files_read(compiler_args):
    """The files the compile reads, from the compiler's own dependency list (-M)."""
    args = [a for a in without_paths(compiler_args) if a != "-c"]
    with tempfile.NamedTemporaryFile(suffix=".d") as dep:
        subprocess.run(args + ["-M", "-MT", "x", "-MF", dep.name], check=True,
                       stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        text = open(dep.name, encoding="utf-8").read()
    words = text.replace("\\\n", " ").replace("\\ ", "\0").split()
    return [w.replace("\0", " ") for w in words[1:]]   # words[0] is the target "x:"


def depfile(compiler_args, files):
    target = option_value(compiler_args, "-MT") or option_value(compiler_args, "-o")
    return target + ": " + " ".join(f.replace(" ", "\\ ") for f in files) + "\n"


def why_not_reused(main_dir, off_dir, compiler_args):
    """None when the main build's object is this compile's; else the reason to compile."""
    obj = option_value(compiler_args, "-o")
    if obj is None or "-c" not in compiler_args:
        return "not a compile to an object"
    relative_object = os.path.relpath(os.path.abspath(obj), off_dir)
    try:
        found = main_compile(main_dir, relative_object)
    except (OSError, ValueError) as e:
        return f"no compile database in {main_dir}: {e}"
    if found is None:
        return "not compiled by the main build"
    directory, main_args = found
    if os.path.relpath(directory, main_dir) != os.path.relpath(os.getcwd(), off_dir):
        return "compiled from another directory"
    mine = without_paths(compiler_args)
    if without_paths(main_args) != mine:
        return "another command: " + " ".join(sorted(set(mine) ^ set(without_paths(main_args))))
    binary_dirs = {off_dir, main_dir, os.path.realpath(off_dir), os.path.realpath(main_dir)}
    for a in mine:
        if any(d in a for d in binary_dirs):
            return "an argument names a binary directory: " + a
    main_object = os.path.join(directory, option_value(main_args, "-o"))
    if not os.path.isfile(main_object):
        return "the main build has not built it"
    try:
        files = files_read(compiler_args)
    except (subprocess.CalledProcessError, OSError) as e:
        return f"the dependency list failed: {e}"
    built = os.stat(main_object).st_mtime_ns
    for f in files + [os.path.join(main_dir, "compile_commands.json")]:
        if inside(f, off_dir):
            return "reads a file generated here: " + f
        if os.stat(f).st_mtime_ns >= built:
            return "the main build's object is older than " + f
    shutil.copyfile(main_object, obj)
    dep = option_value(compiler_args, "-MF")
    if dep:
        with open(dep, "w", encoding="utf-8") as f:
            f.write(depfile(compiler_args, files))
    return None


def main(argv):
    if "--" not in argv or len(argv) < 4:
        sys.exit("usage: reuse_identical_objects.py MAIN_BINARY_DIR OFF_BINARY_DIR [LAUNCHER...] -- COMPILER ARGS...")
    split = argv.index("--")
    main_dir, off_dir = (os.path.abspath(d) for d in argv[1:3])
    launcher, compiler_args = argv[3:split], argv[split + 1:]
    obj = option_value(compiler_args, "-o") or "?"
    relative_object = os.path.relpath(os.path.abspath(obj), off_dir)
    reason = why_not_reused(main_dir, off_dir, compiler_args)
    with open(os.path.join(off_dir, "objects.log"), "a", encoding="utf-8") as log:
        log.write(f"reused {relative_object}\n" if reason is None
                  else f"compiled {relative_object} ({reason})\n")
    if reason is None:
        return 0
    os.execvp((launcher + compiler_args)[0], launcher + compiler_args)


if __name__ == "__main__":
    sys.exit(main(sys.argv))
