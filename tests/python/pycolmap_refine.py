#!/usr/bin/env python3
# SPDX-License-Identifier: BSD-3-Clause
"""pysba with pycolmap (PyPI): a scene of pycolmap.synthesize_dataset, with noise, converted
to pysba and back unchanged, and refined by pysba.refine_colmap with pycolmap agreeing on
the result.

Checks: to_pycolmap(from_pycolmap(rec)) is rec, the same bits (every image's pose, every
camera's parameters, every point's coordinates, color, error and track, the rigs and frames);
refine_colmap(from_pycolmap(rec)) refines the poses, and pycolmap's own projection of the
refined model gives the Result's final RMS reprojection error (1e-6 relative);
refine_colmap(rec) gives a pycolmap.Reconstruction, the same as converting that result, and
its Result's model is that Reconstruction, also on a KeyboardInterrupt's result;
write_colmap(rec) writes the files of write_colmap(from_pycolmap(rec)).
A scene of two rigs of three cameras (frames of three images), the cameras' poses in their rigs
and focal lengths moved: refine_colmap(rec) ends no worse than pycolmap.bundle_adjustment at
its defaults (1 + 1e-6) by pycolmap's projection, and every image's pose is its frame's
composed with its camera's pose in the rig (1e-12); with a camera's intrinsics, a camera's pose
in its rig and points held (hold_intrinsics, hold_sensor_from_rig, hold_points), refine_colmap(rec)
solves refine_colmap(from_pycolmap(rec))'s problem and gives back the held values with pycolmap's
bits. Of that scene from_pycolmap and
refine_colmap(itmax=0) give every image pycolmap's own pose, the same bits. A scene with two
frames deregistered: from_pycolmap and to_pycolmap keep them and their images, without a pose;
refine_colmap gives them back as they were and solves what pycolmap writes of the scene, the
same bits. refine_colmap(rec, in_place=True) refines rec itself, with no file written, to the
copy's bits, held values, keypoints and an unregistered frame as they were.

Exit status: 0 every check passed, 1 a check failed, 77 (ctest's SKIP_RETURN_CODE) no Python
here can import both pycolmap and pysba, or a sanitizer build (pycolmap is not built with
the sanitizers).

  pycolmap_refine.py [--python PY]
With --python, a Python that cannot import pycolmap runs this script with PY instead (pysba
found as here, by PYTHONPATH: the module is CPython's extension ABI, so PY must be the same
CPython version as the one pysba was built for).
"""
import argparse
import os
import sys
import tempfile

# The scene and the RMS error by pycolmap's projection are sbarefine's test's (tests/pycolmap).
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "pycolmap"))
from pycolmap_check import Failure, expect, perturb_rigs, rms, synthesize  # noqa: E402

SKIP = 77
REEXEC = "PYSBA_PYCOLMAP_REEXEC"


def values(x):
    return [float(v) for v in x]


def pose(p):
    return values(p.rotation.quat) + values(p.translation)


def data_ids(frame):
    return sorted((int(d.sensor_id.type.value), d.sensor_id.id, d.id) for d in frame.data_ids)


def same_reconstruction(a, b, what):
    """a and b hold the same values, bit for bit (floats compared as Python floats, which
    are the doubles themselves)."""
    expect(sorted(a.cameras) == sorted(b.cameras) and sorted(a.images) == sorted(b.images) and
           sorted(a.points3D) == sorted(b.points3D), what + ": other ids")
    for k, c in a.cameras.items():
        d = b.cameras[k]
        expect((c.model, c.width, c.height, values(c.params)) ==
               (d.model, d.width, d.height, values(d.params)),
               "%s: camera %d" % (what, k))
    for k, im in a.images.items():
        other = b.images[k]
        expect((im.name, im.camera_id, im.frame_id, im.has_pose) ==
               (other.name, other.camera_id, other.frame_id, other.has_pose), "%s: image %d" % (what, k))
        expect(not im.has_pose or pose(im.cam_from_world()) == pose(other.cam_from_world()),
               "%s: image %d's pose" % (what, k))
        expect([(values(p.xy), p.point3D_id) for p in im.points2D] ==
               [(values(p.xy), p.point3D_id) for p in other.points2D], "%s: image %d's keypoints" % (what, k))
    for k, p in a.points3D.items():
        q = b.points3D[k]
        expect((values(p.xyz), values(p.color), float(p.error)) ==
               (values(q.xyz), values(q.color), float(q.error)),
               "%s: point %d" % (what, k))
        expect([(e.image_id, e.point2D_idx) for e in p.track.elements] ==
               [(e.image_id, e.point2D_idx) for e in q.track.elements], "%s: point %d's track" % (what, k))
    expect(sorted(a.frames) == sorted(b.frames) and sorted(a.rigs) == sorted(b.rigs),
           what + ": rigs or frames")
    for k, f in a.frames.items():
        g = b.frames[k]
        expect((f.rig_id, data_ids(f), f.has_pose()) == (g.rig_id, data_ids(g), g.has_pose()),
               "%s: frame %d" % (what, k))
        expect(not f.has_pose() or pose(f.rig_from_world) == pose(g.rig_from_world),
               "%s: frame %d's pose" % (what, k))


