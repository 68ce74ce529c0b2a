#!/usr/bin/env python3
# SPDX-License-Identifier: BSD-3-Clause
"""sbarefine against Ceres 2.2 as COLMAP 4 runs it (pycolmap.bundle_adjustment), to the end and
to a cost tolerance.

Run it with a Python that has pycolmap 4 (the venv of tests/pycolmap, build/pycolmap-venv):

  build/pycolmap-venv/bin/python3 bench/pycolmap_ceres.py --sbagen build/demo/sbagen \\
      --sbarefine build/demo/sbarefine [--problems photo:100,orbit:100,bal:FILE,...] \\
      [--points-per-image 100] [--threads 2] [--repeat 1] [--ceres default,dense,sparse,iterative] \\
      [--sba trust-region,sba] [--timeout SEC] [--out bench/results/pycolmap_ceres] [--work DIR]
  ... --report-only OUT.json,...   (no runs: the report of earlier runs, several files merged)

The problems (--problems), each a COLMAP model both programs read:
  photo:N, orbit:N  the scenes of bench/series.sh (sbagen --trajectory photo|orbit --cameras N
                    --points N*PPI, tracks of 4..min(N, 300) and 3..40 cameras, seed 7) as
                    COLMAP models (--kind fixed --colmap): one PINHOLE camera shared by every
                    image, its focal length, the poses and the points perturbed as sbagen does;
  bal:FILE          a BAL problem (.txt or .txt.bz2) as a COLMAP model that projects exactly as
                    BAL's camera does: a RADIAL camera per image (f, principal point 0, k1, k2),
                    each pose turned by 180 degrees about its x axis (BAL's cameras look down -z)
                    and the observations' y negated. COLMAP's defaults refine the focal lengths
                    and k1, k2 and hold the principal points: BAL's nine parameters a camera.

The runs, each in a process of its own, --threads threads:
  ceres:default    pycolmap.bundle_adjustment at pycolmap's defaults (COLMAP picks the linear
                   solver from the number of images: DENSE_SCHUR, SPARSE_SCHUR or
                   ITERATIVE_SCHUR with SCHUR_JACOBI);
  ceres:dense, ceres:sparse, ceres:iterative
                   the same with that solver (iterative: SCHUR_JACOBI) and
                   auto_select_solver_type off;
  sba:trust-region sbarefine at its defaults (for a COLMAP model, the trust region);
  sba:sba          sbarefine --strategy sba (sba 1.6's Levenberg-Marquardt).

Reported per run: the cost (half the sum of squared reprojection errors, Ceres's) at the start
and the end, the iterations, the seconds to the end, and the seconds to reach each cost
tolerance tau of 10%, 1% and 0.3%: the first iteration whose cost is at most
f* + tau (f0 - f*), where f0 is the start's cost and f* the lowest final cost of any run on the
problem (the measure of the Power Bundle Adjustment and RootBA papers). A run that never gets
there shows "-". Seconds are the solver's own: Ceres's total_time column (from the start of
ceres::Solve, its preprocessing included, COLMAP's building of the problem not) and sbarefine's
solve (its --json "seconds" and per-iteration times: reading the model not included). The
Python call's wall time around pycolmap.bundle_adjustment (with COLMAP's building of the
problem) is in the JSON as call_seconds. A Ceres run that --timeout stops is reported with
what it printed until then: its times to the tolerances it reached, the last cost it printed
as its final one, and "> TIMEOUT" to the end; an sba run that it stops is left out.

Writes OUT.md (the tables and the exact commands) and OUT.json (one JSON object a run, each
written as its run ends).
"""
import argparse
import bz2
import datetime
import json
import os
import re
import statistics
import subprocess
import sys
import tempfile

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
TAUS = (0.1, 0.01, 0.003)
# Final costs closer than this, relatively, are the same minimum.
SAME_COST = 1e-9
CERES = {
    "default": None,
    "dense": ("DENSE_SCHUR", None),
    "sparse": ("SPARSE_SCHUR", None),
    "iterative": ("ITERATIVE_SCHUR", "SCHUR_JACOBI"),
}
# A line of Ceres's minimizer progress: iter cost cost_change |gradient| |step| tr_ratio
# tr_radius ls_iter iter_time total_time.
PROGRESS = re.compile(r"^\s*(\d+)\s+(\S+)\s+\S+\s+\S+\s+\S+\s+\S+\s+\S+\s+\S+\s+\S+\s+(\S+)\s*$")


