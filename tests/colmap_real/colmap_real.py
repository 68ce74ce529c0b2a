#!/usr/bin/env python3
# SPDX-License-Identifier: BSD-3-Clause
"""sbarefine against the real COLMAP (`colmap bundle_adjuster`), on scenes sbagen writes.

For each scene: sbagen writes a COLMAP text model, the scene's edit is applied to it, `colmap
model_converter` turns it into a binary model (so that the input is one COLMAP wrote), then
`colmap bundle_adjuster` and `sbarefine`, both at their defaults, refine it into separate
directories. Checks:
  - both exit 0;
  - RMS reprojection error of sbarefine's result <= COLMAP's * (1 + 1e-6), both measured by
    this file's own projection of the written models (one yardstick for both: COLMAP's
    model_analyzer reports the mean of the points' stored ERROR fields, which each program
    fills in its own way), and both below the input's RMS;
  - `colmap model_analyzer` reads sbarefine's binary and text outputs and counts the
    input's cameras, images, registered images, points and observations;
  - each camera's focal length agrees with COLMAP's within 1e-4 (relative; full_opencv: compared
    only, its minimum being flat); per scene: the
    shared focal length moved from its start 2% off, or the image that sees no point is
    written back unchanged.
Scenes (40 images, 2,500 points seen by 2..8 images each, about 12,300 observations):
  shared_camera         one PINHOLE camera for every image, its focal length started 2% long;
  opencv                an OPENCV camera per image (sbagen --kind varKD);
  full_opencv           the same cameras as FULL_OPENCV, k3..k6 started at 0;
  radial                the same cameras as RADIAL (one focal length: what sbarefine refines
                        is then what COLMAP refines, whatever either does with fy/fx);
  image_without_points  SIMPLE_RADIAL cameras and one more image, with a camera of its own,
                        that sees no point.
Every check of every scene is run and printed (PASS/FAIL and why), so that one failure does
not hide the others. Exit status: 0 every check passed, 1 a check failed, 2 bad usage,
77 no COLMAP found (ctest's SKIP_RETURN_CODE: the tests need the real program).

  colmap_real.py --sbagen EXE --sbarefine EXE [--colmap EXE] [--keep DIR] SCENE...|all
  (SBA_COLMAP=EXE in the environment does what --colmap does, for runs under ctest)
  colmap_real.py --selftest
"""
import argparse
import math
import os
import re
import shutil
import struct
import subprocess
import sys
import tempfile

SKIP = 77
TIMEOUT = 600  # seconds per program run; a scene takes a few seconds

# COLMAP's camera models: id and number of parameters (the model's documented layout).
CAMERA_MODELS = {
    "SIMPLE_PINHOLE": (0, 3), "PINHOLE": (1, 4), "SIMPLE_RADIAL": (2, 4), "RADIAL": (3, 5),
    "OPENCV": (4, 8), "OPENCV_FISHEYE": (5, 8), "FULL_OPENCV": (6, 12), "FOV": (7, 5),
    "SIMPLE_RADIAL_FISHEYE": (8, 4), "RADIAL_FISHEYE": (9, 5), "THIN_PRISM_FISHEYE": (10, 12),
}
MODEL_NAMES = {mid: name for name, (mid, _) in CAMERA_MODELS.items()}


# ---------------------------------------------------------------------------------------
# Reading a model (text or binary, .bin first as COLMAP does)

class Model:
    def __init__(self):
        self.cameras = {}  # id -> (model name, width, height, [params])
        self.images = {}   # id -> dict(q, t, camera_id, name, xys [(x, y)], ids [point3D id])
        self.points = {}   # id -> dict(xyz, rgb, error, track [(image id, point2D index)])

    def observations(self):
        return sum(len(p["track"]) for p in self.points.values())


def _data_lines(path):
    """The lines of a COLMAP text file but its comments; an empty line is kept (the
    points2D line of an image that sees nothing)."""
    with open(path, encoding="utf-8") as f:
        return [ln.rstrip("\r\n") for ln in f if not ln.startswith("#")]


