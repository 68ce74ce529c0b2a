#!/usr/bin/env python3
# SPDX-License-Identifier: BSD-3-Clause
"""Compare eucsbademo with sba 1.6's own demo on the sba distribution's seven data sets.

sba 1.6 is not bitwise reproducible: its results move with the BLAS's thread count, the BLAS's
kernels and the compiler's rounding. Its envelope is two builds (plain, and with FMA
contraction), each at 1 and 2 OpenBLAS threads, under each OpenBLAS kernel named by
--coretypes (OPENBLAS_CORETYPE; "default" is the one OpenBLAS picks for the CPU). Given a
directory that holds 1.6's demo built once per compile-time variant
(BUILD/eucsbademo16-HOWTO-DRIVER-JACOBIAN for the builds named by --builds), this script runs
those reference runs and ours on every variant
(HOWTO motstr, mot, str, mot-then-motstr; DRIVER expert or simple; JACOBIAN analytic or
numeric; the simple structure-only ones only with --simple-str: they take minutes) and
reports two judgements:

(a) "minimum": ours ends at 1.6's minimum (the printed error equal where 1.6's runs
    agree, else within their range; on the flat valleys of 7camsvarK and 9camsvarK within
    0.2% of that range, and there the iterations within [min/1.25 - 3, 1.25 max + 3] of
    1.6's), and does not run into itmax where 1.6 stops.
(b) "in kind", against each build's runs: iterations within that window of the build's,
    the stop reason one of theirs (2 and 4 stand for each other), the function and
    Jacobian evaluations and the linear systems each within 35% of one of the build's, and
    the minimum as in (a). The same judgement of each of 1.6's builds against the other is
    printed beside it: what "as close as 1.6 is to itself" means.

1.6's runs are cached (--cache) since they do not change. --envelope prints, for each
variant, the range of 1.6's iterations and final errors over all its runs: the figures the
tests' tables of 1.6's behaviour hold. Example:

  scripts/compare_sba16.py --sba16 PATH/sba16 --data PATH/sba-demo \\
      --demo build/demo/eucsbademo --cache /tmp/sba16.json \\
      --coretypes default,Haswell,SandyBridge,Nehalem,Prescott --envelope
"""
import argparse
import concurrent.futures
import json
import os
import re
import subprocess
import sys

SETS = ["7cams", "9cams", "54cams", "7camsvarK", "9camsvarK", "54camsvarK", "54camsvarKD"]
FLAT = {"7camsvarK", "9camsvarK"}
HOWTOS = ["motstr", "mot", "str", "mot-then-motstr"]
OUR_REFINE = {"motstr": "motstr", "mot": "mot", "str": "str", "mot-then-motstr": "mot-motstr"}
RETURNED = re.compile(
    r"SBA returned (-?\d+) in (\d+) iter, reason (\d+), error (\S+) \[initial (\S+)\], "
    r"(\d+)/(\d+) func/fjac evals, (\d+) lin\. systems")


def files(data, name):
    pts = {"7": "7pts", "9": "9pts", "54": "54pts"}[re.match(r"\d+", name).group(0)]
    args = [os.path.join(data, name + ".txt"), os.path.join(data, pts + ".txt")]
    if "var" not in name:
        args.append(os.path.join(data, "calib.txt"))
    return args


def parse(out):
    m = None
    for m in RETURNED.finditer(out):
        pass
    if not m:
        return None
    g = m.groups()
    return {"ret": int(g[0]), "iters": int(g[1]), "reason": int(g[2]), "error": g[3],
            "nfev": int(g[5]), "njev": int(g[6]), "nlin": int(g[7])}


def run(cmd, env=None):
    p = subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=3600)
    return parse(p.stdout)


def variants(simple_str):
    for s in SETS:
        for how in HOWTOS:
            for drv in ["expert", "simple"]:
                if how == "str" and drv == "simple" and not simple_str:
                    continue
                for jac in ["analytic", "numeric"]:
                    yield (s, how, drv, jac)


def key(v):
    return ".".join(v)


def window(iters):
    return min(iters) / 1.25 - 3, 1.25 * max(iters) + 3


def minimum_ok(v, r, refs):
    errs = [x["error"] for x in refs]
    if r is None:
        return False
    if len(set(errs)) == 1 and v[0] not in FLAT:
        return r["error"] == errs[0]
    lo, hi = min(map(float, errs)), max(map(float, errs))
    if v[0] in FLAT:
        lo, hi = lo * (1 - 0.002), hi * (1 + 0.002)
    return lo <= float(r["error"]) <= hi


def judge_a(v, r, refs):
    if not minimum_ok(v, r, refs):
        return False
    if r["reason"] == 3 and all(x["reason"] != 3 for x in refs):
        return False
    if v[0] in FLAT:
        lo, hi = window([x["iters"] for x in refs])
        if not lo <= r["iters"] <= hi:
            return False
    return True


def near(a, refs, field):
    return any(abs(a - x[field]) <= 0.35 * x[field] for x in refs)


def judge_b(v, r, runs, refs):
    if r is None or not minimum_ok(v, r, refs):
        return False
    lo, hi = window([x["iters"] for x in runs])
    if not lo <= r["iters"] <= hi:
        return False
    same = {2: 4, 4: 2}
    if not any(r["reason"] == x["reason"] or same.get(r["reason"]) == x["reason"] for x in runs):
        return False
    counters = ("nfev", "njev", "nlin")
    return all(near(r[f], runs, f) for f in counters)


