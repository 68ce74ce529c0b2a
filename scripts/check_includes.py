#!/usr/bin/env python3
# SPDX-License-Identifier: BSD-3-Clause
"""Checks the include graph of the project's own sources: no cycle, no catch-all header, and
the library's layers in their order.

    check_includes.py [REPO]      check REPO's src/, lib/, demo/ and python/src/ (default: the
                                  repository this script is in); exit 1 naming what is wrong
    check_includes.py --selftest  check that the checks find a cycle, a catch-all header, an
                                  upward include and a file in no layer in made-up trees, and
                                  pass a clean one

The graph is drawn between modules, not files: foo.h, the foo.cpp that implements it and the
foo_impl.h that foo.cpp compiles are one module, since an arrow into foo.cpp is an arrow into foo. So a cycle is also found where
two modules each use the other through their .cpp files only (a.cpp includes b.h and b.cpp
includes a.h), which no compiler notices but which ties the two together all the same.

A catch-all header holds nothing but includes (and its guard): it hides what a file really
uses, and every file that includes it depends on all of it.

The layers are read from tables of docs/architecture.md, top to bottom, so that the document
the reader is sent to is the one the check holds the code to: the library's (src/) from the
table under "## Layers", lib/'s from the table under "## Layers of lib/". Each row names its
files in backquotes in its second column, as paths under its folder (the "src/" or "lib/" may
be written or left out) or as patterns ("kernels.*", "solver_*.cpp", "cameras/*"); names of
files outside the folder (sba.h) match nothing there. Every file of the folder must be named
by exactly one row, and may include only files of its own row and the rows below it, and
nothing of the folder's clients: src/ includes nothing of lib/, demo/ or python/src/, which
sit above the whole library; lib/ includes nothing of demo/ or python/src/, its clients, nor
of src/, which it uses through the public headers only.

Only quoted includes are followed ("x.h"), resolved against the including file's folder, then
against each checked folder; what resolves to no file of a checked folder (sba.h, the
generated LAPACK header, system headers) is outside the graph.

Python 3 standard library only.
"""

import fnmatch
import os
import re
import sys
import tempfile

ROOTS = ("src", "lib", "demo", "python/src")
LAYER_DOC = "docs/architecture.md"
# The folders held to layers: each with the heading of its table in LAYER_DOC and how an
# include out of the folder is said.
LAYERED = (("src", "## Layers", "a client of the library"),
           ("lib", "## Layers of lib/", "outside lib/ (lib/ uses the library through its public headers only)"))
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


def file_includes(repo, files, roots):
    """Every (file, included file) pair among the checked files, in file order."""
    known = set(files)
    pairs = []
    for f in files:
        for line in strip_comments(read(repo, f)).splitlines():
            m = INCLUDE.match(line)
            if m:
                target = resolve(m.group(1), f, known, roots)
                if target is not None:
                    pairs.append((f, target))
    return pairs


def include_edges(files, includes):
    """{module: {included module: (file, included file)}}: one example arrow per pair."""
    edges = {module(f): {} for f in files}
    for f, target in includes:
        if module(target) != module(f):
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


def read_layers(repo, folder, heading):
    """[(layer, [pattern, ...]), ...] from the table under heading in LAYER_DOC, top row first;
    patterns relative to folder."""
    path = os.path.join(repo, LAYER_DOC)
    if not os.path.isfile(path):
        return []
    rows, in_section = [], False
    for line in read(repo, LAYER_DOC).splitlines():
        if line.startswith("#"):
            in_section = line.strip() == heading
            continue
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if not in_section or not line.lstrip().startswith("|") or len(cells) < 2:
            continue
        if cells[0] == "layer" or set(cells[0]) <= set("-: "):
            continue  # the header row and the line under it
        names = re.findall(r"`([^`]+)`", cells[1])
        prefix = folder + "/"
        rows.append((cells[0], [n[len(prefix):] if n.startswith(prefix) else n for n in names]))
    return rows


def find_layer_violations(repo, files, includes, folder, heading, outside):
    """One message per file of folder in no layer or in two, and per include that points up
    its table or out of the folder."""
    rows = read_layers(repo, folder, heading)
    own = [f for f in files if f.startswith(folder + "/")]
    if not rows:
        return ["%s has no table under \"%s\": the layers cannot be checked" % (LAYER_DOC, heading)] \
            if own else []
    messages, level = [], {}
    for f in own:
        name = f[len(folder) + 1:]
        found = [i for i, (_, patterns) in enumerate(rows)
                 if any(fnmatch.fnmatchcase(name, p) for p in patterns)]
        if not found:
            messages.append("%s is in no layer of %s's table: add it to the row it belongs to"
                            % (f, LAYER_DOC))
        elif len(found) > 1:
            messages.append("%s is in two layers of %s's table: %s" % (
                f, LAYER_DOC, " and ".join(rows[i][0] for i in found)))
        else:
            level[f] = found[0]  # 0 is the top row
    for f, target in includes:
        if f not in level:
            continue
        if not target.startswith(folder + "/"):
            messages.append("%s includes %s, %s" % (f, target, outside))
        elif target in level and level[target] < level[f]:
            messages.append("upward include: %s (%s) includes %s (%s, above it)" % (
                f, rows[level[f]][0], target, rows[level[target]][0]))
    return messages


