#!/usr/bin/env python3
# SPDX-License-Identifier: BSD-3-Clause
"""sba inside COLMAP 4's incremental mapper: pycolmap.incremental_mapping against
pysba.colmap.incremental_mapping (the same pipeline driven from Python, its adjustments by
sba), on databases of pycolmap.synthesize_dataset with 0.5 px of noise on the keypoints.

For each size it runs, in turn: pycolmap.incremental_mapping (the reference: its wall time);
pysba's pipeline with the mapper's own adjustments ("pipeline": the Python pipeline's own cost
against pycolmap's; left out with --no-pipeline); the same with COLMAP's adjustments timed
("colmap": the split of the time: the local refinements and their solves alone, the global
adjustments, the rest; the local adjustments taken step by step in Python with COLMAP's solve
to time it; left out with --no-split, for the models and the whole mapping's time alone);
pysba's pipeline with sba's global adjustment ("sba", with the part of its time spent reading
the mapper's model through pycolmap's API); and, with --local-sba, with sba's local
adjustments too ("sba-local"; with --no-global-only, instead of "sba"). --probe takes the split
from pycolmap's own run instead, by uprobes on its functions (Linux perf, as root), and leaves
out the pipeline with COLMAP's adjustments timed: the split of the mapper as pycolmap runs it,
which that pipeline does not reproduce with priors (it calls COLMAP's pose-prior adjuster from
Python, and that takes longer than the mapper's own global adjustments). With --repeat N the whole round runs N times, the modes
interleaved, and every time is the median of the N (a machine whose speed drifts during a run
then moves every mode alike). Each model is compared with the synthesized truth: registered
images, points, mean reprojection error, and the camera centres' RMS distance after a
similarity onto the truth's centres (a range where the runs of a mode differ).

  colmap_mapping.py --frames 100,150 [--points-per-frame 15] [--kind shared|per-image|rigs]
                    [--priors] [--local-sba [--no-global-only]] [--no-pipeline] [--no-split]
                    [--probe] [--repeat 1] [--threads 2] [--work DIR] [--reuse] [--markdown FILE]
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
import signal
import statistics
import subprocess
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


# pycolmap's own functions whose calls --probe times: COLMAP's global and local adjustments
# (each a whole IncrementalMapper call), and within a local one its solve, from the making of
# the adjuster to the summary made of Ceres's (the span the Python pipeline times as a local
# solve).
PROBED = {
    "global": "_ZN6colmap17IncrementalMapper18AdjustGlobalBundleERKNS0_7OptionsERKNS_23BundleAdjustmentOptionsE",
    "local": "_ZN6colmap17IncrementalMapper17AdjustLocalBundleERKNS0_7OptionsERKNS_23BundleAdjustmentOptionsERKNS_"
             "23IncrementalTriangulator7OptionsEjRKSt13unordered_setImSt4hashImESt8equal_toImESaImEE",
    "adjuster": "_ZN6colmap27CreateDefaultBundleAdjusterERKNS_23BundleAdjustmentOptionsERKNS_22BundleAdjustment"
                "ConfigERNS_14ReconstructionE",
    "summary": "_ZN6colmap28CeresBundleAdjustmentSummary6CreateEN5ceres6Solver7SummaryE",
}
PROBE_GROUP = "sbamapping"


class Probes:
    """Linux uprobes (perf probe, as root) on the PROBED functions of pycolmap's library, and
    perf record attached to this process while pycolmap.incremental_mapping runs: the split
    of pycolmap's own mapping (its global adjustments, local adjustments and their solves, at
    the threads it was given) from the times its calls enter and return."""

    def __init__(self, pycolmap, work):
        if shutil.which("perf") is None or os.geteuid() != 0:
            raise SystemExit("--probe needs Linux perf (Debian's linux-perf) and root")
        library = pycolmap._core.__file__
        symbols = {}
        for line in subprocess.run(["nm", "-D", "--defined-only", library], capture_output=True, text=True,
                                   check=True).stdout.splitlines():
            fields = line.split()
            if len(fields) == 3:
                symbols[fields[2]] = fields[0]
        missing = [name for name, symbol in PROBED.items() if symbol not in symbols]
        if missing:
            raise SystemExit("--probe: pycolmap's library exports no %s function here" % ", ".join(missing))
        self.delete()
        for name, symbol in PROBED.items():
            for event, at in (("%s_in" % name, ""), ("%s_out" % name, "%return")):
                if name in ("adjuster", "summary") and at:
                    continue  # their entries are enough
                subprocess.run(["perf", "probe", "-q", "-x", library, "-a",
                                "%s:%s=0x%s%s" % (PROBE_GROUP, event, symbols[symbol].lstrip("0"), at)],
                               check=True)
        self.data = os.path.join(work, "probes.data")
        self.recorder = None

    def delete(self):
        subprocess.run(["perf", "probe", "-q", "-d", PROBE_GROUP + ":*"], stderr=subprocess.DEVNULL)

    def start(self):
        self.recorder = subprocess.Popen(["perf", "record", "-q", "-e", PROBE_GROUP + ":*", "-p", str(os.getpid()),
                                          "-o", self.data], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        time.sleep(1.0)  # attached by then: it is long before the mapper's first adjustment

    def stop(self):
        """The split of what ran since start: seconds and calls of each."""
        self.recorder.send_signal(signal.SIGINT)
        self.recorder.wait()
        out = subprocess.run(["perf", "script", "-i", self.data, "-F", "tid,time,event"], capture_output=True,
                             text=True, check=True).stdout
        split = dict(global_calls=0, local_calls=0, local_solve=0.0)
        split["global"] = split["local"] = 0.0
        opened = {}
        for line in out.splitlines():
            fields = line.replace(":", " ").split()
            if len(fields) < 4:
                continue
            tid, when, event = fields[0], float(fields[1]), fields[3]
            if event.endswith("__return"):  # perf's name of a return probe's event
                name, edge = event[:-len("__return")].rpartition("_")[0], "out"
            else:
                name, edge = event.rpartition("_")[0], "in"
            if name in ("global", "local"):
                if edge == "in":
                    opened[(tid, name)] = when
                elif (tid, name) in opened:
                    split[name] += when - opened.pop((tid, name))
                    split[name + "_calls"] += 1
            elif (tid, "local") in opened:
                if name == "adjuster":
                    opened[(tid, "solve")] = when
                elif name == "summary" and (tid, "solve") in opened:
                    split["local_solve"] += when - opened.pop((tid, "solve"))
        return split


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
    ap.add_argument("--probe", action="store_true",
                    help="split pycolmap's own mapping by uprobes on its functions (root, Linux perf) instead of "
                         "the pipeline with COLMAP's adjustments timed")
    ap.add_argument("--repeat", type=int, default=1, help="run every mode this many times, interleaved")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--work", default="/tmp/sba-colmap-mapping")
    ap.add_argument("--reuse", action="store_true")
    ap.add_argument("--markdown", help="append the table to this file")
    args = ap.parse_args(argv)
    import pycolmap
    import pysba.colmap
    probes = Probes(pycolmap, args.work) if args.probe else None
    try:
        return run(args, pycolmap, pysba, probes)
    finally:
        if probes:
            probes.delete()


def run(args, pycolmap, pysba, probes):
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
        if args.no_split or probes:
            modes = [m for m in modes if m[0] != "colmap"]
        # The modes shown against COLMAP's adjustments timed ("colmap"), in the order run.
        shown = [name for name, _, _ in modes if name != "colmap"]
        references, runs = [], {name: [] for name, _, _ in modes}
        for _ in range(args.repeat):
            if probes:
                probes.start()
            start = time.perf_counter()
            models = pycolmap.incremental_mapping(database, d, os.path.join(d, "pycolmap"), options)
            total = time.perf_counter() - start
            references.append(dict(describe(pycolmap, models, truth), total=total, **(probes.stop() if probes else {})))
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
        # The split: pycolmap's own (probed), or the pipeline's with COLMAP's adjustments timed.
        c = reference if probes else runs.get("colmap")
        line = "%s frames, %d run(s): pycolmap %.1f s%s (%s)" % (
            label, args.repeat, reference["total"], spread(reference), figures(reference))
        if "pipeline" in runs:
            p = runs["pipeline"]
            line += "; pipeline with the mapper's adjustments %.1f s%s (%.2fx pycolmap)" % (
                p["total"], spread(p), p["total"] / reference["total"])
        if c:
            line += ("; %s %.1f s%s (local %.1f, of which solves %.1f in %d; global "
                     "%.1f in %d; rest %.1f)" % ("its split (probed)" if probes else "with COLMAP's adjustments timed",
                                                 c["total"], spread(c), c["local"], c["local_solve"],
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
            f.write("| frames | runs | pycolmap | its model | %s: total | local: solves (calls) | local: the rest | global (calls) | rest | run | total "
                    "| of pycolmap's | global | global ratio | local solves | model |\n"
                    "|---:|---:|---:|---|---:|---:|---:|---:|---:|---|---:|---:|---:|---:|---:|---|\n"
                    % ("its own split (probed)" if probes else "pipeline, COLMAP's adjustments timed"))
            for r in rows:
                ref = r["reference"]
                c = ref if probes else r.get("colmap")
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
