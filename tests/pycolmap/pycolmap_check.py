#!/usr/bin/env python3
# SPDX-License-Identifier: BSD-3-Clause
"""sbarefine against COLMAP's own reader and writer of models, through pycolmap (PyPI).

Scenes are made by pycolmap.synthesize_dataset, with noise, and written by pycolmap: models
with rigs and frames, as COLMAP 4 writes them. Cases:
  written   an unrigged model (one rig per camera, one frame per image), text and binary,
            refined by sbarefine into a new folder, in place, and converted to the other
            encoding in place and into a new folder. pycolmap reads every model sbarefine
            writes; each image's pose there (composed from its frame) is the pose sbarefine
            wrote into the images file (1e-12); the RMS reprojection error pycolmap's
            projection gives is sbarefine's final RMS (--json, 1e-6 relative), and COLMAP's mean
            reprojection error of the model sbarefine's final mean (1e-9); the poses were
            refined; the folder holds the five files of its encoding and nothing else.
  one_image_frames
            a rig of three cameras whose frames each hold one image (pycolmap's rig, its frames
            split): the images of the cameras that are not the rig's reference are composed
            from the rig's sensor poses. The same checks, text into a new folder and binary in
            place.
  rigs      two rigs of three cameras, three images a frame, the cameras' poses in their rigs
            and focal lengths perturbed too: sbarefine refines them as COLMAP 4 does, text and
            binary, into a new folder and in place, with the checks above (every image's pose
            the composition of its frame's and its camera's in the rig: the rigs rigid), the
            rigs' reference cameras still without a pose, the others' poses refined; and
            pycolmap.bundle_adjustment at its defaults on the same model is the yardstick:
            sbarefine's RMS (pycolmap's projection of what it wrote) is no worse than
            pycolmap's x (1 + 1e-6).
  as_read   the rig model of `rigs` as pycolmap writes it (binary), rewritten by sbarefine
            with --itmax 0: the same bytes, each image's pose the one pycolmap composed.
  gauge     the model of `written` (binary) refined by pycolmap.bundle_adjustment at its defaults
            and by sbarefine at its own: both hold the same image's pose whole and the same
            coordinate of another image's translation (COLMAP's TWO_CAMS_FROM_WORLD gauge), every
            other pose number refined; sbarefine's RMS no worse than pycolmap's x (1 + 1e-6).
Exit status: 0 every check passed, 1 a check failed, 2 bad usage, 77 no pycolmap (ctest's
SKIP_RETURN_CODE): `scripts/deps.sh test` makes a venv with it (build/pycolmap-venv).

  pycolmap_check.py [--python PY] --sbarefine EXE --work DIR CASE...
With --python, a Python that cannot import pycolmap runs this script with PY instead.
"""
import argparse
import json
import math
import os
import shutil
import subprocess
import sys

SKIP = 77
HERE = os.path.dirname(os.path.abspath(__file__))
REEXEC = "SBA_PYCOLMAP_REEXEC"
EXT = {"text": ".txt", "binary": ".bin"}
OTHER = {"text": "binary", "binary": "text"}


class Failure(Exception):
    pass


def expect(ok, what):
    if not ok:
        raise Failure(what)


def files(encoding):
    x = EXT[encoding]
    return sorted(name + x for name in ("cameras", "images", "points3D", "rigs", "frames"))


def synthesize(pycolmap, cameras_per_rig, seed, rigs=None):
    pycolmap.set_random_seed(seed)
    o = pycolmap.SyntheticDatasetOptions()
    o.num_rigs = rigs or (2 if cameras_per_rig == 1 else 1)
    o.num_cameras_per_rig = cameras_per_rig
    o.num_frames_per_rig = 8 if cameras_per_rig == 1 else 5
    o.num_points3D = 300
    rec = pycolmap.synthesize_dataset(o)
    noise = pycolmap.SyntheticNoiseOptions()
    noise.point2D_stddev = 0.5
    noise.rig_from_world_translation_stddev = 0.02
    noise.rig_from_world_rotation_stddev = 0.3
    pycolmap.synthesize_noise(noise, rec)
    return rec