def run(pycolmap, pysba):
    rec = synthesize(pycolmap, 1, 7)
    model = pysba.from_pycolmap(rec)
    expect(repr(model) == "ColmapModel(cameras=2, images=16, points3D=300, rigs=2, frames=16)", repr(model))
    same_reconstruction(rec, pysba.to_pycolmap(model), "to_pycolmap(from_pycolmap(rec))")
    print("PASS to_pycolmap(from_pycolmap(rec)) is rec")

    refined, result = pysba.refine_colmap(model)
    back = pysba.to_pycolmap(refined)
    moved = max(abs(a - b) for k, im in back.images.items()
                for a, b in zip(values(im.cam_from_world().translation),
                                values(rec.images[k].cam_from_world().translation)))
    expect(moved > 1e-3, "no pose was refined (%g)" % moved)
    theirs = rms(pycolmap, back)
    expect(result.rms_final < 0.5 * result.rms_initial, "the error did not drop: %r" % result)
    expect(abs(theirs - result.rms_final) <= 1e-6 * result.rms_final,
           "pycolmap's RMS %.17g, pysba's %.17g" % (theirs, result.rms_final))
    print("PASS refine_colmap: RMS %.9g px -> %.9g px, pycolmap's %.9g px"
          % (result.rms_initial, result.rms_final, theirs))

    direct, again = pysba.refine_colmap(rec)
    expect(isinstance(direct, pycolmap.Reconstruction) and again.model is direct,
           "refine_colmap(rec) gave a %s, its result's model a %s" % (type(direct).__name__,
                                                                     type(again.model).__name__))
    expect(again.info.tolist() == result.info.tolist(), "refine_colmap(rec) solved another problem")
    same_reconstruction(back, direct, "refine_colmap(rec)")
    print("PASS refine_colmap(rec) is a pycolmap.Reconstruction, the same")

    def interrupt(state):
        if state.iteration == 2:
            raise KeyboardInterrupt

    try:
        pysba.refine_colmap(rec, progress=interrupt)
        expect(False, "refine_colmap(rec) went on after a KeyboardInterrupt")
    except KeyboardInterrupt as e:
        so_far = e.result.model
        expect(isinstance(so_far, pycolmap.Reconstruction),
               "a KeyboardInterrupt's result.model is a %s" % type(so_far).__name__)
        same_reconstruction(pysba.refine_colmap(rec, itmax=2)[0], so_far, "refine_colmap(rec) interrupted")
    print("PASS a KeyboardInterrupt in refine_colmap(rec) carries the Reconstruction so far")

    import tempfile
    with tempfile.TemporaryDirectory() as d:
        written = []
        for k, given in enumerate((rec, model)):
            pysba.write_colmap(given, os.path.join(d, str(k)))
            written.append({name: open(os.path.join(d, str(k), name), "rb").read()
                            for name in sorted(os.listdir(os.path.join(d, str(k))))})
        expect(written[0] == written[1], "write_colmap(rec) wrote other files than write_colmap(from_pycolmap(rec))")
    print("PASS write_colmap(rec) writes what write_colmap(from_pycolmap(rec)) writes")

    rigs = synthesize(pycolmap, 3, 13, rigs=2)
    perturb_rigs(pycolmap, rigs)
    expect(rigs.num_frames() < len(rigs.images), "the rig scene has no frame of several images")
    # Every image's pose is pycolmap's own, bit for bit (its composition, which pysba's would
    # round otherwise), and so is what refine_colmap gives back without a solve.
    as_read = pysba.from_pycolmap(rigs)
    unsolved, _ = pysba.refine_colmap(as_read, itmax=0)
    for model, what in ((as_read, "from_pycolmap"), (unsolved, "refine_colmap(itmax=0)")):
        for im in model.images:
            theirs = rigs.images[im.id].cam_from_world()
            xyzw = values(theirs.rotation.quat)
            expect(values(im.q) == xyzw[3:] + xyzw[:3] and values(im.t) == values(theirs.translation),
                   "rigs: %s: image %d's pose is not pycolmap's" % (what, im.id))
    print("PASS from_pycolmap and refine_colmap(itmax=0) of rigs: pycolmap's poses, the same bits")
    reference = pycolmap.Reconstruction(rigs)
    options = pycolmap.BundleAdjustmentOptions()
    options.print_summary = False
    pycolmap.bundle_adjustment(reference, options)
    theirs = rms(pycolmap, reference)
    refined, result = pysba.refine_colmap(rigs)
    mine = rms(pycolmap, refined)
    expect(abs(mine - result.rms_final) <= 1e-6 * mine, "pycolmap's RMS %.17g, pysba's %.17g" % (mine, result.rms_final))
    expect(mine <= theirs * (1 + 1e-6), "rigs: RMS %.17g, pycolmap.bundle_adjustment's %.17g" % (mine, theirs))
    worst = 0.0
    for im in refined.images.values():
        frame = refined.frames[im.frame_id]
        rig = refined.rigs[frame.rig_id]
        composed = frame.rig_from_world
        if rig.ref_sensor_id.id != im.camera_id:
            composed = rig.sensor_from_rig(pycolmap.sensor_t(pycolmap.SensorType.CAMERA, im.camera_id)) * composed
        worst = max(worst, float(abs(im.cam_from_world().matrix() - composed.matrix()).max()))
    expect(worst <= 1e-12, "rigs: an image's pose is %g from its frame's and its rig's" % worst)
    print("PASS refine_colmap of rigs: RMS %.9g px, pycolmap.bundle_adjustment's %.9g px, rigid to %g"
          % (mine, theirs, worst))

    # COLMAP's other constants on a Reconstruction: camera 1's intrinsics, camera 2's pose in rig
    # 1 and five points held come back with pycolmap's bits; the solve is the converted model's.
    sensor = pycolmap.sensor_t(pycolmap.SensorType.CAMERA, 2)
    points = sorted(rigs.points3D)[:5]
    kw = dict(hold_intrinsics=[1], hold_sensor_from_rig=[2], hold_points=points)
    held, result = pysba.refine_colmap(rigs, **kw)
    converted, again = pysba.refine_colmap(pysba.from_pycolmap(rigs), **kw)
    expect(isinstance(held, pycolmap.Reconstruction) and again.info.tolist() == result.info.tolist(),
           "held: refine_colmap(rec) solved another problem than refine_colmap(from_pycolmap(rec))")
    same_reconstruction(pysba.to_pycolmap(converted), held, "held: refine_colmap(rec)")
    expect(values(held.cameras[1].params) == values(rigs.cameras[1].params), "held: camera 1's parameters moved")
    expect(values(held.cameras[2].params) != values(rigs.cameras[2].params), "held: camera 2's parameters kept")
    expect(pose(held.rigs[1].sensor_from_rig(sensor)) == pose(rigs.rigs[1].sensor_from_rig(sensor)),
           "held: camera 2's pose in rig 1 moved")
    other = pycolmap.sensor_t(pycolmap.SensorType.CAMERA, 3)
    expect(pose(held.rigs[1].sensor_from_rig(other)) != pose(rigs.rigs[1].sensor_from_rig(other)),
           "held: camera 3's pose in rig 1 kept")
    expect(all(values(held.points3D[k].xyz) == values(rigs.points3D[k].xyz) for k in points),
           "held: a held point moved")
    expect(sum(values(held.points3D[k].xyz) != values(rigs.points3D[k].xyz) for k in rigs.points3D) ==
           len(rigs.points3D) - len(points), "held: a point not held was kept")
    print("PASS refine_colmap(rec) with hold_intrinsics, hold_sensor_from_rig and hold_points: "
          "pycolmap's bits where held")


