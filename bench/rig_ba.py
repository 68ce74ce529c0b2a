#!/usr/bin/env python3
# SPDX-License-Identifier: BSD-3-Clause
"""sbarefine against COLMAP 4's bundle adjustment (pycolmap.bundle_adjustment) on rig scenes.

Each scene is made by pycolmap.synthesize_dataset: --rigs rigs of --cameras-per-rig cameras
(SIMPLE_RADIAL, pycolmap's default), --frames frames in all (spread over the rigs), so that
every frame holds one image of each camera of its rig; --points-per-frame points per frame,
each seen by --track-length images (0: by every image). Noise as COLMAP's own tests add it: 0.5 px on the
observations, 0.02 on the frames' translations and 0.3 deg on their rotations; written by
pycolmap as a binary model (cameras, images, points3D, rigs, frames).

Both programs start from that model at their defaults, which refine the same unknowns: the
frames' poses (rig_from_world), the cameras' poses in their rigs (sensor_from_rig, one for all
the frames of a rig; the reference camera's the identity), the focal lengths and the extra
parameters of the cameras (shared by their images) and the points. pycolmap runs in a process
of its own: read the model, bundle_adjustment(reconstruction) with BundleAdjustmentOptions()
(Ceres takes every hardware thread), write it; sbarefine with --threads THREADS (and once for
each of --solvers, if given). Each process under /usr/bin/time -v: its wall time (the median
of --repeat) and peak RSS; pycolmap's adjustment alone is timed as well (without reading and
writing the model). The RMS reprojection error of each written model is measured one way for
both, by pycolmap's projection; sbarefine's model is checked to be rigid (every image's pose
its frame's composed with its camera's pose in the rig).

Needs a Python that imports pycolmap 4 (`scripts/deps.sh test` makes build/pycolmap-venv).

  build/pycolmap-venv/bin/python3 bench/rig_ba.py --sbarefine build/demo/sbarefine \\
      [--frames 100,1000] [--rigs 2] [--cameras-per-rig 2] [--points-per-frame 20] \\
      [--track-length 8] [--repeat 1] [--threads 2] [--solvers LIST] [--timeout SEC] \\
      [--out bench/results/rig_ba] [--work DIR] [--pysba build/python/pkg]
With --pysba DIR (the directory holding the pysba package, build/python/pkg), pysba too:
pysba.read_colmap, pysba.refine_colmap at its defaults (threads=THREADS, solver= each of
--solvers), pysba.write_colmap. (refine_colmap also takes a pycolmap.Reconstruction, read in
memory: bench/pycolmap_conversion.py times that route.)

writes OUT.md (the table and the exact commands) and OUT.json (one JSON object a run).
"""
import argparse
import datetime
import json
import math
import os
import shutil
import statistics
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.dont_write_bytecode = True
sys.path.insert(0, HERE)
from colmap_ba import timed  # noqa: E402  (a process under /usr/bin/time -v)


