#!/usr/bin/env python3
# SPDX-License-Identifier: BSD-3-Clause
"""Times whole processes on the sba distribution's 54-camera problems: start, reading the
files, the solve and the exit, as a user who runs a program on them waits for it.

sba_bench --no-fork solves one problem in its own process with one engine (sba's chol with
each strategy, or Ceres's DENSE_SCHUR or SPARSE_SCHUR at its defaults), the BLAS left as the
environment sets it (--blas-threads=default) and every thread count at its default
(--threads all), so the sba and Ceres processes differ only in the engine they run. The same
program with no engine gives the floor (start, reading, exit); eucsbademo is sba's own demo
at its defaults. The commands run in rounds, in the same order every round, and each one's
median, minimum and maximum wall times are reported with its final mean squared error (from
sba_bench's output; eucsbademo's from its "error" line).

    python3 bench/whole_process.py [--build build-bench] [--rounds 30] [--with-env NAME=VALUE]

writes bench/results/whole_process.md and .json. With --with-env every command also runs with
the variable in its environment, in the same rounds, right after its run without it, and is
compared with the peer's run with it (OPENBLAS_THREAD_TIMEOUT=24: OpenBLAS's idle workers
spin a few milliseconds instead of a tenth of a second, docs/threads.md). Only the standard
library is used.
"""

import argparse
import datetime
import json
import os
import platform
import re
import statistics
import subprocess
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
DATA = os.path.join("..", "shared", "data", "sba-demo")  # from ROOT, where the commands run

# (name, cameras file, calibration file or None)
PROBLEMS = [
    ("54cams", "54cams.txt", "calib.txt"),
    ("54camsvarK", "54camsvarK.txt", None),
    ("54camsvarKD", "54camsvarKD.txt", None),
]

# (label, sba_bench engine arguments or None for eucsbademo, SBA_AVOID_SHARED_CORES or None
# for unset). The library moves a worker that finds itself on another pool thread's core only
# when asked (sba_ext_options.avoid_shared_cores, or the variable); the programs ask unless
# the variable says otherwise. The runs with and without it show what sharing a core costs.
RUNS = [
    ("sba chol, 1.6's strategy", ["--solvers", "chol", "--strategy", "sba", "--ceres", "none"], None),
    ("sba chol, 1.6's strategy, avoid_shared_cores on",
     ["--solvers", "chol", "--strategy", "sba", "--ceres", "none", "--avoid-shared-cores"], None),
    ("sba chol, trust region", ["--solvers", "chol", "--strategy", "trust-region", "--ceres", "none"], None),
    ("sba chol, trust region, avoid_shared_cores on",
     ["--solvers", "chol", "--strategy", "trust-region", "--ceres", "none", "--avoid-shared-cores"], None),
    ("Ceres DENSE_SCHUR", ["--solvers", "none", "--ceres", "dense"], None),
    ("Ceres SPARSE_SCHUR", ["--solvers", "none", "--ceres", "sparse"], None),
    ("no solve (start, reading, exit)", ["--solvers", "none", "--ceres", "none"], None),
    ("eucsbademo", None, None),
    ("eucsbademo, SBA_AVOID_SHARED_CORES=0", None, "0"),
]
PEER = "Ceres DENSE_SCHUR"


def commands(build, name, cams, calib, with_env):
    files = [os.path.join(DATA, cams), os.path.join(DATA, "54pts.txt")]
    if calib:
        files.append(os.path.join(DATA, calib))
    bench = [os.path.relpath(os.path.join(build, "bench", "sba_bench"), ROOT), "--cams", files[0], "--pts", files[1]]
    if calib:
        bench += ["--calib", files[2]]
    bench += ["--name", name, "--threads", "all", "--repeat", "1", "--no-fork", "--blas-threads=default"]
    demo = [os.path.relpath(os.path.join(build, "demo", "eucsbademo"), ROOT)] + files
    out = []
    for label, args, avoid in RUNS:
        # None: unset, whatever the caller's environment holds.
        env = {"SBA_AVOID_SHARED_CORES": avoid}
        cmd = demo if args is None else bench + args
        out.append((label, cmd, {**env, with_env[0]: None} if with_env else env, PEER))
        if with_env:
            suffix = f", {with_env[0]}={with_env[1]}"
            out.append((label + suffix, cmd, {**env, with_env[0]: with_env[1]}, PEER + suffix))
    return out