def check(repo, roots=ROOTS):
    roots = [r for r in roots if os.path.isdir(os.path.join(repo, r))]
    files = source_files(repo, roots)
    includes = file_includes(repo, files, roots)
    messages = find_cycles(include_edges(files, includes)) + find_catch_alls(repo, files)
    for folder, heading, outside in LAYERED:
        messages += find_layer_violations(repo, files, includes, folder, heading, outside)
    return messages


def layers_doc(*rows, lib=(("all", "`*`"),)):
    """A made-up docs/architecture.md whose layers tables have these (layer, where) rows: src/'s
    and lib/'s."""
    def table(heading, table_rows):
        return "## %s\n\n| layer | where | what it holds |\n|---|---|---|\n" % heading + \
            "".join("| %s | %s | things |\n" % row for row in table_rows) + "\n"
    return "# Architecture\n\n" + table("Layers", rows) + table("Layers of lib/", lib) + \
        "## Rules\n\n| a | `*` |\n"


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
                         ["include cycle demo/x -> src/y -> demo/x",
                          "src/y.h includes demo/x.h, a client of the library"]),
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
        # layers: a file may include its own row and the rows below it, never a row above
        "layers_down": ({LAYER_DOC: layers_doc(("top", "`src/a.*`"), ("bottom", "`b.h`, `c_*.h`")),
                         "src/a.h": '#include "b.h"\nint a;\n', "src/a.cpp": '#include "c_x.h"\n',
                         "src/b.h": '#include "c_x.h"\nint b;\n', "src/c_x.h": "int c;\n"},
                        []),
        "upward_include": ({LAYER_DOC: layers_doc(("top", "`a.h`"), ("bottom", "`b.*`")),
                            "src/a.h": "int a;\n", "src/b.cpp": '#include "a.h"\n'},
                           ["upward include: src/b.cpp (bottom) includes src/a.h (top, above it)"]),
        "client_include": ({"src/a.cpp": '#include "../demo/x.h"\n', "demo/x.h": "int x;\n"},
                           ["src/a.cpp includes demo/x.h, a client of the library"]),
        "no_layer": ({LAYER_DOC: layers_doc(("top", "`a.h`, `sba.h`")),
                      "src/a.h": "int a;\n", "src/c.h": "int c;\n"},
                     ["src/c.h is in no layer"]),
        "two_layers": ({LAYER_DOC: layers_doc(("top", "`*.h`"), ("bottom", "`a.h`")), "src/a.h": "int a;\n"},
                       ["src/a.h is in two layers of %s's table: top and bottom" % LAYER_DOC]),
        # lib/'s layers: generator -> formats -> cameras, by folder
        "lib_layers_down": ({LAYER_DOC: layers_doc(("all", "`*`"), lib=(
                                 ("generator", "`generator/*`"), ("formats", "`lib/formats/*`"),
                                 ("cameras", "`cameras/*`"))),
                             "lib/generator/g.h": '#include "formats/f.h"\n#include "cameras/c.h"\nint g;\n',
                             "lib/formats/f.h": '#include "cameras/c.h"\n#include "sba.h"\nint f;\n',
                             "lib/cameras/c.h": "int c;\n", "lib/cameras/c.cpp": '#include "cameras/c.h"\n'},
                            []),
        "lib_upward_include": ({LAYER_DOC: layers_doc(("all", "`*`"), lib=(
                                    ("formats", "`formats/*`"), ("cameras", "`cameras/*`"))),
                                "lib/formats/f.h": "int f;\n", "lib/cameras/c.cpp": '#include "formats/f.h"\n'},
                               ["upward include: lib/cameras/c.cpp (cameras) includes lib/formats/f.h "
                                "(formats, above it)"]),
        "lib_includes_the_library": ({"lib/formats/f.cpp": '#include "../../src/a.h"\n', "src/a.h": "int a;\n"},
                                     ["lib/formats/f.cpp includes src/a.h, outside lib/"]),
        "lib_no_layer": ({LAYER_DOC: layers_doc(("all", "`*`"), lib=(("cameras", "`cameras/*`"),)),
                          "lib/cameras/c.h": "int c;\n", "lib/extra/e.h": "int e;\n"},
                         ["lib/extra/e.h is in no layer"]),
        "lib_no_table": ({LAYER_DOC: "# Architecture\n\n## Layers\n\n| layer | where |\n|---|---|\n| x | `*` |\n",
                          "lib/cameras/c.h": "int c;\n"},
                         ["%s has no table under \"## Layers of lib/\"" % LAYER_DOC]),
        # a table under another heading is not the layers' table
        "no_table": ({LAYER_DOC: "# Architecture\n\n## Other\n\n| layer | where |\n|---|---|\n| x | `*` |\n",
                      "src/a.h": "int a;\n"},
                     ["%s has no table under \"## Layers\"" % LAYER_DOC]),
    }
    failed = 0
    for name, (tree, expected) in sorted(cases.items()):
        with tempfile.TemporaryDirectory() as repo:
            if LAYER_DOC not in tree:
                tree = dict(tree, **{LAYER_DOC: layers_doc(("all", "`*`"))})
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
    print("include graph of %s: no cycle, no catch-all header, %s's layers in order" % (", ".join(
        r for r in ROOTS if os.path.isdir(os.path.join(repo, r))), LAYER_DOC))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
