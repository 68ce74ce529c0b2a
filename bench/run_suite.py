#!/usr/bin/env python3
# SPDX-License-Identifier: BSD-3-Clause
"""Runs the benchmark suite of bench/ and writes bench/results/:

  results.json   one JSON object per run (JSON lines, as sba_bench --out writes them)
  results.md     the tables (Markdown)
  scaling.dat    the scaling series as columns for gnuplot; scaling.gp the plot script
  scaling.png    time per iteration and peak RSS against the problem size (gnuplot)
  kernels.json   Google Benchmark results of kernels_benchmark

Usually started through run_suite.sh, which builds first. Only the standard library is used.
"""

import argparse
import datetime
import json
import math
import os
import platform
import shutil
import subprocess
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)

# The scaling series measures how the cost of an iteration and the memory grow, so it runs
# a fixed number of iterations (SCALING_ITMAX) with every hardware thread. The two largest
# problems run sparse-chol only on our side and Ceres SPARSE_SCHUR only: a dense S of 6000 or
# 12000 unknowns costs 10 s to minutes per factorization on two cores.
SCALING = [
    # (cameras, points, our solvers, ceres linear solvers)
    (10, 1000, "chol,sparse-chol", "dense,sparse"),
    (50, 5000, "chol,sparse-chol", "dense,sparse"),
    (200, 20000, "chol,sparse-chol", "dense,sparse"),
    (500, 60000, "chol,sparse-chol", "dense,sparse"),
    (1000, 200000, "sparse-chol", "sparse"),
    (2000, 500000, "sparse-chol", "sparse"),
]
SCALING_QUICK = SCALING[:2]
SCALING_TRACK = "2..10"
SCALING_ITMAX = 30
SCALING_THREADS = "all"

# The long sequence: each point seen by 3-6 consecutive cameras; chol costs about 13 s
# per iteration here on two cores, hence the iteration limit (both solvers take the same steps,
# so their errors after LONGSEQ_ITMAX iterations agree).
LONGSEQ = ("cameras=1000,points=50000,track=3..6,trajectory=path", "chol,sparse-chol", "sparse", 30)
LONGSEQ_QUICK = ("cameras=1000,points=10000,track=3..6,trajectory=path", "chol,sparse-chol", "none", 3)
LONGSEQ_THREADS = "all"
# The same long sequence solved to each engine's own default stopping, with both LM strategies:
# the comparison the 54-camera and BAL problems make, on a problem with thousands of cameras.
CONVERGE = ("cameras=1000,points=50000,track=3..6,trajectory=path", "sparse-chol", "sparse,iterative")

# The 54-camera and BAL problems take seconds per run, and this shared machine's timings of one
# run vary by 10-30%: each configuration runs REPEAT times (in rounds) and reports its median.
REPEAT = 3

# The 54-camera and BAL problems run both LM strategies and Ceres's three Schur solvers, each at
# its default stopping: the headline comparison.
STRATEGIES = ["--strategy", "sba,trust-region"]
CERES = ["--ceres", "dense,sparse,iterative"]

# dubrovnik-3-7 has fewer measurements (38) than parameters (48): sba refuses it, as 1.6
# does (SBA_ERROR), and only Ceres solves it; it stays in the suite to show that.
BAL_FILES = [
    "dubrovnik-3-7-pre.txt.bz2",
    "problem-49-7776-pre.txt.bz2",
    "problem-73-11032-pre.txt.bz2",
    "problem-21-11315-pre.txt.bz2",
    "problem-39-18060-pre.txt.bz2",
    "problem-16-22106-pre.txt.bz2",
]


def log(msg):
    print(msg, file=sys.stderr, flush=True)


