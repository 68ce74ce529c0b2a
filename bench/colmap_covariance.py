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
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "tests", "pycolmap"))
from covariance_check import compare, pycolmap_covariance, sbarefine_covariance  # noqa: E402
from sbagen_scene import add_scene_options, sbagen_scene  # noqa: E402


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    add_scene_options(ap)
    ap.add_argument("--damping", type=float, default=None,
                    help="pycolmap's damping and sbarefine's --covariance-damping (default: pycolmap's)")
    args = ap.parse_args()
    import pycolmap
    shutil.rmtree(args.work, ignore_errors=True)
    model = os.path.join(args.work, "model")
    sbagen_scene(args, model)
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
