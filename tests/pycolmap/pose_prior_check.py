#!/usr/bin/env python3
# SPDX-License-Identifier: BSD-3-Clause
"""sbarefine's pose priors against COLMAP 4's pose-prior bundle adjuster, through pycolmap (PyPI).

Every scene is pycolmap.synthesize_dataset's with position priors in its database
(prior_position=True), the noise of COLMAP's tests (0.5 px on the observations, 0.02 and 0.3 deg
on the frames' poses; the priors 1.5 m off the true centres, synthesize_noise's default), the
cameras' poses in their rigs and the focal lengths perturbed too (pycolmap_check.perturb_rigs),
and the whole model moved by a similarity (scale 0.6), so that the model starts far from its
priors and the alignment matters. pycolmap writes the model and the database; pycolmap's
create_pose_prior_bundle_adjuster (BundleAdjustmentOptions() and
PosePriorBundleAdjustmentOptions() at their defaults, every registered image in the problem)
refines a copy of it (its alignment's RANSAC seeded, so that the reference does not change from
run to run, and required to end in Ceres's CONVERGENCE); sbarefine refines the written model
with --database-path. Both results are measured by one function, evaluate(): the sum over the
observations of the squared reprojection error (pycolmap's projection of the point into the
image) plus the sum over the priors of the Mahalanobis term (c - prior)^T Cov^-1 (c - prior) at
the image's projection centre c; a prior without a finite covariance counts with the fallback
1^2 I (see case options for the others). On pycolmap's result it must give Ceres's final cost x 2
(1e-9 relative). Checks, in each case of at least 3 priors:
  - sbarefine's cost <= pycolmap's x (1 + 1e-6), at the defaults of both (100 iterations at most);
  - every image's projection centre is pycolmap's to 1e-6 of the scene's extent (the diagonal of
    the box of pycolmap's centres);
  - the model moved: the priors' median squared distance (Mahalanobis) before refinement is over
    10 times pycolmap's final one;
  - --json's cost, projection_cost and prior_cost (final) are evaluate()'s, to 1e-6 relative;
  - the same priors from a text file (--pose-priors, a line per prior: the image's name, the
    position, the covariance row by row, the coordinate system) give the database's result:
    the centres to 1e-9 of the extent, the costs to 1e-9 relative.
A failed comparison with pycolmap reports how sbarefine stopped and what it reaches with
--itmax 1000.
Cases:
  cartesian   two rigs of one camera (12 images), CARTESIAN priors, a text model.
  wgs84       the same with WGS84 priors (latitude, longitude, altitude), a binary model: the
              reference run takes its priors from DatabaseCache.create with
              convert_pose_priors_to_enu (ENU around the first prior, as sbarefine converts them).
  rigs        two rigs of three cameras (24 images), a prior on every image, binary.
  rigs_reference_priors
              the same scene, the priors of the cameras that are not their rig's reference
              deleted from the database: priors on the frames' reference images only.
  held_sensor_from_rig
              two rigs of two cameras, one non-reference camera's pose in its rig held
              (--hold-sensor-from-rig; pycolmap's set_constant_sensor_from_rig_pose): its
              rotation bit for bit unchanged, its translation only scaled (the alignment's
              similarity scales the rig: pycolmap does so), both as pycolmap's; the other
              refined.
  options     the scene of cartesian (another seed), half of the priors without a covariance (9
              NaNs in the database, none in the text file), one prior 20 m off:
              --prior-position-fallback-stddev 2 and --prior-position-loss cauchy
              (--prior-position-loss-scale, its default given), pycolmap's
              prior_position_fallback_stddev and Cauchy loss; evaluate() counts the fallback
              covariance 2^2 I and the loss.
  two_priors  all priors but two deleted: sbarefine with --database-path writes the bytes it
              writes without it, and the same final RMS (--json).
  bad_input   a database without the pose_priors table, and one whose prior 2 has a position
              blob of 16 bytes: sbarefine exits with status 1, one line on stderr naming the
              table (pose_priors), or the prior (2, a word of its own) and "position"; nothing
              in --write's directory.
Exit status: 0 every check passed, 1 a check failed, 77 (ctest's SKIP_RETURN_CODE) no pycolmap.

  pose_prior_check.py [--python PY] --sbarefine EXE --work DIR CASE...
With --python, a Python that cannot import pycolmap runs this script with PY instead.
"""
import collections
import json
import math
import os
import shutil
import sqlite3
import struct
import subprocess
import sys

