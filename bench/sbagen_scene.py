# SPDX-License-Identifier: BSD-3-Clause
"""The scene of the COLMAP benchmarks against pycolmap (colmap_covariance.py,
colmap_pose_priors.py): sbagen's orbit written as a COLMAP model, with the options both take."""
import os
import subprocess


def add_scene_options(ap):
    """--sbarefine, --sbagen, --work and sbagen's options of the scene, --threads and --repeat."""
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


def sbagen_scene(args, colmap_dir, *extra):
    """sbagen's scene of args as a COLMAP text model in colmap_dir (made), its own files
    WORK/gen-*; extra: more of sbagen's options."""
    os.makedirs(colmap_dir)
    subprocess.run([args.sbagen, "--out", os.path.join(args.work, "gen"), "--cameras", str(args.cameras),
                    "--points", str(args.points), "--track-min", str(args.track_min), "--track-max",
                    str(args.track_max), "--kind", args.kind, *extra, "--colmap", colmap_dir], check=True,
                   stdout=subprocess.DEVNULL)
