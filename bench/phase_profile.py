#!/usr/bin/env python3
# SPDX-License-Identifier: BSD-3-Clause
"""Where a solve's time goes, by sampling: each phase's CPU seconds per iteration against its
bound on this machine.

  /usr/bin/python3 bench/phase_profile.py [--build build] [--data DIR] [--threads 2] [--runs NAME,...]
      [--strategies sba,trust-region] [--colmap NAME=DIR,...] [--out bench/results/phase_profile]

(any Python with numpy; Linux perf on PATH).

Each run is one of this repository's programs under `perf record` (Linux perf, with the call
sites' symbols: libsba's are not stripped), its samples (every thread's) put into phases by the
function they fall in:

  linearization  the residuals and the Jacobian: the camera models' projections and
                 derivatives, the program's callbacks, the loops that call them;
  assembly       the normal equations and the reduced camera system S: the blocks' Gram
                 products, the points' inverses, the couplings and their products into S;
  factor/solve   S's factorization (dense or sparse Cholesky, OpenBLAS's or the library's own)
                 and the substitutions, and the points' back-substitution;
  CG             iterative-schur's conjugate gradients on the implicit S;
  threads        waiting: the pool's spin and sleep, the scheduler, OpenBLAS's idle threads;
  rest           everything else (reading the input, the page faults of new memory, ...).

The bounds, measured in the same run: a STREAM-like copy (numpy, 1 GiB, on one thread: the
memory bandwidth this machine gives), and dgemm's rate on --threads threads (numpy's OpenBLAS,
n = 3000: the flops these cores give to a dense kernel). A linearization writes the Jacobian
once (observations x 2 x (cnp + pnp) doubles) and an assembly reads it at least once: their
bound is those bytes over the bandwidth. A dense factorization of S costs N^3/3 flops (N its
unknowns): its bound is that over dgemm's rate. These are floors, not estimates: the measured
phase is n times its floor.

Runs (--runs): 54cams (eucsbademo, fixed K), problem-16 (balsba, BAL problem-16), and each
COLMAP model of --colmap NAME=DIR (sbarefine at its defaults), each with every strategy of
--strategies; --runs '' runs the COLMAP models alone.

Writes OUT.md (the table and the commands) and OUT.json (one object a run).
"""
import argparse
import datetime
import json
import os
import re
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
PHASES = ["linearization", "assembly", "factor/solve", "CG", "threads", "rest"]
# First match wins: the order matters where names overlap (chol::factor before "factor").
RULES = [
    ("threads", r"sched|finish_task_switch|wait_for_workers|ThreadPool::work\b|futex|blas_thread_server|"
                r"_raw_spin|do_syscall_64|entry_SYSCALL|Barrier"),
    ("CG", r"IterativeSchur|PointPass|point_pass|BlockJacobi|ClusterJacobi|conjugate|preconditioner|Preconditioner"),
    ("assembly", r"gram_|assemble|pair_sweep|pair_update|couplings|point_terms|inverse_diagonals|"
                 r"damped_inverse|MappedSchur|schur_pattern|SchurAssembly|schur_assembly"),
    ("factor/solve", r"chol::|Cholesky|cholmod|potrf|trsm|trsv|syrk|gemm|back_substitute|panel_columns|"
                     r"trailing_rows|libopenblas|libcholmod|libamd|libsuitesparse"),
    ("linearization", r"fjac|_func\b|::project|jacobian|Jacobian|sbacameras|hypot|radtan|linearized|residual|"
                      r"reweight|sqnorm|zero_held"),
]


def bandwidth():
    """Bytes a second of a 1 GiB copy (read + write), the best of three."""
    import numpy as np
    a = np.ones(1 << 27)
    b = np.empty_like(a)
    best = 0.0
    for _ in range(3):
        t = time.perf_counter()
        np.copyto(b, a)
        best = max(best, 2 * a.nbytes / (time.perf_counter() - t))
    return best


def dgemm_rate(threads):
    """Flops a second of numpy's dgemm at n = 3000 on `threads` threads, the best of three."""
    env = dict(os.environ, OPENBLAS_NUM_THREADS=str(threads), OMP_NUM_THREADS=str(threads))
    code = ("import numpy as np, time\n"
            "a = np.random.rand(3000, 3000); b = np.random.rand(3000, 3000); a @ b\n"
            "best = 0\n"
            "for _ in range(3):\n"
            "    t = time.perf_counter(); a @ b; best = max(best, 2 * 3000 ** 3 / (time.perf_counter() - t))\n"
            "print(best)\n")
    return float(subprocess.run([sys.executable, "-c", code], env=env, check=True, stdout=subprocess.PIPE,
                                text=True).stdout)


