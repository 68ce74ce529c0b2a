#!/usr/bin/env python3
# SPDX-License-Identifier: BSD-3-Clause
"""sba inside COLMAP 4's incremental mapper: pycolmap.incremental_mapping against
pysba.colmap.incremental_mapping (the same pipeline driven from Python, its global adjustment
by sba), on databases of pycolmap.synthesize_dataset with 0.5 px of noise on the keypoints.

For each size it runs, in turn: pycolmap.incremental_mapping (the reference: its wall time);
pysba's pipeline with the mapper's own global adjustment (the split of the time: the local
refinements, the global adjustments alone, the rest); pysba's pipeline with sba's. Each model
is compared with the synthesized truth: registered images, points, mean reprojection error,
and the camera centres' RMS distance after a similarity onto the truth's centres.

  colmap_mapping.py --frames 100,150 [--points-per-frame 15] [--kind shared|per-image]
                    [--threads 2] [--work DIR] [--markdown FILE]
Needs pycolmap (build/pycolmap-venv) and pysba on PYTHONPATH (build/python/pkg).
"""
import argparse
import os
import shutil
import sys
import time


def scene(pycolmap, d, frames, points, kind, seed):
    """The database d/database.db of a synthesized scene and its truth."""
    shutil.rmtree(d, ignore_errors=True)
    os.makedirs(d)
    database = os.path.join(d, "database.db")
    pycolmap.set_random_seed(seed)
    o = pycolmap.SyntheticDatasetOptions()
    o.num_rigs, o.num_cameras_per_rig = (frames, 1) if kind == "per-image" else (1, 1)
    o.num_frames_per_rig = 1 if kind == "per-image" else frames
    o.num_points3D = points
    db = pycolmap.Database.open(database)
    try:
        truth = pycolmap.synthesize_dataset(o, db)
        noise = pycolmap.SyntheticNoiseOptions()
        noise.point2D_stddev = 0.5
        pycolmap.synthesize_noise(noise, truth, db)
    finally:
        db.close()
    return database, truth


def centre_rms(pycolmap, rec, truth):
    """The RMS distance of rec's camera centres from the truth's after the similarity that
    best takes them there (pycolmap's alignment by projection centres), in the truth's units."""
    import numpy as np
    sim = pycolmap.align_reconstructions_via_proj_centers(rec, truth, 1.0)
    if sim is None:
        return float("nan")
    names = {im.name: im for im in truth.images.values()}
    d = [np.linalg.norm(sim * im.projection_center() - names[im.name].projection_center())
         for im in rec.images.values() if im.has_pose]
    return float(np.sqrt(np.mean(np.square(d))))


def describe(pycolmap, models, truth):
    if not models:
        return dict(models=0)
    rec = max(models.values(), key=lambda r: r.num_reg_images())
    return dict(models=len(models), images=rec.num_reg_images(), points=rec.num_points3D(),
                error=rec.compute_mean_reprojection_error(), centres=centre_rms(pycolmap, rec, truth))


def main(argv):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--frames", default="100,150")
    ap.add_argument("--points-per-frame", type=int, default=15)
    ap.add_argument("--kind", choices=("shared", "per-image"), default="shared")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--work", default="/tmp/sba-colmap-mapping")
    ap.add_argument("--markdown", help="append the table to this file")
    args = ap.parse_args(argv)
    import pycolmap
    import pysba.colmap
    rows = []
    for frames in (int(x) for x in args.frames.split(",")):
        d = os.path.join(args.work, "%s-%d" % (args.kind, frames))
        database, truth = scene(pycolmap, d, frames, frames * args.points_per_frame, args.kind, 1)
        options = pycolmap.IncrementalPipelineOptions()
        options.num_threads = args.threads
        start = time.perf_counter()
        models = pycolmap.incremental_mapping(database, d, os.path.join(d, "pycolmap"), options)
        reference = dict(describe(pycolmap, models, truth), seconds=time.perf_counter() - start)
        runs = {}
        for mode in ("colmap", "sba"):
            timings = {}
            models = pysba.colmap.incremental_mapping(database, d, os.path.join(d, mode), options,
                                                      global_adjustment=mode, timings=timings)
            runs[mode] = dict(describe(pycolmap, models, truth), **timings)
        row = dict(frames=frames, reference=reference, **runs)
        rows.append(row)
        c, s = runs["colmap"], runs["sba"]
        print("%d frames: pycolmap %.1f s (%d images, %d points, %.4f px, centres %.3g); pipeline with the mapper's "
              "adjustment %.1f s (local %.1f, global %.1f in %d, rest %.1f); with sba %.1f s (global %.1f: %.2fx; "
              "%d images, %d points, %.4f px, centres %.3g)" % (
                  frames, reference["seconds"], reference["images"], reference["points"], reference["error"],
                  reference["centres"], c["total"], c["local"], c["global"], c["global_calls"],
                  c["total"] - c["local"] - c["global"], s["total"], s["global"], s["global"] / c["global"],
                  s["images"], s["points"], s["error"], s["centres"]), flush=True)
    if args.markdown:
        with open(args.markdown, "a") as f:
            f.write("| frames | pycolmap | its images, points, px, centres | pipeline, mapper's adjustment: total "
                    "| local | global (calls) | rest | pipeline with sba: total | global | global ratio "
                    "| images, points, px, centres |\n|---:|---:|---|---:|---:|---:|---:|---:|---:|---:|---|\n")
            for r in rows:
                ref, c, s = r["reference"], r["colmap"], r["sba"]
                f.write("| %d | %.1f s | %d, %d, %.4f, %.3g | %.1f s | %.1f s | %.1f s (%d) | %.1f s | %.1f s | %.1f s "
                        "| %.2fx | %d, %d, %.4f, %.3g |\n" % (
                            r["frames"], ref["seconds"], ref["images"], ref["points"], ref["error"], ref["centres"],
                            c["total"], c["local"], c["global"], c["global_calls"],
                            c["total"] - c["local"] - c["global"], s["total"], s["global"], s["global"] / c["global"],
                            s["images"], s["points"], s["error"], s["centres"]))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