from pycolmap_check import Failure, expect, perturb_rigs, run_cases

TOLERANCE = 1e-6     # sbarefine against pycolmap
SAME = 1e-9          # the text file's route against the database's
# PosePriorBundleAdjustmentOptions' prior_position_fallback_stddev and, when cauchy_scale is not
# None, its Cauchy loss of that scale on the priors (ceres.prior_position_loss_function_type and
# _scale); the defaults are pycolmap's and sbarefine's.
PriorSettings = collections.namedtuple("PriorSettings", "fallback cauchy_scale")
DEFAULT = PriorSettings(1.0, None)


def sbarefine_options(settings):
    out = []
    if settings.fallback != DEFAULT.fallback:
        out += ["--prior-position-fallback-stddev", repr(settings.fallback)]
    if settings.cauchy_scale is not None:
        out += ["--prior-position-loss", "cauchy", "--prior-position-loss-scale", repr(settings.cauchy_scale)]
    return out


def moved_by_similarity(pycolmap, rec):
    """rec moved into another frame: scale 0.6, a turn of 0.6 rad, a shift of about 11."""
    import numpy as np
    axis = np.array([0.3, -0.5, 0.8])
    turn = pycolmap.Rotation3d(0.6 * axis / np.linalg.norm(axis))
    rec.transform(pycolmap.Sim3d(0.6, turn, np.array([10.0, -4.0, 3.0])))


def make_scene(pycolmap, d, seed, system, cameras_per_rig, frames_per_rig, encoding, exact=()):
    """Synthesizes a scene with priors into d (database.db, the model in model/), perturbed and
    moved (the poses in their rigs of the cameras in exact left true); returns the model's
    directory and the database's path."""
    shutil.rmtree(d, ignore_errors=True)
    os.makedirs(d)
    pycolmap.set_random_seed(seed)
    o = pycolmap.SyntheticDatasetOptions()
    o.num_rigs = 2
    o.num_cameras_per_rig = cameras_per_rig
    o.num_frames_per_rig = frames_per_rig
    o.num_points3D = 150
    o.prior_position = True
    o.prior_position_coordinate_system = getattr(pycolmap.PosePriorCoordinateSystem, system)
    database = os.path.join(d, "database.db")
    db = pycolmap.Database.open(database)
    try:
        rec = pycolmap.synthesize_dataset(o, db)
        noise = pycolmap.SyntheticNoiseOptions()
        noise.point2D_stddev = 0.5
        noise.rig_from_world_translation_stddev = 0.02
        noise.rig_from_world_rotation_stddev = 0.3
        pycolmap.synthesize_noise(noise, rec, db)
    finally:
        db.close()
    true = {s.id: (rig, s, pycolmap.Rigid3d(pycolmap.Rotation3d(pose.rotation.quat.copy()), pose.translation.copy()))
            for rig in rec.rigs.values() for s, pose in rig.non_ref_sensors.items()}
    perturb_rigs(pycolmap, rec)
    for c in exact:
        rig, sensor, pose = true[c]
        rig.set_sensor_from_rig(sensor, pose)
    moved_by_similarity(pycolmap, rec)
    model = os.path.join(d, "model")
    os.makedirs(model)
    (rec.write_text if encoding == "text" else rec.write_binary)(model)
    return model, database


def database_priors(pycolmap, database):
    """The priors as written (read_all_pose_priors) and as the adjuster takes them: WGS84 ones
    in ENU around the first, by DatabaseCache (convert_pose_priors_to_enu)."""
    db = pycolmap.Database.open(database)
    try:
        raw = db.read_all_pose_priors()
        wgs84 = [p for p in raw if p.coordinate_system == pycolmap.PosePriorCoordinateSystem.WGS84]
        if not wgs84:
            return raw, raw
        expect(len(wgs84) == len(raw), "%s: priors of two coordinate systems" % database)
        options = pycolmap.DatabaseCacheOptions()
        options.convert_pose_priors_to_enu = True
        cache = pycolmap.DatabaseCache.create(db, options)
        converted = list(cache.pose_priors)
        expect(len(converted) == len(raw), "DatabaseCache kept %d priors of %d" % (len(converted), len(raw)))
        return raw, converted
    finally:
        db.close()