def run_bench(exe, args, out, timeout):
    cmd = [exe] + args + ["--out", out, "--timeout", str(timeout)]
    log("$ " + " ".join(cmd))
    load = os.getloadavg()[0]
    proc = subprocess.run(cmd, stdout=subprocess.PIPE, text=True)
    sys.stdout.write(proc.stdout)
    sys.stdout.flush()
    if proc.returncode != 0:
        log("  (sba_bench exit status %d: some run failed, see its status)" % proc.returncode)
    return {"command": " ".join(cmd), "load": load, "stdout": proc.stdout}


def read_runs(path):
    runs = []
    if os.path.exists(path):
        with open(path) as f:
            for line in f:
                line = line.strip()
                if line:
                    runs.append(json.loads(line))
    return runs


def forget_problem(out, meta, name):
    """Drops the earlier runs of a problem about to run again, and its command, so that an
    appended run replaces them instead of standing beside them in the tables."""
    if os.path.exists(out):
        with open(out) as f:
            kept = [line for line in f if line.strip() and json.loads(line)["problem"] != name]
        with open(out, "w") as f:
            f.writelines(kept)
    meta["commands"] = [c for c in meta["commands"] if " --name %s " % name not in c + " "]
    meta["loads"].pop(name, None)


# ---- formatting ----

def num(v, fmt="%.3f"):
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return "-"
    return fmt % v


def ratio(v):
    return num(v, "%.2fx")


def mb(v):
    return num(v / 1e6 if v else None, "%.1f")


def status_text(r):
    if not r["ok"] and r.get("message"):
        return "%s: %s" % (r["status"], r["message"].replace("|", "/"))
    return r["status"]


def run_name(r):
    if r["engine"] != "sba":
        return "Ceres " + r["solver"] + (" (tol 1e-12)" if r.get("ceres_tolerances") == "1e-12" else "")
    strategy = r.get("strategy") or "sba"
    return "sba " + r["solver"] + ("" if strategy == "sba" else " " + strategy)


def worse_mark(r):
    return " (worse error)" if r.get("worse_than_ceres_best") else ""


def run_table(runs):
    head = ("| run | threads | status | iterations | linear solves | time [s] | ms/iter | initial MSE | "
            "final MSE | peak RSS [MB] | time / Ceres best | time to best [s] | ttb / Ceres best | "
            "times of the repetitions [s] |")
    lines = [head, "|" + "---|" * 14]
    for r in runs:
        lines.append("| %s | %d | %s | %d | %d | %s | %s | %s | %s | %s | %s | %s | %s | %s |" % (
            run_name(r), r["threads"], status_text(r), r["iterations"], r["linear_solves"],
            num(r["seconds"]), num(r["seconds_per_iteration"] and r["seconds_per_iteration"] * 1e3, "%.2f"),
            num(r["initial_mse"], "%.6g"), num(r["final_mse"], "%.8g"), mb(r["peak_rss_bytes"]),
            ratio(r.get("ratio_time_vs_ceres_best")) + worse_mark(r), num(r["time_to_best_seconds"]),
            ratio(r.get("ratio_time_to_best_vs_ceres_best")),
            " ".join(num(t) for t in r.get("seconds_all", [])) if r.get("repeats", 1) > 1 else "-"))
    return lines


def problem_header(r):
    return ("%d cameras, %d points, %d observations, cnp %d, %d variables; J %.1f MB, dense S %.1f MB, "
            "sparse S %.1f MB (%d camera blocks), inputs %.1f MB" % (
                r["cameras"], r["points"], r["observations"], r["cnp"], r["variables"],
                r["jacobian_bytes"] / 1e6, r["dense_s_bytes"] / 1e6, r["sparse_s_bytes"] / 1e6,
                r["camera_pairs"], r["input_bytes"] / 1e6))


def find(runs, engine, solver, threads, strategy="sba"):
    for r in runs:
        if (r["engine"] == engine and r["solver"] == solver and r["threads"] == threads and r["ok"]
                and (engine != "sba" or (r.get("strategy") or "sba") == strategy)):
            return r
    return None