def write(rec, d, encoding):
    shutil.rmtree(d, ignore_errors=True)
    os.makedirs(d)
    (rec.write_text if encoding == "text" else rec.write_binary)(d)


def split_frames(d):
    """One frame per image: each frame of several images becomes one for each (the image keeps
    its pose: the frame's pose stays, and the image's sensor pose is in the rig)."""
    path = os.path.join(d, "frames.txt")
    with open(path) as f:
        lines = [ln.rstrip("\n") for ln in f]
    out, next_id = [], 1000
    for ln in lines:
        if ln.startswith("#") or not ln.strip():
            out.append(ln)
            continue
        w = ln.split()
        data = [w[10 + 3 * k:13 + 3 * k] for k in range(int(w[9]))]
        for k, item in enumerate(data):
            frame_id = w[0] if k == 0 else str(next_id)
            next_id += k > 0
            out.append(" ".join([frame_id] + w[1:9] + ["1"] + item))
    with open(path, "w") as f:
        f.write("\n".join(out) + "\n")


def rms(pycolmap, rec):
    total, count = 0.0, 0
    for im in rec.images.values():
        for p in im.points2D:
            if not p.has_point3D():
                continue
            x = im.project_point(rec.points3D[p.point3D_id].xyz)
            expect(x is not None, "image %d: a point behind the camera" % im.image_id)
            total += float((x[0] - p.xy[0]) ** 2 + (x[1] - p.xy[1]) ** 2)
            count += 1
    return math.sqrt(total / count)


def each(runs, check):
    """check(run) for every run, each failure printed: one does not hide the others."""
    failed = []
    for run in runs:
        try:
            check(run)
        except Failure as f:
            print("FAIL %s" % f)
            failed.append(str(run[0]))
    expect(not failed, "failed: " + ", ".join(failed))


def refine(args, model, out, extra=()):
    cmd = [args.sbarefine, model, "--write", out, "--json", out + ".json"] + list(extra)
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=600)
    expect(r.returncode == 0, "%s: exit %d: %s" % (" ".join(cmd), r.returncode, r.stderr))
    with open(out + ".json") as f:
        return json.load(f)["rms_px"]["final"]


def check_written(pycolmap, colmap_real, before, out, encoding, final_rms):
    """What pycolmap reads from sbarefine's model in out agrees with what sbarefine wrote."""
    expect(sorted(os.listdir(out)) == files(encoding), "%s holds %s" % (out, sorted(os.listdir(out))))
    rec = pycolmap.Reconstruction(out)
    expect(rec.num_rigs() == before.num_rigs() and rec.num_frames() == before.num_frames(),
           "%s: %d rigs, %d frames, expected %d and %d" % (out, rec.num_rigs(), rec.num_frames(),
                                                           before.num_rigs(), before.num_frames()))
    written = colmap_real.read_model(out)  # the images file's poses, as sbarefine wrote them
    moved = 0.0
    for image_id, im in rec.images.items():
        pose = im.cam_from_world()
        xyzw = [float(v) for v in pose.rotation.quat]
        q = [xyzw[3]] + xyzw[:3]
        mine = written.images[image_id]
        sign = 1.0 if sum(a * b for a, b in zip(q, mine["q"])) >= 0 else -1.0
        err = max([abs(sign * a - b) for a, b in zip(q, mine["q"])] +
                  [abs(float(a) - b) for a, b in zip(pose.translation, mine["t"])])
        expect(err < 1e-12, "%s: image %d: pycolmap reads a pose %.3g away from the images file's"
               % (out, image_id, err))
        old = before.images[image_id].cam_from_world().translation
        moved = max(moved, max(abs(float(a) - float(b)) for a, b in zip(pose.translation, old)))
    expect(moved > 1e-6, "%s: no pose was refined" % out)
    theirs = rms(pycolmap, rec)
    expect(abs(theirs - final_rms) <= 1e-6 * final_rms,
           "%s: pycolmap's RMS %.17g, sbarefine's final %.17g" % (out, theirs, final_rms))
    # COLMAP's mean reprojection error of the model written (from its points' ERROR) is the one
    # sbarefine reports.
    with open(out + ".json") as f:
        mean = json.load(f)["mean_px"]["final"]
    colmaps = rec.compute_mean_reprojection_error()
    expect(abs(colmaps - mean) <= 1e-9 * mean,
           "%s: COLMAP's mean reprojection error %.17g, sbarefine's final %.17g" % (out, colmaps, mean))
    print("PASS %s: %d images, %d frames; RMS %.9g px, mean %.9g px both"
          % (out, len(rec.images), rec.num_frames(), theirs, colmaps))


