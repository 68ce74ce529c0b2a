#!/usr/bin/env python3
# SPDX-License-Identifier: BSD-3-Clause
"""sbarefine's pose priors against pycolmap's pose-prior bundle adjuster on one large model: the
time of each and the cost of each result by one function (tests/pycolmap/pose_prior_check.py's
evaluate(): the sum of squared reprojection errors plus the priors' Mahalanobis terms at the
images' projection centres); bench/results/colmap_pose_priors.md has the figures and commands.

The model is sbagen's (--colmap): CAMERAS images on an orbit, each point seen by TRACK_MIN to
TRACK_MAX of them, its initial (perturbed) estimate, then moved by a similarity (scale 0.6, a
turn of 0.6 rad, a shift of about 11) and written by pycolmap as a binary model. The priors, in
a COLMAP database made by pycolmap (Database.write_pose_prior, CARTESIAN, corr_data_id the
image), are sbagen's true centres (its truth-cams file) plus Gaussian noise of --prior-stddev in
each axis, each with the covariance --prior-stddev^2 I. pycolmap: read the model,
create_pose_prior_bundle_adjuster (BundleAdjustmentOptions() and
PosePriorBundleAdjustmentOptions() at their defaults, every image in the problem) and solve,
timed (the adjuster's creation and solve: the alignment and the adjustment; not the reading);
sbarefine MODEL --database-path DB --write OUT, timed whole (reading the model and the
database, the alignment, the adjustment, writing the model), and its solve alone (--json
seconds).

  colmap_pose_priors.py --sbarefine EXE --sbagen EXE --work DIR [--cameras 1000] [--points 60000]
                        [--track-min 3] [--track-max 8] [--kind fixed|varK] [--prior-stddev 0.05]
                        [--seed S] [--threads N] [--repeat R]
Run it with a Python that can import pycolmap (scripts/deps.sh test makes a venv with it).
"""
import argparse
import json
import os
import shutil
import subprocess
import sys
import time

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "tests", "pycolmap"))
from pose_prior_check import (evaluate, extent, largest_centre_difference, moved_by_similarity,  # noqa: E402
                              pycolmap_refine)
from sbagen_scene import add_scene_options, sbagen_scene  # noqa: E402


def true_centres(path):
    """sbagen's truth-cams file (a line per camera, in the images' order, ending with its pose
    q0 q1 q2 q3 tx ty tz, world to camera, after the intrinsics of --kind varK and varKD): each
    camera's centre -R^T t."""
    import numpy as np
    out = []
    with open(path) as f:
        for line in f:
            w = line.split()
            if not w or w[0].startswith("#"):
                continue
            q = [float(v) for v in w[-7:-3]]
            t = np.array([float(v) for v in w[-3:]])
            r = np.array(rotation_matrix(q))
            out.append(-r.T @ t)
    return out


def rotation_matrix(q):
    """The rotation matrix of the unit quaternion (w, x, y, z)."""
    w, x, y, z = q
    n = (w * w + x * x + y * y + z * z) ** 0.5
    w, x, y, z = w / n, x / n, y / n, z / n
    return [[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]]


def make(pycolmap, args):
    """The model (moved) and the database of priors; returns their paths."""
    import numpy as np
    shutil.rmtree(args.work, ignore_errors=True)
    text = os.path.join(args.work, "sbagen_model")
    prefix = os.path.join(args.work, "gen")
    sbagen_scene(args, text, "--seed", str(args.seed))
    rec = pycolmap.Reconstruction(text)
    centres = true_centres(prefix + "-truth-cams.txt")
    names = sorted((im.name, i) for i, im in rec.images.items())
    if len(names) != len(centres):
        raise SystemExit("%d images, %d true cameras" % (len(names), len(centres)))
    moved_by_similarity(pycolmap, rec)
    model = os.path.join(args.work, "model")
    os.makedirs(model)
    rec.write_binary(model)
    database = os.path.join(args.work, "database.db")
    rng = np.random.default_rng(args.seed)
    db = pycolmap.Database.open(database)
    try:
        for (name, image_id), c in zip(names, centres):  # sbagen names its images img_%04d in its order
            p = pycolmap.PosePrior()
            camera = pycolmap.sensor_t(pycolmap.SensorType.CAMERA, rec.images[image_id].camera_id)
            p.corr_data_id = pycolmap.data_t(camera, image_id)
            p.position = c + rng.normal(0.0, args.prior_stddev, 3)
            p.position_covariance = args.prior_stddev ** 2 * np.eye(3)
            p.coordinate_system = pycolmap.PosePriorCoordinateSystem.CARTESIAN
            db.write_pose_prior(p)
        priors = db.read_all_pose_priors()
    finally:
        db.close()
    return model, database, priors