def write_priors_text(pycolmap, rec, raw, path):
    """The priors as sbarefine's --pose-priors file: NAME X Y Z C11..C33 SYSTEM, in their order (a
    prior without a covariance NAME X Y Z SYSTEM)."""
    with open(path, "w") as f:
        f.write("# NAME X Y Z C11 C12 C13 C21 C22 C23 C31 C32 C33 SYSTEM\n")
        for p in raw:
            name = rec.images[p.corr_data_id.id].name
            values = [float(v) for v in p.position]
            if p.has_position_cov():
                values += [float(v) for v in p.position_covariance.reshape(9)]
            system = str(p.coordinate_system).split(".")[-1]
            f.write(" ".join([name] + [repr(v) for v in values] + [system]) + "\n")


def pycolmap_refine(pycolmap, model, priors, held_cameras=(), summary_out=None, settings=DEFAULT):
    """COLMAP 4's pose-prior bundle adjuster on the model in model, at its defaults: the refined
    reconstruction and Ceres's final cost x 2. The alignment's RANSAC is seeded, so that the
    reference is the same run after run (from some of its random starts Ceres creeps along a
    valley for its 100 iterations); the run must end in Ceres's CONVERGENCE, a minimum, unless
    summary_out (a list) is given: Ceres's summary is appended to it instead. model: a directory,
    or a Reconstruction (refined in place)."""
    rec = model if isinstance(model, pycolmap.Reconstruction) else pycolmap.Reconstruction(model)
    options = pycolmap.BundleAdjustmentOptions()
    options.print_summary = False
    prior_options = pycolmap.PosePriorBundleAdjustmentOptions()
    prior_options.alignment_ransac.random_seed = 1
    prior_options.prior_position_fallback_stddev = settings.fallback
    if settings.cauchy_scale is not None:
        prior_options.ceres.prior_position_loss_function_type = pycolmap.LossFunctionType.CAUCHY
        prior_options.ceres.prior_position_loss_scale = settings.cauchy_scale
    config = pycolmap.BundleAdjustmentConfig()
    for i in rec.reg_image_ids():
        config.add_image(i)
    for c in held_cameras:
        config.set_constant_sensor_from_rig_pose(pycolmap.sensor_t(pycolmap.SensorType.CAMERA, c))
    adjuster = pycolmap.create_pose_prior_bundle_adjuster(options, prior_options, config, priors, rec)
    summary = adjuster.solve().ceres_summary
    if summary_out is not None:
        summary_out.append(summary)
        return rec, 2.0 * summary.final_cost
    expect(summary.termination_type.name == "CONVERGENCE",
           "pycolmap's adjuster ended %s after %d steps" % (summary.termination_type, summary.num_successful_steps))
    return rec, 2.0 * summary.final_cost


def evaluate(pycolmap, rec, priors, settings=DEFAULT):
    """(reprojection, prior): the sum of the squared reprojection errors by pycolmap's
    projection, and the sum of the priors' Mahalanobis terms at their images' projection
    centres (a prior whose image is not in rec is not counted; one without a finite covariance
    weighted by fallback^2 I); with settings' Cauchy loss of scale a, each prior's term s counts
    as a^2 log(1 + s / a^2), Ceres's CauchyLoss(a) x 2."""
    import numpy as np
    reprojection = 0.0
    for im in rec.images.values():
        if not im.has_pose:
            continue
        camera = rec.cameras[im.camera_id]
        pose = im.cam_from_world()
        seen = [p for p in im.points2D if p.has_point3D()]
        if not seen:
            continue
        world = np.array([rec.points3D[p.point3D_id].xyz for p in seen])
        cam = np.array([pose * x for x in world])
        expect(bool(np.all(cam[:, 2] > 0)), "image %d: a point behind the camera" % im.image_id)
        projected = camera.img_from_cam(cam)
        observed = np.array([p.xy for p in seen])
        reprojection += float(((projected - observed) ** 2).sum())
    prior = 0.0
    for term in squared_distances(pycolmap, rec, priors, settings.fallback):
        if settings.cauchy_scale is not None:
            b = settings.cauchy_scale ** 2
            term = b * math.log1p(term / b)
        prior += term
    return reprojection, prior


