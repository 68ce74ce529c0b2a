#!/usr/bin/env python3
# SPDX-License-Identifier: BSD-3-Clause
"""Lists the longest functions of C and C++ sources, and fails on one longer than a limit.

    function_lengths.py [--max N] [--top K] PATH...
                                   every function defined in the files under PATH (folders are
                                   walked), the K longest first (default 10); exit 1 naming
                                   every function longer than N lines (default 80)
    function_lengths.py --selftest check the finder on made-up sources

A function's length is its lines from the first line of its head (return type and name) to
its closing brace, both included: what a reader has to hold to follow it. Lambdas and local
classes count as part of the function they are written in; a lambda written outside any
function counts as a function of its own.

The finder reads the code, not the compiler's view of it: comments, string and character
literals and preprocessor lines are set aside, and a block is a function's body when what
precedes its brace closes a parameter list, outside any function. That is enough for code
written in the style of this repository; it is not a C++ parser.

Python 3 standard library only.
"""

import os
import re
import sys

SOURCE_EXT = (".h", ".hpp", ".c", ".cc", ".cpp")
SCOPE_HEAD = re.compile(r"\b(namespace|extern\s*\"C\"|class|struct|union|enum)\b")
NAME = re.compile(r"((?:[A-Za-z_]\w*\s*::\s*)*(?:operator\s*\(\)|operator\s*[^\s(]+|~?[A-Za-z_]\w*))"
                  r"\s*(?:<[^()]*>)?\s*\(")
# What may precede a function's head without being part of it, and what may sit inside it
# without being its name; both are blanked (lengths kept) before the head is read.
ACCESS = re.compile(r"^\s*(?:(?:public|private|protected)\s*:\s*)+")
ATTRIBUTE = re.compile(r"__attribute__\s*\(\([^()]*(?:\([^()]*\)[^()]*)*\)\)")
NOT_NAMES = ("if", "for", "while", "switch", "return", "sizeof", "decltype", "alignas", "catch")


def blank_out(text):
    """text with comments, literals and preprocessor lines turned into spaces, lines kept."""
    out, i, n = [], 0, len(text)
    at_line_start = True
    while i < n:
        c = text[i]
        if at_line_start and c == "#":
            # a directive, with its continuation lines
            j = i
            while j < n and text[j] != "\n":
                j += 2 if text[j] == "\\" else 1
            out.append(re.sub(r"[^\n]", " ", text[i:j]))
            i = j
            continue
        if c == "\n":
            at_line_start = True
        elif not c.isspace():
            at_line_start = False
        if c in "\"'":
            j = i + 1
            while j < n and text[j] != c and text[j] != "\n":
                j += 2 if text[j] == "\\" else 1
            out.append(c + " " * (j - i - 1) + (c if j < n and text[j] == c else ""))
            i = j + 1
        elif text.startswith("//", i):
            j = text.find("\n", i)
            j = n if j < 0 else j
            out.append(" " * (j - i))
            i = j
        elif text.startswith("/*", i):
            j = text.find("*/", i + 2)
            j = n if j < 0 else j + 2
            out.append(re.sub(r"[^\n]", " ", text[i:j]))
            i = j
        else:
            out.append(c)
            i += 1
    return "".join(out)


def matching(code, i):
    """The index of the brace that closes the one at code[i]."""
    depth = 0
    for j in range(i, len(code)):
        if code[j] == "{":
            depth += 1
        elif code[j] == "}":
            depth -= 1
            if depth == 0:
                return j
    return len(code) - 1


def head_params_end(head):
    """The index in head just past the parenthesis closing its first top-level parameter list,
    or -1 when head has none (a class, a namespace, an initializer)."""
    depth, seen = 0, -1
    for k, c in enumerate(head):
        if c == "(":
            depth += 1
        elif c == ")":
            depth -= 1
            if depth == 0 and seen < 0:
                seen = k + 1
    return seen


def function_name(head):
    """The name before head's parameter list ("" for a lambda)."""
    for m in NAME.finditer(head):
        if m.group(1) not in NOT_NAMES:
            return re.sub(r"\s+", "", m.group(1))
        if head.find("(") < m.start():
            break
    return ""


