#!/usr/bin/env python3
# SPDX-License-Identifier: BSD-3-Clause
"""Checks the include graph of the project's own sources: no cycle, no catch-all header.

    check_includes.py [REPO]      check REPO's src/, demo/ and python/src/ (default: the
                                  repository this script is in); exit 1 naming what is wrong
    check_includes.py --selftest  check that the checks find a cycle and a catch-all header in
                                  a made-up tree, and pass a clean one

The graph is drawn between modules, not files: foo.h, the foo.cpp that implements it and the
foo_impl.h that foo.cpp compiles are one module, since an arrow into foo.cpp is an arrow into foo. So a cycle is also found where
two modules each use the other through their .cpp files only (a.cpp includes b.h and b.cpp
includes a.h), which no compiler notices but which ties the two together all the same.

A catch-all header holds nothing but includes (and its guard): it hides what a file really
uses, and every file that includes it depends on all of it.

Only quoted includes are followed ("x.h"), resolved against the including file's folder, then
against each checked folder; what resolves to no file of a checked folder (sba.h, the
generated LAPACK header, system headers) is outside the graph.

Python 3 standard library only.
"""

import os
import re
import sys
import tempfile

ROOTS = ("src", "demo", "python/src")
HEADER_EXT = (".h", ".hpp")
SOURCE_EXT = HEADER_EXT + (".c", ".cc", ".cpp")

INCLUDE = re.compile(r'^\s*#\s*include\s*"([^"]+)"')
# The lines a header may have that say nothing of its own: includes and its guard.
EMPTY_LINE = re.compile(r"^\s*(#\s*include\b.*|#\s*pragma\s+once\s*|#\s*ifndef\s+\w+\s*|"
                        r"#\s*define\s+\w+\s*|#\s*endif\b.*|)$")


def strip_comments(text):
    """text without its comments (line and block), string literals left as they are."""
    out, i, n = [], 0, len(text)
    while i < n:
        c = text[i]
        if c == '"' or c == "'":
            j = i + 1
            while j < n and text[j] != c and text[j] != "\n":
                j += 2 if text[j] == "\\" else 1
            out.append(text[i:j + 1])
            i = j + 1
        elif text.startswith("//", i):
            j = text.find("\n", i)
            i = n if j < 0 else j
        elif text.startswith("/*", i):
            j = text.find("*/", i + 2)
            out.append("\n" * text.count("\n", i, n if j < 0 else j))
            i = n if j < 0 else j + 2
        else:
            out.append(c)
            i += 1
    return "".join(out)


def source_files(repo, roots):
    """Every source file under the roots, as paths relative to repo with '/' separators."""
    files = []
    for root in roots:
        top = os.path.join(repo, root)
        for folder, dirs, names in os.walk(top):
            dirs[:] = sorted(d for d in dirs if not d.startswith("."))
            for name in sorted(names):
                if name.endswith(SOURCE_EXT):
                    rel = os.path.relpath(os.path.join(folder, name), repo)
                    files.append(rel.replace(os.sep, "/"))
    return files


def module(path):
    """foo for foo.h, foo.cpp and foo_impl.h (the implementation a foo*.cpp includes)."""
    stem = os.path.splitext(path)[0]
    return stem[:-len("_impl")] if stem.endswith("_impl") else stem


def resolve(name, including, known, roots):
    """The checked file that `#include "name"` in `including` means, or None."""
    candidates = [os.path.dirname(including)] + list(roots)
    for folder in candidates:
        path = os.path.normpath(os.path.join(folder, name)).replace(os.sep, "/")
        if path in known:
            return path
    return None


def read(repo, path):
    with open(os.path.join(repo, path), encoding="utf-8", errors="replace") as f:
        return f.read()


def include_edges(repo, files, roots):
    """{module: {included module: (file, included file)}}: one example arrow per pair."""
    known = set(files)
    edges = {module(f): {} for f in files}
    for f in files:
        for line in strip_comments(read(repo, f)).splitlines():
            m = INCLUDE.match(line)
            if not m:
                continue
            target = resolve(m.group(1), f, known, roots)
            if target is None or module(target) == module(f):
                continue
            edges[module(f)].setdefault(module(target), (f, target))
    return edges


def strongly_connected(edges):
    """Tarjan's components of the graph, iteratively (no recursion limit to meet)."""
    index, low, on_stack, stack, comps = {}, {}, set(), [], []
    counter = 0
    for start in sorted(edges):
        if start in index:
            continue
        work = [(start, iter(sorted(edges[start])))]
        index[start] = low[start] = counter
        counter += 1
        stack.append(start)
        on_stack.add(start)
        while work:
            node, children = work[-1]
            advanced = False
            for child in children:
                if child not in index:
                    index[child] = low[child] = counter
                    counter += 1
                    stack.append(child)
                    on_stack.add(child)
                    work.append((child, iter(sorted(edges.get(child, {})))))
                    advanced = True
                    break
                if child in on_stack:
                    low[node] = min(low[node], index[child])
            if advanced:
                continue
            work.pop()
            if work:
                parent = work[-1][0]
                low[parent] = min(low[parent], low[node])
            if low[node] == index[node]:
                comp = []
                while True:
                    top = stack.pop()
                    on_stack.discard(top)
                    comp.append(top)
                    if top == node:
                        break
                comps.append(sorted(comp))
    return comps