def squared_distances(pycolmap, rec, priors, fallback):
    """Each prior's (c - prior)^T Cov^-1 (c - prior) at its image's projection centre c, the
    priors of images not in rec left out, Cov fallback^2 I where it is not finite."""
    import numpy as np
    out = []
    for p in priors:
        image_id = p.corr_data_id.id
        if image_id not in rec.images:
            continue
        cov = np.array(p.position_covariance)
        if not np.all(np.isfinite(cov)):
            cov = fallback ** 2 * np.eye(3)
        d = rec.images[image_id].projection_center() - np.array(p.position)
        out.append(float(d @ np.linalg.solve(cov, d)))
    return out


def centres(rec):
    return {i: rec.images[i].projection_center() for i in rec.reg_image_ids()}


def extent(rec):
    import numpy as np
    c = np.array(list(centres(rec).values()))
    return float(np.linalg.norm(c.max(axis=0) - c.min(axis=0)))


def largest_centre_difference(a, b):
    """The largest distance between the centres of an image in a and in b, over b's extent."""
    import numpy as np
    ca, cb = centres(a), centres(b)
    expect(sorted(ca) == sorted(cb), "registered images %s and %s" % (sorted(ca), sorted(cb)))
    return max(float(np.linalg.norm(ca[i] - cb[i])) for i in cb) / extent(b)


def run_sbarefine(args, model, out, extra):
    """sbarefine model --write out --json out.json extra: (exit status, stderr, the JSON or None)."""
    shutil.rmtree(out, ignore_errors=True)
    if os.path.exists(out + ".json"):
        os.remove(out + ".json")
    cmd = [args.sbarefine, model, "--write", out, "--json", out + ".json"] + list(extra)
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=600)
    report = None
    if r.returncode == 0 and os.path.exists(out + ".json"):
        with open(out + ".json") as f:
            report = json.load(f)
    return r.returncode, r.stderr, report, cmd


def refine_ok(args, model, out, extra):
    status, stderr, report, cmd = run_sbarefine(args, model, out, extra)
    expect(status == 0, "%s: exit %d: %s" % (" ".join(cmd), status, stderr.strip()))
    return report


def json_cost(report, name):
    """report's NAME_final (or NAME: {final}) if sbarefine writes it, else None."""
    for key in (name + "_final", name):
        v = report.get(key)
        if isinstance(v, dict):
            v = v.get("final")
        if isinstance(v, (int, float)):
            return float(v)
    return None


def diagnose(pycolmap, args, name, model, extra, report, priors, t_cost, theirs, settings):
    """A failure's context: how sbarefine stopped, and where it ends with --itmax 1000."""
    out = os.path.join(args.work, name, "sbarefine_itmax1000")
    longer = refine_ok(args, model, out, extra + ["--itmax", "1000"])
    rec = pycolmap.Reconstruction(out)
    cost = sum(evaluate(pycolmap, rec, priors, settings))
    return ("; sbarefine stopped after %s iterations (%s); with --itmax 1000 after %s (%s): cost ratio - 1 = %.3g, "
            "largest centre difference %.3g of the extent"
            % (report.get("ret"), report.get("stop_reason"), longer.get("ret"), longer.get("stop_reason"),
               cost / t_cost - 1, largest_centre_difference(rec, theirs)))