def read_text_model(d):
    m = Model()
    for ln in _data_lines(os.path.join(d, "cameras.txt")):
        w = ln.split()
        if not w:
            continue
        m.cameras[int(w[0])] = (w[1], int(w[2]), int(w[3]), [float(v) for v in w[4:]])
    lines = _data_lines(os.path.join(d, "images.txt"))
    # A file written without the last (empty) points2D line still has whole images.
    i = 0
    while i < len(lines):
        w = lines[i].split()
        if not w:
            i += 1
            continue
        pts = lines[i + 1].split() if i + 1 < len(lines) else []
        m.images[int(w[0])] = {
            "q": [float(v) for v in w[1:5]], "t": [float(v) for v in w[5:8]], "camera_id": int(w[8]),
            "name": " ".join(w[9:]),
            "xys": [(float(pts[k]), float(pts[k + 1])) for k in range(0, len(pts), 3)],
            "ids": [int(pts[k + 2]) for k in range(0, len(pts), 3)]}
        i += 2
    for ln in _data_lines(os.path.join(d, "points3D.txt")):
        w = ln.split()
        if not w:
            continue
        tr = w[8:]
        m.points[int(w[0])] = {
            "xyz": [float(v) for v in w[1:4]], "rgb": [int(v) for v in w[4:7]], "error": float(w[7]),
            "track": [(int(tr[k]), int(tr[k + 1])) for k in range(0, len(tr), 2)]}
    return m


class _Reader:
    def __init__(self, path):
        with open(path, "rb") as f:
            self.b = f.read()
        self.o = 0

    def get(self, fmt):
        v = struct.unpack_from("<" + fmt, self.b, self.o)
        self.o += struct.calcsize("<" + fmt)
        return v

    def cstring(self):
        e = self.b.index(b"\0", self.o)
        s = self.b[self.o:e].decode("utf-8")
        self.o = e + 1
        return s


def read_binary_model(d):
    m = Model()
    r = _Reader(os.path.join(d, "cameras.bin"))
    for _ in range(r.get("Q")[0]):
        cid, mid, width, height = r.get("IiQQ")
        name = MODEL_NAMES[mid]
        m.cameras[cid] = (name, width, height, list(r.get("%dd" % CAMERA_MODELS[name][1])))
    r = _Reader(os.path.join(d, "images.bin"))
    for _ in range(r.get("Q")[0]):
        iid = r.get("I")[0]
        q = list(r.get("4d"))
        t = list(r.get("3d"))
        cid = r.get("I")[0]
        name = r.cstring()
        n = r.get("Q")[0]
        xys, ids = [], []
        for _ in range(n):
            x, y, pid = r.get("ddq")
            xys.append((x, y))
            ids.append(pid)
        m.images[iid] = {"q": q, "t": t, "camera_id": cid, "name": name, "xys": xys, "ids": ids}
    r = _Reader(os.path.join(d, "points3D.bin"))
    for _ in range(r.get("Q")[0]):
        pid = r.get("Q")[0]
        xyz = list(r.get("3d"))
        rgb = list(r.get("3B"))
        err = r.get("d")[0]
        n = r.get("Q")[0]
        m.points[pid] = {"xyz": xyz, "rgb": rgb, "error": err, "track": [r.get("II") for _ in range(n)]}
    return m


def read_model(d):
    if all(os.path.exists(os.path.join(d, f + ".bin")) for f in ("cameras", "images", "points3D")):
        return read_binary_model(d)
    return read_text_model(d)


def write_text_model(m, d):
    os.makedirs(d, exist_ok=True)
    with open(os.path.join(d, "cameras.txt"), "w", encoding="utf-8") as f:
        for cid in sorted(m.cameras):
            name, w, h, p = m.cameras[cid]
            f.write("%d %s %d %d %s\n" % (cid, name, w, h, " ".join(repr(v) for v in p)))
    with open(os.path.join(d, "images.txt"), "w", encoding="utf-8") as f:
        for iid in sorted(m.images):
            im = m.images[iid]
            f.write("%d %s %s %d %s\n" % (iid, " ".join(repr(v) for v in im["q"]),
                                          " ".join(repr(v) for v in im["t"]), im["camera_id"], im["name"]))
            f.write(" ".join("%r %r %d" % (xy[0], xy[1], pid) for xy, pid in zip(im["xys"], im["ids"])) + "\n")
    with open(os.path.join(d, "points3D.txt"), "w", encoding="utf-8") as f:
        for pid in sorted(m.points):
            p = m.points[pid]
            f.write("%d %s %s %r %s\n" % (pid, " ".join(repr(v) for v in p["xyz"]), " ".join(str(v) for v in p["rgb"]),
                                          p["error"], " ".join("%d %d" % tuple(o) for o in p["track"])))