def rotations(w):
    """The rotation matrices of angle-axis vectors w (k x 3), Rodrigues' formula."""
    theta = np.linalg.norm(w, axis=1)
    axis = w / np.where(theta > 0, theta, 1.0)[:, None]
    K = np.zeros((len(w), 3, 3))
    K[:, 0, 1], K[:, 0, 2], K[:, 1, 2] = -axis[:, 2], axis[:, 1], -axis[:, 0]
    K -= K.transpose(0, 2, 1)
    s, c = np.sin(theta)[:, None, None], np.cos(theta)[:, None, None]
    return np.eye(3) + s * K + (1 - c) * (K @ K)


def bal_to_colmap(path, out):
    """Writes BAL problem `path` as a COLMAP text model in directory out (see the opening
    comment); returns (cameras, points, observations) written, and the observations behind their
    cameras, the points and their other observations left out."""
    opener = bz2.open if path.endswith(".bz2") else open
    with opener(path, "rt") as f:
        tokens = f.read().split()
    m, n, k = int(tokens[0]), int(tokens[1]), int(tokens[2])
    pos = 3
    obs = np.array(tokens[pos:pos + 4 * k], np.float64).reshape(k, 4)
    pos += 4 * k
    cams = np.array(tokens[pos:pos + 9 * m], np.float64).reshape(m, 9)
    pos += 9 * m
    pts = np.array(tokens[pos:pos + 3 * n], np.float64).reshape(n, 3)
    # An observation of a point behind its camera is a residual of BAL's camera but none of
    # COLMAP's (pycolmap 4 costs it zero, colmap 3.8's adjuster leaves it out): left out here,
    # and with it a point seen fewer than twice.
    R = rotations(cams[:, 0:3])
    cam_idx, pt_idx = obs[:, 0].astype(int), obs[:, 1].astype(int)
    depth = np.einsum("kj,kj->k", R[cam_idx, 2, :], pts[pt_idx]) + cams[cam_idx, 5]
    keep = depth < 0
    behind = int((~keep).sum())
    seen = np.bincount(pt_idx[keep], minlength=n)
    keep &= seen[pt_idx] >= 2
    lost = (n - int((seen >= 2).sum()), k - behind - int(keep.sum()))
    obs, cam_idx = obs[keep], cam_idx[keep]
    used = np.flatnonzero(seen >= 2)
    renumber = np.full(n, -1)
    renumber[used] = np.arange(len(used))
    pts, pt_idx, n, k = pts[used], renumber[pt_idx[keep]], len(used), int(keep.sum())
    os.makedirs(out, exist_ok=True)
    extent = int(np.ceil(np.abs(obs[:, 2:]).max())) + 1
    with open(os.path.join(out, "cameras.txt"), "w") as f:
        for j in range(m):
            fl, k1, k2 = cams[j, 6:9]
            f.write("%d RADIAL %d %d %.17g 0 0 %.17g %.17g\n" % (j + 1, 2 * extent, 2 * extent, fl, k1, k2))
    # Each point's track: its observations in file order, each its keypoint's index in its image.
    keypoint = np.zeros(k, np.int64)
    per_image = [[] for _ in range(m)]
    for o in range(k):
        j = cam_idx[o]
        keypoint[o] = len(per_image[j])
        per_image[j].append(o)
    with open(os.path.join(out, "images.txt"), "w") as f:
        for j in range(m):
            w = cams[j, 0:3]
            theta = float(np.linalg.norm(w))
            axis = w / theta if theta > 0 else np.array([1.0, 0.0, 0.0])
            qw, (qx, qy, qz) = np.cos(theta / 2), np.sin(theta / 2) * axis
            # diag(1, -1, -1) R: the quaternion (0, 1, 0, 0) times q.
            q = (-qx, qw, -qz, qy)
            t = cams[j, 3:6] * np.array([1.0, -1.0, -1.0])
            f.write("%d %s %s %d image%06d\n" % (j + 1, " ".join("%.17g" % v for v in q),
                                                 " ".join("%.17g" % v for v in t), j + 1, j))
            f.write(" ".join("%.17g %.17g %d" % (obs[o, 2], -obs[o, 3], pt_idx[o] + 1) for o in per_image[j]) + "\n")
    tracks = [[] for _ in range(n)]
    for o in range(k):
        tracks[pt_idx[o]].append((cam_idx[o] + 1, keypoint[o]))
    with open(os.path.join(out, "points3D.txt"), "w") as f:
        for i in range(n):
            track = " ".join("%d %d" % e for e in tracks[i])
            f.write("%d %.17g %.17g %.17g 128 128 128 0 %s\n" % (i + 1, *pts[i], track))
    return m, n, k, behind, lost


