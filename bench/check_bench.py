#!/usr/bin/env python3
# SPDX-License-Identifier: BSD-3-Clause
"""Checks that sba_bench still measures what the suite reports (make check-bench).

Runs sba_bench once on a small generated problem (both engines, both LM strategies, sba's
Jacobian in double and in single precision, Ceres's three Schur solvers at its defaults, both
thread counts, the scaling series' --warm-up) and
checks its JSON: every run solved the problem to the same minimum from the same start (to
Ceres's default tolerance), sba's iterations are in the window this problem takes for each
strategy, each run's comparison with the fastest Ceres run is what its fields say, a
1-thread run took one core's CPU time, and the memory fields add up (the data peak holds
at least the Jacobian and at most the peak; after the warm-up no code page of sba's solve is
first touched during the measured solve), and each run carries the price of a cache line's
round trip between two CPUs before and after it (a positive figure, or null with one CPU).
A run in sba_bench's own process (--no-fork, whole_process.py's) measures no round trip: it
would wait for the BLAS's idle workers after the solve, which a program that exits does not.
Timings are not checked: they belong to the suite, not to a pass/fail test.

    check_bench.py path/to/sba_bench
"""
import json
import os
import subprocess
import sys
import tempfile

SPEC = "cameras=12,points=1500,track=2..6,trajectory=path"
ITMAX = 40
# Iterations this problem takes: 1.6's strategy 22-28, the trust region 5 (Ceres: 5).
SBA_ITERATIONS = {"sba": (15, 40), "trust-region": (3, 8)}
# Ceres stops at a relative cost change of 1e-6 (its default function tolerance): its final
# error and the trust region's lie within a few 1e-7 of the tightly converged one.
SAME_MINIMUM = 2e-6


