#!/usr/bin/env python3
# SPDX-License-Identifier: BSD-3-Clause
"""The programs a new user runs as the README says: `make demo` (the README's first command)
builds every program of demo/ and every `build/demo/NAME` that README.md runs, and still runs
eucsbademo on the demo problem; `cmake --build build --target NAME` builds the program NAME
(the target of a program is named as the program, not as a library).

usage: check_programs.py SOURCE_DIR BUILD_DIR NAME=FILE...
  NAME=FILE: the programs of demo/, by the target of each name and the file it builds
  ($<TARGET_FILE:NAME>).
Exit status 0 when all holds, 1 with a line per failure, 77 (skipped) without make.
"""
import os
import re
import shutil
import subprocess
import sys


def readme_programs(source):
    with open(os.path.join(source, "README.md"), encoding="utf-8") as f:
        return sorted(set(re.findall(r"\bbuild/demo/([A-Za-z0-9_]+)", f.read())))


def make_demo_commands(source, build):
    """The commands `make demo` runs, as make -n prints them (nothing is run)."""
    out = subprocess.run(["make", "-n", "-C", source, "demo", "BUILD=" + build], check=True,
                         capture_output=True, text=True).stdout
    return out.splitlines()


def built_targets(commands):
    """The targets of every `cmake --build ... --target A B ...` line."""
    targets = set()
    for line in commands:
        words = line.split()
        if "cmake" not in words[:1] or "--build" not in words or "--target" not in words:
            continue
        for word in words[words.index("--target") + 1:]:
            if word.startswith("-"):
                break
            targets.add(word)
    return targets


def main(argv):
    if len(argv) < 3:
        print(__doc__, file=sys.stderr)
        return 2
    source, build = os.path.abspath(argv[1]), os.path.abspath(argv[2])
    files = dict(arg.split("=", 1) for arg in argv[3:])
    if not shutil.which("make"):
        print("check_programs: no make: skipped")
        return 77
    readme = readme_programs(source)
    if not readme:
        return print("check_programs: README.md runs no build/demo/ program") or 1
    programs = sorted(set(readme) | set(files))
    commands = make_demo_commands(source, build)
    failures = []
    targets = built_targets(commands)
    for name in programs:
        if name not in targets:
            failures.append("make demo does not build the program %s (it builds: %s)"
                            % (name, " ".join(sorted(targets)) or "nothing"))
        if name not in files:
            failures.append("no program target is named %s, which README.md runs as build/demo/%s" % (name, name))
        elif os.path.abspath(files[name]) != os.path.join(build, "demo", name):
            failures.append("the target %s builds %s, not build/demo/%s"
                            % (name, os.path.relpath(files[name], build), name))
    demo = os.path.join(build, "demo", "eucsbademo") + " data/orbit-fixedK-cams.txt"
    if not any(line.startswith(demo) for line in commands):
        failures.append("make demo no longer runs eucsbademo on data/orbit-fixedK")
    for f in failures:
        print("check_programs: " + f)
    if not failures:
        print("check_programs: make demo builds %s, each the target of its name" % ", ".join(programs))
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