def best_sba(runs, threads, strategy="sba"):
    c = [r for r in runs if r["engine"] == "sba" and r["threads"] == threads and r["ok"]
         and (r.get("strategy") or "sba") == strategy]
    return min(c, key=lambda r: r["seconds"]) if c else None


def best_ceres(runs, threads):
    c = [r for r in runs if r["engine"] == "ceres" and r["threads"] == threads and r["ok"]]
    return min(c, key=lambda r: r["seconds"]) if c else None


def div(a, b):
    return a / b if a is not None and b not in (None, 0) else None


# ---- the report ----

def write_markdown(path, meta, groups, runs_by_problem, kernels):
    L = []
    L.append("# Benchmark results")
    L.append("")
    L.append("Regenerate with `bench/run_suite.sh` (see bench/README.md). Generated %s on %s (%s, %d hardware "
             "threads, %s).%s" % (meta["date"], meta["host"], meta["cpu"], meta["threads"], meta["mem"],
                                  " **Quick run (reduced set).**" if meta["quick"] else ""))
    L.append("")
    L.append("Every run starts from the same parameters in a fresh child process, with the BLAS (OpenBLAS) set to "
             "the run's thread count. Time is the wall time of the "
             "solve (file reading and generation excluded; for Ceres the ceres::Problem construction is "
             "included). MSE is the sum of squared reprojection errors divided by the number of observations "
             "(sba's info[1]/nobs; 2 x Ceres cost / nobs). sba iterations are outer LM iterations "
             "(info[5]); Ceres iterations are LM steps tried (successful + unsuccessful), so ms/iter compares "
             "different units: see also linear solves. \"time to best\" is when a run's error first came "
             "within 1e-6 relative of the best final error of all runs of that problem (- : never). Peak RSS "
             "is VmHWM of the child, reset just before the solve (program + inputs + solver). Ceres holds "
             "the intrinsics that eucsbademo holds (nccalib 2, ncdist 3) constant with a SubsetManifold; "
             "sba carries them as zero Jacobian columns. Load average at the start of each problem is shown: "
             "other processes on this shared machine disturb the timings. Where a problem's command has "
             "`--repeat N`, every configuration ran N times in rounds and its row is the run with the "
             "median time (the last column lists all N times).")
    L.append("")
    for title, names in groups:
        present = [n for n in names if n in runs_by_problem]
        if not present:
            continue
        L.append("## " + title)
        L.append("")
        for name in present:
            info = runs_by_problem[name]
            runs = info["runs"]
            L.append("### " + name)
            L.append("")
            L.append(problem_header(runs[0]) + ". Best final MSE %s. Load average %.2f." % (
                num(runs[0]["best_final_mse"], "%.8g"), info["load"]))
            L.append("")
            L.append("`" + info["command"] + "`")
            L.append("")
            L.extend(run_table(runs))
            L.append("")

    # Summary against Ceres: for each strategy our fastest solver vs Ceres's fastest
    # configuration at each thread count, both at their own default stopping.
    L.append("## Summary: this library's fastest solver (per LM strategy) vs Ceres's fastest configuration")
    L.append("")
    L.append("Both stop by their own default rules (Ceres: its default Solver::Options). A run whose final "
             "error is worse than the Ceres run's by more than 1e-6 relative is marked \"worse\" and is no win.")
    L.append("")
    L.append("| problem | threads | strategy | sba fastest | iterations | time [s] | final MSE | Ceres fastest | "
             "iterations | time [s] | final MSE | time ratio | error |")
    L.append("|" + "---|" * 13)
    for title, names in groups:
        for name in names:
            if name not in runs_by_problem:
                continue
            runs = runs_by_problem[name]["runs"]
            strategies = sorted({r.get("strategy") or "sba" for r in runs if r["engine"] == "sba"})
            for t in sorted({r["threads"] for r in runs}):
                c = best_ceres(runs, t)
                for st in strategies:
                    s = best_sba(runs, t, st)
                    if not s or not c:
                        continue
                    worse = s["final_mse"] > c["final_mse"] * (1 + 1e-6)
                    L.append("| %s | %d | %s | %s | %d | %s | %s | %s | %d | %s | %s | %s | %s |" % (
                        name, t, st, s["solver"], s["iterations"], num(s["seconds"]), num(s["final_mse"], "%.8g"),
                        c["solver"], c["iterations"], num(c["seconds"]), num(c["final_mse"], "%.8g"),
                        ratio(div(s["seconds"], c["seconds"])), "worse" if worse else "same or better"))
    L.append("")

    # Threads.
    L.append("## Thread scaling (time with 1 thread / time with all threads)")
    L.append("")
    L.append("| problem | run | 1 thread [s] | all [s] | speed-up |")
    L.append("|---|---|---|---|---|")
    for title, names in groups:
        for name in names:
            if name not in runs_by_problem:
                continue
            runs = runs_by_problem[name]["runs"]
            ts = sorted({r["threads"] for r in runs})
            if len(ts) < 2:
                continue
            for r1 in [r for r in runs if r["threads"] == 1 and r["ok"]]:
                rn = find(runs, r1["engine"], r1["solver"], ts[-1], r1.get("strategy") or "sba")
                if rn:
                    L.append("| %s | %s | %s | %s | %s |" % (name, run_name(r1), num(r1["seconds"]),
                                                             num(rn["seconds"]),
                                                             ratio(div(r1["seconds"], rn["seconds"]))))
    L.append("")

    # The linear solvers compared (the heading keeps the name the recorded results use).
    L.append("## Linear solvers")
    L.append("")
    if "54cams" in runs_by_problem:
        runs = runs_by_problem["54cams"]["runs"]
        L.append("54cams (fixed K), time per iteration (and per linear system) of each solver and its ratio to chol "
                 "(the sba paper reports the Schur approach 2.2-2.9x faster than the whole-system LDL):")
        L.append("")
        L.append("| threads | solver | iterations | linear solves | ms/iter | ms/linear solve | "
                 "ms/iter ratio to chol | ms/linear solve ratio to chol | final MSE |")
        L.append("|" + "---|" * 9)
        for t in sorted({r["threads"] for r in runs}):
            chol = find(runs, "sba", "chol", t)
            for s in ("chol", "ldl-amd", "sparse-chol"):
                r = find(runs, "sba", s, t)
                if not r:
                    continue
                L.append("| %d | %s | %d | %d | %s | %s | %s | %s | %s |" % (
                    t, s, r["iterations"], r["linear_solves"], num(r["seconds_per_iteration"] * 1e3, "%.2f"),
                    num(r["seconds_per_linear_solve"] * 1e3, "%.2f"), ratio(r["ratio_per_iteration_vs_chol"]),
                    ratio(div(r["seconds_per_linear_solve"], chol and chol["seconds_per_linear_solve"])),
                    num(r["final_mse"], "%.8g")))
        L.append("")
    if "longseq" in runs_by_problem:
        runs = runs_by_problem["longseq"]["runs"]
        L.append("Long sequence (`%s`, itmax %d): sparse-chol against chol, per iteration and peak RSS:" %
                 (runs[0]["description"], runs[0]["itmax"]))
        L.append("")
        L.append("| threads | chol ms/iter | sparse-chol ms/iter | chol / sparse-chol (time) | chol RSS [MB] | "
                 "sparse-chol RSS [MB] | chol / sparse-chol (RSS) | chol final MSE | sparse-chol final MSE |")
        L.append("|" + "---|" * 9)
        for t in sorted({r["threads"] for r in runs}):
            c, s = find(runs, "sba", "chol", t), find(runs, "sba", "sparse-chol", t)
            if not c or not s:
                continue
            L.append("| %d | %s | %s | %s | %s | %s | %s | %s | %s |" % (
                t, num(c["seconds_per_iteration"] * 1e3, "%.1f"), num(s["seconds_per_iteration"] * 1e3, "%.1f"),
                ratio(div(c["seconds_per_iteration"], s["seconds_per_iteration"])), mb(c["peak_rss_bytes"]),
                mb(s["peak_rss_bytes"]), ratio(div(c["peak_rss_bytes"], s["peak_rss_bytes"])),
                num(c["final_mse"], "%.8g"), num(s["final_mse"], "%.8g")))
        L.append("")

    # Scaling.
    scal = [n for n in runs_by_problem if n.startswith("scale-")]
    if scal:
        L.append("## Scaling series (sbagen path, fixed K, tracks %s, itmax %d, %s threads)" % (
            SCALING_TRACK, SCALING_ITMAX, SCALING_THREADS))
        L.append("")
        L.append("Reference bytes = Jacobian + S + inputs (S dense for dense solvers, its nonzero blocks for "
                 "sparse-chol and Ceres SPARSE_SCHUR); RSS ratio = peak RSS / reference bytes. Data peak = "
                 "peak RSS less the file-backed pages resident when the solve started (the shared code of "
                 "the program and its libraries; these runs warm up first, so the solve adds almost none) "
                 "and less the program's own anonymous memory before it read the problem (runtime, "
                 "libraries' data): what the problem and the solve hold, inputs included; data ratio = "
                 "data peak / reference bytes. Threads: those the run used; sba's are its default for "
                 "nthreads 0 (every hardware thread, one per 10,000 projections at most).")
        L.append("")
        L.append("| problem | cameras | points | observations | run | threads | status | iterations | time [s] | "
                 "ms/iter | peak RSS [MB] | data peak [MB] | reference [MB] | RSS ratio | data ratio | final MSE |")
        L.append("|" + "---|" * 16)
        for name in scal:
            for r in runs_by_problem[name]["runs"]:
                ref = reference_bytes(r)
                data = r.get("data_peak_bytes")
                L.append("| %s | %d | %d | %d | %s | %d | %s | %d | %s | %s | %s | %s | %s | %s | %s | %s |" % (
                    name, r["cameras"], r["points"], r["observations"], run_name(r), r.get("threads_used") or r["threads"],
                    r["status"],
                    r["iterations"], num(r["seconds"]),
                    num(r["seconds_per_iteration"] and r["seconds_per_iteration"] * 1e3, "%.1f"),
                    mb(r["peak_rss_bytes"]), mb(data), mb(ref), num(div(r["peak_rss_bytes"], ref), "%.2f"),
                    num(div(data, ref), "%.2f"), num(r["final_mse"], "%.8g")))
        L.append("")
        growth = scaling_growth(runs_by_problem, scal)
        if growth:
            L.append("Growth from the smallest to the largest problem each run completed (exponent k in "
                     "cost ~ observations^k):")
            L.append("")
            L.extend(growth)
            L.append("")
        L.append("![time per iteration and peak RSS against observations](scaling.png)")
        L.append("")

    if kernels:
        L.append("## Kernel micro-benchmarks (kernels_benchmark, Google Benchmark)")
        L.append("")
        L.append("| benchmark | real time | CPU time | unit |")
        L.append("|---|---|---|---|")
        for b in kernels:
            if b.get("run_type") == "aggregate" or "error_occurred" in b and b["error_occurred"]:
                continue
            L.append("| %s | %.4g | %.4g | %s |" % (b["name"], b["real_time"], b["cpu_time"], b["time_unit"]))
        L.append("")

    L.append("## Commands")
    L.append("")
    for c in meta["commands"]:
        L.append("    " + c)
    L.append("")
    with open(path, "w") as f:
        f.write("\n".join(L))