# ---------------------------------------------------------------------------------------
# The yardstick: COLMAP's camera models, projected here

def rotate(q, x):
    """R(q) x for a unit quaternion q = (w, x, y, z) (Hamilton, COLMAP's convention)."""
    w, a, b, c = q
    n = math.sqrt(w * w + a * a + b * b + c * c)
    w, a, b, c = w / n, a / n, b / n, c / n
    return [
        (1 - 2 * (b * b + c * c)) * x[0] + 2 * (a * b - w * c) * x[1] + 2 * (a * c + w * b) * x[2],
        2 * (a * b + w * c) * x[0] + (1 - 2 * (a * a + c * c)) * x[1] + 2 * (b * c - w * a) * x[2],
        2 * (a * c - w * b) * x[0] + 2 * (b * c + w * a) * x[1] + (1 - 2 * (a * a + b * b)) * x[2]]


def project(camera, q, t, xyz):
    """The pixel COLMAP's camera model maps the world point xyz to."""
    name, _, _, p = camera
    xc = rotate(q, xyz)
    xc = [xc[k] + t[k] for k in range(3)]
    u, v = xc[0] / xc[2], xc[1] / xc[2]
    r2 = u * u + v * v
    if name == "SIMPLE_PINHOLE":
        return p[0] * u + p[1], p[0] * v + p[2]
    if name == "PINHOLE":
        return p[0] * u + p[2], p[1] * v + p[3]
    if name in ("SIMPLE_RADIAL", "RADIAL"):
        k2 = p[4] if name == "RADIAL" else 0.0
        s = 1 + p[3] * r2 + k2 * r2 * r2
        return p[0] * u * s + p[1], p[0] * v * s + p[2]
    if name in ("OPENCV", "FULL_OPENCV"):
        k1, k2, p1, p2 = p[4:8]
        k3, k4, k5, k6 = p[8:12] if name == "FULL_OPENCV" else (0.0, 0.0, 0.0, 0.0)
        s = (1 + k1 * r2 + k2 * r2 * r2 + k3 * r2 ** 3) / (1 + k4 * r2 + k5 * r2 * r2 + k6 * r2 ** 3)
        ud = u * s + 2 * p1 * u * v + p2 * (r2 + 2 * u * u)
        vd = v * s + p1 * (r2 + 2 * v * v) + 2 * p2 * u * v
        return p[0] * ud + p[2], p[1] * vd + p[3]
    raise ValueError("camera model %s is not projected by this test" % name)


def rms_error(m):
    """RMS over every observation of the distance in pixels between the measurement and the
    projection of its point, and the number of observations."""
    total, n = 0.0, 0
    for p in m.points.values():
        for iid, k in p["track"]:
            im = m.images[iid]
            x, y = project(m.cameras[im["camera_id"]], im["q"], im["t"], p["xyz"])
            mx, my = im["xys"][k]
            total += (x - mx) ** 2 + (y - my) ** 2
            n += 1
    return math.sqrt(total / n), n


# ---------------------------------------------------------------------------------------
# Running the programs

class Failure(Exception):
    pass


def colmap_logs_into(directory):
    """COLMAP's glog writes a log file for every run into /tmp unless told another directory:
    this process's COLMAP runs write theirs into `directory` (unless GLOG_log_dir is set)."""
    os.environ.setdefault("GLOG_log_dir", directory)


def run(cmd, what):
    try:
        r = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, timeout=TIMEOUT)
    except subprocess.TimeoutExpired:
        raise Failure("%s took more than %d s: %s" % (what, TIMEOUT, " ".join(cmd)))
    if r.returncode != 0:
        tail = (r.stderr.strip() or r.stdout.strip()).splitlines()[-3:]
        raise Failure("%s exited %d: %s\n      %s" % (what, r.returncode, " ".join(cmd), "\n      ".join(tail)))
    return r.stdout + r.stderr


def analyze(colmap, d):
    """What `colmap model_analyzer` counts in the model d (it logs to stderr)."""
    out = run([colmap, "model_analyzer", "--path", d], "colmap model_analyzer")
    counts = {}
    for key in ("Cameras", "Images", "Registered images", "Points", "Observations"):
        mt = re.search(r"\b%s: (\d+)" % key, out)
        if not mt:
            raise Failure("colmap model_analyzer printed no '%s:' for %s" % (key, d))
        counts[key] = int(mt.group(1))
    return counts


