#!/usr/bin/env python3
# SPDX-License-Identifier: BSD-3-Clause
"""--json of eucsbademo and balsba, checked against the summary the same run printed.

usage: check_json.py EUCSBADEMO BALSBA PROJECT_DIR SHARED_DATA_DIR SCRATCH_DIR

Every number the JSON object and the printed lines share must agree: the sizes (balsba's
"unknowns", which it does not print, equal to its "variables": it holds nothing), every info[]
value the "SBA returned" line shows, the RMS errors, the stop reason, the solver and threads.
The JSON's own additions are checked for consistency: one iteration entry per iteration, the
last one's error equal to info[1], and per-camera observations and RMS that add up to the
totals.
"""
import json
import math
import os
import re
import subprocess
import sys

failures = []


def check(ok, what):
    if not ok:
        failures.append(what)


def close(a, b, rel):
    return abs(a - b) <= rel * max(abs(a), abs(b))


RETURNED = re.compile(r"SBA returned (-?\d+) in (\d+) iter, reason (\d+), error (\S+) \[initial (\S+)\], "
                      r"(\d+)/(\d+) func/fjac evals, (\d+) lin\. systems")
RMS = re.compile(r"RMS reprojection error: initial (\S+) px, final (\S+) px")
STOP = re.compile(r"Stop reason (\d+): (.+)")
SOLVER = re.compile(r"Solver (\S+)( \(auto\))? on (\d+) threads?(?:, strategy (\S+))?, (\d+\.\d+) s")


def run(label, cmd, sizes_re, json_path, weighted, asked=None, all_unknown=None):
    """all_unknown: None for a program whose report counts no unknowns (eucsbademo: no
    "unknowns" key), True where every parameter is one (balsba without --mcon and --ncon)."""
    proc = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    if proc.returncode != 0:
        failures.append("%s: exit status %d: %s" % (label, proc.returncode, proc.stderr))
        return
    out = proc.stdout
    with open(json_path) as f:
        j = json.load(f)
    info = j["info"]
    sizes = j["sizes"]
    check(j["options"]["solver"] == asked, "%s: options.solver %r, expected %r" % (label, j["options"]["solver"], asked))

    m = re.search(sizes_re, out)
    check(m is not None, "%s: no sizes line in\n%s" % (label, out))
    if m:
        printed = {k: int(v) for k, v in m.groupdict().items()}
        for k, v in printed.items():
            check(sizes[k] == v, "%s: sizes.%s %s, printed %d" % (label, k, sizes[k], v))
    nobs = sizes["observations"]
    # "variables" counts the parameters as sba 1.6 does; "unknowns" what the solve estimates.
    check(("unknowns" in sizes) == (all_unknown is not None), "%s: sizes %s" % (label, sorted(sizes)))
    if all_unknown:
        check(sizes["unknowns"] == sizes["variables"], "%s: sizes.unknowns %s, variables %s" %
              (label, sizes["unknowns"], sizes["variables"]))

    m = RETURNED.search(out)
    check(m is not None, "%s: no 'SBA returned' line" % label)
    if m:
        ret, iters, reason, err, err0, nfunc, njac, nlin = m.groups()
        check(j["ret"] == int(ret), "%s: ret %s, printed %s" % (label, j["ret"], ret))
        for name, printed in (("iterations", iters), ("stop_reason", reason), ("function_evals", nfunc),
                              ("jacobian_evals", njac), ("linear_systems", nlin)):
            check(info[name] == int(printed), "%s: info.%s %s, printed %s" % (label, name, info[name], printed))
        # %g keeps 6 significant digits.
        check(close(info["final_error"] / nobs, float(err), 5e-6), "%s: final error %s / %d, printed %s" %
              (label, info["final_error"], nobs, err))
        check(close(info["initial_error"] / nobs, float(err0), 5e-6), "%s: initial error %s / %d, printed %s" %
              (label, info["initial_error"], nobs, err0))

    m = RMS.search(out)
    check(m is not None, "%s: no RMS line" % label)
    if m:
        check(close(j["rms_px"]["initial"], float(m.group(1)), 5e-6), "%s: rms initial" % label)
        check(close(j["rms_px"]["final"], float(m.group(2)), 5e-6), "%s: rms final" % label)
        # Without a loss the squared error is info's: RMS^2 is the printed mean squared error.
        check(close(j["rms_px"]["final"] ** 2, info["final_error"] / nobs, 1e-12), "%s: rms^2 != error" % label)

    m = STOP.search(out)
    check(m is not None and int(m.group(1)) == info["stop_reason"] and m.group(2) == j["stop_reason"],
          "%s: stop line %r against %s / %r" % (label, m and m.group(0), info["stop_reason"], j["stop_reason"]))
    m = SOLVER.search(out)
    # The solver that ran, never "auto"; "(auto)" after it where auto chose it.
    check(m is not None and m.group(1) == j["solver"] and j["solver"] != "auto"
          and bool(m.group(2)) == (j["options"]["solver"] == "auto") and int(m.group(3)) == j["threads"]
          and (m.group(4) or "sba") == j["strategy"],
          "%s: solver line %r against %s (asked %s) / %s / %s" % (label, m and m.group(0), j["solver"],
                                                                   j["options"]["solver"], j["threads"], j["strategy"]))
    if m:
        check(abs(float(m.group(5)) - j["seconds"]) <= 0.0005 + 1e-9, "%s: seconds" % label)

    its = j["iterations"]
    check([it["iteration"] for it in its] == list(range(1, info["iterations"] + 1)),
          "%s: iterations %s" % (label, [it["iteration"] for it in its]))
    if its:
        check(its[-1]["error"] == info["final_error"], "%s: last iteration's error %s, info[1] %s" %
              (label, its[-1]["error"], info["final_error"]))
        times = [it["seconds"] for it in its]
        check(times == sorted(times) and times[-1] <= j["seconds"] + 1e-3, "%s: iteration times" % label)

    cams = j["cameras"]
    check(len(cams) == sizes["cameras"], "%s: %d camera entries" % (label, len(cams)))
    check(sum(c["observations"] for c in cams) == nobs, "%s: camera observations add up" % label)
    if not weighted:
        total = sum(c["rms_px"] ** 2 * c["observations"] for c in cams if c["observations"])
        check(close(math.sqrt(total / nobs), j["rms_px"]["final"], 1e-9),
              "%s: per-camera RMS %s against %s" % (label, math.sqrt(total / nobs), j["rms_px"]["final"]))


