#!/usr/bin/env python3
# SPDX-License-Identifier: BSD-3-Clause
"""pysba's two routes between a pycolmap.Reconstruction and its solve, timed on scenes of
pycolmap.synthesize_dataset (rig_ba.py's: --rigs rigs of --cameras-per-rig cameras over
--frames frames, --points-per-frame points per frame seen by --track-length images, 0.5 px of
noise on the keypoints, 0.02 and 0.3 deg on the frames' poses).

- files: from_pycolmap (pycolmap writes a binary model into a temporary directory, pysba reads
  it) and to_pycolmap (pysba writes one, pycolmap reads it): the route refine_colmap took for a
  Reconstruction before it read one in memory;
- memory: what refine_colmap(rec) reads through pycolmap's API (every camera, rig, frame and
  pose, every point, and only the keypoints that observe one) and what it writes back into a
  Reconstruction, timed with every refined value changed (every frame, pose in a rig, camera and
  point written), onto a copy made beforehand;
- whole: refine_colmap(rec, in_place=True) at its defaults against the files route around a
  refine_colmap of the converted model, the same solve (its time, the progress callback's
  last elapsed, given apart).

Each figure is the fastest of --repeat runs. Writes a Markdown table to stdout.

  pycolmap_conversion.py [--frames 100,1000] [--rigs 2] [--cameras-per-rig 2]
                         [--points-per-frame 20] [--track-length 8] [--repeat 3] [--seed 1]
                         [--no-whole]
Run it with a Python that imports pycolmap and pysba (scripts/deps.sh test makes a venv with
pycolmap; PYTHONPATH=build/python/pkg finds pysba).
"""
import argparse
import os
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from rig_ba import synthesize  # noqa: E402  (the scenes rig_ba.py times)


def fastest(repeat, run):
    """The fastest of repeat runs of run(), each given fresh what it needs by run itself."""
    best = None
    for _ in range(repeat):
        seconds = run()
        best = seconds if best is None else min(best, seconds)
    return best


def moved(model):
    """model with every refined value changed: what _write_into writes at most."""
    import copy
    out = copy.deepcopy(model)
    for c in out.cameras:
        c.params = c.params * (1 + 1e-9)
    for f in out.frames or ():
        if f.t is not None:
            f.t = f.t + 1e-6
    for r in out.rigs or ():
        for s in r.sensors:
            if s.t is not None:
                s.t = s.t + 1e-6
    out.points3D.xyz = out.points3D.xyz + 1e-6
    out.points3D.error = out.points3D.error + 1e-3
    return out


def timed(f):
    t = time.perf_counter()
    f()
    return time.perf_counter() - t


def main(argv):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--frames", default="100,1000")
    ap.add_argument("--rigs", type=int, default=2)
    ap.add_argument("--cameras-per-rig", type=int, default=2)
    ap.add_argument("--points-per-frame", type=int, default=20)
    ap.add_argument("--track-length", type=int, default=8)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--no-whole", action="store_true", help="leave out the refine_colmap rows")
    a = ap.parse_args(argv)
    import pycolmap
    import pysba
    import pysba._colmap as pc
    print("pycolmap %s, pysba %s, Python %s, %d hardware threads, load average %.2f"
          % (pycolmap.__version__, pysba.__file__, sys.version.split()[0], os.cpu_count(), os.getloadavg()[0]))
    print()
    print("| frames | images | observations | keypoints | files: read | files: write | memory: read | "
          "memory: write | memory / files | whole: files | whole: memory | solve |")
    print("|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for frames in [int(f) for f in a.frames.split(",")]:
        rec = synthesize(pycolmap, a, frames, a.seed)
        keypoints = sum(im.num_points2D() for im in rec.images.values())
        model = pysba.from_pycolmap(rec)
        files_read = fastest(a.repeat, lambda: timed(lambda: pysba.from_pycolmap(rec)))
        files_write = fastest(a.repeat, lambda: timed(lambda: pysba.to_pycolmap(model)))
        given = pc._from_reconstruction(rec)
        memory_read = fastest(a.repeat, lambda: timed(lambda: pc._from_reconstruction(rec)))
        changed = moved(given)

        def write_back():
            target = pycolmap.Reconstruction(rec)
            return timed(lambda: pc._write_into(target, changed, given))

        memory_write = fastest(a.repeat, write_back)
        ratio = (memory_read + memory_write) / (files_read + files_write)
        whole_files = whole_memory = solve = float("nan")
        if not a.no_whole:
            def old_route():
                t = time.perf_counter()
                refined, _ = pysba.refine_colmap(pysba.from_pycolmap(rec))
                pysba.to_pycolmap(refined)
                return time.perf_counter() - t

            def new_route():
                target = pycolmap.Reconstruction(rec)
                t = time.perf_counter()
                pysba.refine_colmap(target, in_place=True)
                return time.perf_counter() - t

            whole_files = fastest(a.repeat, old_route)
            whole_memory = fastest(a.repeat, new_route)
            last = []
            pysba.refine_colmap(pycolmap.Reconstruction(rec), in_place=True,
                                progress=lambda state: last.append(state.elapsed))
            solve = last[-1]
        print("| %d | %d | %d | %d | %.3f s | %.3f s | %.3f s | %.3f s | %.3f | %.2f s | %.2f s | %.2f s |"
              % (frames, len(rec.images), rec.compute_num_observations(), keypoints, files_read, files_write,
                 memory_read, memory_write, ratio, whole_files, whole_memory, solve), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