def counts_of(m):
    return {"Cameras": len(m.cameras), "Images": len(m.images), "Registered images": len(m.images),
            "Points": len(m.points), "Observations": m.observations()}


# ---------------------------------------------------------------------------------------
# The scenes: sbagen's model and the edit that makes each

def focal_of(cam):
    return cam[3][0]


def edit_shared(m):
    """One camera for every image (sbagen --kind fixed), its focal length started 2% long."""
    assert len(m.cameras) == 1, "sbagen --kind fixed should write one camera"
    (cid, (name, w, h, p)), = m.cameras.items()
    p = list(p)
    p[0] *= 1.02
    if name == "PINHOLE":
        p[1] *= 1.02
    m.cameras[cid] = (name, w, h, p)


def edit_full_opencv(m):
    """Each OPENCV camera as a FULL_OPENCV one, k3..k6 started at zero."""
    for cid, (name, w, h, p) in list(m.cameras.items()):
        assert name == "OPENCV"
        m.cameras[cid] = ("FULL_OPENCV", w, h, list(p) + [0.0, 0.0, 0.0, 0.0])


def to_simple_radial(m):
    """Each PINHOLE camera (fx = fy, as sbagen writes them) as a SIMPLE_RADIAL one, k = 0."""
    for cid, (name, w, h, p) in list(m.cameras.items()):
        assert name == "PINHOLE" and p[0] == p[1]
        m.cameras[cid] = ("SIMPLE_RADIAL", w, h, [p[0], p[2], p[3], 0.0])


def to_radial(m):
    """Each OPENCV camera as a RADIAL one: its k1 k2 kept, its tangential terms dropped (the
    data keep theirs: both programs fit the same model to them)."""
    for cid, (name, w, h, p) in list(m.cameras.items()):
        assert name == "OPENCV" and p[0] == p[1]
        m.cameras[cid] = ("RADIAL", w, h, [p[0], p[2], p[3], p[4], p[5]])


def edit_image_without_points(m):
    """SIMPLE_RADIAL cameras, and one more image, with its own camera, that sees no point
    (last, so that neither program's choice of the images whose pose is held can fall on it)."""
    to_simple_radial(m)
    cid, iid = max(m.cameras) + 1, max(m.images) + 1
    m.cameras[cid] = m.cameras[min(m.cameras)]
    m.images[iid] = {"q": [0.9238795325112867, 0.0, 0.3826834323650898, 0.0], "t": [0.25, -0.5, 3.0],
                     "camera_id": cid, "name": "sees_nothing.png", "xys": [], "ids": []}


SCENES = {
    # name: (sbagen options, edit, what else is checked)
    "shared_camera": (["--kind", "fixed"], edit_shared, "focal"),
    "opencv": (["--kind", "varKD"], None, None),
    "full_opencv": (["--kind", "varKD"], edit_full_opencv, "flat"),
    "radial": (["--kind", "varKD"], to_radial, None),
    "image_without_points": (["--kind", "varK"], edit_image_without_points, "lonely"),
}
SCENE_SIZE = ["--cameras", "40", "--points", "2500", "--track-min", "2", "--track-max", "8"]


class Scene:
    def __init__(self, name, args, work):
        self.name, self.args, self.dir = name, args, os.path.join(work, name)
        self.checks = []  # (ok, text)

    def check(self, ok, text):
        self.checks.append((bool(ok), text))
        return ok

    def note(self, text):
        self.checks.append((None, text))

    def passed(self):
        return bool(self.checks) and all(ok is not False for ok, _ in self.checks)


