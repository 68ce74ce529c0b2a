#!/usr/bin/env python3
# SPDX-License-Identifier: BSD-3-Clause
"""sbarefine's projection of COLMAP's eighteen camera models against COLMAP's own (pycolmap).

For every model, random parameters around a sample that exercises each of its terms and random
points of the camera frame (in front of the camera, and behind it) are projected by
colmap_project (lib/cameras/colmap_camera.h through a small program) and by pycolmap's
Camera.img_from_cam without its cheirality check (the formula wherever it has a value, as a
bundle adjustment's residual sees it). They must agree to 1e-10 relative (of the pixel
coordinate, or of 1 near 0), and be non-finite together (DIVISION outside its field of view).

pycolmap is looked for in this interpreter, then in the one $SBA_PYCOLMAP_PYTHON names (a
virtual environment's python, say); without it the run is skipped: exit status 77 (ctest's
SKIP_RETURN_CODE) with the reason.

  pycolmap_models.py --project EXE [--seed N] [--points N]
  pycolmap_models.py --cpp      prints the reference table of tests/test_colmap_camera.cpp
"""
import argparse
import math
import os
import random
import subprocess
import sys

SKIP = 77
TOLERANCE = 1e-10

# Model id: (name, sample parameters); the same samples as tests/test_colmap_camera.cpp.
MODELS = {
    0: ("SIMPLE_PINHOLE", [500, 320, 240]),
    1: ("PINHOLE", [500, 530, 320, 240]),
    2: ("SIMPLE_RADIAL", [500, 320, 240, -0.12]),
    3: ("RADIAL", [500, 320, 240, -0.12, 0.03]),
    4: ("OPENCV", [500, 520, 320, 240, 0.1, -0.05, 0.01, -0.02]),
    5: ("OPENCV_FISHEYE", [350, 355, 320, 240, 0.1, -0.02, 0.003, -0.0004]),
    6: ("FULL_OPENCV", [600, 610, 300, 200, 0.1, -0.05, 0.001, -0.002, 0.02, 0.03, -0.01, 0.005]),
    7: ("FOV", [400, 410, 320, 240, 0.9]),
    8: ("SIMPLE_RADIAL_FISHEYE", [300, 320, 240, 0.05]),
    9: ("RADIAL_FISHEYE", [300, 320, 240, 0.05, -0.01]),
    10: ("THIN_PRISM_FISHEYE", [300, 305, 320, 240, 0.05, -0.01, 0.001, -0.0015, 0.002, -0.0005, 0.0007, -0.0004]),
    11: ("RAD_TAN_THIN_PRISM_FISHEYE", [300, 305, 320, 240, 0.05, -0.01, 0.002, -0.0005, 1e-4, -2e-5,
                                        0.001, -0.0015, 0.0007, -0.0004, 0.0003, 0.0002]),
    12: ("SIMPLE_DIVISION", [500, 320, 240, -0.1]),
    13: ("DIVISION", [500, 510, 320, 240, 0.05]),
    14: ("SIMPLE_FISHEYE", [300, 320, 240]),
    15: ("FISHEYE", [300, 310, 320, 240]),
    16: ("EUCM", [400, 410, 320, 240, 0.6, 1.1]),
    17: ("EQUIRECTANGULAR", [1000, 500]),
}

# The points of the C++ reference table: in front of the camera, on the optical axis, far off
# it, behind the camera; for DIVISION the last is outside its field of view (no pixel).
CPP_POINTS = [(0.3, -0.45, 1.0), (-0.8, 0.6, 1.2), (0.0, 0.0, 2.0), (1.5, 0.4, 1.0), (0.2, -0.1, -1.0),
              (3.0, 2.0, 1.0)]


def import_pycolmap():
    """pycolmap; without it, this script run again by $SBA_PYCOLMAP_PYTHON, or the skip."""
    try:
        import pycolmap  # noqa: PLC0415 (optional: the run skips without it)
        return pycolmap
    except ImportError as e:
        reason = "%s: %s" % (sys.executable, e)
    other = os.environ.get("SBA_PYCOLMAP_PYTHON")
    if other and os.path.abspath(other) != os.path.abspath(sys.executable):
        if not os.access(other, os.X_OK):
            reason += "; SBA_PYCOLMAP_PYTHON=%s is not an executable" % other
        else:
            env = dict(os.environ, SBA_PYCOLMAP_PYTHON="")  # once: no loop if it has none either
            sys.stdout.flush()
            os.execve(other, [other, os.path.abspath(__file__)] + sys.argv[1:], env)
    print("pycolmap_models: SKIPPED: pycolmap cannot be imported (%s); set SBA_PYCOLMAP_PYTHON to a python "
          "that has it (pip install pycolmap)" % reason)
    sys.exit(SKIP)