def reference_bytes(r):
    sparse = r["solver"] in ("sparse-chol", "SPARSE_SCHUR", "ldl-amd")
    s = r["sparse_s_bytes"] if sparse else r["dense_s_bytes"]
    return r["jacobian_bytes"] + s + r["input_bytes"]


def scaling_growth(runs_by_problem, names):
    series = {}
    for name in names:
        for r in runs_by_problem[name]["runs"]:
            if r["ok"]:
                series.setdefault((run_name(r), r["threads"]), []).append(r)
    lines = ["| run | threads | from obs | to obs | time/iter exponent | peak RSS exponent |",
             "|---|---|---|---|---|---|"]
    for (name, t), rs in sorted(series.items()):
        if len(rs) < 2:
            continue
        a, b = rs[0], rs[-1]
        lo = math.log(b["observations"] / a["observations"])
        kt = math.log(b["seconds_per_iteration"] / a["seconds_per_iteration"]) / lo
        km = math.log(b["peak_rss_bytes"] / a["peak_rss_bytes"]) / lo
        lines.append("| %s | %d | %d | %d | %.2f | %.2f |" % (name, t, a["observations"], b["observations"], kt, km))
    return lines if len(lines) > 2 else []


def write_plot(results, runs_by_problem, gnuplot):
    names = [n for n in runs_by_problem if n.startswith("scale-")]
    runs = [r for name in names for r in runs_by_problem[name]["runs"]]
    return plot_runs(results, "scaling", "Scaling series (sbagen path, fixed K, tracks %s)" % SCALING_TRACK,
                     runs, gnuplot)


