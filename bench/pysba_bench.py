#!/usr/bin/env python3
# SPDX-License-Identifier: BSD-3-Clause
"""pysba's speed against its peers, in one run.

1. pysba.solve against the C programs on the same problem (54cams with eucsbademo,
   problem-21 with balsba): the solve time of each, median of --repeat runs. Target: pysba
   within 5% of the program.
2. A camera model written in Python (BAL's, in numpy, forward differences) through
   pysba.motstr against scipy.optimize.least_squares with jac_sparsity (its trust-region
   reflective method, the same model function and forward differences), on a BAL problem.
   Target: pysba 10x faster. Both stop at a relative cost change of 1e-4 (scipy's ftol, the
   trust-region strategy's eps4); the final costs are reported beside the times.

    PYTHONPATH=build/python/pkg python3 bench/pysba_bench.py --build build [--repeat 5]

Writes bench/results/pysba.json (one object per measurement) and prints a table.
"""
import argparse
import json
import os
import re
import statistics
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

import pysba

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT.parent / "shared" / "data"


def program_seconds(cmd):
    """The solve time a C program prints ('Elapsed time: S seconds')."""
    out = subprocess.run(cmd, capture_output=True, text=True, check=True).stdout
    return float(re.search(r"Elapsed time: (\S+) seconds", out).group(1))


def timed(fn):
    t = time.perf_counter()
    value = fn()
    return time.perf_counter() - t, value


def rodrigues_rotate(w, X):
    """R(w) X for rotation vectors w (k, 3) and points X (k, 3)."""
    theta = np.linalg.norm(w, axis=1, keepdims=True)
    small = theta[:, 0] < 1e-12
    safe = np.where(theta == 0, 1.0, theta)
    k = w / safe
    cos, sin = np.cos(theta), np.sin(theta)
    kx = np.cross(k, X)
    kdot = np.sum(k * X, axis=1, keepdims=True)
    rotated = X * cos + kx * sin + k * kdot * (1 - cos)
    # At w = 0 the rotation is the identity to first order: X + w x X.
    rotated[small] = X[small] + np.cross(w[small], X[small])
    return rotated


def bal_project(cams, pts, ci, pi):
    """The BAL camera model (cameras/bal_camera.h) on the listed observations."""
    c = cams[ci]
    Q = rodrigues_rotate(c[:, :3], pts[pi]) + c[:, 3:6]
    p = -Q[:, :2] / Q[:, 2:3]
    r2 = np.sum(p * p, axis=1, keepdims=True)
    return c[:, 6:7] * (1 + c[:, 7:8] * r2 + c[:, 8:9] * r2 * r2) * p


def scipy_sparsity(m, n, ci, pi):
    from scipy.sparse import lil_matrix
    A = lil_matrix((2 * len(ci), 9 * m + 3 * n), dtype=int)
    rows = np.arange(len(ci))
    for s in range(9):
        A[2 * rows, 9 * ci + s] = 1
        A[2 * rows + 1, 9 * ci + s] = 1
    for s in range(3):
        A[2 * rows, 9 * m + 3 * pi + s] = 1
        A[2 * rows + 1, 9 * m + 3 * pi + s] = 1
    return A


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--build", default=str(ROOT / "build"), help="CMake build with demo/eucsbademo and balsba")
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--bal", default=str(DATA / "bal" / "problem-49-7776-pre.txt.bz2"),
                    help="problem of the Python-model comparison")
    ap.add_argument("--out", default=str(ROOT / "bench" / "results" / "pysba.json"))
    args = ap.parse_args()
    build = Path(args.build)
    demo = DATA / "sba-demo"
    records = []

    cases = [
        ("54cams", lambda: pysba.read_eucsbademo(demo / "54cams.txt", demo / "54pts.txt", demo / "calib.txt"),
         [build / "demo" / "eucsbademo", demo / "54cams.txt", demo / "54pts.txt", demo / "calib.txt"]),
        ("problem-21", lambda: pysba.read_bal(DATA / "bal" / "problem-21-11315-pre.txt.bz2"),
         [build / "demo" / "balsba", DATA / "bal" / "problem-21-11315-pre.txt.bz2", "--no-progress"]),
    ]
    print(f"{'problem':12} {'C program s':>12} {'pysba s':>10} {'ratio':>7}")
    for name, load, cmd in cases:
        problem = load()
        c_times, py_times = [], []
        for _ in range(args.repeat):
            c_times.append(program_seconds([os.fspath(a) for a in cmd]))
            t, result = timed(lambda: pysba.solve(problem))
            py_times.append(t)
        c, py = statistics.median(c_times), statistics.median(py_times)
        records.append(dict(kind="solve_vs_program", problem=name, program_seconds=c_times, pysba_seconds=py_times,
                            ratio=py / c, final_mse=result.final_mse, iterations=result.iterations))
        print(f"{name:12} {c:12.3f} {py:10.3f} {py / c:7.2f}")

    from scipy.optimize import least_squares
    p = pysba.read_bal(args.bal)
    ci, pi = p.camera_index, p.point_index
    m, n = p.ncameras, p.npoints
    # The same stop rule on both sides: a relative cost change below 1e-4 (scipy's ftol,
    # the trust-region strategy's eps4).
    t_sba, r = timed(lambda: pysba.motstr(bal_project, p.cameras, p.points, ci, pi, p.observations,
                                          strategy="trust-region", opts=[1e-3, 1e-12, 1e-12, 1e-12, 1e-4]))

    def residuals(x):
        return (bal_project(x[:9 * m].reshape(m, 9), x[9 * m:].reshape(n, 3), ci, pi) - p.observations).ravel()

    x0 = np.hstack([p.cameras.ravel(), p.points.ravel()])
    sparsity = scipy_sparsity(m, n, ci, pi)
    t_scipy, s = timed(lambda: least_squares(residuals, x0, jac_sparsity=sparsity, x_scale="jac", ftol=1e-4,
                                             method="trf"))
    scipy_mse = float(np.sum(s.fun ** 2)) / len(ci)
    records.append(dict(kind="python_model_vs_scipy", problem=Path(args.bal).name, pysba_seconds=t_sba,
                        scipy_seconds=t_scipy, speedup=t_scipy / t_sba, pysba_final_mse=r.final_mse,
                        pysba_iterations=r.iterations, scipy_final_mse=scipy_mse, scipy_nfev=int(s.nfev),
                        initial_mse=r.initial_mse))
    print(f"\nPython BAL model on {Path(args.bal).name}: pysba.motstr {t_sba:.2f} s (mse {r.final_mse:.4g}, "
          f"{r.iterations} it), scipy least_squares {t_scipy:.2f} s (mse {scipy_mse:.4g}, {s.nfev} evals): "
          f"{t_scipy / t_sba:.1f}x")
    Path(args.out).write_text("".join(json.dumps(rec) + "\n" for rec in records))
    return 0


if __name__ == "__main__":
    sys.exit(main())