def case_written(pycolmap, colmap_real, args):
    rec = synthesize(pycolmap, 1, 7)
    runs = []
    for encoding in ("text", "binary"):
        source = os.path.join(args.work, "input_" + encoding)
        write(rec, source, encoding)
        other = ["--write-format", OTHER[encoding]]
        runs += [("new_" + encoding, source, encoding, []), ("inplace_" + encoding, source, encoding, []),
                 ("converted_" + encoding, source, OTHER[encoding], other),
                 ("inplace_converted_" + encoding, source, OTHER[encoding], other)]
    before = pycolmap.Reconstruction(os.path.join(args.work, "input_binary"))

    def check(run):
        name, source, written_as, extra = run
        out = os.path.join(args.work, name)
        shutil.rmtree(out, ignore_errors=True)
        model = source
        if name.startswith("inplace"):
            shutil.copytree(source, out)
            model = out
        check_written(pycolmap, colmap_real, before, out, written_as, refine(args, model, out, extra))
    each(runs, check)


def case_one_image_frames(pycolmap, colmap_real, args):
    rec = synthesize(pycolmap, 3, 11)
    split = os.path.join(args.work, "split")
    write(rec, split, "text")
    split_frames(split)
    before = pycolmap.Reconstruction(split)
    expect(before.num_frames() == len(before.images), "the split model has frames of several images")
    for image_id, im in before.images.items():
        a, b = im.cam_from_world(), rec.images[image_id].cam_from_world()
        expect(max(abs(float(x) - float(y)) for x, y in zip(a.translation, b.translation)) < 1e-12,
               "image %d moved when its frame was split" % image_id)
    out = os.path.join(args.work, "split_out")
    shutil.rmtree(out, ignore_errors=True)
    binary = os.path.join(args.work, "split_binary")
    write(before, binary, "binary")
    each([(split, out, "text"), (binary, binary, "binary")],
         lambda run: check_written(pycolmap, colmap_real, before, run[1], run[2], refine(args, run[0], run[1])))


def perturb_rigs(pycolmap, rec):
    """Turns each camera's pose in its rig (not the reference's) by about 0.01 rad and shifts it
    by 1 cm, and lengthens the focal lengths by 1%: synthesize_noise moves only the frames."""
    import numpy as np
    for rig_id in sorted(rec.rigs):
        rig = rec.rigs[rig_id]
        for k, (sensor, pose) in enumerate(sorted(rig.non_ref_sensors.items(), key=lambda s: s[0].id)):
            turn = pycolmap.Rigid3d(pycolmap.Rotation3d(np.array([0.01, -0.005 * k, 0.004])),
                                    np.array([0.01, -0.01, 0.005]))
            rig.set_sensor_from_rig(sensor, turn * pose)
    for camera in rec.cameras.values():
        params = camera.params.copy()
        params[0] *= 1.01
        camera.params = params


def sensor_poses(rec):
    """Each rig's sensors' poses (camera id: (xyzw, t)), None for its reference."""
    out = {}
    for rig in rec.rigs.values():
        out[rig.ref_sensor_id.id] = None
        for sensor, pose in rig.non_ref_sensors.items():
            out[sensor.id] = ([float(v) for v in pose.rotation.quat], [float(v) for v in pose.translation])
    return out