def worker_ceres(inp, config, threads, report, out):
    """The pycolmap process: read, adjust (Ceres's progress on stdout), write, report."""
    import time
    import pycolmap
    from pycolmap import pyceres
    rec = pycolmap.Reconstruction(inp)
    o = pycolmap.BundleAdjustmentOptions()
    o.print_summary = False
    so = o.ceres.solver_options
    so.num_threads = int(threads)
    so.logging_type = pyceres.LoggingType.PER_MINIMIZER_ITERATION
    so.minimizer_progress_to_stdout = True
    forced = CERES[config]
    if forced is not None:
        o.ceres.auto_select_solver_type = False
        so.linear_solver_type = getattr(pyceres.LinearSolverType, forced[0])
        if forced[1]:
            so.preconditioner_type = getattr(pyceres.PreconditionerType, forced[1])
    facts = {"images": rec.num_reg_images(), "dense_max": o.ceres.max_num_images_direct_dense_cpu_solver,
             "sparse_max": o.ceres.max_num_images_direct_sparse_cpu_solver}
    # Written before the solve too, so that a run stopped at --timeout still tells its solver.
    with open(report, "w", encoding="utf-8") as f:
        json.dump(facts, f)
    sys.stdout.flush()
    t0 = time.perf_counter()
    pycolmap.bundle_adjustment(rec, o)
    facts["call_seconds"] = time.perf_counter() - t0
    sys.stdout.flush()
    os.makedirs(out, exist_ok=True)
    rec.write_binary(out)
    with open(report, "w", encoding="utf-8") as f:
        json.dump(facts, f)


def run_ceres(a, inp, config, work):
    report, out = os.path.join(work, "ceres-%s.json" % config), os.path.join(work, "ceres-%s" % config)
    cmd = [sys.executable, os.path.abspath(__file__), "--worker", "ceres", inp, config, str(a.threads), report, out]
    if os.path.exists(report):
        os.remove(report)
    try:
        stdout = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True, timeout=a.timeout,
                                check=True).stdout
        stopped = False
    except subprocess.TimeoutExpired as e:
        # What it printed until then (bytes: the run was killed before its output was decoded).
        stdout, stopped = e.stdout or b"", True
        if isinstance(stdout, bytes):
            stdout = stdout.decode("utf-8", "replace")
    trace = [(float(mt.group(3)), float(mt.group(2))) for mt in map(PROGRESS.match, stdout.splitlines()) if mt]
    if stopped and (len(trace) < 2 or not os.path.exists(report)):
        raise subprocess.TimeoutExpired(cmd, a.timeout)
    with open(report, encoding="utf-8") as f:
        r = json.load(f)
    if config == "default":
        images = r["images"]
        r["solver"] = "DENSE_SCHUR" if images <= r["dense_max"] else \
            "SPARSE_SCHUR" if images <= r["sparse_max"] else "ITERATIVE_SCHUR"
    else:
        r["solver"] = CERES[config][0]
    # Ceres's cost after each iteration, to the 7 digits it prints; iteration 0 is the start. A
    # rejected step repeats the cost of the iterate kept. The final cost to all its digits is
    # the written model's, measured as sbarefine measures its own (its --itmax 0, which, as
    # COLMAP does, leaves out an observation behind its camera; own_final: Ceres's).
    r.update(initial=trace[0][1], own_final=trace[-1][1], trace=trace[1:], iterations=len(trace) - 1, cmd=cmd[1:])
    if stopped:
        # Stopped at --timeout: no model was written, so its final cost is the last it printed,
        # and its time to the end is more than the timeout; its times to the tolerances stand.
        r.update(final=trace[-1][1], seconds=a.timeout, stopped=True)
    else:
        r.update(final=score(a, out, work), seconds=trace[-1][0])
    return r


def score(a, model, work):
    """Half the squared reprojection error of a COLMAP model, by sbarefine --itmax 0."""
    js = os.path.join(work, "score.json")
    subprocess.run([a.sbarefine, model, "--itmax", "0", "--json", js, "--no-progress"], stdout=subprocess.DEVNULL,
                   stderr=subprocess.DEVNULL, check=True)
    with open(js, encoding="utf-8") as f:
        return json.load(f)["squared_error"]["final"] / 2