def colmap_pixels(pycolmap, model, params, points):
    import numpy as np  # noqa: PLC0415 (pycolmap's own dependency)
    cam = pycolmap.Camera(model=MODELS[model][0], width=640, height=480, params=params)
    out = cam.img_from_cam(np.array(points, dtype=float), check_cheirality=False)
    return [(float(x), float(y)) for x, y in out]


def our_pixels(exe, cases):
    """cases: [(model, params, point)]."""
    text = "".join(" ".join([str(m)] + [repr(float(v)) for v in list(p) + list(X)]) + "\n" for m, p, X in cases)
    r = subprocess.run([exe], input=text, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, timeout=300)
    if r.returncode != 0:
        raise SystemExit("pycolmap_models: %s exited %d: %s" % (exe, r.returncode, r.stderr.strip()))
    return [tuple(float(v) for v in ln.split()) for ln in r.stdout.splitlines()]


def agree(a, b):
    if not (math.isfinite(a) and math.isfinite(b)):
        return not math.isfinite(a) and not math.isfinite(b)
    return abs(a - b) <= TOLERANCE * max(1.0, abs(a), abs(b))


def random_params(rng, model):
    """The sample's parameters, each moved by up to 30% (a model's zero stays 0)."""
    params = [v * (1 + rng.uniform(-0.3, 0.3)) for v in MODELS[model][1]]
    if MODELS[model][0] == "EUCM":  # alpha in [0, 1], as the model is defined
        params[4] = rng.uniform(0.2, 0.9)
    return params


def random_point(rng, behind, wide):
    """A point seen at up to 39 degrees off the axis (wide: 76 degrees), or behind the camera."""
    z, s = rng.uniform(0.5, 5.0), 3.0 if wide else 0.8
    X = (rng.uniform(-s, s) * z, rng.uniform(-s, s) * z, z)
    return (X[0], X[1], -X[2]) if behind else X


def compare(pycolmap, exe, seed, npoints):
    rng = random.Random(seed)
    cases = []
    for model in MODELS:
        for k in range(npoints):
            # Each point with parameters of its own; one point in four behind the camera, one in
            # eight far off the axis (beyond DIVISION's field of view, some of them).
            cases.append((model, random_params(rng, model), random_point(rng, k % 4 == 3, k % 8 == 5)))
    ours = our_pixels(exe, cases)
    failures, finite = 0, {}
    for (model, params, X), got in zip(cases, ours):
        want = colmap_pixels(pycolmap, model, params, [X])[0]
        if math.isfinite(want[0]):
            finite[model] = finite.get(model, 0) + 1
        if not (agree(got[0], want[0]) and agree(got[1], want[1])):
            failures += 1
            if failures <= 20:
                print("FAIL %s %r at %r: sbarefine %r, pycolmap %r" % (MODELS[model][0], params, X, got, want))
    for model, (name, _) in MODELS.items():
        print("%-28s %d points, %d with a pixel" % (name, npoints, finite.get(model, 0)))
    print("pycolmap %s: %d of %d projections disagree beyond %g relative"
          % (pycolmap.__version__, failures, len(cases), TOLERANCE))
    return 1 if failures or len(ours) != len(cases) else 0


def print_cpp(pycolmap):
    """The reference table of tests/test_colmap_camera.cpp, as C++ initializers."""
    print("// pycolmap %s, Camera.img_from_cam(points, check_cheirality=False)" % pycolmap.__version__)
    for model, (name, params) in MODELS.items():
        pix = ["{%s, %s}" % tuple("NAN" if not math.isfinite(v) else "%.17g" % v for v in p)
               for p in colmap_pixels(pycolmap, model, params, CPP_POINTS)]
        lines = [", ".join(pix[k:k + 2]) for k in range(0, len(pix), 2)]
        print("      {%d,  // %s\n       {%s}}," % (model, name, ",\n        ".join(lines)))


def main(argv):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--project", metavar="EXE", help="the colmap_project program")
    ap.add_argument("--seed", type=int, default=43)
    ap.add_argument("--points", type=int, default=200, help="points per model")
    ap.add_argument("--cpp", action="store_true", help="print the C++ reference table")
    a = ap.parse_args(argv)
    if not a.cpp and not a.project:
        ap.print_usage(sys.stderr)
        return 2
    pycolmap = import_pycolmap()
    if a.cpp:
        print_cpp(pycolmap)
        return 0
    return compare(pycolmap, a.project, a.seed, a.points)


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