def seconds(runs):
    return ", ".join("%.2f" % s for s in runs)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    add_scene_options(ap)
    ap.add_argument("--prior-stddev", type=float, default=0.05, help="the priors' noise and standard deviation, "
                    "in sbagen's units (its point cloud's radius)")
    ap.add_argument("--seed", type=int, default=1, help="sbagen's seed and the priors' noise's")
    args = ap.parse_args()
    import pycolmap
    load = os.getloadavg()[0]
    model, database, priors = make(pycolmap, args)
    start = pycolmap.Reconstruction(model)
    observations = sum(p.track.length() for p in start.points3D.values())
    print("model: %d images, %d cameras, %d points, %d observations, %d priors (stddev %g)" %
          (start.num_reg_images(), len(start.cameras), len(start.points3D), observations, len(priors),
           args.prior_stddev))
    print("start: reprojection %.9g + prior %.9g" % evaluate(pycolmap, start, priors))
    theirs_s, ours_s, solve_s = [], [], []
    for k in range(args.repeat):
        rec = pycolmap.Reconstruction(model)
        summaries = []
        t0 = time.perf_counter()
        theirs, _ = pycolmap_refine(pycolmap, rec, priors, summary_out=summaries)
        theirs_s.append(time.perf_counter() - t0)
        out = os.path.join(args.work, "sbarefine_%d" % k)
        shutil.rmtree(out, ignore_errors=True)
        cmd = [args.sbarefine, model, "--database-path", database, "--write", out, "--json", out + ".json"] + \
            (["--threads", str(args.threads)] if args.threads else [])
        t0 = time.perf_counter()
        subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
        ours_s.append(time.perf_counter() - t0)
        with open(out + ".json") as f:
            report = json.load(f)
        solve_s.append(report["seconds"])
    summary = summaries[0]
    ours = pycolmap.Reconstruction(out)
    t_rep, t_pri = evaluate(pycolmap, theirs, priors)
    o_rep, o_pri = evaluate(pycolmap, ours, priors)
    print("pycolmap %s create_pose_prior_bundle_adjuster + solve: %.2f s (runs: %s); %s after %d steps "
          "(%d unsuccessful)" % (pycolmap.__version__, min(theirs_s), seconds(theirs_s), summary.termination_type.name,
                                 summary.num_successful_steps, summary.num_unsuccessful_steps))
    print("sbarefine --database-path (whole run): %.2f s (%.3fx pycolmap's; runs: %s), solve %.2f s (runs: %s); "
          "%d iterations, %s, solver %s, %d threads"
          % (min(ours_s), min(ours_s) / min(theirs_s), seconds(ours_s), min(solve_s), seconds(solve_s),
             report["ret"], report["stop_reason"], report["solver"], report["threads"]))
    print("cost pycolmap:  %.12g + %.12g = %.12g" % (t_rep, t_pri, t_rep + t_pri))
    print("cost sbarefine: %.12g + %.12g = %.12g (ratio - 1 = %.3g)" % (o_rep, o_pri, o_rep + o_pri,
                                                                         (o_rep + o_pri) / (t_rep + t_pri) - 1))
    print("largest centre difference: %.3g of the extent %.4g" % (largest_centre_difference(ours, theirs),
                                                                  extent(theirs)))
    print("command: %s" % " ".join(cmd))
    print("1-minute load average at the start %.2f, at the end %.2f" % (load, os.getloadavg()[0]))


if __name__ == "__main__":
    main()