def run_scene(s, colmap):
    gen_opts, edit, extra = SCENES[s.name]
    os.makedirs(s.dir)
    gen = os.path.join(s.dir, "sbagen_text")
    run([s.args.sbagen, "--out", os.path.join(s.dir, "gen"), "--colmap", gen, "--seed", "36", "--quiet"]
        + SCENE_SIZE + gen_opts, "sbagen")
    if edit:
        m = read_text_model(gen)
        edit(m)
        gen = os.path.join(s.dir, "edited_text")
        write_text_model(m, gen)
    inp = os.path.join(s.dir, "input")
    os.makedirs(inp)
    run([colmap, "model_converter", "--input_path", gen, "--output_path", inp, "--output_type", "BIN"],
        "colmap model_converter")
    initial = read_model(inp)
    rms0, nobs = rms_error(initial)
    expected = counts_of(initial)
    s.check(analyze(colmap, inp) == expected, "model_analyzer counts the input as written: %s" % expected)

    out_colmap = os.path.join(s.dir, "colmap_ba")
    os.makedirs(out_colmap)
    run([colmap, "bundle_adjuster", "--input_path", inp, "--output_path", out_colmap], "colmap bundle_adjuster")
    ref = read_model(out_colmap)
    rms_colmap, _ = rms_error(ref)
    s.check(rms_colmap < rms0, "COLMAP lowers the RMS: %.9g -> %.9g px (%d observations)" % (rms0, rms_colmap, nobs))

    out_bin, out_txt = os.path.join(s.dir, "sbarefine_bin"), os.path.join(s.dir, "sbarefine_text")
    try:
        run([s.args.sbarefine, inp, "--write", out_bin], "sbarefine")
        run([s.args.sbarefine, inp, "--write", out_txt, "--write-format", "text"], "sbarefine --write-format text")
    except Failure as e:
        s.check(False, str(e))
        return
    for d, fmt in ((out_bin, "binary"), (out_txt, "text")):
        try:
            got = analyze(colmap, d)
            s.check(got == expected, "model_analyzer reads sbarefine's %s model: %s (input %s)" % (fmt, got, expected))
        except Failure as e:
            s.check(False, "model_analyzer on sbarefine's %s model: %s" % (fmt, e))
    mine = read_model(out_bin)
    rms_sba, _ = rms_error(mine)
    s.check(rms_sba <= rms_colmap * (1 + 1e-6),
            "sbarefine's RMS %.9g px <= COLMAP's %.9g px * (1 + 1e-6) (relative difference %+.3g)"
            % (rms_sba, rms_colmap, rms_sba / rms_colmap - 1))
    compare_intrinsics(s, initial, ref, mine, flat=extra == "flat")
    rms_txt, _ = rms_error(read_model(out_txt))
    s.check(abs(rms_txt - rms_sba) <= 1e-9 * rms_sba,
            "sbarefine's text and binary models agree: RMS %.12g and %.12g px" % (rms_txt, rms_sba))

    if extra == "focal":
        f0 = focal_of(initial.cameras[min(initial.cameras)])
        fs = focal_of(mine.cameras[min(mine.cameras)])
        # The start was 2% long (the truth is sbagen's): one that did not move was not refined.
        s.check(abs(fs - f0) > 0.01 * f0, "sbarefine moved the shared focal length by %.3g%% (> 1%%)"
                % (100 * (fs - f0) / f0))
    if extra == "lonely":
        iid = max(initial.images)
        a, b = initial.images[iid], mine.images.get(iid)
        same = (b is not None and b["name"] == a["name"] and b["camera_id"] == a["camera_id"]
                and b["q"] == a["q"] and b["t"] == a["t"] and not b["xys"]
                and mine.cameras.get(a["camera_id"]) == initial.cameras[a["camera_id"]])
        s.check(same, "the image that sees no point (%d, %s) is written back as read, with its camera"
                % (iid, a["name"]))