def main():
    if len(sys.argv) != 2:
        sys.exit(__doc__)
    exe = sys.argv[1]
    failures = []

    def check(ok, what):
        if not ok:
            failures.append(what)

    with tempfile.TemporaryDirectory() as tmp:
        out = os.path.join(tmp, "runs.json")
        cmd = [exe, "--gen", SPEC, "--solvers", "chol,sparse-chol", "--strategy", "sba,trust-region",
               "--jacobian", "double,single", "--ceres", "dense,sparse,iterative",
               "--threads", "1,2", "--itmax", str(ITMAX), "--warm-up", "--out", out]
        print("$ " + " ".join(cmd))
        subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
        with open(out) as f:
            runs = [json.loads(line) for line in f]
        here = os.path.join(tmp, "inline.json")
        cmd = [exe, "--gen", SPEC, "--solvers", "chol", "--strategy", "trust-region", "--ceres", "none",
               "--threads", "2", "--itmax", str(ITMAX), "--no-fork", "--blas-threads=default", "--out", here]
        print("$ " + " ".join(cmd))
        subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
        with open(here) as f:
            inline = [json.loads(line) for line in f]

    check(len(runs) == 22, "expected 22 runs (2 sba solvers x 2 strategies x 2 Jacobians + 3 Ceres, 1 and 2 "
          "threads), got %d" % len(runs))
    best = min(r["final_mse"] for r in runs if r["ok"])
    for r in runs:
        name = "%s %s%s%s, %d thread(s)" % (r["engine"], r["solver"], " " + r["strategy"] if r["strategy"] else "",
                                            " " + r["jacobian"] if r["jacobian"] else "", r["threads"])
        check(r["ok"], name + ": not solved (" + r["status"] + ")")
        if not r["ok"]:
            continue
        check(abs(r["final_mse"] - best) <= SAME_MINIMUM * best,
              "%s: final MSE %.10g, best of all runs %.10g" % (name, r["final_mse"], best))
        check(r["initial_mse"] == runs[0]["initial_mse"],
              "%s: starts from MSE %.10g, the first run from %.10g" % (name, r["initial_mse"], runs[0]["initial_mse"]))
        check(r["final_mse"] < 0.01 * r["initial_mse"], name + ": the error barely went down")
        # Counts given explicitly are used as given (the library's own choice is for "all").
        check(r["threads_used"] == r["threads"], "%s: ran %s threads" % (name, r["threads_used"]))
        # One thread keeps one core busy. More CPU time means another thread of the process ran
        # beside it: OpenBLAS's, which spin for 0.1 s after openblas_set_num_threads started
        # them in the child, before sba_bench waited for them to sleep (CPU 2.0x the wall
        # time then on 54cams).
        if r["threads"] == 1:
            check(r["cpu_seconds"] <= 1.25 * r["seconds"] + 0.02,
                  "%s: %.3f s of CPU in %.3f s on one thread" % (name, r["cpu_seconds"], r["seconds"]))
        if r["engine"] == "sba":
            lo, hi = SBA_ITERATIONS[r["strategy"]]
            check(lo <= r["iterations"] <= hi, "%s: %d iterations, outside [%d, %d]" % (name, r["iterations"], lo, hi))
        # The peer is the fastest Ceres run with the same threads, and "worse" means what it says.
        peers = [c for c in runs if c["engine"] == "ceres" and c["threads"] == r["threads"] and c["ok"]]
        if peers:
            peer = min(peers, key=lambda c: c["seconds"])
            check(r["ceres_best_solver"] == peer["solver"],
                  "%s: compared with Ceres %s, the fastest is %s" % (name, r["ceres_best_solver"], peer["solver"]))
            check(abs(r["ratio_time_vs_ceres_best"] - r["seconds"] / peer["seconds"]) <= 1e-9 * r["ratio_time_vs_ceres_best"],
                  name + ": ratio_time_vs_ceres_best is not its time over the fastest Ceres run's")
            check(r["worse_than_ceres_best"] == (r["final_mse"] > peer["final_mse"] * (1 + 1e-6)),
                  name + ": worse_than_ceres_best disagrees with the final errors")
        trips = r["core_round_trip_ns_all"]
        two_cpus = len(os.sched_getaffinity(0)) >= 2
        check(len(trips) == r["repeats"] and all(len(t) == 2 for t in trips),
              "%s: core_round_trip_ns_all %s, not one [before, after] per repetition" % (name, trips))
        check(all((0 < v < 1e7) if two_cpus else v is None for t in trips for v in t),
              "%s: core_round_trip_ns_all %s with %s CPUs" % (name, trips, "two or more" if two_cpus else "one"))
        peak, data = r["peak_rss_bytes"], r["data_peak_bytes"]
        check(r["peak_rss_reset"], name + ": VmHWM could not be reset, the peak includes the loading")
        # jacobian_bytes is the Jacobian in double; in single precision it takes half.
        stored = r["jacobian_bytes"] // 2 if r["jacobian"] == "single" else r["jacobian_bytes"]
        check(data is not None and stored <= data < peak,
              "%s: data peak %s not between the Jacobian (%d) and the peak RSS (%d)" % (name, data, stored, peak))
        check(0 < r["program_anon_bytes"] < peak, name + ": program_anon_bytes %s" % r["program_anon_bytes"])
        if r["engine"] == "sba":
            # The warm-up runs one iteration; the measured solve may still fault in a few
            # pages of code only later iterations run (64 KB at a time, the kernel's
            # fault-around). Without the warm-up this is 1.9-3.1 MB here.
            grown = r["file_rss_end_bytes"] - r["file_rss_start_bytes"]
            check(grown <= 256 * 1024,
                  "%s: %d bytes of code first touched during the measured solve despite --warm-up" % (name, grown))

    check(len(inline) == 1 and inline[0]["ok"] and inline[0]["core_round_trip_ns_all"] == [[None, None]],
          "--no-fork run: %s" % [(r["status"], r["core_round_trip_ns_all"]) for r in inline])

    for f in failures:
        print("check-bench: FAIL: " + f)
    if failures:
        sys.exit(1)
    print("check-bench: %d runs, every check passed (best final MSE %.8g)" % (len(runs), best))


if __name__ == "__main__":
    main()