def plot_runs(results, stem, title, runs, gnuplot):
    """Time per iteration and peak RSS against the observations, one line per run kind:
    STEM.dat, STEM.gp and (with gnuplot) STEM.png in the results directory."""
    series = {}
    for r in runs:
        if r["ok"]:
            series.setdefault("%s, %d thr" % (run_name(r), r["threads"]), []).append(r)
    if not series:
        return None
    dat = os.path.join(results, stem + ".dat")
    with open(dat, "w") as f:
        f.write("# observations seconds_per_iteration peak_rss_MB seconds (one block per run kind)\n")
        keys = sorted(series)
        for key in keys:
            f.write("# %s\n" % key)
            for r in sorted(series[key], key=lambda r: r["observations"]):
                f.write("%d %.6g %.6g %.6g\n" % (r["observations"], r["seconds_per_iteration"],
                                                 r["peak_rss_bytes"] / 1e6, r["seconds"]))
            f.write("\n\n")
    gp = os.path.join(results, stem + ".gp")
    plots_t, plots_m = [], []
    for k, key in enumerate(keys):
        plots_t.append("'%s.dat' index %d using 1:($2*1000) with linespoints title '%s'" % (stem, k, key))
        plots_m.append("'%s.dat' index %d using 1:3 with linespoints title '%s'" % (stem, k, key))
    with open(gp, "w") as f:
        f.write("# gnuplot script written by bench/run_suite.py; run in bench/results: gnuplot %s.gp\n" % stem)
        f.write("set terminal pngcairo size 1400,600 font 'sans,10' noenhanced\n")
        f.write("set output '%s.png'\n" % stem)
        f.write("set multiplot layout 1,2 title '%s'\n" % title)
        f.write("set logscale xy\nset grid\nset key top left\n")
        f.write("set xlabel 'observations'\n")
        f.write("set ylabel 'time per iteration [ms] (sba: outer iteration; Ceres: LM step)'\n")
        f.write("plot " + ", \\\n     ".join(plots_t) + "\n")
        f.write("set ylabel 'peak RSS [MB]'\n")
        f.write("plot " + ", \\\n     ".join(plots_m) + "\n")
        f.write("unset multiplot\n")
    if not gnuplot:
        log("gnuplot not found (Debian package gnuplot-nox): %s.png not drawn; %s.gp is ready" % (stem, stem))
        return None
    subprocess.run([gnuplot, stem + ".gp"], cwd=results, check=True)
    return os.path.join(results, stem + ".png")


