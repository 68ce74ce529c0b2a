#!/usr/bin/env python3
# SPDX-License-Identifier: BSD-3-Clause
"""sbarefine --covariance against pycolmap's estimate_ba_covariance (PyPI), on the same model.

pycolmap_check.py's scene of two rigs of one camera (every frame one image), with noise,
written by pycolmap; sbarefine --itmax 0 --covariance at that model, two images' poses held
(the gauge: rotation, translation and scale), and pycolmap's estimate_ba_covariance of the
same problem (its default bundle adjuster, those two frames constant) agree: every image's
pose block and every camera's block of refined parameters equal to 1e-6 relative (the
largest difference over the block's largest entry), the held poses absent from both; at
each at its default damping (the same: sbarefine's is pycolmap's) and both at none. The
covariance is the Jacobian's, at any estimate: no solve is needed for both to describe the
same problem. bench/colmap_covariance.py times the two at 1,000 images with the functions here.

Exit status: 0 the checks passed, 1 one failed, 77 (ctest's SKIP_RETURN_CODE) no pycolmap.

  covariance_check.py [--python PY] --sbarefine EXE --work DIR
With --python, a Python that cannot import pycolmap runs this script with PY instead.
"""
import argparse
import os
import shutil
import subprocess
import sys
import time

from pycolmap_check import SKIP, Failure, expect, import_pycolmap, synthesize

TOLERANCE = 1e-6


def read_covariances(path):
    """sbarefine's --covariance file: {kind: {id: (coords, rows)}} and SIGMA2's line's values."""
    blocks, head = {}, {}
    with open(path) as f:
        for line in f:
            w = line.split()
            if not w or w[0].startswith("#"):
                continue
            if w[0] == "SIGMA2":
                head = {"sigma2": float(w[1]), "rank": int(w[3]), "nfree": int(w[5])}
                continue
            named = w[0] == "IMAGE"
            coords = w[3 if named else 2].split(",")
            values = [float(v) for v in w[4 if named else 3:]]
            k = len(coords)
            expect(len(values) == k * k, "%s: a %s record of %d coordinates has %d values" % (path, w[0], k, len(values)))
            blocks.setdefault(w[0], {})[int(w[1])] = (coords, [values[r * k:(r + 1) * k] for r in range(k)])
    return blocks, head


def held_frames(rec, image_ids):
    return [rec.images[i].frame_id for i in image_ids]


def pycolmap_covariance(pycolmap, rec, held_images, damping=None):
    """estimate_ba_covariance of rec's default bundle adjustment problem, the frames of
    held_images constant, at BACovarianceOptions.damping (None: pycolmap's default), and the
    seconds it took (the problem's setup not counted)."""
    options = pycolmap.BundleAdjustmentOptions()
    options.print_summary = False
    config = pycolmap.BundleAdjustmentConfig()
    for i in rec.reg_image_ids():
        config.add_image(i)
    for f in held_frames(rec, held_images):
        config.set_constant_rig_from_world_pose(f)
    adjuster = pycolmap.create_default_ceres_bundle_adjuster(options, config, rec)
    cov_options = pycolmap.BACovarianceOptions()
    if damping is not None:
        cov_options.damping = damping
    start = time.perf_counter()
    cov = pycolmap.estimate_ba_covariance(cov_options, rec, adjuster)
    seconds = time.perf_counter() - start
    expect(cov is not None, "pycolmap: estimate_ba_covariance failed")
    return cov, seconds


def sbarefine_covariance(exe, model, out, held_images, damping, extra=()):
    """sbarefine --itmax 0 --covariance --covariance-damping damping (None: its default) on model,
    held_images' poses held: the file read, and the seconds the whole run took."""
    cmd = [exe, model, "--itmax", "0", "--hold-poses", ",".join(str(i) for i in held_images),
           "--covariance", out] + ([] if damping is None else ["--covariance-damping", repr(damping)]) + list(extra)
    start = time.perf_counter()
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=3600)
    seconds = time.perf_counter() - start
    expect(r.returncode == 0, "%s: exit %d: %s" % (" ".join(cmd), r.returncode, r.stderr))
    return read_covariances(out), seconds


def relative_difference(a, b):
    top = max(abs(v) for row in b for v in row)
    return max(abs(x - y) for ra, rb in zip(a, b) for x, y in zip(ra, rb)) / top


def compare(rec, cov, blocks, held_images):
    """The largest relative difference over the pose blocks and over the cameras' blocks, every
    block of one present in the other."""
    images = blocks.get("IMAGE", {})
    worst = {"poses": 0.0, "cameras": 0.0}
    for i in rec.reg_image_ids():
        theirs = cov.get_cam_cov_from_world(i)
        expect((theirs is None) == (i in held_images) == (i not in images),
               "image %d: held %s, pycolmap's block %s, sbarefine's %s" %
               (i, i in held_images, theirs is not None, i in images))
        if theirs is not None:
            expect(images[i][0] == ["rx", "ry", "rz", "tx", "ty", "tz"], "image %d: coordinates %s" % (i, images[i][0]))
            worst["poses"] = max(worst["poses"], relative_difference(images[i][1], theirs.tolist()))
    for c, (coords, rows) in blocks.get("CAMERA", {}).items():
        theirs = cov.get_other_params_cov(rec.cameras[c].params)
        expect(theirs is not None and theirs.shape == (len(coords), len(coords)),
               "camera %d: pycolmap's block %s for coordinates %s" % (c, None if theirs is None else theirs.shape, coords))
        worst["cameras"] = max(worst["cameras"], relative_difference(rows, theirs.tolist()))
    return worst


def check(pycolmap, args):
    rec = synthesize(pycolmap, 1, 11)
    model = os.path.join(args.work, "model")
    os.makedirs(model)
    rec.write_text(model)
    held = sorted(rec.reg_image_ids())[:2]
    for damping in (None, 0.0):
        cov, _ = pycolmap_covariance(pycolmap, rec, held, damping)
        (blocks, head), _ = sbarefine_covariance(args.sbarefine, model, os.path.join(args.work, "cov.txt"), held,
                                                 damping)
        expect(sorted(blocks.get("CAMERA", {})) == sorted(rec.cameras),
               "a block for each camera, got %s" % sorted(blocks.get("CAMERA", {})))
        expect(head.get("rank") == head.get("nfree"),
               "the gauge fixed: rank %s of %s" % (head.get("rank"), head.get("nfree")))
        worst = compare(rec, cov, blocks, held)
        print("damping %s: largest relative differences from pycolmap %s: %s" % ("default" if damping is None else damping, pycolmap.__version__, worst))
        expect(max(worst.values()) <= TOLERANCE, "beyond %g" % TOLERANCE)


def main(argv):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--python", help="a Python with pycolmap, used when this one has none")
    ap.add_argument("--sbarefine", required=True)
    ap.add_argument("--work", required=True, help="a scratch directory (emptied)")
    args = ap.parse_args(argv)
    pycolmap = import_pycolmap(args.python, __file__, argv)
    if pycolmap is None:
        return SKIP
    shutil.rmtree(args.work, ignore_errors=True)
    os.makedirs(args.work)
    try:
        check(pycolmap, args)
    except Failure as f:
        print("FAIL %s" % f)
        return 1
    print("PASS")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