def case_rigs(pycolmap, colmap_real, args):
    rec = synthesize(pycolmap, 3, 13, rigs=2)
    perturb_rigs(pycolmap, rec)
    expect(rec.num_frames() < len(rec.images), "the model has no frame of several images")
    source = os.path.join(args.work, "rigs_reference")
    write(rec, source, "binary")
    reference = pycolmap.Reconstruction(source)
    options = pycolmap.BundleAdjustmentOptions()
    options.print_summary = False
    pycolmap.bundle_adjustment(reference, options)
    theirs = rms(pycolmap, reference)
    runs = []
    for encoding in ("text", "binary"):
        model = os.path.join(args.work, "rigs_input_" + encoding)
        write(rec, model, encoding)
        runs += [("rigs_new_" + encoding, model, encoding), ("rigs_inplace_" + encoding, model, encoding)]
    before = pycolmap.Reconstruction(os.path.join(args.work, "rigs_input_binary"))
    expect(rms(pycolmap, before) > 10 * theirs, "the perturbed model fits already")
    start = sensor_poses(before)

    def check(run):
        name, source, encoding = run
        out = os.path.join(args.work, name)
        shutil.rmtree(out, ignore_errors=True)
        model = source
        if "inplace" in name:
            shutil.copytree(source, out)
            model = out
        final = refine(args, model, out)
        check_written(pycolmap, colmap_real, before, out, encoding, final)
        mine = rms(pycolmap, pycolmap.Reconstruction(out))
        expect(mine <= theirs * (1 + 1e-6), "%s: RMS %.17g, pycolmap.bundle_adjustment's %.17g" % (out, mine, theirs))
        refined = sensor_poses(pycolmap.Reconstruction(out))
        expect(sorted(refined) == sorted(start), "%s: the rigs' cameras changed" % out)
        for camera_id, pose in refined.items():
            if start[camera_id] is None:
                expect(pose is None, "%s: reference camera %d has a pose in its rig" % (out, camera_id))
                continue
            moved = max(abs(a - b) for a, b in zip(pose[1], start[camera_id][1]))
            expect(moved > 1e-6, "%s: camera %d's pose in its rig was not refined" % (out, camera_id))
        print("PASS %s: RMS %.9g px, pycolmap.bundle_adjustment's %.9g px" % (out, mine, theirs))
    each(runs, check)


def case_as_read(pycolmap, colmap_real, args):
    rec = synthesize(pycolmap, 3, 13, rigs=2)
    model = os.path.join(args.work, "as_read_input")
    write(rec, model, "binary")
    out = os.path.join(args.work, "as_read")
    shutil.rmtree(out, ignore_errors=True)
    refine(args, model, out, ["--itmax", "0"])
    for name in files("binary"):
        with open(os.path.join(model, name), "rb") as a, open(os.path.join(out, name), "rb") as b:
            expect(a.read() == b.read(), "%s: %s is not the bytes pycolmap wrote" % (out, name))
    print("PASS %s: the five files pycolmap wrote, the same bytes" % out)


def kept(before, after):
    """Per image id, which of its pose's numbers came back exactly: (the rotation, [tx, ty, tz])."""
    out = {}
    for image_id, im in before.images.items():
        a, b = im.cam_from_world(), after.images[image_id].cam_from_world()
        same_q = [float(v) for v in a.rotation.quat] == [float(v) for v in b.rotation.quat]
        out[image_id] = (same_q, [float(x) == float(y) for x, y in zip(a.translation, b.translation)])
    return out


def gauge_of(kept_numbers, who):
    """The image whose pose is held whole, and the other image and the coordinate of its
    translation held; every other number must have changed."""
    whole = [i for i, (q, t) in kept_numbers.items() if q and all(t)]
    partial = [(i, t.index(True)) for i, (q, t) in kept_numbers.items() if not q and t.count(True) == 1]
    rest = [i for i, (q, t) in kept_numbers.items() if (q or any(t)) and i not in whole + [p[0] for p in partial]]
    expect(len(whole) == 1 and len(partial) == 1 and not rest,
           "%s: held whole %s, one coordinate %s, other numbers kept in %s" % (who, whole, partial, rest))
    return whole[0], partial[0]


