#!/usr/bin/env python3
# SPDX-License-Identifier: BSD-3-Clause
"""sba's trust region against Ceres on bench/'s six problems, the runs split by what it costs
the machine's two CPUs to exchange a cache line while they run.

On a virtual machine the host can place the two vCPUs on one cache or on two, and move them
from one placement to the other every minute or so. A 2-thread solve whose threads hand each
other its data (one phase writes the Jacobian by points, the next reads it by cameras) then
runs at two speeds, and so does its peer. sba_bench measures the round trip of a cache line
between the first two CPUs just before and just after each solve (core_round_trip_ns); a run
is "near" when both are under --near ns, "far" when both are over --far, and left out
otherwise (the placement changed during it).

Every round runs each problem once: sba_bench with sba's chol and trust region at the
library's defaults and Ceres's DENSE_SCHUR, SPARSE_SCHUR and ITERATIVE_SCHUR at theirs, then
sba_bench with sba alone and avoid_shared_cores on. The problems are interleaved so that both
placements fall on all of them. Each engine's median time is taken per placement, and each sba
time over the fastest Ceres median of the same placement.

    python3 bench/core_states.py [--build build-bench] [--rounds 12] [--threads 2]
        [--near 150] [--far 250] [--out bench/results/core_states]

writes OUT.md and OUT.json. Only the standard library is used.
"""

import argparse
import datetime
import json
import os
import statistics
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
BAL = os.path.join("..", "shared", "data", "bal")
DEMO = os.path.join("..", "shared", "data", "sba-demo")

PROBLEMS = [(name, ["--bal", os.path.join(BAL, f"{name}-pre.txt.bz2")])
            for name in ("problem-21-11315", "problem-16-22106", "problem-49-7776", "problem-73-11032",
                         "problem-39-18060")]
PROBLEMS.append(("54cams", ["--cams", os.path.join(DEMO, "54cams.txt"), "--pts", os.path.join(DEMO, "54pts.txt"),
                            "--calib", os.path.join(DEMO, "calib.txt")]))

SBA = "sba trust region"
SBA_AVOID = "sba trust region, avoid_shared_cores"
CERES = ("DENSE_SCHUR", "SPARSE_SCHUR", "ITERATIVE_SCHUR")
INVOCATIONS = [
    ["--solvers", "chol", "--strategy", "trust-region", "--ceres", "dense,sparse,iterative"],
    ["--solvers", "chol", "--strategy", "trust-region", "--ceres", "none", "--avoid-shared-cores"],
]