def track_length(a, frames):
    """--track-length, or with 0 every image of the scene (frames * cameras_per_rig)."""
    return a.track_length if a.track_length > 0 else max(1, frames // a.rigs) * a.rigs * a.cameras_per_rig


def synthesize(pycolmap, a, frames, seed):
    pycolmap.set_random_seed(seed)
    o = pycolmap.SyntheticDatasetOptions()
    o.num_rigs = a.rigs
    o.num_cameras_per_rig = a.cameras_per_rig
    o.num_frames_per_rig = max(1, frames // a.rigs)
    o.num_points3D = frames * a.points_per_frame
    o.track_length = track_length(a, frames)
    rec = pycolmap.synthesize_dataset(o)
    noise = pycolmap.SyntheticNoiseOptions()
    noise.point2D_stddev = 0.5
    noise.rig_from_world_translation_stddev = 0.02
    noise.rig_from_world_rotation_stddev = 0.3
    pycolmap.synthesize_noise(noise, rec)
    return rec


def rms(rec):
    total, count = 0.0, 0
    for im in rec.images.values():
        for p in im.points2D:
            if not p.has_point3D():
                continue
            x = im.project_point(rec.points3D[p.point3D_id].xyz)
            if x is None:
                return float("inf")
            total += float((x[0] - p.xy[0]) ** 2 + (x[1] - p.xy[1]) ** 2)
            count += 1
    return math.sqrt(total / count)


def rigidity(pycolmap, rec):
    """The largest difference between an image's pose and its frame's composed with its
    camera's pose in the rig (matrix entries)."""
    worst = 0.0
    for im in rec.images.values():
        frame = rec.frames[im.frame_id]
        rig = rec.rigs[frame.rig_id]
        sensor = pycolmap.sensor_t(pycolmap.SensorType.CAMERA, im.camera_id)
        composed = frame.rig_from_world
        if rig.ref_sensor_id != sensor:
            composed = rig.sensor_from_rig(sensor) * frame.rig_from_world
        a = im.cam_from_world().matrix()
        b = composed.matrix()
        worst = max(worst, float(abs(a - b).max()))
    return worst


def worker_ba(inp, out, report):
    """The pycolmap process: read, adjust at the defaults, write; the adjustment's own time."""
    import pycolmap
    rec = pycolmap.Reconstruction(inp)
    options = pycolmap.BundleAdjustmentOptions()
    options.print_summary = False
    t0 = time.monotonic()
    pycolmap.bundle_adjustment(rec, options)
    seconds = time.monotonic() - t0
    os.makedirs(out, exist_ok=True)
    rec.write_binary(out)
    with open(report, "w", encoding="utf-8") as f:
        json.dump({"ba_seconds": seconds}, f)


def worker_pysba(inp, out, report, threads, solver):
    """The pysba process: read the model with pysba.read_colmap, refine it with
    pysba.refine_colmap at its defaults (COLMAP's), write it with pysba.write_colmap; the
    refinement's own time."""
    import pysba
    model = pysba.read_colmap(inp)
    t0 = time.monotonic()
    refined, result = pysba.refine_colmap(model, threads=int(threads), solver=solver or None)
    seconds = time.monotonic() - t0
    pysba.write_colmap(refined, out)
    with open(report, "w", encoding="utf-8") as f:
        json.dump({"ba_seconds": seconds, "iterations": result.iterations, "solver": result.solver}, f)


def main(argv):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sbarefine", required=True)
    ap.add_argument("--frames", default="100,1000")
    ap.add_argument("--rigs", type=int, default=2)
    ap.add_argument("--cameras-per-rig", type=int, default=2)
    ap.add_argument("--points-per-frame", type=int, default=20)
    ap.add_argument("--track-length", type=int, default=8)
    ap.add_argument("--repeat", type=int, default=1)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--solvers", default="", help="sbarefine --solver values, a row each (default: its own)")
    ap.add_argument("--timeout", type=float, default=3600)
    ap.add_argument("--seed", type=int, default=3)
    ap.add_argument("--out", default=os.path.join(HERE, "results", "rig_ba"))
    ap.add_argument("--work", default="")
    ap.add_argument("--pysba", default="", help="a directory holding the pysba package: pysba rows too")
    a = ap.parse_args(argv)
    import pycolmap

    work = a.work or tempfile.mkdtemp(prefix="rig_ba.")
    os.makedirs(work, exist_ok=True)
    solvers = [s for s in a.solvers.split(",") if s] or [None]
    runs, cmds = [], []
    for frames in [int(x) for x in a.frames.split(",")]:
        scene = os.path.join(work, "frames%d" % frames)
        inp = os.path.join(scene, "input")
        shutil.rmtree(scene, ignore_errors=True)
        os.makedirs(inp)
        rec = synthesize(pycolmap, a, frames, a.seed)
        rec.write_binary(inp)
        shape = {"frames": frames, "images": rec.num_images(), "observations": rec.compute_num_observations(),
                 "points": rec.num_points3D(), "initial_rms": rms(rec)}
        cmds.append("synthesize_dataset(num_rigs=%d, num_cameras_per_rig=%d, num_frames_per_rig=%d, "
                    "num_points3D=%d, track_length=%d), seed %d, noise 0.5 px, 0.02, 0.3 deg -> %s"
                    % (a.rigs, a.cameras_per_rig, max(1, frames // a.rigs), frames * a.points_per_frame,
                       track_length(a, frames), a.seed, inp))
        programs = [("pycolmap", None)] + [("sbarefine", s) for s in solvers]
        if a.pysba:
            programs += [("pysba", s) for s in solvers]
        for program, solver in programs:
            for k in range(a.repeat):
                out = os.path.join(scene, "%s%s_%d" % (program, "_" + solver if solver else "", k))
                shutil.rmtree(out, ignore_errors=True)
                report = out + ".json"
                env = None
                if program == "pycolmap":
                    cmd = [sys.executable, os.path.abspath(__file__), "--worker-ba", inp, out, report]
                elif program == "pysba":
                    cmd = [sys.executable, os.path.abspath(__file__), "--worker-pysba", inp, out, report,
                           str(a.threads), solver or ""]
                    env = dict(os.environ, PYTHONPATH=os.path.abspath(a.pysba))
                else:
                    cmd = [a.sbarefine, inp, "--write", out, "--json", report, "--threads", str(a.threads)]
                    if solver:
                        cmd += ["--solver", solver]
                if k == 0:
                    cmds.append(("PYTHONPATH=%s " % env["PYTHONPATH"] if env else "") + " ".join(cmd))
                load = os.getloadavg()[0]
                status, wall, peak, text, killed = timed(cmd, out + ".log", a.timeout, env=env)
                r = dict(shape, program=program, solver=solver or "", run=k, status=status, wall=wall,
                         peak_mib=peak, killed=killed, load=load)
                if status == 0 and not killed:
                    done = pycolmap.Reconstruction(out)
                    r["rms"] = rms(done)
                    r["rigidity"] = rigidity(pycolmap, done)
                    with open(report, encoding="utf-8") as f:
                        j = json.load(f)
                    if program == "pycolmap":
                        r["ba_seconds"] = j["ba_seconds"]
                    elif program == "pysba":
                        r["ba_seconds"] = j["ba_seconds"]
                        r["iterations"] = j["iterations"]
                        r["linsolver"] = j["solver"]
                    else:
                        r["ba_seconds"] = j["seconds"]
                        r["iterations"] = j["info"]["iterations"]
                        r["sbarefine_rms"] = j["rms_px"]["final"]
                        r["linsolver"] = j["solver"]
                runs.append(r)
                print(json.dumps(r), flush=True)
                if killed or status != 0:
                    break
    write_report(a, runs, cmds)
    if not a.work:
        shutil.rmtree(work, ignore_errors=True)
    return 0


def write_report(a, runs, cmds):
    with open(a.out + ".json", "w", encoding="utf-8") as f:
        for r in runs:
            f.write(json.dumps(r) + "\n")
    rows = {}
    for r in runs:
        rows.setdefault((r["frames"], r["program"], r["solver"]), []).append(r)
    now = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    lines = ["# sbarefine against pycolmap.bundle_adjustment on rig scenes", "",
             "Written by `bench/rig_ba.py` (see bench/README.md) on %s; %d rigs of %d cameras, %d points per frame "
             "seen by %s each; the median of %d wall times; peak RSS from /usr/bin/time -v; RMS by pycolmap's "
             "projection of each written model; rigidity: the largest difference between an image's pose and its "
             "frame's composed with its camera's in the rig. Adjustment alone: pycolmap's bundle_adjustment call, "
             "sbarefine's solve (its --json seconds: reading and writing the model excluded), pysba's refine_colmap "
             "call (reading and writing excluded, as for sbarefine). sbarefine and pysba "
             "with threads=%d, pycolmap every hardware thread (%d here). The load column is the 1-minute load "
             "average when each run started."
             % (now, a.rigs, a.cameras_per_rig, a.points_per_frame,
                "%d images" % a.track_length if a.track_length > 0 else "every image", a.repeat, a.threads,
                os.cpu_count()), "",
             "| frames | images | observations | program | wall s (all) | load | adjustment alone s | peak RSS MiB | "
             "iterations | RMS px (initial) | rigidity | wall / pycolmap's | adjustment / pycolmap's |",
             "|---:|---:|---:|---|---|---|---:|---:|---:|---|---:|---:|---:|"]
    base, base_ba = {}, {}
    for (frames, program, solver), rs in rows.items():
        ok = [r for r in rs if r["status"] == 0 and not r["killed"]]
        med = statistics.median(r["wall"] for r in ok) if ok else None
        ba = statistics.median(r["ba_seconds"] for r in ok) if ok and "ba_seconds" in ok[0] else None
        if program == "pycolmap" and med:
            base[frames] = med
            base_ba[frames] = ba
        name = program + (" " + solver if solver else "")
        if program != "pycolmap" and ok and ok[0].get("linsolver"):
            name += " (%s)" % ok[0]["linsolver"] if not solver else ""
        lines.append("| %d | %d | %d | %s | %s | %s | %s | %.0f | %s | %s | %s | %s | %s |" % (
            frames, rs[0]["images"], rs[0]["observations"], name,
            ("%.2f (%s)" % (med, " ".join("%.2f" % r["wall"] for r in rs))) if med else
            "failed: exit %d%s" % (rs[-1]["status"], ", killed" if rs[-1]["killed"] else ""),
            " ".join("%.1f" % r["load"] for r in rs),
            "%.2f" % ba if ba is not None else "",
            max(r["peak_mib"] for r in rs), ok[0].get("iterations", "") if ok else "",
            "%.6f (%.3f)" % (ok[0]["rms"], rs[0]["initial_rms"]) if ok else "",
            "%.1e" % ok[0]["rigidity"] if ok else "",
            "%.3f" % (med / base[frames]) if med and program != "pycolmap" and frames in base else "",
            "%.3f" % (ba / base_ba[frames]) if ba and program != "pycolmap" and base_ba.get(frames) else ""))
    lines += ["", "Commands (each run writes into a fresh directory):", "", "```"] + cmds + ["```", ""]
    with open(a.out + ".md", "w", encoding="utf-8") as f:
        f.write("\n".join(lines))


if __name__ == "__main__":
    if len(sys.argv) == 5 and sys.argv[1] == "--worker-ba":
        worker_ba(*sys.argv[2:])
        sys.exit(0)
    if len(sys.argv) == 7 and sys.argv[1] == "--worker-pysba":
        worker_pysba(*sys.argv[2:])
        sys.exit(0)
    sys.exit(main(sys.argv[1:]))