def keypoints(im):
    return [(values(p.xy), p.point3D_id) for p in im.points2D]


def in_place(pycolmap, pysba):
    """refine_colmap(rec, in_place=True) refines rec itself, reading it through pycolmap's API
    with no file written: the values of refine_colmap(rec) (the copy's), the same bits; held
    values, ids, tracks and keypoints as they were; a frame without a pose untouched; on a
    KeyboardInterrupt, rec holds the estimate so far."""
    import pysba._colmap as pc
    rec = synthesize(pycolmap, 4, 13, rigs=2)
    perturb_rigs(pycolmap, rec)
    gone = sorted(rec.frames)[2]
    rec.deregister_frame(gone)
    before = pycolmap.Reconstruction(rec)
    kw = dict(hold_intrinsics=[1], hold_sensor_from_rig=[2], hold_points=sorted(rec.points3D)[:5])
    copied, result = pysba.refine_colmap(rec, **kw)
    same_reconstruction(before, rec, "refine_colmap(rec) changed rec")

    # No file: the route through files would need a temporary directory.
    def no_files(*args, **kwargs):
        raise AssertionError("a temporary directory was asked for")

    made = pc.tempfile.TemporaryDirectory
    pc.tempfile.TemporaryDirectory = no_files
    try:
        back, again = pysba.refine_colmap(rec, in_place=True, **kw)
    finally:
        pc.tempfile.TemporaryDirectory = made
    expect(back is rec and again.model is rec, "refine_colmap(rec, in_place=True) gave another object")
    expect(again.info.tolist() == result.info.tolist(), "in place: another problem")
    same_reconstruction(copied, rec, "refine_colmap(rec, in_place=True)")
    for k, im in rec.images.items():
        expect(keypoints(im) == keypoints(before.images[k]), "in place: image %d's keypoints" % k)
    sensor = pycolmap.sensor_t(pycolmap.SensorType.CAMERA, 2)
    expect(values(rec.cameras[1].params) == values(before.cameras[1].params) and
           pose(rec.rigs[1].sensor_from_rig(sensor)) == pose(before.rigs[1].sensor_from_rig(sensor)) and
           all(values(rec.points3D[k].xyz) == values(before.points3D[k].xyz) for k in kw["hold_points"]),
           "in place: a held value moved")
    expect(values(rec.cameras[2].params) != values(before.cameras[2].params) and
           sum(pose(f.rig_from_world) != pose(before.frames[k].rig_from_world)
               for k, f in rec.frames.items() if f.has_pose()) == rec.num_reg_frames(),
           "in place: a free value was not refined")
    expect(not rec.frames[gone].has_pose() and data_ids(rec.frames[gone]) == data_ids(before.frames[gone]),
           "in place: the frame without a pose")
    print("PASS refine_colmap(rec, in_place=True): rec refined, no file, refine_colmap(rec)'s bits, "
          "held values, keypoints and the unregistered frame as they were")

    def interrupt(state):
        if state.iteration == 2:
            raise KeyboardInterrupt

    rec = pycolmap.Reconstruction(before)
    try:
        pysba.refine_colmap(rec, progress=interrupt, in_place=True)
        expect(False, "refine_colmap(rec, in_place=True) went on after a KeyboardInterrupt")
    except KeyboardInterrupt as e:
        expect(e.result.model is rec, "a KeyboardInterrupt's result.model is not rec")
        same_reconstruction(pysba.refine_colmap(before, itmax=2)[0], rec, "in place, interrupted")
    for bad, message in ((dict(in_place=1), "in_place must be a bool, got int"),):
        try:
            pysba.refine_colmap(rec, **bad)
            expect(False, "refine_colmap(rec, %r) was taken" % bad)
        except TypeError as e:
            expect(str(e) == message, str(e))
    try:
        pysba.refine_colmap(pysba.from_pycolmap(rec), in_place=True)
        expect(False, "refine_colmap(ColmapModel, in_place=True) was taken")
    except TypeError as e:
        expect(str(e) == "in_place=True refines a pycolmap.Reconstruction, got ColmapModel", str(e))
    print("PASS refine_colmap(rec, in_place=True) interrupted leaves rec at the estimate so far; bad in_place refused")