def compare_intrinsics(s, initial, ref, mine, flat=False):
    """Each camera's focal length (fx) against COLMAP's, and a note on fy/fx, which is where
    a difference of RMS comes from when the programs refine different parameters. flat: the
    minimum is a long flat valley (FULL_OPENCV's k3..k6 trade against the focal length and
    k1, k2), along which both programs are still moving when they stop: the focal lengths are
    compared in a note, and the RMS decides."""
    fdiff, worst, ratio_colmap, ratio_sba = 0.0, None, 0.0, 0.0
    for cid, (name, _, _, p0) in initial.cameras.items():
        pc, ps = ref.cameras[cid][3], mine.cameras[cid][3]
        d = abs(ps[0] - pc[0]) / pc[0]
        if worst is None or d > fdiff:
            fdiff, worst = d, cid
        if name in ("PINHOLE", "OPENCV", "FULL_OPENCV"):
            r0 = p0[1] / p0[0]
            ratio_colmap = max(ratio_colmap, abs(pc[1] / pc[0] - r0))
            ratio_sba = max(ratio_sba, abs(ps[1] / ps[0] - r0))
    what = "focal lengths agree with COLMAP's: largest relative difference %.3g <= 1e-4 " \
        "(camera %d: sbarefine %.9g, COLMAP %.9g, from %.9g)" % (
            fdiff, worst, mine.cameras[worst][3][0], ref.cameras[worst][3][0], initial.cameras[worst][3][0])
    if flat:
        s.note(what.replace("agree with", "compared with").replace(" <= 1e-4", ""))
    else:
        s.check(fdiff <= 1e-4, what)
    if ratio_colmap > 0 or ratio_sba > 0:
        s.note("largest change of fy/fx: COLMAP %.3g, sbarefine %.3g%s" % (
            ratio_colmap, ratio_sba, " (sbarefine holds the aspect ratio, COLMAP refines fx and fy apart)"
            if ratio_sba == 0 and ratio_colmap > 0 else ""))


def find_colmap(given):
    if given:
        return given if os.access(given, os.X_OK) else None
    return shutil.which("colmap") or (os.access("/usr/bin/colmap", os.X_OK) and "/usr/bin/colmap") or None


def main(argv):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--sbagen")
    ap.add_argument("--sbarefine")
    ap.add_argument("--colmap", help="the colmap program (default: $SBA_COLMAP if set, else colmap on PATH, "
                    "else /usr/bin/colmap)")
    ap.add_argument("--keep", metavar="DIR", help="work in DIR and keep it (default: a temporary directory)")
    ap.add_argument("--selftest", action="store_true", help="check this file's yardstick and skip logic")
    ap.add_argument("scenes", nargs="*", metavar="SCENE", help="any of %s, or all" % ", ".join(SCENES))
    a = ap.parse_args(argv)
    if a.selftest:
        return selftest()
    names = list(SCENES) if a.scenes == ["all"] else a.scenes
    bad = [n for n in names if n not in SCENES]
    if not names or bad or not a.sbagen or not a.sbarefine:
        ap.print_usage(sys.stderr)
        print("colmap_real: --sbagen, --sbarefine and scenes (%s or all) are required%s"
              % (", ".join(SCENES), "; unknown: " + " ".join(bad) if bad else ""), file=sys.stderr)
        return 2
    given = a.colmap or os.environ.get("SBA_COLMAP")
    colmap = find_colmap(given)
    if not colmap:
        print("colmap_real: SKIPPED: no COLMAP program (%s); install Debian's colmap (scripts/deps.sh test)"
              % ("%s is not an executable" % given if given else "colmap is not on PATH nor /usr/bin/colmap"))
        return SKIP
    work = a.keep or tempfile.mkdtemp(prefix="colmap_real.")
    if a.keep:
        os.makedirs(work, exist_ok=True)
    colmap_logs_into(work)
    failed = []
    try:
        for n in names:
            s = Scene(n, a, work)
            if os.path.exists(s.dir):
                shutil.rmtree(s.dir)
            try:
                run_scene(s, colmap)
            except Failure as e:
                s.check(False, str(e))
            print("%s %s" % ("PASS" if s.passed() else "FAIL", n))
            for ok, text in s.checks:
                print("  %s %s" % ("note" if ok is None else "ok  " if ok else "FAIL", text))
            if not s.passed():
                failed.append(n)
    finally:
        if not a.keep:
            shutil.rmtree(work, ignore_errors=True)
    if failed:
        print("colmap_real: failed: %s" % " ".join(failed))
        return 1
    return 0


# ---------------------------------------------------------------------------------------