def set_vars(env):
    """The variables a run sets (those it unsets are None in env)."""
    return {k: v for k, v in env.items() if v is not None}


def final_error(label, out):
    if label.startswith("no solve"):
        return None
    demo = label.startswith("eucsbademo")
    m = re.search(r"error ([0-9.eE+-]+) \[initial" if demo else r"final MSE ([0-9.eE+-]+)", out)
    return float(m.group(1)) if m else None


def measure(cmds, rounds):
    times = {label: [] for label, *_ in cmds}
    errors = {label: None for label, *_ in cmds}
    for _ in range(rounds):
        for label, cmd, added, _ in cmds:
            env = {k: v for k, v in os.environ.items() if k not in added}
            env.update(set_vars(added))
            start = time.perf_counter()
            done = subprocess.run(cmd, cwd=ROOT, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
            elapsed = time.perf_counter() - start
            if done.returncode != 0:
                sys.exit(f"whole_process.py: {' '.join(cmd)} failed ({done.returncode}):\n{done.stdout}")
            times[label].append(elapsed)
            errors[label] = final_error(label, done.stdout)
    return times, errors


def table(name, cmds, times, errors):
    rows = [f"### {name}", "", "| run | median [s] | min [s] | max [s] | / Ceres DENSE_SCHUR | final MSE |",
            "|---|---:|---:|---:|---:|---|"]
    for label, _, _, peer_label in cmds:
        t = times[label]
        err = "-" if errors[label] is None else f"{errors[label]:.8g}"
        peer = statistics.median(times[peer_label])
        rows.append(f"| {label} | {statistics.median(t):.4f} | {min(t):.4f} | {max(t):.4f} | "
                    f"{statistics.median(t) / peer:.2f}x | {err} |")
    rows += ["", "Commands:", ""] + ["    " + "".join(f"{k}={v} " for k, v in set_vars(added).items()) +
                                     " ".join(cmd) for _, cmd, added, _ in cmds] + [""]
    return rows


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--build", default=os.path.join(ROOT, "build-bench"),
                    help="build directory with bench/ and demo/ (default build-bench)")
    ap.add_argument("--rounds", type=int, default=30, help="runs of every command (default 30)")
    ap.add_argument("--out", default=os.path.join(HERE, "results", "whole_process"),
                    help="output path without extension (default bench/results/whole_process)")
    ap.add_argument("--with-env", metavar="NAME=VALUE",
                    help="run every command also with this variable in its environment")
    args = ap.parse_args()
    with_env = None
    if args.with_env is not None:
        name, sep, value = args.with_env.partition("=")
        if not sep or not name:
            ap.error("--with-env takes NAME=VALUE")
        with_env = (name, value)
    options = f"--rounds {args.rounds}" + (f" --with-env {args.with_env}" if with_env else "")
    started = datetime.datetime.now(datetime.timezone.utc)
    load = os.getloadavg()[0]
    md = ["# Whole processes on the 54-camera problems", "",
          f"Written by `bench/whole_process.py {options}` (see its opening comment) on "
          f"{started:%Y-%m-%d %H:%M} UTC, {os.cpu_count()} hardware threads, {platform.machine()}, "
          f"load average {load:.2f} at the start. Wall times of whole processes, {args.rounds} rounds.", ""]
    record = {"date": started.isoformat(), "rounds": args.rounds, "with_env": args.with_env, "cpus": os.cpu_count(),
              "load": load, "problems": []}
    for name, cams, calib in PROBLEMS:
        cmds = commands(args.build, name, cams, calib, with_env)
        times, errors = measure(cmds, args.rounds)
        md += table(name, cmds, times, errors)
        record["problems"].append({"name": name, "runs": [
            {"label": label, "command": cmd, "env": set_vars(added), "times": times[label],
             "final_mse": errors[label]} for label, cmd, added, _ in cmds]})
        print(f"{name}: " + ", ".join(f"{label} {statistics.median(times[label]):.4f} s" for label, *_ in cmds))
    with open(args.out + ".md", "w") as f:
        f.write("\n".join(md))
    with open(args.out + ".json", "w") as f:
        json.dump(record, f, indent=1)
        f.write("\n")


if __name__ == "__main__":
    main()
