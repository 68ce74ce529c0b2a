#!/usr/bin/env python3
# SPDX-License-Identifier: BSD-3-Clause
"""sbarefine --covariance against pycolmap's estimate_ba_covariance on one model: the time of
each and the largest relative difference of their pose and camera blocks
(tests/pycolmap/covariance_check.py's functions; bench/results/colmap_covariance.md has the
figures and the commands).

The model is sbagen's (--colmap): CAMERAS images on an orbit, each point seen by TRACK_MIN to
TRACK_MAX of them, its initial (perturbed) estimate, two images' poses held. sbarefine runs
with --itmax 0: the covariance at the model as read, as pycolmap takes it; its time is the
whole run (reading the model included), pycolmap's the estimate_ba_covariance call alone.

  colmap_covariance.py --sbarefine EXE --sbagen EXE --work DIR [--cameras 1000] [--points 60000]
                       [--kind fixed|varK] [--threads N] [--repeat R] [--damping D]
--damping D is pycolmap's BACovarianceOptions.damping and sbarefine's --covariance-damping
(default: pycolmap's default, 1e-8); --damping 0 compares the undamped inverses.
Run it with a Python that can import pycolmap (scripts/deps.sh test makes a venv with it).
"""
import argparse
import os
import shutil
import subprocess
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "tests", "pycolmap"))
from covariance_check import compare, pycolmap_covariance, sbarefine_covariance  # noqa: E402


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--sbarefine", required=True)
    ap.add_argument("--sbagen", required=True)
    ap.add_argument("--work", required=True, help="a scratch directory (emptied)")
    ap.add_argument("--cameras", type=int, default=1000)
    ap.add_argument("--points", type=int, default=60000)
    ap.add_argument("--track-min", type=int, default=3)
    ap.add_argument("--track-max", type=int, default=8)
    ap.add_argument("--kind", default="fixed", help="sbagen's --kind: fixed (one camera) or varK (one per image)")
    ap.add_argument("--threads", type=int, default=0, help="sbarefine's --threads (0: its default)")
    ap.add_argument("--repeat", type=int, default=1, help="runs of each, the fastest reported")
    ap.add_argument("--damping", type=float, default=None,
                    help="pycolmap's damping and sbarefine's --covariance-damping (default: pycolmap's)")
    args = ap.parse_args()
    import pycolmap
    shutil.rmtree(args.work, ignore_errors=True)
    model = os.path.join(args.work, "model")
    os.makedirs(model)
    subprocess.run([args.sbagen, "--out", os.path.join(args.work, "gen"), "--cameras", str(args.cameras),
                    "--points", str(args.points), "--track-min", str(args.track_min), "--track-max",
                    str(args.track_max), "--kind", args.kind, "--colmap", model], check=True,
                   stdout=subprocess.DEVNULL)
    rec = pycolmap.Reconstruction(model)
    held = sorted(rec.reg_image_ids())[:2]
    extra = ["--threads", str(args.threads)] if args.threads else []
    damping = pycolmap.BACovarianceOptions().damping if args.damping is None else args.damping
    ours, theirs = [], []
    for _ in range(args.repeat):
        cov, seconds = pycolmap_covariance(pycolmap, rec, held, damping)
        theirs.append(seconds)
        (blocks, head), seconds = sbarefine_covariance(args.sbarefine, model, os.path.join(args.work, "cov.txt"),
                                                       held, damping, extra)
        ours.append(seconds)
    worst = compare(rec, cov, blocks, held)
    observations = sum(p.track.length() for p in rec.points3D.values())
    print("model: %d images, %d cameras, %d points, %d observations; rank %d of %d" %
          (rec.num_reg_images(), len(rec.cameras), len(rec.points3D), observations, head["rank"], head["nfree"]))
    print("pycolmap %s estimate_ba_covariance (damping %g): %.2f s" % (pycolmap.__version__, damping, min(theirs)))
    print("sbarefine --itmax 0 --covariance (whole run): %.2f s (%.3fx pycolmap's)" %
          (min(ours), min(ours) / min(theirs)))
    print("largest relative difference: poses %.3g, cameras %.3g" % (worst["poses"], worst["cameras"]))


if __name__ == "__main__":
    main()