def selftest():
    """The yardstick on hand-computed cases, both readers on one model, and the skip."""
    errors = []

    def expect(cond, what):
        if not cond:
            errors.append(what)

    def close(a, b, tol=1e-12):
        return all(abs(x - y) <= tol * max(1.0, abs(y)) for x, y in zip(a, b))

    ident = [1.0, 0.0, 0.0, 0.0]
    # (0.2, -0.1, 2) in front of an identity pose: u = 0.1, v = -0.05, r2 = 0.0125.
    xyz, t = [0.2, -0.1, 2.0], [0.0, 0.0, 0.0]
    expect(close(project(("SIMPLE_PINHOLE", 0, 0, [500, 320, 240]), ident, t, xyz), (370, 215)), "SIMPLE_PINHOLE")
    expect(close(project(("PINHOLE", 0, 0, [500, 600, 320, 240]), ident, t, xyz), (370, 210)), "PINHOLE")
    s = 1 + 0.1 * 0.0125
    expect(close(project(("SIMPLE_RADIAL", 0, 0, [500, 320, 240, 0.1]), ident, t, xyz),
                 (320 + 50 * s, 240 - 25 * s)), "SIMPLE_RADIAL")
    s = 1 + 0.1 * 0.0125 - 0.2 * 0.0125 ** 2
    expect(close(project(("RADIAL", 0, 0, [500, 320, 240, 0.1, -0.2]), ident, t, xyz),
                 (320 + 50 * s, 240 - 25 * s)), "RADIAL")
    # OPENCV with p1 = 0.01, p2 = -0.02 only: du = 2 p1 u v + p2 (r2 + 2 u^2), dv = p1 (r2 + 2 v^2) + 2 p2 u v.
    du = 2 * 0.01 * 0.1 * -0.05 - 0.02 * (0.0125 + 0.02)
    dv = 0.01 * (0.0125 + 0.005) + 2 * -0.02 * 0.1 * -0.05
    opencv = [500, 600, 320, 240, 0, 0, 0.01, -0.02]
    expect(close(project(("OPENCV", 0, 0, opencv), ident, t, xyz), (320 + 500 * (0.1 + du), 240 + 600 * (-0.05 + dv))),
           "OPENCV tangential")
    # FULL_OPENCV: with k3..k6 zero it is OPENCV; k4 divides.
    cv = [500, 600, 320, 240, 0.1, -0.2, 0.01, -0.02]
    expect(close(project(("FULL_OPENCV", 0, 0, cv + [0, 0, 0, 0]), ident, t, xyz),
                 project(("OPENCV", 0, 0, cv), ident, t, xyz)), "FULL_OPENCV = OPENCV")
    s = 1 / (1 + 0.5 * 0.0125)
    expect(close(project(("FULL_OPENCV", 0, 0, [500, 600, 320, 240, 0, 0, 0, 0, 0, 0.5, 0, 0]), ident, t, xyz),
                 (320 + 50 * s, 240 - 30 * s)), "FULL_OPENCV k4")
    # A quarter turn about y (q = (cos 45, 0, sin 45, 0)) takes x to -z and z to x.
    h = math.sqrt(0.5)
    expect(close(rotate([h, 0, h, 0], [1, 0, 0]), [0, 0, -1]) and close(rotate([h, 0, h, 0], [0, 0, 1]), [1, 0, 0]),
           "rotation")
    # A two-image model written as text and read back; its RMS by hand.
    m = Model()
    m.cameras[1] = ("PINHOLE", 640, 480, [500.0, 500.0, 320.0, 240.0])
    m.images[1] = {"q": ident, "t": [0.0, 0.0, 0.0], "camera_id": 1, "name": "a.png",
                   "xys": [(370.0 + 3, 215.0 + 4)], "ids": [7]}
    m.images[2] = {"q": ident, "t": [0.0, 0.0, 0.0], "camera_id": 1, "name": "b.png", "xys": [], "ids": []}
    m.points[7] = {"xyz": xyz, "rgb": [1, 2, 3], "error": 0.5, "track": [(1, 0)]}
    with tempfile.TemporaryDirectory(prefix="colmap_real_selftest.") as d:
        write_text_model(m, d)
        back = read_text_model(d)
        expect(counts_of(back) == counts_of(m) and back.images[2]["xys"] == [], "text model round trip")
        expect(abs(rms_error(back)[0] - 5.0) < 1e-12, "RMS of a 3-4-5 residual")
        # The skip: a colmap that does not exist makes the run exit 77 with a message.
        r = subprocess.run([sys.executable, os.path.abspath(__file__), "--sbagen", "x", "--sbarefine", "y",
                            "--colmap", os.path.join(d, "no_colmap"), "opencv"],
                           stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        expect(r.returncode == SKIP and "SKIPPED" in r.stdout, "skip without colmap: exit %d, %r" % (r.returncode, r.stdout))
    for e in errors:
        print("selftest FAIL: %s" % e)
    print("colmap_real selftest: %d failures" % len(errors))
    return 1 if errors else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