def case_gauge(pycolmap, colmap_real, args):
    rec = synthesize(pycolmap, 1, 7)
    model = os.path.join(args.work, "gauge_input")
    write(rec, model, "binary")
    before = pycolmap.Reconstruction(model)
    reference = pycolmap.Reconstruction(model)
    options = pycolmap.BundleAdjustmentOptions()
    options.print_summary = False
    pycolmap.bundle_adjustment(reference, options)
    theirs = gauge_of(kept(before, reference), "pycolmap.bundle_adjustment")
    out = os.path.join(args.work, "gauge")
    shutil.rmtree(out, ignore_errors=True)
    refine(args, model, out)
    refined = pycolmap.Reconstruction(out)
    mine = gauge_of(kept(before, refined), "sbarefine")
    expect(mine == theirs, "sbarefine holds image %d and image %d's t[%d], pycolmap image %d and image %d's t[%d]"
           % (mine[0], mine[1][0], mine[1][1], theirs[0], theirs[1][0], theirs[1][1]))
    rms_mine, rms_theirs = rms(pycolmap, refined), rms(pycolmap, reference)
    expect(rms_mine <= rms_theirs * (1 + 1e-6), "%s: RMS %.17g, pycolmap's %.17g" % (out, rms_mine, rms_theirs))
    print("PASS %s: image %d's pose and image %d's t[%d] held, as pycolmap holds them; RMS %.9g px, pycolmap's %.9g px"
          % (out, mine[0], mine[1][0], mine[1][1], rms_mine, rms_theirs))


def import_pycolmap(python, script, argv):
    """pycolmap, or, when this Python cannot import it, script run again with argv by python (a
    Python with pycolmap) when given, else None, the reason printed for ctest's SKIPPED."""
    try:
        import pycolmap
        return pycolmap
    except ImportError as e:
        if python and not os.environ.get(REEXEC) and os.access(python, os.X_OK):
            os.environ[REEXEC] = "1"
            os.execv(python, [python, os.path.abspath(script)] + argv)
        print("%s: SKIPPED: %s cannot import pycolmap (%s); scripts/deps.sh test makes a venv with it" %
              (os.path.basename(script), sys.executable, e))
        return None


CASES = {"written": case_written, "one_image_frames": case_one_image_frames, "rigs": case_rigs,
         "as_read": case_as_read, "gauge": case_gauge}


def run_cases(argv, doc, script, cases, run=lambda case, pycolmap, args: case(pycolmap, args)):
    """The main of a script of cases (this one's, pose_prior_check.py's): its usage (doc's first
    line) is [--python PY] --sbarefine EXE --work DIR CASE..., the work directory emptied first;
    run(case, pycolmap, args) runs each case named. The exit status: 0 all passed, 1 one
    failed, SKIP without pycolmap."""
    ap = argparse.ArgumentParser(description=doc.split("\n")[0])
    ap.add_argument("--python", help="a Python with pycolmap, used when this one has none")
    ap.add_argument("--sbarefine", required=True)
    ap.add_argument("--work", required=True, help="a scratch directory (emptied)")
    ap.add_argument("cases", nargs="+", choices=sorted(cases))
    args = ap.parse_args(argv)
    pycolmap = import_pycolmap(args.python, script, argv)
    if pycolmap is None:
        return SKIP
    shutil.rmtree(args.work, ignore_errors=True)
    os.makedirs(args.work)
    print("pycolmap %s" % pycolmap.__version__)
    failed = 0
    for name in args.cases:
        try:
            run(cases[name], pycolmap, args)
            print("PASS %s" % name)
        except Failure as f:
            print("FAIL %s: %s" % (name, f))
            failed += 1
    return 1 if failed else 0


def main(argv):
    def run(case, pycolmap, args):
        sys.path.insert(0, os.path.join(HERE, "..", "colmap_real"))
        import colmap_real
        case(pycolmap, colmap_real, args)
    return run_cases(argv, __doc__, __file__, CASES, run)


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