def functions(text):
    """[(name, first line, last line)] of every function defined in text (1-based lines)."""
    code = ATTRIBUTE.sub(lambda m: re.sub(r"[^\n]", " ", m.group(0)), blank_out(text))
    found = []
    head_start = 0  # where the text before the next brace begins
    i, n = 0, len(code)
    while i < n:
        c = code[i]
        if c in ";}":
            head_start = i + 1
            i += 1
            continue
        if c != "{":
            i += 1
            continue
        head = code[head_start:i]
        params = head_params_end(head)
        is_scope = SCOPE_HEAD.search(head) and (params < 0 or SCOPE_HEAD.search(head[:head.find("(")]))
        if params < 0 or (is_scope and not re.search(r"\)\s*(const|noexcept|override|final|->|\{|$)",
                                                      head[params - 1:])):
            # a namespace, a class or an initializer: look inside it for functions
            head_start = i + 1
            i += 1
            continue
        end = matching(code, i)
        after = code[end + 1:].lstrip()
        if re.search(r"\)\s*:", head[params - 1:]) and after[:1] in (",", "{"):
            # a member initialized with braces in a constructor's initializer list
            i = end + 1
            continue
        stripped = head[ACCESS.match(head).end():] if ACCESS.match(head) else head.lstrip()
        first = code.count("\n", 0, head_start + len(head) - len(stripped)) + 1
        last = code.count("\n", 0, end) + 1
        found.append((function_name(stripped) or "<lambda>", first, last))
        head_start = end + 1
        i = end + 1
    return found


def source_files(paths):
    for path in paths:
        if os.path.isfile(path):
            yield path
            continue
        for folder, dirs, names in os.walk(path):
            dirs[:] = sorted(d for d in dirs if not d.startswith("."))
            for name in sorted(names):
                if name.endswith(SOURCE_EXT):
                    yield os.path.join(folder, name)


def measure(paths):
    """[(lines, file, name, first line)] of every function, longest first."""
    rows = []
    for path in source_files(paths):
        with open(path, encoding="utf-8", errors="replace") as f:
            text = f.read()
        for name, first, last in functions(text):
            rows.append((last - first + 1, path, name, first))
    rows.sort(key=lambda r: (-r[0], r[1], r[3]))
    return rows


def selftest():
    source = '''// a comment with a brace {
#define BRACE {
namespace sba {
namespace {
struct Point {
  int x{0};
  int get() const { return x; }
};
}  // namespace

int two(int a,
        int b) {
  const char *s = "}";
  auto f = [&](int c) { return c + '{'; };
  if (a) {
    return f(b);
  }
  return 0;
}

class K {
 public:
  __attribute__((noinline)) K(int a) : a_{a}, b_(a) {
    a_ += 1;
  }
  ~K() noexcept {}
  bool operator()(int v) const
  {
    return v > a_;
  }
 private:
  int a_, b_;
};

extern "C" {
int c_entry(void) { return 1; }
}
}  // namespace sba
'''
    expected = [("get", 7, 7), ("two", 11, 19), ("K", 23, 25), ("~K", 26, 26),
                ("operator()", 27, 30), ("c_entry", 36, 36)]
    got = functions(source)
    if got != expected:
        print("selftest: expected %r, found %r" % (expected, got))
        return 1
    print("selftest: all %d functions found with their lines" % len(expected))
    return 0


def main(argv):
    args = argv[1:]
    if args == ["--selftest"]:
        return selftest()
    limit, top = 80, 10
    try:
        while args and args[0].startswith("--"):
            if args[0] == "--max":
                limit = int(args[1])
            elif args[0] == "--top":
                top = int(args[1])
            else:
                raise ValueError(args[0])
            args = args[2:]
    except (IndexError, ValueError):
        args = []
    if not args:
        print(__doc__.strip(), file=sys.stderr)
        return 2
    rows = measure(args)
    for lines, path, name, first in rows[:top]:
        print("%4d  %s:%d  %s" % (lines, path, first, name))
    over = [r for r in rows if r[0] > limit]
    for lines, path, name, first in over:
        print("%s:%d: %s is %d lines, over %d: cut it into named stages" % (path, first, name, lines, limit))
    return 1 if over else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