def one_cycle(edges, comp):
    """A shortest cycle through comp's first module, inside comp, as a list of modules."""
    members = set(comp)
    start = comp[0]
    came_from = {start: None}
    frontier = [start]
    while frontier:
        nxt = []
        for node in frontier:
            for child in sorted(edges[node]):
                if child not in members:
                    continue
                if child == start:
                    path = [node]
                    while came_from[path[-1]] is not None:
                        path.append(came_from[path[-1]])
                    return list(reversed(path)) + [start]
                if child not in came_from:
                    came_from[child] = node
                    nxt.append(child)
        frontier = nxt
    return [start, start]


def find_cycles(edges):
    """One message per include cycle, each arrow named by a file that makes it."""
    messages = []
    for comp in strongly_connected(edges):
        if len(comp) < 2:
            continue
        cycle = one_cycle(edges, comp)
        arrows = ["%s includes %s" % edges[a][b] for a, b in zip(cycle, cycle[1:])]
        messages.append("include cycle %s: %s%s" % (
            " -> ".join(cycle), "; ".join(arrows),
            "" if len(comp) == len(cycle) - 1 else
            "; the cycle also reaches %s" % ", ".join(m for m in comp if m not in cycle)))
    return messages


def find_catch_alls(repo, files):
    """One message per header that holds nothing but includes."""
    messages = []
    for f in files:
        if not f.endswith(HEADER_EXT):
            continue
        lines = strip_comments(read(repo, f)).splitlines()
        if not any(INCLUDE.match(line) for line in lines):
            continue
        if all(EMPTY_LINE.match(line) for line in lines):
            messages.append("%s holds nothing but includes: include what it includes instead" % f)
    return messages


def check(repo, roots=ROOTS):
    roots = [r for r in roots if os.path.isdir(os.path.join(repo, r))]
    files = source_files(repo, roots)
    return find_cycles(include_edges(repo, files, roots)) + find_catch_alls(repo, files)


def selftest():
    cases = {
        # header cycle: a.h -> b.h -> a.h
        "header_cycle": ({"src/a.h": '#include "b.h"\nint a;\n', "src/b.h": '#include "a.h"\nint b;\n'},
                         ["include cycle src/a -> src/b -> src/a"]),
        # the arrow back runs through a .cpp: a.cpp -> b.h -> a.h
        "module_cycle": ({"src/a.h": "int a();\n", "src/a.cpp": '#include "a.h"\n#include "b.h"\n',
                          "src/b.h": '#include "a.h"\nint b();\n'},
                         ["include cycle src/a -> src/b -> src/a"]),
        # across folders, resolved against a checked folder: demo/x.cpp -> src/y.h -> demo/x.h
        "folder_cycle": ({"demo/x.h": "int x();\n", "demo/x.cpp": '#include "y.h"\n',
                          "src/y.h": '#include "../demo/x.h"\nint y();\n'},
                         ["include cycle demo/x -> src/y -> demo/x"]),
        # an implementation header belongs to its module: k.cpp -> k_impl.h -> k.h is no cycle
        "impl_header": ({"src/k.h": "int k();\n", "src/k.cpp": '#include "k_impl.h"\n',
                         "src/k_impl.h": '#include "k.h"\nint k() { return 0; }\n'},
                        []),
        "catch_all": ({"src/all.h": '/* all */\n#ifndef ALL_H\n#define ALL_H\n#include "a.h"\n'
                                    '// nothing else\n#endif\n',
                       "src/a.h": "int a;\n"},
                      ["src/all.h holds nothing but includes"]),
        "clean": ({"src/a.h": '#include "b.h"\n// #include "a.h"\n#define A 1\n',
                   "src/a.cpp": '#include "a.h"\n#include "b.h"\n#include "sba.h"\n',
                   "src/b.h": "#ifndef B_H\n#define B_H\n#include <vector>\nint b;\n#endif\n",
                   "src/v.h": '#ifndef V_H\n#define V_H\n#pragma GCC visibility push(default)\n'
                              '#include "b.h"\n#pragma GCC visibility pop\n#endif\n'},
                  []),
    }
    failed = 0
    for name, (tree, expected) in sorted(cases.items()):
        with tempfile.TemporaryDirectory() as repo:
            for path, text in tree.items():
                os.makedirs(os.path.join(repo, os.path.dirname(path)), exist_ok=True)
                with open(os.path.join(repo, path), "w", encoding="utf-8") as f:
                    f.write(text)
            found = check(repo)
        ok = len(found) == len(expected) and all(
            any(msg.startswith(want) for msg in found) for want in expected)
        if not ok:
            failed += 1
            print("selftest %s: expected %r, found %r" % (name, expected, found))
    print("selftest: %d of %d cases failed" % (failed, len(cases)) if failed else
          "selftest: all %d cases pass" % len(cases))
    return 1 if failed else 0


def main(argv):
    if argv[1:] == ["--selftest"]:
        return selftest()
    if len(argv) > 2 or (len(argv) == 2 and argv[1].startswith("-")):
        print(__doc__.strip(), file=sys.stderr)
        return 2
    repo = argv[1] if len(argv) == 2 else os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    problems = check(repo)
    for msg in problems:
        print(msg)
    if problems:
        return 1
    print("include graph of %s: no cycle, no catch-all header" % ", ".join(
        r for r in ROOTS if os.path.isdir(os.path.join(repo, r))))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