def run(bench, problem_args, extra, threads):
    """The records of one sba_bench call: (engine label, seconds, final MSE, (rt before, rt after))."""
    with tempfile.NamedTemporaryFile(suffix=".json") as out:
        cmd = [bench, *problem_args, *extra, "--threads", str(threads), "--repeat", "1", "--out", out.name]
        subprocess.run(cmd, cwd=ROOT, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        records = []
        for line in open(out.name):
            d = json.loads(line)
            if d["engine"] == "sba":
                label = SBA_AVOID if d["avoid_shared_cores"] else SBA
            else:
                label = d["solver"]
            records.append((label, d["seconds"], d["final_mse"], tuple(d["core_round_trip_ns_all"][0])))
        return records


def placement(rt, near, far):
    if any(x is None for x in rt):
        return None
    if max(rt) < near:
        return "near"
    if min(rt) > far:
        return "far"
    return None


def summarize(runs, near, far):
    """{problem: {placement: {label: (median seconds, count)}}}, "all" over every run."""
    out = {}
    for problem, records in runs.items():
        split = {"near": {}, "far": {}, "all": {}}
        for label, seconds, _, rt in records:
            for key in ("all", placement(rt, near, far)):
                if key:
                    split[key].setdefault(label, []).append(seconds)
        out[problem] = {k: {label: (statistics.median(v), len(v)) for label, v in d.items()} for k, d in split.items()}
    return out


def final_errors(runs):
    """{problem: (sba's worst final MSE, Ceres's best)}: sba's runs must end where the best
    Ceres run does, within 1e-6 relative, to count."""
    out = {}
    for problem, records in runs.items():
        sba = [mse for label, _, mse, _ in records if label in (SBA, SBA_AVOID)]
        ceres = [mse for label, _, mse, _ in records if label in CERES]
        out[problem] = (max(sba), min(ceres))
    return out


def table(summary, errors):
    lines = ["| problem | placement | sba trust region [s] | with avoid_shared_cores [s] | fastest Ceres [s] | "
             "ratio | with avoid_shared_cores | runs (sba, Ceres) |",
             "|---|---|---:|---:|---|---:|---:|---|"]
    for problem, by in summary.items():
        sba_mse, ceres_mse = errors[problem]
        if sba_mse > ceres_mse * (1 + 1e-6):
            lines.append(f"| {problem} | | sba ends at MSE {sba_mse:.9g}, Ceres at {ceres_mse:.9g}: no win | | | | | |")
            continue
        for key in ("near", "far", "all"):
            d = by[key]
            ceres = [(d[c][0], c) for c in CERES if c in d]
            if not ceres or SBA not in d:
                lines.append(f"| {problem} | {key} | | | | | | none |")
                continue
            best, name = min(ceres)
            sba, avoid = d[SBA][0], d.get(SBA_AVOID, (float("nan"), 0))[0]
            lines.append(f"| {problem} | {key} | {sba:.3f} | {avoid:.3f} | {name} {best:.3f} | {sba / best:.2f}x | "
                         f"{avoid / best:.2f}x | {d[SBA][1]}, {min(d[c][1] for c in CERES if c in d)} |")
    return "\n".join(lines)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--build", default="build-bench")
    ap.add_argument("--rounds", type=int, default=12)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--near", type=float, default=150.0)
    ap.add_argument("--far", type=float, default=250.0)
    ap.add_argument("--out", default=os.path.join("bench", "results", "core_states"))
    a = ap.parse_args()
    bench = os.path.join(ROOT, a.build, "bench", "sba_bench")
    if not os.path.exists(bench):
        sys.exit(f"core_states.py: {bench} not found (configure with -DSBA_BUILD_BENCH=ON)")
    runs = {name: [] for name, _ in PROBLEMS}
    for r in range(a.rounds):
        for name, args in PROBLEMS:
            for extra in INVOCATIONS:
                runs[name].extend(run(bench, args, extra, a.threads))
        print(f"core_states.py: round {r + 1} of {a.rounds}", file=sys.stderr)
    summary = summarize(runs, a.near, a.far)
    stamp = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT, capture_output=True,
                            text=True).stdout.strip()
    md = (f"# sba's trust region against Ceres, by the placement of the two CPUs\n\n"
          f"Written by `bench/core_states.py` (see its opening comment) on {stamp} at {commit}, "
          f"{a.rounds} rounds, {a.threads} threads; near: a cache line's round trip under {a.near:g} ns "
          f"before and after the run, far: over {a.far:g} ns.\n\n"
          f"    python3 bench/core_states.py --build {a.build} --rounds {a.rounds} --threads {a.threads}\n\n"
          f"{table(summary, final_errors(runs))}\n")
    os.makedirs(os.path.dirname(os.path.join(ROOT, a.out)), exist_ok=True)
    with open(os.path.join(ROOT, a.out + ".md"), "w") as f:
        f.write(md)
    with open(os.path.join(ROOT, a.out + ".json"), "w") as f:
        json.dump({"time": stamp, "commit": commit, "threads": a.threads, "near": a.near, "far": a.far,
                   "runs": {p: [list(r) for r in rs] for p, rs in runs.items()}}, f, indent=1)
    print(md)


if __name__ == "__main__":
    main()