def machine():
    cpu = platform.processor() or platform.machine()
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    cpu = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    mem = "?"
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemTotal"):
                    mem = "%.1f GiB RAM" % (int(line.split()[1]) / 1024.0 / 1024.0)
    except OSError:
        pass
    return cpu, mem


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--build", required=True, help="build directory holding bench/sba_bench")
    ap.add_argument("--data", default=os.path.join(ROOT, "..", "shared", "data"),
                    help="shared data directory (sba-demo/, bal/)")
    ap.add_argument("--results", default=os.path.join(HERE, "results"), help="output directory")
    ap.add_argument("--quick", action="store_true", help="a reduced set, to check that everything works")
    ap.add_argument("--only", default="", help="comma-separated groups: demo,bal,scaling,longseq,converge,kernels")
    ap.add_argument("--timeout", type=float, default=3600, help="seconds per run before it is killed")
    ap.add_argument("--repeat", type=int, default=REPEAT,
                    help="runs per configuration of the 54-camera and BAL problems (median reported)")
    ap.add_argument("--report-only", action="store_true", help="rewrite results.md and the plot from results.json")
    ap.add_argument("--append", action="store_true",
                    help="keep results.json and suite.json, replacing only the problems run again")
    a = ap.parse_args()

    exe = os.path.join(a.build, "bench", "sba_bench")
    kexe = os.path.join(a.build, "bench", "kernels_benchmark")
    os.makedirs(a.results, exist_ok=True)
    out = os.path.join(a.results, "results.json")
    meta_path = os.path.join(a.results, "suite.json")
    groups_wanted = set(a.only.split(",")) if a.only else {"demo", "bal", "scaling", "longseq", "converge",
                                                           "kernels"}
    demo = os.path.join(a.data, "sba-demo")
    bal = os.path.join(a.data, "bal")

    problems = []  # (group title, name, args)
    repeat = ["--repeat", str(max(1, a.repeat))] if not a.quick and a.repeat > 1 else []
    if "demo" in groups_wanted:
        problems.append(("sba-demo, 54 cameras", "54cams",
                         ["--cams", os.path.join(demo, "54cams.txt"), "--pts", os.path.join(demo, "54pts.txt"),
                          "--calib", os.path.join(demo, "calib.txt"), "--solvers", "chol,chol-lapack,ldl-amd,sparse-chol"]
                         + STRATEGIES + CERES + repeat))
        if not a.quick:
            for name in ("54camsvarK", "54camsvarKD"):
                problems.append(("sba-demo, 54 cameras", name,
                                 ["--cams", os.path.join(demo, name + ".txt"), "--pts", os.path.join(demo, "54pts.txt"),
                                  "--solvers", "chol,sparse-chol"] + STRATEGIES + CERES + repeat))
    if "bal" in groups_wanted:
        for f in (BAL_FILES[1:2] if a.quick else BAL_FILES):
            name = f.replace(".txt.bz2", "")
            problems.append(("BAL problems", name,
                             ["--bal", os.path.join(bal, f), "--solvers", "chol,sparse-chol"] + STRATEGIES + CERES
                             + repeat))
    if "scaling" in groups_wanted:
        for cams, pts, solvers, ceres in (SCALING_QUICK if a.quick else SCALING):
            name = "scale-%dc-%dp" % (cams, pts)
            problems.append(("Scaling series", name,
                             ["--gen", "cameras=%d,points=%d,track=%s,trajectory=path" % (cams, pts, SCALING_TRACK),
                              "--solvers", solvers, "--ceres", ceres, "--itmax", str(SCALING_ITMAX),
                              "--threads", SCALING_THREADS, "--warm-up"]))
    if "longseq" in groups_wanted:
        spec, solvers, ceres, itmax = LONGSEQ_QUICK if a.quick else LONGSEQ
        problems.append(("Long sequence", "longseq",
                         ["--gen", spec, "--solvers", solvers, "--ceres", ceres, "--itmax", str(itmax),
                          "--threads", LONGSEQ_THREADS]))

    if "converge" in groups_wanted and not a.quick:
        spec, solvers, ceres = CONVERGE
        problems.append(("Long sequence to convergence", "longseq-converged",
                         ["--gen", spec, "--solvers", solvers] + STRATEGIES + ["--ceres", ceres,
                                                                              "--threads", LONGSEQ_THREADS]))

    if not a.report_only:
        if not os.path.exists(exe):
            sys.exit("run_suite: %s not found: build the bench target first (run_suite.sh does)" % exe)
        missing = [p for p in (demo, bal) if not os.path.isdir(p)]
        if missing:
            log("run_suite: shared data not found (%s): those problems are skipped" % ", ".join(missing))
        meta = {"commands": [], "loads": {}}
        if a.append and os.path.exists(meta_path):
            with open(meta_path) as f:
                meta = json.load(f)
        elif os.path.exists(out):
            os.replace(out, out + ".old")
        for title, name, args in problems:
            paths = [args[i + 1] for i, v in enumerate(args) if v in ("--cams", "--pts", "--calib", "--bal")]
            if any(not os.path.exists(p) for p in paths):
                log("run_suite: skipping %s (data not found)" % name)
                continue
            if a.append:
                forget_problem(out, meta, name)
            res = run_bench(exe, ["--name", name] + args, out, a.timeout)
            meta["commands"].append(res["command"])
            meta["loads"][name] = {"load": res["load"], "command": res["command"]}
        if "kernels" in groups_wanted and os.path.exists(kexe):
            kout = os.path.join(a.results, "kernels.json")
            cmd = [kexe, "--benchmark_out=" + kout, "--benchmark_out_format=json"]
            if a.quick:
                cmd.append("--benchmark_filter=Solve1/54cams|Fjac|AxbChol/324")
            log("$ " + " ".join(cmd))
            subprocess.run(cmd, check=False)
            meta["commands"].append(" ".join(cmd))
        meta["quick"] = meta.get("quick", False) if a.append else a.quick
        with open(meta_path, "w") as f:
            json.dump(meta, f, indent=1)

    with open(meta_path) as f:
        meta = json.load(f)
    runs = read_runs(out)
    runs_by_problem = {}
    for r in runs:
        entry = runs_by_problem.setdefault(r["problem"], {"runs": [], "load": float("nan"), "command": ""})
        entry["runs"].append(r)
        if r["problem"] in meta["loads"]:
            entry.update(meta["loads"][r["problem"]])
    kernels = []
    kpath = os.path.join(a.results, "kernels.json")
    if os.path.exists(kpath):
        with open(kpath) as f:
            kernels = json.load(f).get("benchmarks", [])
    cpu, mem = machine()
    meta.update({"date": datetime.datetime.utcnow().strftime("%Y-%m-%d %H:%M UTC"), "host": platform.node(),
                 "cpu": cpu, "mem": mem, "threads": os.cpu_count() or 1})
    groups = [
        ("sba-demo, 54 cameras", ["54cams", "54camsvarK", "54camsvarKD"]),
        ("BAL problems", [f.replace(".txt.bz2", "") for f in BAL_FILES]),
        ("Long sequence", ["longseq"]),
        ("Long sequence to convergence", ["longseq-converged"]),
    ]
    write_markdown(os.path.join(a.results, "results.md"), meta, groups, runs_by_problem, kernels)
    png = write_plot(a.results, runs_by_problem, shutil.which("gnuplot"))
    log("wrote %s/results.md, results.json%s" % (a.results, ", scaling.png" if png else ""))


if __name__ == "__main__":
    main()