def check_against_pycolmap(pycolmap, args, name, model, database, held_cameras=(), settings=DEFAULT):
    """sbarefine (database and text file) against pycolmap's adjuster on the model: returns
    sbarefine's refined reconstruction (the database's route) and pycolmap's."""
    raw, priors = database_priors(pycolmap, database)
    expect(len(priors) >= 3, "%s: %d priors" % (name, len(priors)))
    start = pycolmap.Reconstruction(model)
    start_reprojection, start_prior = evaluate(pycolmap, start, priors, settings)
    theirs, ceres_cost = pycolmap_refine(pycolmap, model, priors, held_cameras, settings=settings)
    t_reprojection, t_prior = evaluate(pycolmap, theirs, priors, settings)
    t_cost = t_reprojection + t_prior
    expect(abs(t_cost - ceres_cost) <= 1e-9 * ceres_cost,
           "%s: evaluate() gives pycolmap's result %.17g, Ceres's final cost x 2 %.17g" % (name, t_cost, ceres_cost))
    hold = ["--hold-sensor-from-rig", ",".join(str(c) for c in held_cameras)] if held_cameras else []
    hold += sbarefine_options(settings)
    out = os.path.join(args.work, name, "sbarefine_database")
    report = refine_ok(args, model, out, ["--database-path", database] + hold)
    ours = pycolmap.Reconstruction(out)
    o_reprojection, o_prior = evaluate(pycolmap, ours, priors, settings)
    o_cost = o_reprojection + o_prior
    difference = largest_centre_difference(ours, theirs)
    print("%s: %d images, %d priors; cost (reprojection + prior) from %.9g + %.9g: pycolmap %.12g + %.12g = %.12g, "
          "sbarefine %.12g + %.12g = %.12g (ratio - 1 = %.3g); largest centre difference %.3g of the extent %.4g"
          % (name, len(theirs.images), len(priors), start_reprojection, start_prior, t_reprojection, t_prior, t_cost,
             o_reprojection, o_prior, o_cost, o_cost / t_cost - 1, difference, extent(theirs)))
    # The same priors from a text file.
    text = os.path.join(args.work, name, "priors.txt")
    write_priors_text(pycolmap, start, raw, text)
    out_text = os.path.join(args.work, name, "sbarefine_text")
    refine_ok(args, model, out_text, ["--pose-priors", text] + hold)
    by_text = pycolmap.Reconstruction(out_text)
    x_cost = sum(evaluate(pycolmap, by_text, priors, settings))
    same = largest_centre_difference(by_text, ours)
    print("%s: --pose-priors: cost %.12g, largest centre difference from --database-path's %.3g of the extent"
          % (name, x_cost, same))
    failed = []

    def check(ok, what):
        if not ok:
            failed.append(what)
    moved = [sorted(squared_distances(pycolmap, r, priors, settings.fallback)) for r in (start, theirs)]
    moved = [d[len(d) // 2] for d in moved]
    check(moved[0] > 10 * moved[1], "the priors' median squared distance starts at %.6g, ends at %.6g: the model "
          "was not moved" % tuple(moved))
    note = ""
    if o_cost > t_cost * (1 + TOLERANCE) or difference > TOLERANCE:
        note = diagnose(pycolmap, args, name, model, ["--database-path", database] + hold, report, priors, t_cost,
                        theirs, settings)
    check(o_cost <= t_cost * (1 + TOLERANCE), "sbarefine's cost %.17g, pycolmap's %.17g (ratio - 1 = %.3g)"
          % (o_cost, t_cost, o_cost / t_cost - 1))
    check(difference <= TOLERANCE, "a centre %.3g of the extent from pycolmap's" % difference)
    for key, mine in (("projection_cost", o_reprojection), ("prior_cost", o_prior), ("cost", o_cost)):
        v = json_cost(report, key)
        check(v is not None and abs(v - mine) <= 1e-6 * mine,
              "--json's %s final %s, evaluate()'s %.17g" % (key, "absent" if v is None else "%.17g" % v, mine))
    check(same <= SAME, "--pose-priors' centres %.3g of the extent from --database-path's" % same)
    check(abs(x_cost - o_cost) <= SAME * o_cost,
          "--pose-priors' cost %.17g, --database-path's %.17g" % (x_cost, o_cost))
    expect(not failed, "%s: %s%s" % (name, "; and ".join(failed), note))
    return ours, theirs, start


def case_cartesian(pycolmap, args):
    model, database = make_scene(pycolmap, os.path.join(args.work, "cartesian"), 21, "CARTESIAN", 1, 6, "text")
    check_against_pycolmap(pycolmap, args, "cartesian", model, database)


def case_wgs84(pycolmap, args):
    model, database = make_scene(pycolmap, os.path.join(args.work, "wgs84"), 22, "WGS84", 1, 6, "binary")
    check_against_pycolmap(pycolmap, args, "wgs84", model, database)


def case_rigs(pycolmap, args):
    model, database = make_scene(pycolmap, os.path.join(args.work, "rigs"), 23, "CARTESIAN", 3, 4, "binary")
    check_against_pycolmap(pycolmap, args, "rigs", model, database)


def reference_cameras(database):
    with sqlite3.connect(database) as c:
        return sorted(r[0] for r in c.execute("SELECT ref_sensor_id FROM rigs WHERE ref_sensor_type = 0"))


def case_rigs_reference_priors(pycolmap, args):
    name = "rigs_reference_priors"
    model, database = make_scene(pycolmap, os.path.join(args.work, name), 23, "CARTESIAN", 3, 4, "binary")
    refs = reference_cameras(database)
    with sqlite3.connect(database) as c:
        before = c.execute("SELECT COUNT(*) FROM pose_priors").fetchone()[0]
        c.execute("DELETE FROM pose_priors WHERE corr_sensor_type = 0 AND corr_sensor_id NOT IN (%s)"
                  % ",".join(str(r) for r in refs))
        after = c.execute("SELECT COUNT(*) FROM pose_priors").fetchone()[0]
    expect(0 < after < before, "%s: %d priors of %d left" % (name, after, before))
    check_against_pycolmap(pycolmap, args, name, model, database)


def sensor_poses(rec):
    """{camera id: (quaternion xyzw, translation)} of every non-reference camera."""
    return {s.id: ([float(v) for v in p.rotation.quat], [float(v) for v in p.translation])
            for rig in rec.rigs.values() for s, p in rig.non_ref_sensors.items()}


def case_held_sensor_from_rig(pycolmap, args):
    name = "held_sensor_from_rig"
    held = 2  # the first rig's second camera, its pose in the rig left true
    model, database = make_scene(pycolmap, os.path.join(args.work, name), 24, "CARTESIAN", 2, 6, "binary", [held])
    expect(held in sensor_poses(pycolmap.Reconstruction(model)), "%s: camera %d not in a rig" % (name, held))
    ours, theirs, start = check_against_pycolmap(pycolmap, args, name, model, database, [held])
    s0, so, st = sensor_poses(start), sensor_poses(ours), sensor_poses(theirs)
    for who, poses in (("sbarefine", so), ("pycolmap", st)):
        expect(poses[held][0] == s0[held][0], "%s: %s turned camera %d in its rig: %s, was %s"
               % (name, who, held, poses[held][0], s0[held][0]))
        ratios = [a / b for a, b in zip(poses[held][1], s0[held][1])]
        expect(max(ratios) - min(ratios) <= 1e-12 * abs(ratios[0]),
               "%s: %s moved camera %d in its rig other than by a scale: %s" % (name, who, held, ratios))
    top = max(abs(v) for v in st[held][1])
    shift = max(abs(a - b) for a, b in zip(so[held][1], st[held][1])) / top
    expect(shift <= TOLERANCE, "%s: camera %d's translation in its rig %s, pycolmap's %s"
           % (name, held, so[held][1], st[held][1]))
    for c in s0:
        if c != held:
            moved = max(abs(a - b) for a, b in zip(so[c][0], s0[c][0]))
            expect(moved > 1e-6, "%s: camera %d's rotation in its rig was not refined" % (name, c))
    print("%s: camera %d's rotation in its rig unchanged bit for bit, its translation scaled by %.9g "
          "(pycolmap's by %.9g; difference %.3g relative)" % (name, held, so[held][1][0] / s0[held][1][0],
                                                              st[held][1][0] / s0[held][1][0], shift))


def case_options(pycolmap, args):
    name = "options"
    model, database = make_scene(pycolmap, os.path.join(args.work, name), 27, "CARTESIAN", 1, 6, "text")
    nan = struct.pack("<9d", *[float("nan")] * 9)
    with sqlite3.connect(database) as c:
        c.execute("UPDATE pose_priors SET position_covariance = ? WHERE pose_prior_id % 2 = 1", (nan,))
        blob, = c.execute("SELECT position FROM pose_priors WHERE pose_prior_id = 4").fetchone()
        x, y, z = struct.unpack("<3d", blob)
        c.execute("UPDATE pose_priors SET position = ? WHERE pose_prior_id = 4", (struct.pack("<3d", x + 20, y, z),))
    check_against_pycolmap(pycolmap, args, name, model, database, settings=PriorSettings(2.0, 2.7954834829151074))


def model_bytes(d):
    out = {}
    for f in sorted(os.listdir(d)):
        with open(os.path.join(d, f), "rb") as h:
            out[f] = h.read()
    return out


def case_two_priors(pycolmap, args):
    name = "two_priors"
    model, database = make_scene(pycolmap, os.path.join(args.work, name), 25, "CARTESIAN", 1, 5, "text")
    with sqlite3.connect(database) as c:
        c.execute("DELETE FROM pose_priors WHERE pose_prior_id NOT IN "
                  "(SELECT pose_prior_id FROM pose_priors ORDER BY pose_prior_id LIMIT 2)")
        left = c.execute("SELECT COUNT(*) FROM pose_priors").fetchone()[0]
    expect(left == 2, "%s: %d priors left" % (name, left))
    plain = os.path.join(args.work, name, "without")
    with_db = os.path.join(args.work, name, "with_database")
    a = refine_ok(args, model, plain, [])
    b = refine_ok(args, model, with_db, ["--database-path", database])
    expect(model_bytes(plain) == model_bytes(with_db), "%s: the model written with 2 priors differs from "
           "the one written without a database" % name)
    ra, rb = a["rms_px"]["final"], b["rms_px"]["final"]
    expect(ra == rb, "%s: final RMS %.17g with the database, %.17g without" % (name, rb, ra))
    print("%s: with 2 priors the written model is the one without a database, byte for byte (RMS %.9g px)"
          % (name, ra))


def case_bad_input(pycolmap, args):
    name = "bad_input"
    model, database = make_scene(pycolmap, os.path.join(args.work, name), 26, "CARTESIAN", 1, 4, "text")
    no_table = os.path.join(args.work, name, "no_table.db")
    shutil.copy(database, no_table)
    with sqlite3.connect(no_table) as c:
        c.execute("DROP TABLE pose_priors")
    short_blob = os.path.join(args.work, name, "short_blob.db")
    shutil.copy(database, short_blob)
    with sqlite3.connect(short_blob) as c:
        c.execute("UPDATE pose_priors SET position = zeroblob(16) WHERE pose_prior_id = 2")
        expect(c.execute("SELECT length(position) FROM pose_priors WHERE pose_prior_id = 2").fetchone()[0] == 16,
               "%s: the blob was not shortened" % name)
    for db, words in ((no_table, ["pose_priors"]), (short_blob, ["2", "position"])):
        out = os.path.join(args.work, name, "out_" + os.path.basename(db).split(".")[0])
        status, stderr, _, cmd = run_sbarefine(args, model, out, ["--database-path", db])
        lines = stderr.strip().split("\n")
        print("%s: %s: exit %d, stderr %r" % (name, os.path.basename(db), status, stderr))
        expect(status == 1, "%s: exit %d, expected 1" % (" ".join(cmd), status))
        expect(len(lines) == 1 and lines[0], "%s: stderr is %d lines: %r" % (" ".join(cmd), len(lines), stderr))
        tokens = set(lines[0].replace(":", " ").replace(",", " ").replace("'", " ").replace('"', " ").split())
        expect(all(w in lines[0] if not w.isdigit() else w in tokens for w in words),
               "%s: the message %r names none of %s" % (" ".join(cmd), lines[0], words))
        written = os.listdir(out) if os.path.exists(out) else []
        expect(not written, "%s: %s holds %s" % (" ".join(cmd), out, written))


CASES = {"cartesian": case_cartesian, "wgs84": case_wgs84, "rigs": case_rigs,
         "rigs_reference_priors": case_rigs_reference_priors, "held_sensor_from_rig": case_held_sensor_from_rig,
         "options": case_options, "two_priors": case_two_priors, "bad_input": case_bad_input}


def main(argv):
    return run_cases(argv, __doc__, __file__, CASES)


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
