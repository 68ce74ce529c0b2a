#!/usr/bin/env python3
# SPDX-License-Identifier: BSD-3-Clause
"""Two or more builds of a program on the same problems, in interleaved rounds: a before and an
after measured under the same state of the machine.

  python3 bench/interleave.py --builds before=DIR,after=DIR [--program demo/sbarefine]
      [--rounds 7] --case NAME='ARGS' [--case ...] [--out OUT]

Each round runs every case once with every build, one after the other (the builds' order
alternating from round to round), each run a process of its own with `--json FILE` appended to
its arguments: the program's own report, whose "seconds" (the solve, reading not included),
iterations and final error are taken. On a machine whose state changes from one minute to the
next (bench/README.md, core_states.py), runs taken minutes apart differ by more than most
changes do; runs taken in turn share the state. Reported per case and build: the median and
the range of the seconds, the iterations and final errors seen (a set: one value where every
run agrees), and each build's median over the first's.

Writes OUT.md (the table and the command) and OUT.json (one JSON object a run).
"""
import argparse
import datetime
import json
import os
import shlex
import statistics
import subprocess
import sys
import tempfile


def main(argv):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--builds", required=True, help="NAME=DIR,...: build directories, the first the reference")
    ap.add_argument("--program", default="demo/sbarefine", help="the program, relative to each build")
    ap.add_argument("--rounds", type=int, default=7)
    ap.add_argument("--case", action="append", required=True, help="NAME=ARGS: the program's arguments")
    ap.add_argument("--out", default="")
    a = ap.parse_args(argv)
    builds = [b.partition("=")[::2] for b in a.builds.split(",")]
    cases = [c.partition("=")[::2] for c in a.case]
    work = tempfile.mkdtemp(prefix="interleave.")
    runs = []
    for rnd in range(a.rounds):
        order = builds if rnd % 2 == 0 else builds[::-1]
        for case, args in cases:
            for name, build in order:
                js = os.path.join(work, "r.json")
                cmd = [os.path.join(build, a.program)] + shlex.split(args) + ["--json", js]
                subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
                with open(js, encoding="utf-8") as f:
                    d = json.load(f)
                runs.append({"round": rnd, "case": case, "build": name, "seconds": d["seconds"],
                             "iterations": d["info"]["iterations"], "final_error": d["info"]["final_error"],
                             "command": cmd})
        print("round %d of %d done" % (rnd + 1, a.rounds), file=sys.stderr)
    lines = ["# %s of %s, interleaved" % (a.program, ", ".join(n for n, _ in builds)), "",
             "Written by `bench/interleave.py` (see its opening comment) on %s UTC, %d rounds:" %
             (datetime.datetime.utcnow().strftime("%Y-%m-%d %H:%M"), a.rounds), "",
             "    python3 bench/interleave.py " + " ".join(shlex.quote(x) for x in argv), "",
             "| case | build | median s | range s | iterations | final error | / %s |" % builds[0][0],
             "|---|---|---:|---:|---|---|---:|"]
    for case, _ in cases:
        ref = None
        for name, _ in builds:
            rs = [r for r in runs if r["case"] == case and r["build"] == name]
            secs = [r["seconds"] for r in rs]
            med = statistics.median(secs)
            ref = med if ref is None else ref
            its = sorted({r["iterations"] for r in rs})
            errs = sorted({"%.10e" % r["final_error"] for r in rs})
            lines.append("| %s | %s | %.3f | %.3f-%.3f | %s | %s | %.2fx |" %
                         (case, name, med, min(secs), max(secs), ", ".join(map(str, its)), ", ".join(errs),
                          med / ref))
    text = "\n".join(lines) + "\n"
    print(text)
    if a.out:
        with open(a.out + ".md", "w", encoding="utf-8") as f:
            f.write(text)
        with open(a.out + ".json", "w", encoding="utf-8") as f:
            for r in runs:
                f.write(json.dumps(r) + "\n")


if __name__ == "__main__":
    main(sys.argv[1:])