def short(symbol):
    """A symbol as the table shows it: a thread pool job by the function it runs, without the
    namespaces that every name here has."""
    m = re.match(r"std::_Function_handler<void \(int\), sba::ThreadPool::for_range(?:_t)?<(.*?)::\{lambda", symbol)
    if m:
        symbol = m.group(1)
    for noise in ("(anonymous namespace)::", "sba::avx2::", "sba::"):
        symbol = symbol.replace(noise, "")
    return symbol.strip()[:90]


def phase_of(symbol, dso):
    text = symbol + " " + dso
    for phase, pattern in RULES:
        if re.search(pattern, text):
            return phase
    return "rest"


def profile(cmd, work, tag):
    """(phase -> CPU seconds, top symbols, wall seconds) of cmd under perf record."""
    data = os.path.join(work, tag + ".perf")
    t = time.perf_counter()
    subprocess.run(["perf", "record", "-q", "-F", "2000", "-o", data, "--"] + cmd, check=True,
                   stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    wall = time.perf_counter() - t
    rep = subprocess.run(["perf", "report", "-i", data, "--stdio", "--no-children", "--sort", "dso,symbol",
                          "-F", "sample,dso,symbol", "--percent-limit", "0"], check=True, stdout=subprocess.PIPE,
                         stderr=subprocess.DEVNULL, text=True).stdout
    samples, total = {}, 0
    line = re.compile(r"^\s*(\d+)\s+(\S+)\s+\[[.k]\]\s+(.*?)\s*$")
    for row in rep.splitlines():
        m = line.match(row)
        if not m:
            continue
        n, dso, sym = int(m.group(1)), m.group(2), m.group(3)
        samples[(dso, sym)] = samples.get((dso, sym), 0) + n
        total += n
    phases = dict.fromkeys(PHASES, 0.0)
    for (dso, sym), n in samples.items():
        phases[phase_of(sym, dso)] += n / 2000.0  # -F 2000: a sample is half a millisecond of a CPU
    ranked = sorted(samples.items(), key=lambda kv: -kv[1])
    # The eight largest, and the three largest of "rest" below them.
    top = ranked[:8] + [kv for kv in ranked[8:] if phase_of(kv[0][1], kv[0][0]) == "rest"][:3]
    return phases, [(dso, short(sym), n / 2000.0, phase_of(sym, dso)) for (dso, sym), n in top], wall


def runs_of(a, work):
    """[(name, program, strategy, cmd, json path, (cnp, pnp))]."""
    demo = os.path.join(a.build, "demo")
    sba_demo, bal = os.path.join(a.data, "sba-demo"), os.path.join(a.data, "bal")
    out = []
    for strategy in a.strategies.split(","):
        for name in filter(None, a.runs.split(",")):
            js = os.path.join(work, "%s-%s.json" % (name.replace("/", "_"), strategy))
            common = ["--threads", str(a.threads), "--strategy", strategy, "--json", js, "--no-progress"]
            if name == "54cams":
                cmd = [os.path.join(demo, "eucsbademo"), os.path.join(sba_demo, "54cams.txt"),
                       os.path.join(sba_demo, "54pts.txt"), os.path.join(sba_demo, "calib.txt")] + common
                out.append((name, "eucsbademo", strategy, cmd, js, (6, 3)))
            elif name == "problem-16":
                cmd = [os.path.join(demo, "balsba"), os.path.join(bal, "problem-16-22106-pre.txt.bz2")] + common
                out.append((name, "balsba", strategy, cmd, js, (9, 3)))
            else:
                raise SystemExit("phase_profile.py: unknown run %r" % name)
        for spec in filter(None, a.colmap.split(",")):
            name, _, path = spec.partition("=")
            js = os.path.join(work, "%s-%s.json" % (name, strategy))
            cmd = [os.path.join(demo, "sbarefine"), path, "--threads", str(a.threads), "--strategy", strategy,
                   "--json", js, "--no-progress"]
            out.append((name, "sbarefine", strategy, cmd, js, None))
    return out


def main(argv):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--build", default=os.path.join(ROOT, "build"))
    ap.add_argument("--data", default=os.path.join(ROOT, "..", "shared", "data"),
                    help="the directory holding sba-demo/ and bal/ (as run_suite.py's --data)")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--runs", default="54cams,problem-16")
    ap.add_argument("--colmap", default="", help="NAME=DIR,...: COLMAP models for sbarefine")
    ap.add_argument("--strategies", default="sba,trust-region")
    ap.add_argument("--out", default=os.path.join(HERE, "results", "phase_profile"))
    ap.add_argument("--work", default="")
    a = ap.parse_args(argv)
    work = a.work or tempfile.mkdtemp(prefix="phase_profile.")
    os.makedirs(work, exist_ok=True)
    runs = runs_of(a, work)
    if not runs:
        raise SystemExit("phase_profile.py: nothing to run (--runs and --colmap both empty)")
    bw, peak = bandwidth(), dgemm_rate(a.threads)
    results = []
    for name, program, strategy, cmd, js, blocks in runs:
        phases, top, wall = profile(cmd, work, "%s-%s" % (name, strategy))
        with open(js, encoding="utf-8") as f:
            d = json.load(f)
        its = max(1, int(d["info"]["iterations"]))
        systems = max(1, int(d["info"]["linear_systems"]))
        sizes = d["sizes"]
        m, n, nobs = sizes["cameras"], sizes["points"], sizes["observations"]
        cnp, pnp = blocks if blocks else ((sizes["variables"] - 3 * n) / max(1, m), 3)
        jac_bytes = nobs * 2 * (cnp + pnp) * 8
        unknowns = sizes.get("unknowns", sizes["variables"]) - 3 * n
        r = {"run": name, "program": program, "strategy": strategy, "solver": d["solver"], "iterations": its,
             "linear_systems": systems, "seconds": d["seconds"], "wall": wall, "observations": nobs,
             "cameras": m, "points": n, "camera_unknowns": unknowns, "jacobian_bytes": jac_bytes,
             "phases": phases, "top": top, "bandwidth": bw, "dgemm_flops": peak, "command": cmd,
             "bounds": {"linearization": jac_bytes / bw, "assembly": jac_bytes / bw,
                        "factor/solve": (unknowns ** 3 / 3) / peak if d["solver"] in ("chol", "chol-lapack") else None}}
        results.append(r)
        print("%s %s: %.3f s, %d iterations, %s" % (name, strategy, d["seconds"], its,
              ", ".join("%s %.3f" % (p, s) for p, s in phases.items())), file=sys.stderr, flush=True)
    write_report(a, results, argv)


def write_report(a, results, argv):
    with open(a.out + ".json", "w", encoding="utf-8") as f:
        for r in results:
            f.write(json.dumps(r) + "\n")
    r0 = results[0]
    lines = ["# Where a solve's time goes: phases per iteration against their floors", "",
             "Written by `bench/phase_profile.py` (see its opening comment) on %s, %d threads:" % (
                 datetime.date.today().isoformat(), a.threads), "",
             "    /usr/bin/python3 bench/phase_profile.py " + " ".join(argv), "",
             "This machine, measured in the same run: a 1 GiB copy at %.1f GB/s; dgemm at %.1f GFlop/s on %d "
             "threads." % (r0["bandwidth"] / 1e9, r0["dgemm_flops"] / 1e9, a.threads), "",
             "CPU milliseconds per iteration (every thread's samples; with 2 threads, up to twice the wall time), "
             "and in brackets the floor: the Jacobian's bytes over the copy's bandwidth for linearization and "
             "assembly, N^3/3 flops over dgemm's rate for a dense factorization (per linear system).", "",
             "| run | strategy | solver | observations | iterations | solve s | " + " | ".join(PHASES) + " |",
             "|---|---|---|---:|---:|---:|" + "---:|" * len(PHASES)]
    for r in results:
        cells = []
        for p in PHASES:
            ms = 1e3 * r["phases"][p] / r["iterations"]
            b = r["bounds"].get(p)
            if b is not None and p == "factor/solve":
                b *= r["linear_systems"] / r["iterations"]
            cells.append("%.1f" % ms + (" (%.2f)" % (1e3 * b) if b else ""))
        lines.append("| %s | %s | %s | %d | %d | %.3f | %s |" % (r["run"], r["strategy"], r["solver"],
                     r["observations"], r["iterations"], r["seconds"], " | ".join(cells)))
    lines += ["", "The functions that took the most samples, by run (CPU seconds, phase):", ""]
    for r in results:
        lines.append("- %s, %s: " % (r["run"], r["strategy"]) + "; ".join(
            "`%s` %.3f (%s)" % (sym, s, phase) for dso, sym, s, phase in r["top"]))
    lines.append("")
    with open(a.out + ".md", "w", encoding="utf-8") as f:
        f.write("\n".join(lines))


if __name__ == "__main__":
    main(sys.argv[1:])