def main():
    eucsbademo, balsba, project, shared, scratch = sys.argv[1:6]
    os.makedirs(scratch, exist_ok=True)
    data = os.path.join(project, "data")
    sizes_euc = (r"SBA using (?P<points>\d+) 3D pts, (?P<cameras>\d+) frames and (?P<observations>\d+) image "
                 r"projections, (?P<variables>\d+) variables")
    for name, extra in (("orbit-fixedK", []), ("orbit-varKD", ["--solver=sparse-chol", "--threads=2"])):
        files = [os.path.join(data, "%s-%s.txt" % (name, part)) for part in ("cams", "pts", "calib")]
        files = [f for f in files if os.path.exists(f)]
        out = os.path.join(scratch, name + ".json")
        # eucsbademo's default is sba 1.6's chol, asked for by no one.
        run("eucsbademo " + name, [eucsbademo, "--json=" + out] + extra + files, sizes_euc, out, False,
            "sparse-chol" if extra else None)
    bal = os.path.join(shared, "bal", "problem-49-7776-pre.txt.bz2")
    if os.path.exists(bal):
        out = os.path.join(scratch, "bal.json")
        run("balsba", [balsba, bal, "--itmax=5", "--strategy=trust-region", "--json", out],
            r": (?P<cameras>\d+) cameras, (?P<points>\d+) points, (?P<observations>\d+) observations, "
            r"(?P<variables>\d+) variables", out, False, "auto", all_unknown=True)
    else:
        print("check_json: %s is absent: balsba not checked" % bal)
    for f in failures:
        print("check_json: " + f, file=sys.stderr)
    if not failures:
        print("check_json: the JSON objects agree with the printed summaries")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