def run_sba(a, inp, strategy, work):
    js = os.path.join(work, "sba-%s.json" % strategy)
    cmd = [a.sbarefine, inp, "--threads", str(a.threads), "--json", js, "--no-progress"]
    if strategy != "trust-region":
        cmd += ["--strategy", strategy]
    subprocess.run(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, timeout=a.timeout, check=True)
    with open(js, encoding="utf-8") as f:
        d = json.load(f)
    trace = [(it["seconds"], it["error"] / 2) for it in d["iterations"]]
    return {"initial": d["squared_error"]["initial"] / 2, "final": d["squared_error"]["final"] / 2,
            "trace": trace, "seconds": d["seconds"], "iterations": d["info"]["iterations"], "solver": d["solver"],
            "cmd": cmd}


def time_to(run, target):
    for seconds, cost in run["trace"]:
        if cost <= target:
            return seconds
    return run["seconds"] if run["final"] <= target else None


def make_problem(a, spec, work):
    """The problem's name, its binary model directory and the commands that made it."""
    kind, _, arg = spec.partition(":")
    d = os.path.join(work, spec.replace(":", "-").replace("/", "_"))
    os.makedirs(d, exist_ok=True)
    text, binary = os.path.join(d, "text"), os.path.join(d, "input")
    if kind in ("photo", "orbit"):
        n = int(arg)
        # The scenes of bench/series.sh.
        tracks = ("3", "40") if kind == "orbit" else ("4", str(min(n, 300)))
        cmd = [a.sbagen, "--out", os.path.join(d, "gen"), "--colmap", text, "--kind", "fixed", "--trajectory", kind,
               "--cameras", str(n), "--points", str(n * a.points_per_image), "--track-min", tracks[0],
               "--track-max", tracks[1], "--seed", "7", "--quiet"]
        subprocess.run(cmd, check=True)
        name, made = "%s %d" % (kind, n), " ".join(cmd)
    elif kind == "bal":
        behind, lost = bal_to_colmap(arg, text)[3:]
        name = os.path.basename(arg).split(".")[0]
        made = "BAL %s, converted; %d observations behind their cameras left out" % (os.path.basename(arg), behind)
        if lost[0]:
            made += ", and %d points then seen fewer than twice (%d more observations)" % lost
    else:
        raise SystemExit("pycolmap_ceres.py: unknown problem %r (photo:N, orbit:N or bal:FILE)" % spec)
    import pycolmap
    rec = pycolmap.Reconstruction(text)
    os.makedirs(binary, exist_ok=True)
    rec.write_binary(binary)
    return name, binary, made, rec.num_reg_images(), rec.compute_num_observations()


def cell(x):
    return "-" if x is None else "%.3f" % x


def main(argv):
    if argv[:2] == ["--worker", "ceres"]:
        return worker_ceres(*argv[2:])
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sbagen", required=True)
    ap.add_argument("--sbarefine", required=True)
    ap.add_argument("--problems", default="photo:100,orbit:100")
    ap.add_argument("--points-per-image", type=int, default=100)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--repeat", type=int, default=1)
    ap.add_argument("--ceres", default="default,dense,sparse,iterative")
    ap.add_argument("--sba", default="trust-region,sba")
    ap.add_argument("--timeout", type=float, default=3600)
    ap.add_argument("--out", default=os.path.join(HERE, "results", "pycolmap_ceres"))
    ap.add_argument("--work", default="")
    ap.add_argument("--report-only", default="", metavar="JSON,...",
                    help="no runs: the report of these files' runs (this script's OUT.json)")
    a = ap.parse_args(argv)
    import pycolmap
    if a.report_only:
        runs = []
        for path in a.report_only.split(","):
            with open(path, encoding="utf-8") as f:
                runs += [json.loads(line) for line in f if line.strip()]
        return write_report(a, pycolmap.__version__, runs)
    work = a.work or tempfile.mkdtemp(prefix="pycolmap_ceres.")
    runs = []
    # Each run's record is written as soon as it is made: a command stopped during a long run
    # leaves those before it for --report-only.
    with open(a.out + ".json", "w", encoding="utf-8"):
        pass
    for spec in a.problems.split(","):
        name, inp, made, images, nobs = make_problem(a, spec, work)
        for program, configs in (("ceres", a.ceres), ("sba", a.sba)):
            for config in filter(None, configs.split(",")):
                for rep in range(a.repeat):
                    try:
                        r = run_ceres(a, inp, config, work) if program == "ceres" else run_sba(a, inp, config, work)
                    except subprocess.TimeoutExpired:
                        print("%s %s:%s: timed out after %g s" % (name, program, config, a.timeout), file=sys.stderr,
                              flush=True)
                        break
                    r.update(problem=name, made=made, images=images, observations=nobs,
                             run="%s:%s" % (program, config), repeat=rep, repeats=a.repeat, threads=a.threads,
                             date=datetime.date.today().isoformat(),
                             command="build/pycolmap-venv/bin/python3 bench/pycolmap_ceres.py " + " ".join(argv))
                    runs.append(r)
                    with open(a.out + ".json", "a", encoding="utf-8") as f:
                        f.write(json.dumps(r) + "\n")
                    print("%s %s: %.3f s, %d iterations, cost %.6e -> %.9e" % (name, r["run"], r["seconds"],
                          r["iterations"], r["initial"], r["final"]), file=sys.stderr, flush=True)
    write_report(a, pycolmap.__version__, runs)