def unregistered(pycolmap, pysba):
    """A frame without a pose (deregistered, as a mapper leaves one) and its images, which
    pycolmap's files leave out, are kept: from_pycolmap holds them without a pose and
    to_pycolmap gives them back; refine_colmap gives them back as they were and solves the
    registered ones' problem, the problem of the files pycolmap writes."""
    rec = synthesize(pycolmap, 2, 11, rigs=2)
    ids = sorted(rec.frames)
    gone = [ids[1], ids[len(ids) // 2 + 1]]
    for k in gone:
        rec.deregister_frame(k)
    expect(rec.num_reg_frames() == len(ids) - 2 and len(rec.images) == 2 * len(ids), rec.summary())
    model = pysba.from_pycolmap(rec)
    expect(repr(model) == "ColmapModel(cameras=4, images=20, points3D=300, rigs=2, frames=10)", repr(model))
    for f in model.frames:
        expect((f.q is None and f.t is None) == (f.id in gone), "from_pycolmap: frame %d's pose" % f.id)
    for im in model.images:
        theirs = rec.images[im.id]
        expect((im.q is None and im.t is None) == (not theirs.has_pose), "from_pycolmap: image %d's pose" % im.id)
        expect(list(zip(im.points2D.tolist(), im.point3D_ids.tolist())) == keypoints(theirs),
               "from_pycolmap: image %d's keypoints" % im.id)
    same_reconstruction(rec, pysba.to_pycolmap(model), "to_pycolmap(from_pycolmap(rec)) with unregistered frames")
    print("PASS from_pycolmap and to_pycolmap keep the frames without a pose and their images")

    with tempfile.TemporaryDirectory() as d:
        rec.write_binary(d)
        registered = pysba.read_colmap(d)
    expect(len(registered.images) == 16, "pycolmap wrote %d images" % len(registered.images))
    alone, result = pysba.refine_colmap(registered)
    refined, again = pysba.refine_colmap(model)
    expect(again.info.tolist() == result.info.tolist(), "refine_colmap: another problem than the registered ones'")
    expect([im.id for im in refined.images] == [im.id for im in model.images] and
           [f.id for f in refined.frames] == [f.id for f in model.frames], "refine_colmap: other images or frames")
    posed = {im.id: im for im in alone.images}
    for im, before in zip(refined.images, model.images):
        if im.id in posed:
            expect(values(im.q) + values(im.t) == values(posed[im.id].q) + values(posed[im.id].t),
                   "refine_colmap: image %d's pose is not the registered model's" % im.id)
        else:
            expect(im.q is None and im.t is None and im is not before and
                   list(zip(im.points2D.tolist(), im.point3D_ids.tolist())) ==
                   list(zip(before.points2D.tolist(), before.point3D_ids.tolist())),
                   "refine_colmap: image %d was not given back as it was" % im.id)
    back, third = pysba.refine_colmap(rec)
    expect(isinstance(back, pycolmap.Reconstruction) and third.info.tolist() == result.info.tolist(),
           "refine_colmap(rec): another problem")
    expect(sorted(back.frames) == ids and len(back.images) == 20 and back.num_reg_frames() == len(ids) - 2,
           "refine_colmap(rec): %s" % back.summary())
    same_reconstruction(pysba.to_pycolmap(refined), back, "refine_colmap(rec) with unregistered frames")
    for k in gone:
        expect(not back.frames[k].has_pose() and data_ids(back.frames[k]) == data_ids(rec.frames[k]),
               "refine_colmap(rec): frame %d" % k)
    print("PASS refine_colmap keeps the frames without a pose and their images as they were, "
          "and solves the registered ones")


def main(argv):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--python", default="", help="a Python with pycolmap, used when this one has none")
    args = ap.parse_args(argv)
    if os.environ.get("PYSBA_SANITIZED"):
        print("pycolmap_refine: SKIPPED: a sanitizer build (pycolmap is not built with the sanitizers)")
        return SKIP
    try:
        import pycolmap
    except ImportError as e:
        if args.python and not os.environ.get(REEXEC) and os.access(args.python, os.X_OK):
            os.environ[REEXEC] = "1"
            os.execv(args.python, [args.python, os.path.abspath(__file__)] + argv)
        print("pycolmap_refine: SKIPPED: %s cannot import pycolmap (%s); scripts/deps.sh test makes a venv "
              "with it" % (sys.executable, e))
        return SKIP
    try:
        import pysba
    except ImportError as e:
        print("pycolmap_refine: SKIPPED: %s (Python %s) has pycolmap but cannot import pysba: %s"
              % (sys.executable, sys.version.split()[0], e))
        return SKIP
    print("pycolmap %s, pysba %s, Python %s" % (pycolmap.__version__, pysba.__file__, sys.version.split()[0]))
    try:
        run(pycolmap, pysba)
        unregistered(pycolmap, pysba)
        in_place(pycolmap, pysba)
    except Failure as f:
        print("FAIL %s" % f)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
