#!/usr/bin/env python3
# SPDX-License-Identifier: BSD-3-Clause
"""sba inside COLMAP 4's incremental mapper: pycolmap.incremental_mapping against
pysba.colmap.incremental_mapping (the same pipeline driven from Python, its adjustments by
sba), on databases of pycolmap.synthesize_dataset with 0.5 px of noise on the keypoints.

For each size it runs, in turn: pycolmap.incremental_mapping (the reference: its wall time);
pysba's pipeline with the mapper's own adjustments ("pipeline": the Python pipeline's own cost
against pycolmap's; left out with --no-pipeline); the same with COLMAP's adjustments timed ("colmap": the split of the
time: the local refinements and their solves alone, the global adjustments, the rest; the
local adjustments taken step by step in Python with COLMAP's solve to time it; left out with
--no-split, for the models and the whole mapping's time alone, without the global ratio); pysba's
pipeline with sba's global adjustment ("sba", with the part of its time spent reading the
mapper's model through pycolmap's API); and, with --local-sba, with sba's local
adjustments too ("sba-local"; with --no-global-only, instead of "sba"). With --repeat N the
whole round runs N times, the modes interleaved, and every time is the median of the N (a
machine whose speed drifts during a run then moves every mode alike). Each model is compared
with the synthesized truth: registered images, points, mean reprojection error, and the
camera centres' RMS distance after a similarity onto the truth's centres (a range where the
runs of a mode differ).

  colmap_mapping.py --frames 100,150 [--points-per-frame 15] [--kind shared|per-image|rigs]
                    [--priors] [--local-sba [--no-global-only]] [--no-pipeline] [--no-split]
                    [--repeat 1]
                    [--threads 2] [--work DIR] [--reuse] [--markdown FILE]
--kind: one camera shared by every image (FRAMES frames of a rig of one camera), a camera per
image, or a rig of two cameras (FRAMES / 2 frames of two images: FRAMES images either way).
--priors: a position prior per frame in the database, and the mappings with
use_prior_position (each global adjustment the pose-prior adjustment).
Every point is seen by every image: synthesize_dataset's track_length prunes only the truth's
tracks (pycolmap 4.2.1), while the database keeps every point's keypoint in every image, matched
exhaustively, so the mapper's tracks are whole whatever it is. --reuse keeps a database the same
arguments made before (with its truth). Needs pycolmap (build/pycolmap-venv) and pysba on PYTHONPATH
(build/python/pkg).
"""
import argparse
import os
import shutil
import statistics
import sys
import time