def tabulate(runs):
    """[(problem, its runs' median rows with their times to each tolerance, f0, f*)], in the
    order the runs were made."""
    problems = {}
    for r in runs:
        problems.setdefault(r["problem"], {}).setdefault(r["run"], []).append(r)
    out = []
    for name, by_run in problems.items():
        rows = []
        for reps in by_run.values():
            times = [r["seconds"] for r in reps]
            rows.append(dict(reps[times.index(statistics.median_low(times))]))
        best = min(r["final"] for r in rows)
        f0 = rows[0]["initial"]
        for r in rows:
            r["to"] = [time_to(r, best + tau * (f0 - best)) for tau in TAUS]
        out.append((name, rows, f0, best))
    return out


def write_report(a, version, runs):
    commands = list(dict.fromkeys(r["command"] for r in runs))
    lines = ["# sbarefine against Ceres 2.2 as COLMAP 4 runs it (pycolmap %s)" % version, "",
             "Written by `bench/pycolmap_ceres.py` (see its opening comment) on %s, %d threads, each row the "
             "median run of its command's --repeat; the commands:" % (runs[0]["date"], runs[0]["threads"]), ""]
    lines += ["    " + c for c in commands] + [""]
    for name, rows, f0, best in tabulate(runs):
        images, nobs, made = rows[0]["images"], rows[0]["observations"], rows[0]["made"]
        lines += ["## %s: %d images, %d observations" % (name, images, nobs), "", "Made by: `%s`" % made, "",
                  "Cost at the start %.6e; lowest final cost %.9e." % (f0, best), "",
                  "| run | linear solver | iterations | final cost | to 10% | to 1% | to 0.3% | to the end |",
                  "|---|---|---:|---:|---:|---:|---:|---:|"]
        for r in rows:
            final = "%.9e" % r["final"]
            if r.get("stopped"):
                final = "%.6e (stopped at the timeout)" % r["final"]
            elif "own_final" in r and abs(r["final"] - r["own_final"]) > 1e-6 * r["own_final"]:
                final += " (Ceres's: %.6e)" % r["own_final"]
            lines.append("| %s | %s | %d | %s | %s | %s | %s | %s%.3f |" % (
                r["run"], r["solver"], r["iterations"], final, *map(cell, r["to"]), "> " if r.get("stopped") else "",
                r["seconds"]))
        ceres = [r for r in rows if r["run"].startswith("ceres:")]
        for r in rows:
            if r["run"].startswith("sba:") and ceres:
                ratios = []
                for k, tau in enumerate(TAUS):
                    peer = [c["to"][k] for c in ceres if c["to"][k] is not None]
                    ratios.append("-" if r["to"][k] is None or not peer else "%.2fx" % (r["to"][k] / min(peer)))
                lines.append("")
                end = min(c["seconds"] for c in ceres)
                bound = all(c.get("stopped") for c in ceres if c["seconds"] == end)
                lines.append("%s against the best Ceres run at each tolerance: %s (10%%, 1%%, 0.3%%); to the end "
                             "%s%.2fx." % (r["run"], ", ".join(ratios), "under " if bound else "", r["seconds"] / end))
                peer_final = min(c["final"] for c in ceres)
                if r["final"] > peer_final * (1 + SAME_COST):
                    lines[-1] += " It ends %.1e above Ceres's lowest final cost: a loss whatever its time." % (
                        r["final"] / peer_final - 1)
        lines.append("")
    with open(a.out + ".md", "w", encoding="utf-8") as f:
        f.write("\n".join(lines))


if __name__ == "__main__":
    main(sys.argv[1:])