def ref_key(v, b, t, c):
    return "%s.%s.%d" % (key(v), b, t) + ("" if c == "default" else "." + c)


def envelope(v, refs):
    its = [x["iters"] for x in refs]
    errs = sorted(float(x["error"]) for x in refs)
    reasons = sorted(set(x["reason"] for x in refs))
    return "%-40s 1.6 over %d runs: %d..%d iterations, error %g..%g, reasons %s" % (
        key(v), len(refs), min(its), max(its), errs[0], errs[-1], reasons)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sba16", required=True, help="directory holding 1.6's demo builds")
    ap.add_argument("--builds", default="bin,bin-fma", help="its two build directories")
    ap.add_argument("--coretypes", default="default", help="comma-separated OPENBLAS_CORETYPE values for 1.6's runs")
    ap.add_argument("--data", required=True, help="the sba distribution's demo data")
    ap.add_argument("--demo", required=True, help="our eucsbademo")
    ap.add_argument("--cache", help="JSON file caching 1.6's runs")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--simple-str", action="store_true", help="also the simple structure-only variants")
    ap.add_argument("--only", help="comma-separated data sets")
    ap.add_argument("--match", help="only the variants whose key (SET.HOWTO.DRIVER.JACOBIAN) matches this regex")
    ap.add_argument("--envelope", action="store_true", help="print 1.6's range on each variant")
    ap.add_argument("--verbose", action="store_true", help="one line per variant")
    ap.add_argument("extra", nargs="*", help="further options for our eucsbademo (after --)")
    a = ap.parse_args()
    builds = a.builds.split(",")
    cores = a.coretypes.split(",")
    runs = [(b, t, c) for b in builds for t in (1, 2) for c in cores]
    vs = [v for v in variants(a.simple_str) if (not a.only or v[0] in a.only.split(","))
          and (not a.match or re.search(a.match, key(v)))]
    cache = {}
    if a.cache and os.path.exists(a.cache):
        with open(a.cache) as f:
            cache = json.load(f)

    jobs = {}
    with concurrent.futures.ThreadPoolExecutor(a.jobs) as ex:
        for v in vs:
            s, how, drv, jac = v
            for b, t, c in runs:
                k = ref_key(v, b, t, c)
                if k in cache:
                    continue
                exe = os.path.join(a.sba16, b, "eucsbademo16-%s-%s-%s" % (how, drv, jac))
                env = dict(os.environ, OPENBLAS_NUM_THREADS=str(t))
                env.pop("OPENBLAS_CORETYPE", None)
                if c != "default":
                    env["OPENBLAS_CORETYPE"] = c
                jobs[k] = ex.submit(run, [exe] + files(a.data, s), env)
            opts = ["--refine=" + OUR_REFINE[how], "--" + drv] + (["--numeric-jacobian"] if jac == "numeric" else [])
            jobs["ours." + key(v)] = ex.submit(run, [a.demo] + opts + a.extra + files(a.data, s))
        for k, fut in jobs.items():
            r = fut.result()
            if k.startswith("ours."):
                jobs[k] = r
            else:
                cache[k] = r
    if a.cache:
        with open(a.cache, "w") as f:
            json.dump(cache, f, indent=0, sort_keys=True)

    fmt = lambda r: "-" if r is None else "%d it r%d %s %d/%d %d" % (
        r["iters"], r["reason"], r["error"], r["nfev"], r["njev"], r["nlin"])
    count_a, fails_a = 0, []
    kind = {("ours", b): 0 for b in builds}
    for b, t, c in runs:
        for o in builds:
            if o != b:
                kind[("%s@%d/%s" % (b, t, c), o)] = 0
    for v in vs:
        refs = {r: cache[ref_key(v, *r)] for r in runs}
        if any(x is None for x in refs.values()):
            print("1.6 failed on", key(v), file=sys.stderr)
            continue
        allrefs = list(refs.values())
        if a.envelope:
            print(envelope(v, allrefs))
        ours = jobs["ours." + key(v)]
        ok_a = judge_a(v, ours, allrefs)
        count_a += ok_a
        if not ok_a:
            fails_a.append(key(v))
        marks = []
        for b in builds:
            mine = [refs[r] for r in runs if r[0] == b]
            ok = judge_b(v, ours, mine, allrefs)
            kind[("ours", b)] += ok
            marks.append("%s:%s" % (b, "ok" if ok else "--"))
            for r in runs:
                if r[0] != b:
                    continue
                for o in builds:
                    if o != b:
                        other = [refs[x] for x in runs if x[0] == o]
                        kind[("%s@%d/%s" % r, o)] += judge_b(v, refs[r], other, allrefs)
        if a.verbose:
            print("%-40s ours %-34s | a:%s %s" % (key(v), fmt(ours), "ok" if ok_a else "FAIL", " ".join(marks)))
    n = len(vs)
    print("variants: %d" % n)
    print("(a) 1.6's minimum, no itmax where 1.6 stops: %d of %d" % (count_a, n))
    for k in fails_a:
        print("    fails:", k)
    for (who, against), c in kind.items():
        print("(b) %-24s judged in kind against %-8s %d of %d" % (who, against + "'s runs:", c, n))


if __name__ == "__main__":
    main()