def scene(pycolmap, d, frames, points, kind, seed, reuse, priors=False):
    """The database d/database.db of a synthesized scene and its truth (kept in d/truth, with
    reuse taken from there when the same arguments made them)."""
    database, truth_path = os.path.join(d, "database.db"), os.path.join(d, "truth")
    made_by = repr((frames, points, kind, seed) + (("priors",) if priors else ()))
    stamp = os.path.join(d, "made-by")
    if reuse and os.path.isfile(stamp) and open(stamp).read() == made_by:
        return database, pycolmap.Reconstruction(truth_path)
    shutil.rmtree(d, ignore_errors=True)
    os.makedirs(truth_path)
    pycolmap.set_random_seed(seed)
    o = pycolmap.SyntheticDatasetOptions()
    o.num_rigs, o.num_cameras_per_rig, o.num_frames_per_rig = {
        "shared": (1, 1, frames), "per-image": (frames, 1, 1), "rigs": (1, 2, frames // 2)}[kind]
    o.prior_position = priors
    o.num_points3D = points
    db = pycolmap.Database.open(database)
    try:
        truth = pycolmap.synthesize_dataset(o, db)
        noise = pycolmap.SyntheticNoiseOptions()
        noise.point2D_stddev = 0.5
        pycolmap.synthesize_noise(noise, truth, db)
    finally:
        db.close()
    truth.write(truth_path)
    with open(stamp, "w") as f:
        f.write(made_by)
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


def combined(runs):
    """The runs of one mode as one: each time the median of the runs', each figure of the
    model the first run's, with "_range" the lowest and highest where the runs differ (the
    mapper's RANSAC on several threads need not give the same model twice)."""
    first = runs[0]
    model = ("models", "images", "points", "error", "centres")
    out = dict(first)
    for key in model:
        values = [run.get(key) for run in runs]
        if any(v != values[0] for v in values):
            out[key + "_range"] = (min(values), max(values))
    for key, value in first.items():
        if key not in model and isinstance(value, float):
            out[key] = statistics.median(run[key] for run in runs)
    out["spread"] = (min(run["total"] for run in runs), max(run["total"] for run in runs))
    return out


def figures(run):
    """A model's figures: images, points, mean error and centres' RMS, each as a range where
    the runs differ."""
    def one(key, form):
        low, high = run.get(key + "_range", (run[key], run[key]))
        if low == high:
            return form % low
        if form % low == form % high:  # differing in digits the form does not show
            form = "%.7g"
        return (form + "-" + form) % (low, high)
    return "%s images, %s points, %s px, centres %s" % (one("images", "%d"), one("points", "%d"),
                                                      one("error", "%.4f"), one("centres", "%.3g"))


def spread(run):
    low, high = run["spread"]
    return "" if low == high else " (%.1f-%.1f)" % (low, high)


def split(run):
    """The local refinements' seconds apart from their solves, and the rest of the mapping."""
    return run["local"] - run.get("local_solve", 0.0), run["total"] - run["local"] - run["global"]


def main(argv):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--frames", default="100,150")
    ap.add_argument("--points-per-frame", type=int, default=15)
    ap.add_argument("--kind", choices=("shared", "per-image", "rigs"), default="shared")
    ap.add_argument("--priors", action="store_true", help="position priors, mapped with use_prior_position")
    ap.add_argument("--local-sba", action="store_true", help="also run sba's local adjustments")
    ap.add_argument("--no-pipeline", action="store_true",
                    help="leave out the pipeline with the mapper's own adjustments (its cost against pycolmap's)")
    ap.add_argument("--no-global-only", action="store_true",
                    help="with --local-sba, leave out sba's global adjustments with COLMAP's local ones")
    ap.add_argument("--no-split", action="store_true",
                    help="leave out the pipeline with COLMAP's adjustments timed (the split, the global ratio)")
    ap.add_argument("--repeat", type=int, default=1, help="run every mode this many times, interleaved")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--work", default="/tmp/sba-colmap-mapping")
    ap.add_argument("--reuse", action="store_true")
    ap.add_argument("--markdown", help="append the table to this file")
    args = ap.parse_args(argv)
    import pycolmap
    import pysba.colmap
    rows = []
    for frames in (int(x) for x in args.frames.split(",")):
        d = os.path.join(args.work, "%s-%d-%d%s" % (args.kind, frames, args.points_per_frame,
                                                     "-priors" if args.priors else ""))
        database, truth = scene(pycolmap, d, frames, frames * args.points_per_frame, args.kind, 1,
                                args.reuse, args.priors)
        options = pycolmap.IncrementalPipelineOptions()
        options.num_threads = args.threads
        options.use_prior_position = args.priors
        modes = [("pipeline", "colmap", "colmap"), ("colmap", "colmap", "ceres"), ("sba", "sba", "colmap")]
        if args.local_sba:
            modes.append(("sba-local", "sba", "sba"))
            if args.no_global_only:
                modes.remove(("sba", "sba", "colmap"))
        if args.no_pipeline:
            modes = modes[1:]
        if args.no_split:
            modes = [m for m in modes if m[0] != "colmap"]
        # The modes shown against COLMAP's adjustments timed ("colmap"), in the order run.
        shown = [name for name, _, _ in modes if name != "colmap"]
        references, runs = [], {name: [] for name, _, _ in modes}
        for _ in range(args.repeat):
            start = time.perf_counter()
            models = pycolmap.incremental_mapping(database, d, os.path.join(d, "pycolmap"), options)
            references.append(dict(describe(pycolmap, models, truth), total=time.perf_counter() - start))
            for name, global_adjustment, local_adjustment in modes:
                timings = {}
                models = pysba.colmap._incremental_mapping(pycolmap, database, d, os.path.join(d, name), options,
                                                           global_adjustment, local_adjustment, timings)
                runs[name].append(dict(describe(pycolmap, models, truth), **timings))
        reference = combined(references)
        runs = {name: combined(r) for name, r in runs.items()}
        # The scene as the tables name it: its images, and its kind where it is not the default.
        tags = [t for t in (args.kind if args.kind != "shared" else None, "priors" if args.priors else None) if t]
        label = "%d%s" % (frames, " (%s)" % ", ".join(tags) if tags else "")
        row = dict(frames=label, reference=reference, **runs)
        rows.append(row)
        c = runs.get("colmap")
        line = "%s frames, %d run(s): pycolmap %.1f s%s (%s)" % (
            label, args.repeat, reference["total"], spread(reference), figures(reference))
        if "pipeline" in runs:
            p = runs["pipeline"]
            line += "; pipeline with the mapper's adjustments %.1f s%s (%.2fx pycolmap)" % (
                p["total"], spread(p), p["total"] / reference["total"])
        if c:
            line += ("; with COLMAP's adjustments timed %.1f s%s (local %.1f, of which solves %.1f in %d; global "
                     "%.1f in %d; rest %.1f)" % (c["total"], spread(c), c["local"], c["local_solve"],
                                                 c["local_calls"], c["global"], c["global_calls"], split(c)[1]))
        for name in [n for n in shown if n != "pipeline"]:
            s = runs[name]
            local = "%.1f s" % s["local_solve"] if "local_solve" in s else "COLMAP's"
            line += "; %s %.1f s%s (%.2fx pycolmap; global %.1f, reading %.1f%s; local solves %s; %s)" % (
                name, s["total"], spread(s), s["total"] / reference["total"], s["global"], s.get("global_read", 0.0),
                ": %.2fx" % (s["global"] / c["global"]) if c else "", local, figures(s))
        print(line, flush=True)
    if args.markdown:
        with open(args.markdown, "a") as f:
            f.write("| frames | runs | pycolmap | its model | pipeline, COLMAP's adjustments "
                    "timed: total | local: solves (calls) | local: the rest | global (calls) | rest | run | total "
                    "| of pycolmap's | global | global ratio | local solves | model |\n"
                    "|---:|---:|---:|---|---:|---:|---:|---:|---:|---|---:|---:|---:|---:|---:|---|\n")
            for r in rows:
                ref, c = r["reference"], r.get("colmap")
                lead = "| %s | %d | %.1f s%s | %s " % (r["frames"], args.repeat, ref["total"], spread(ref),
                                                        figures(ref))
                lead += ("| %.1f s%s | %.1f s (%d) | %.1f s | %.1f s (%d) | %.1f s " % (
                    c["total"], spread(c), c["local_solve"], c["local_calls"], split(c)[0], c["global"],
                    c["global_calls"], split(c)[1]) if c else "| - | - | - | - | - ")
                for name in shown:
                    s = r[name]
                    f.write(lead + "| %s | %.1f s%s | %.2fx | %.1f s%s | %s | %s | %s |\n" % (
                        name, s["total"], spread(s), s["total"] / ref["total"], s["global"],
                        " (reading %.1f s)" % s["global_read"] if "global_read" in s else "",
                        "%.2fx" % (s["global"] / c["global"]) if c else "-",
                        "%.1f s" % s["local_solve"] if "local_solve" in s else "COLMAP's",
                        figures(s)))
                    lead = "| | | | | | | | | "
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
