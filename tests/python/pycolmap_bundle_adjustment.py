#!/usr/bin/env python3
# SPDX-License-Identifier: BSD-3-Clause
"""pysba.colmap.bundle_adjustment against pycolmap's own bundle adjuster (pycolmap 4, from the
Python package index), with the same pycolmap.BundleAdjustmentOptions and
BundleAdjustmentConfig, on perturbed scenes of pycolmap.synthesize_dataset: SIMPLE_RADIAL
cameras, OPENCV cameras, and rigs of three cameras whose poses in the rigs are moved.

Each run, for pycolmap.bundle_adjustment(rec, options) and for
create_default_bundle_adjuster(options, config, rec).solve() (constant intrinsics, constant
frame poses, constant sensor poses, constant and variable points, a subset of the images, each
gauge, each refine_* flag in turn, a robust loss, min_track_length) checks:
- the object passed in is the one refined, and the Result's model is it;
- ids, tracks and keypoints are as they were;
- the final cost over the configuration's residuals (COLMAP's: the config images'
  observations, and every observation of the variable and constant points), by pycolmap's
  projection and loss, is pycolmap's or lower (1 + 1e-6);
- what pycolmap keeps (the held values, the gauge's frame and translation coordinate, the
  points outside the problem, the points' errors but after pycolmap.bundle_adjustment) keeps
  its bits here, and what pycolmap refines moves here too.
Options sba does not honour are refused with a message that names them.

Exit status: 0 every check passed, 1 a check failed, 77 (ctest's SKIP_RETURN_CODE) no Python
here can import both pycolmap and pysba, or a sanitizer build.

  pycolmap_bundle_adjustment.py [--python PY]
"""
import argparse
import math
import os
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "pycolmap"))
from pycolmap_check import Failure, expect, perturb_rigs  # noqa: E402

SKIP = 77
REEXEC = "PYSBA_PYCOLMAP_BA_REEXEC"


def values(x):
    return [float(v) for v in x]


def scene(pycolmap, kind, seed):
    """A perturbed scene: "simple_radial" (two rigs of one camera, 8 frames each), "opencv" (the
    same with OPENCV cameras), "rigs" (two rigs of three cameras, 5 frames each, the cameras'
    poses in the rigs and the focal lengths moved). Tracks of different lengths: each point
    loses a few observations."""
    import numpy as np
    pycolmap.set_random_seed(seed)
    o = pycolmap.SyntheticDatasetOptions()
    o.num_rigs = 2
    o.num_cameras_per_rig = 3 if kind == "rigs" else 1
    o.num_frames_per_rig = 5 if kind == "rigs" else 8
    o.num_points3D = 200
    if kind == "opencv":
        o.camera_model_id = pycolmap.CameraModelId.OPENCV
        o.camera_params = [1280.0, 1270.0, 512.0, 384.0, 0.03, -0.01, 0.001, -0.002]
    rec = pycolmap.synthesize_dataset(o)
    noise = pycolmap.SyntheticNoiseOptions()
    noise.point2D_stddev = 0.5
    noise.rig_from_world_translation_stddev = 0.02
    noise.rig_from_world_rotation_stddev = 0.3
    pycolmap.synthesize_noise(noise, rec)
    if kind == "rigs":
        perturb_rigs(pycolmap, rec)
    rng = np.random.default_rng(seed)
    for point_id in sorted(rec.points3D):
        elements = [(e.image_id, e.point2D_idx) for e in rec.points3D[point_id].track.elements]
        for k in rng.choice(len(elements), size=int(rng.integers(0, len(elements) - 3)), replace=False):
            rec.delete_observation(*elements[k])
    return rec


def state(rec):
    """Everything bundle adjustment may change, by id, as Python floats (the doubles' bits)."""
    return dict(
        frames={k: (values(f.rig_from_world.rotation.quat), values(f.rig_from_world.translation))
                for k, f in rec.frames.items() if f.has_pose()},
        sensors={(r, s.id): (values(p.rotation.quat), values(p.translation))
                 for r, rig in rec.rigs.items() for s, p in rig.non_ref_sensors.items()},
        cameras={k: values(c.params) for k, c in rec.cameras.items()},
        points={k: values(p.xyz) for k, p in rec.points3D.items()},
        errors={k: [float(p.error)] for k, p in rec.points3D.items()})


def structure(rec):
    """Ids, tracks and keypoints."""
    return (sorted(rec.cameras), sorted(rec.frames), sorted(rec.rigs),
            {k: (im.name, im.camera_id, im.frame_id, [(values(p.xy), p.point3D_id) for p in im.points2D])
             for k, im in rec.images.items()},
            {k: [(e.image_id, e.point2D_idx) for e in p.track.elements] for k, p in rec.points3D.items()})


def residuals(rec, config, min_track_length):
    """COLMAP's residuals of a configuration, as (image, point, keypoint) (config None: every
    observation); a constant residual of the set counts the same in both results compared."""
    out = []
    for point_id, p in rec.points3D.items():
        if p.track.length() < min_track_length:
            continue
        for e in p.track.elements:
            if config is None or config.has_image(e.image_id) or config.has_variable_point(point_id) \
                    or config.has_constant_point(point_id):
                out.append((e.image_id, point_id, e.point2D_idx))
    return out


def loss(pycolmap, options, s):
    kind, a = options.ceres.loss_function_type, options.ceres.loss_function_scale
    if kind == pycolmap.LossFunctionType.TRIVIAL:
        return s
    if kind == pycolmap.LossFunctionType.CAUCHY:
        return a * a * math.log1p(s / (a * a))
    if kind == pycolmap.LossFunctionType.HUBER:
        return s if s <= a * a else 2 * a * math.sqrt(s) - a * a
    return 2 * a * a * (math.sqrt(1 + s / (a * a)) - 1)  # SOFT_L1


def cost(pycolmap, rec, options, terms):
    """Ceres's cost of the terms at rec's values: half the sum of the loss of each squared
    reprojection error, by pycolmap's projection."""
    total = 0.0
    for image_id, point_id, k in terms:
        if point_id not in rec.points3D:
            continue  # deleted with an observation behind its camera
        im = rec.images[image_id]
        x = rec.cameras[im.camera_id].img_from_cam(im.cam_from_world() * rec.points3D[point_id].xyz)
        if x is None:
            continue  # COLMAP 4's cost of a point its projection refuses (behind the camera) is zero
        d = x - im.point2D(k).xy
        total += loss(pycolmap, options, float(d[0] * d[0] + d[1] * d[1]))
    return total / 2


def changed(before, after, exact):
    """The keys of each kind whose values differ; a rotation that moved by less than 1e-12 (the
    normalization pycolmap gives a held quaternion: a few ulp) counts as kept unless exact."""
    out = {}
    for kind in before:
        keys = []
        for k, v in before[kind].items():
            w = after[kind][k]
            if kind in ("frames", "sensors"):
                rotation = v[0] != w[0] if exact else max(abs(a - b) for a, b in zip(v[0], w[0])) > 1e-12
                translation = [a != b for a, b in zip(v[1], w[1])]
                if rotation or any(translation):
                    keys.append((k, rotation, tuple(translation)))
            elif v != w:
                keys.append((k, tuple(a != b for a, b in zip(v, w))))
        out[kind] = sorted(keys)
    return out


def compare(pycolmap, pysba, name, rec, options, config, *, subset_moves=False):
    """Runs pycolmap's adjuster and pysba's on copies of rec and checks them (see the docstring).
    subset_moves: pycolmap moves a value pysba may keep (nothing so far)."""
    theirs = pycolmap.Reconstruction(rec)
    if config is None:
        pycolmap.bundle_adjustment(theirs, options)
    else:
        pycolmap.create_default_bundle_adjuster(options, config, theirs).solve()
    ours = pycolmap.Reconstruction(rec)
    result = pysba.colmap.bundle_adjustment(ours, options, config)
    expect(result.model is ours, "%s: the Result's model is not the Reconstruction passed in" % name)
    # pycolmap's own: rec's, but that pycolmap.bundle_adjustment removes the observations
    # behind their cameras
    expect(structure(ours) == structure(theirs), "%s: ids, tracks or keypoints are not pycolmap's" % name)
    terms = residuals(rec, config, options.min_track_length)
    c0, c_theirs, c_ours = (cost(pycolmap, r, options, terms) for r in (rec, theirs, ours))
    expect(c_ours <= c_theirs * (1 + 1e-6), "%s: final cost %.9g, pycolmap's %.9g (from %.6g)"
           % (name, c_ours, c_theirs, c0))
    before = state(rec)
    for kind in ("points", "errors"):  # a point pycolmap deleted, with its observation behind a camera
        before[kind] = {k: v for k, v in before[kind].items() if k in theirs.points3D}
    moved_theirs = changed(before, state(theirs), exact=False)
    moved_ours = changed(before, state(ours), exact=True)
    expect(moved_ours == moved_theirs, "%s: what moved differs from pycolmap's: %s against %s"
           % (name, {k: v for k, v in moved_ours.items() if v != moved_theirs[k]},
              {k: v for k, v in moved_theirs.items() if v != moved_ours[k]}))
    print("PASS %s: cost %.6g -> %.9g (pycolmap %.9g), %d residuals, %d iterations, the same values held"
          % (name, c0, c_ours, c_theirs, len(terms), result.iterations))


def configured(pycolmap, rec, images=None, variable="track", constant=(), frames=(), sensors=(), intrinsics=(),
               gauge=None):
    """A BundleAdjustmentConfig: images (default every registered one); variable "track" (the
    points the images see, as COLMAP's mapper adds them), "all", or none; the constants."""
    config = pycolmap.BundleAdjustmentConfig()
    images = sorted(rec.reg_image_ids()) if images is None else images
    for image_id in images:
        config.add_image(image_id)
    for point_id, p in rec.points3D.items():
        if point_id in constant:
            config.add_constant_point(point_id)
        elif variable == "all" or (variable == "track" and any(e.image_id in images for e in p.track.elements)):
            config.add_variable_point(point_id)
    for frame_id in frames:
        config.set_constant_rig_from_world_pose(frame_id)
    for camera_id in sensors:
        config.set_constant_sensor_from_rig_pose(pycolmap.sensor_t(pycolmap.SensorType.CAMERA, camera_id))
    for camera_id in intrinsics:
        config.set_constant_cam_intrinsics(camera_id)
    if gauge is not None:
        config.fix_gauge(getattr(pycolmap.BundleAdjustmentGauge, gauge))
    return config


def options_with(pycolmap, **changes):
    o = pycolmap.BundleAdjustmentOptions()
    o.print_summary = False
    for key, value in changes.items():
        if key.startswith("loss"):
            setattr(o.ceres, key.replace("loss", "loss_function"), value)
        else:
            setattr(o, key, value)
    return o


def against_pycolmap(pycolmap, pysba):
    for kind, seed in (("simple_radial", 3), ("opencv", 5), ("rigs", 7)):
        rec = scene(pycolmap, kind, seed)
        plain = options_with(pycolmap)
        points = sorted(rec.points3D)
        frames = sorted(f for f in rec.frames if rec.frames[f].has_pose())
        images = sorted(rec.reg_image_ids())
        cameras = sorted(rec.cameras)
        half = [i for i in images if rec.images[i].frame_id in frames[:len(frames) // 2]]
        compare(pycolmap, pysba, kind + ": pycolmap.bundle_adjustment", rec, plain, None)
        compare(pycolmap, pysba, kind + ": every image, TWO_CAMS_FROM_WORLD", rec, plain,
                configured(pycolmap, rec, gauge="TWO_CAMS_FROM_WORLD"))
        compare(pycolmap, pysba, kind + ": constants, TWO_CAMS_FROM_WORLD", rec, plain,
                configured(pycolmap, rec, constant=points[:4], frames=frames[2:3], sensors=cameras[1:2],
                           intrinsics=cameras[-1:], gauge="TWO_CAMS_FROM_WORLD"))
        compare(pycolmap, pysba, kind + ": two constant frames fix the gauge", rec, plain,
                configured(pycolmap, rec, frames=frames[1:3], gauge="TWO_CAMS_FROM_WORLD"))
        compare(pycolmap, pysba, kind + ": half the frames, their points", rec, plain,
                configured(pycolmap, rec, images=half))
        compare(pycolmap, pysba, kind + ": half the frames, no variable point", rec, plain,
                configured(pycolmap, rec, images=half, variable=None))
        compare(pycolmap, pysba, kind + ": half the frames, every point variable", rec, plain,
                configured(pycolmap, rec, images=half, variable="all"))
        compare(pycolmap, pysba, kind + ": half the frames, constant points", rec, plain,
                configured(pycolmap, rec, images=half, variable=None, constant=points[::3]))
        for flag in ("refine_focal_length", "refine_extra_params", "refine_rig_from_world",
                     "refine_sensor_from_rig", "refine_points3D"):
            compare(pycolmap, pysba, "%s: %s off" % (kind, flag), rec, options_with(pycolmap, **{flag: False}),
                    configured(pycolmap, rec, gauge="TWO_CAMS_FROM_WORLD"))
        compare(pycolmap, pysba, kind + ": refine_principal_point", rec,
                options_with(pycolmap, refine_principal_point=True), None)
        compare(pycolmap, pysba, kind + ": constant_rig_from_world_rotation", rec,
                options_with(pycolmap, constant_rig_from_world_rotation=True), None)
        compare(pycolmap, pysba, kind + ": CAUCHY loss, min_track_length 6", rec,
                options_with(pycolmap, loss_type=pycolmap.LossFunctionType.CAUCHY, loss_scale=2.0,
                             min_track_length=6), None)


def with_points_behind(pycolmap, rec, count):
    """rec with `count` new points, each behind one image (a metre behind its centre) that
    observes it 20 px off the formula's mirrored pixel, and in front of the two or more images
    that see it there, observed without noise (free keypoints of rec's images). Returns the
    (image, point) pairs behind."""
    import numpy as np
    ids = sorted(rec.images)
    used, behind = set(), []
    for a in ids:
        im = rec.images[a]
        P = im.projection_center() - im.viewing_direction()
        placed = []
        for b in ids:
            ib = rec.images[b]
            cam = rec.cameras[ib.camera_id]
            X = ib.cam_from_world() * P
            if b == a:
                x = cam.params[0] * X[:2] / X[2] + cam.params[1:3] + 20.0
            else:
                x = cam.img_from_cam(X)
                if x is None or not (0 <= x[0] < cam.width and 0 <= x[1] < cam.height):
                    continue
            free = [k for k, p in enumerate(ib.points2D) if not p.has_point3D() and (b, k) not in used]
            placed.append((b, free[0], np.array(x)))
        if len(placed) < 3:
            continue
        track = pycolmap.Track()
        for b, k, x in placed:
            used.add((b, k))
            rec.images[b].points2D[k].xy = x
            track.add_element(b, k)
        behind.append((a, rec.add_point3D(P, track)))
        if len(behind) == count:
            break
    expect(len(behind) == count, "only %d points could be put behind an image" % len(behind))
    return behind


def points_behind(pycolmap, pysba):
    """Observations of points behind their cameras, which COLMAP 4's cost takes as zero:
    pycolmap.bundle_adjustment removes them first (the point with them where one is left seen
    once) and its adjusters with a configuration keep them; pysba does as each does, and
    refine_colmap (sbarefine's solve) removes them as pycolmap.bundle_adjustment does."""
    rec = scene(pycolmap, "simple_radial", 3)
    behind = with_points_behind(pycolmap, rec, 3)
    plain = options_with(pycolmap)
    compare(pycolmap, pysba, "points behind: pycolmap.bundle_adjustment", rec, plain, None)
    compare(pycolmap, pysba, "points behind: every image, TWO_CAMS_FROM_WORLD", rec, plain,
            configured(pycolmap, rec, gauge="TWO_CAMS_FROM_WORLD"))
    given = structure(rec)
    refined, result = pysba.refine_colmap(rec)
    expect(structure(rec) == given, "refine_colmap changed the model it was given")
    theirs = pycolmap.Reconstruction(rec)
    pycolmap.bundle_adjustment(theirs, plain)
    expect(structure(refined) == structure(theirs), "refine_colmap: the tracks are not pycolmap.bundle_adjustment's")
    removed = sorted((a, k) for a, p in behind for k in [next(e.point2D_idx for e in rec.points3D[p].track.elements
                                                                  if e.image_id == a)])
    expect(sorted(result.behind) == removed, "refine_colmap: Result.behind %s, not %s" % (result.behind, removed))
    print("PASS points behind their cameras: %d observations, removed as pycolmap.bundle_adjustment removes them, "
          "kept at no cost as its adjusters keep them" % len(behind))


def pose_priors(pycolmap, pysba):
    """With pose priors, against pycolmap.create_pose_prior_bundle_adjuster (pose_prior_check.py's
    scene and reference run): the cost of the reprojections and the priors is pycolmap's or lower
    (1 + 1e-6), and the object passed in is the one refined."""
    import tempfile
    from pose_prior_check import database_priors, evaluate, make_scene, pycolmap_refine
    with tempfile.TemporaryDirectory(prefix="pysba-ba-") as d:
        for system, cameras in (("CARTESIAN", 1), ("WGS84", 2)):
            model, database = make_scene(pycolmap, os.path.join(d, system), 3, system, cameras, 6, "binary")
            priors = database_priors(pycolmap, database)[1]
            theirs, _ = pycolmap_refine(pycolmap, model, priors)
            rec = pycolmap.Reconstruction(model)
            options = options_with(pycolmap)
            prior_options = pycolmap.PosePriorBundleAdjustmentOptions()
            prior_options.alignment_ransac.random_seed = 1
            config = configured(pycolmap, rec)
            result = pysba.colmap.bundle_adjustment(rec, options, config, pose_priors=priors,
                                                    prior_options=prior_options)
            expect(result.model is rec, "pose priors: the Result's model is not the Reconstruction passed in")
            mine, other = sum(evaluate(pycolmap, rec, priors)), sum(evaluate(pycolmap, theirs, priors))
            expect(mine <= other * (1 + 1e-6), "pose priors (%s): cost %.9g, pycolmap's %.9g" % (system, mine, other))
            print("PASS pose priors (%s, %d camera(s) per rig): cost %.9g (pycolmap %.9g), %d iterations"
                  % (system, cameras, mine, other, result.iterations))


def mapper_state(pycolmap, database, registered):
    """A pycolmap.IncrementalMapper of the database part way: its initial pair and the next
    images up to registered frames, each triangulated (seeded: the same state every time); and
    the image registered last."""
    pycolmap.set_random_seed(2)
    db = pycolmap.Database.open(database)
    try:
        cache = pycolmap.DatabaseCache.create(db, pycolmap.DatabaseCacheOptions())
    finally:
        db.close()
    mapper = pycolmap.IncrementalMapper(cache)
    mapper.begin_reconstruction(pycolmap.Reconstruction())
    pipeline = pycolmap.IncrementalPipelineOptions()
    # One thread: the registrations' RANSAC, run on several, does not always give the same state
    # for the same seed.
    pipeline.num_threads = 1
    options, tri = pipeline.get_mapper(), pipeline.get_triangulation()
    (first, second), pose = mapper.find_initial_image_pair(options, -1, -1)
    mapper.register_initial_image_pair(options, first, second, pose)
    for image_id in (first, second):
        mapper.triangulate_image(tri, image_id)
    image_id = second
    while mapper.reconstruction.num_reg_frames() < registered:
        image_id = next(i for i in mapper.find_next_images(options, False) if mapper.register_next_image(options, i))
        mapper.triangulate_image(tri, image_id)
    return cache, mapper, pipeline, image_id


def synthesized_database(pycolmap, database, seed, rigs, frames_per_rig, points, prior_position=False,
                         cameras_per_rig=1):
    """A database of pycolmap.synthesize_dataset (rigs of cameras_per_rig cameras, with a
    position prior per frame with prior_position) with 0.5 px of noise on its keypoints;
    returns the truth."""
    pycolmap.set_random_seed(seed)
    o = pycolmap.SyntheticDatasetOptions()
    o.num_rigs, o.num_cameras_per_rig, o.num_frames_per_rig, o.num_points3D = rigs, cameras_per_rig, frames_per_rig, points
    o.prior_position = prior_position
    db = pycolmap.Database.open(database)
    try:
        truth = pycolmap.synthesize_dataset(o, db)
        noise = pycolmap.SyntheticNoiseOptions()
        noise.point2D_stddev = 0.5
        pycolmap.synthesize_noise(noise, truth, db)
    finally:
        db.close()
    return truth


def mapper_global(pycolmap, pysba):
    """adjust_global_bundle against the mapper's own, from the same state of a mapper of a
    synthesized database (a camera per rig, 0.5 px of noise): the same observations left (those
    behind a camera filtered), the cost pycolmap's or lower (1 + 1e-6), the same values held
    (the gauge's, the constant cameras', the points' errors)."""
    import tempfile
    with tempfile.TemporaryDirectory(prefix="pysba-mapper-") as d:
        database = os.path.join(d, "database.db")
        synthesized_database(pycolmap, database, 4, 2, 8, 300)
        for constant_cameras in ((), (1,)):
            runs = {}
            for who in ("pycolmap", "pysba"):
                cache, mapper, pipeline, _ = mapper_state(pycolmap, database, 9)
                options = pipeline.get_mapper()
                options.constant_cameras = set(constant_cameras)
                before = pycolmap.Reconstruction(mapper.reconstruction)
                if who == "pycolmap":
                    expect(mapper.adjust_global_bundle(options, pipeline.get_global_bundle_adjustment()),
                           "the mapper's global adjustment failed")
                else:
                    result = pysba.colmap.adjust_global_bundle(mapper, options, pipeline.get_global_bundle_adjustment())
                    expect(result.model is mapper.reconstruction, "adjust_global_bundle: another reconstruction")
                runs[who] = (before, pycolmap.Reconstruction(mapper.reconstruction))
            (b0, theirs), (b1, ours) = runs["pycolmap"], runs["pysba"]
            name = "adjust_global_bundle, constant_cameras %s" % (set(constant_cameras) or "{}")
            expect(state(b0) == state(b1) and structure(b0) == structure(b1), name + ": the mapper's states differ")
            expect(structure(theirs) == structure(ours), name + ": other observations left")
            terms = residuals(ours, None, 0)
            plain = options_with(pycolmap)
            c0, c_theirs, c_ours = (cost(pycolmap, r, plain, terms) for r in (b0, theirs, ours))
            expect(c_ours <= c_theirs * (1 + 1e-6), "%s: cost %.9g, pycolmap's %.9g" % (name, c_ours, c_theirs))
            before = state(b0)
            moved_theirs, moved_ours = changed(before, state(theirs), False), changed(before, state(ours), True)
            expect(moved_ours == moved_theirs, "%s: what moved differs: %s against %s" % (
                name, {k: v for k, v in moved_ours.items() if v != moved_theirs[k]},
                {k: v for k, v in moved_theirs.items() if v != moved_ours[k]}))
            print("PASS %s: %d frames, cost %.6g -> %.9g (pycolmap %.9g), the same values held"
                  % (name, ours.num_reg_frames(), c0, c_ours, c_theirs))


def part_read(pycolmap, pysba):
    """A configuration of a few images reads only what its adjustment sees (the points of its
    images, a point held with only its elements there when its track leaves them, the variable
    and constant points whole): the result is the one of reading everything, bit for bit."""
    from pysba import colmap as pc
    for kind, seed in (("simple_radial", 3), ("opencv", 5), ("rigs", 7)):
        rec = scene(pycolmap, kind, seed)
        frames = sorted(f for f in rec.frames if rec.frames[f].has_pose())
        images = sorted(rec.reg_image_ids())
        points = sorted(rec.points3D)
        quarter = [i for i in images if rec.images[i].frame_id in frames[:len(frames) // 4]]
        for name, config in (("constant points", configured(pycolmap, rec, images=quarter, variable=None,
                                                             constant=points[::3])),
                             ("THREE_POINTS", configured(pycolmap, rec, images=quarter, variable=None,
                                                         gauge="THREE_POINTS")),
                             ("every point variable", configured(pycolmap, rec, images=quarter, variable="all",
                                                                 gauge="TWO_CAMS_FROM_WORLD"))):
            runs = []
            for whole in (False, True):
                part = pc._part
                if whole:
                    pc._part = lambda *args: None
                try:
                    ours = pycolmap.Reconstruction(rec)
                    result = pysba.colmap.bundle_adjustment(ours, options_with(pycolmap), config)
                finally:
                    pc._part = part
                runs.append((state(ours), result.iterations))
            expect(pc._part(pycolmap, rec, config, {}) is not None, "%s, %s: the whole model read" % (kind, name))
            expect(runs[0] == runs[1], "%s, %s: the part read gives another result" % (kind, name))
            print("PASS %s, a quarter of the frames, %s: the part read gives the whole read's result, bit for bit "
                  "(%d iterations)" % (kind, name, runs[0][1]))


def mapper_local(pycolmap, pysba):
    """adjust_local_bundle against the mapper's own, from the same state of a mapper of a
    synthesized database (two rigs of one camera, 0.5 px of noise): the same observations
    adjusted, left, merged, completed and filtered (the report), the local cost pycolmap's or
    lower (1 + 1e-6), the same frames and cameras refined and held. And the steps around the
    solve as pysba takes them with COLMAP's solve give the mapper's result (the same problem:
    the order Ceres is given the points in can differ, and with it the rounding)."""
    import tempfile
    from pysba import colmap as pc
    with tempfile.TemporaryDirectory(prefix="pysba-mapper-local-") as d:
        database = os.path.join(d, "database.db")
        synthesized_database(pycolmap, database, 4, 2, 8, 300)
        # Nine frames: a local bundle of six images, the cameras held (their other images stay
        # out); five: every image, the cameras refined unless constant.
        for registered, constant_cameras in ((9, ()), (5, ()), (5, (2,))):
            runs = {}
            for who in ("pycolmap", "steps", "pysba"):
                cache, mapper, pipeline, image_id = mapper_state(pycolmap, database, registered)
                options = pipeline.get_mapper()
                options.constant_cameras = set(constant_cameras)
                ba, tri = pipeline.get_local_bundle_adjustment(), pipeline.get_triangulation()
                ba.ceres.solver_options.num_threads = 1
                rec, modified = mapper.reconstruction, mapper.get_modified_points3D()
                before = pycolmap.Reconstruction(rec)
                config = pc._local_config(pycolmap, mapper, options, image_id,
                                          mapper.find_local_bundle(options, image_id), modified)
                if who == "pycolmap":
                    report = mapper.adjust_local_bundle(options, ba, tri, image_id, modified)
                elif who == "steps":
                    report = pc._adjust_local_bundle(
                        pycolmap, mapper, options, tri, image_id, modified,
                        lambda r, c: pycolmap.create_default_bundle_adjuster(ba, c, r).solve().num_residuals // 2)
                else:
                    report = pysba.colmap.adjust_local_bundle(mapper, options, ba, tri, image_id, modified)
                runs[who] = (before, pycolmap.Reconstruction(rec), report, config, ba)
            name = "adjust_local_bundle, %d frames, constant_cameras %s" % (registered, set(constant_cameras) or "{}")
            (b0, theirs, r_theirs, config, ba) = runs["pycolmap"]
            held = sorted(config.constant_cam_intrinsics)
            expect((len(config.images) < len(b0.reg_image_ids())) == (registered == 9) and
                   held == ([1, 2] if registered == 9 else sorted(constant_cameras)),
                   "%s: %d of %d images in the local bundle, cameras %s held" % (
                       name, len(config.images), len(b0.reg_image_ids()), held))
            for who in ("steps", "pysba"):
                b1, ours, r_ours = runs[who][:3]
                expect(state(b0) == state(b1) and structure(b0) == structure(b1), name + ": the mapper's states differ")
                expect(r_ours.todict() == r_theirs.todict(), "%s (%s): report %s, the mapper's %s"
                       % (name, who, r_ours.todict(), r_theirs.todict()))
                expect(structure(theirs) == structure(ours), "%s (%s): other observations left" % (name, who))
                moved_theirs = changed(state(b0), state(theirs), False)
                moved_ours = changed(state(b0), state(ours), who == "pysba")
                for kind in ("frames", "sensors", "cameras"):
                    expect(moved_ours[kind] == moved_theirs[kind], "%s (%s): the %s moved differ: %s against %s"
                           % (name, who, kind, moved_ours[kind], moved_theirs[kind]))
            terms = residuals(b0, config, 0)
            c0, c_theirs = cost(pycolmap, b0, ba, terms), cost(pycolmap, theirs, ba, terms)
            c_steps, c_ours = cost(pycolmap, runs["steps"][1], ba, terms), cost(pycolmap, runs["pysba"][1], ba, terms)
            expect(abs(c_steps - c_theirs) <= 1e-9 * c_theirs, "%s: the steps with COLMAP's solve: cost %.12g, the "
                   "mapper's %.12g" % (name, c_steps, c_theirs))
            expect(c_ours <= c_theirs * (1 + 1e-6), "%s: cost %.9g, pycolmap's %.9g" % (name, c_ours, c_theirs))
            print("PASS %s: %d of %d images, cameras %s held, %d observations adjusted, cost %.6g -> %.9g (pycolmap "
                  "%.9g), the same report, frames and cameras refined and held; the steps with COLMAP's solve give "
                  "its cost (%.12g)" % (name, len(config.images), len(b0.reg_image_ids()), held,
                                        r_theirs.num_adjusted_observations, c0, c_ours, c_theirs, c_steps))


def digest(rec):
    """Every value and track of rec (the doubles' shortest reprs, which give their bits): two
    models are the same when these are."""
    import hashlib
    values_of = {kind: sorted(by_id.items()) for kind, by_id in state(rec).items()}
    tracks = sorted(structure(rec)[4].items())
    return hashlib.sha1(repr((sorted(values_of.items()), tracks)).encode()).hexdigest()


def as_good_as(name, theirs, ours):
    """The issue's criteria for a mapping against pycolmap's: every image pycolmap registers
    registered, the points within 1%, the mean reprojection error pycolmap's or lower (1 + 1e-3)."""
    expect(set(theirs.reg_image_ids()) <= set(ours.reg_image_ids()), name + ": images pycolmap registers are not")
    expect(abs(ours.num_points3D() - theirs.num_points3D()) <= 0.01 * theirs.num_points3D(),
           "%s: %d points, pycolmap %d" % (name, ours.num_points3D(), theirs.num_points3D()))
    ea, eb = theirs.compute_mean_reprojection_error(), ours.compute_mean_reprojection_error()
    expect(eb <= ea * (1 + 1e-3), "%s: mean reprojection error %.9g px, pycolmap's %.9g" % (name, eb, ea))


def pipeline_bits(pycolmap, pysba):
    """On one thread, the Python pipeline with the mapper's own adjustments gives
    pycolmap.incremental_mapping's model bit for bit, with one camera shared by every image and
    a camera per image: at the default options, and (shared) with two local refinements after
    every image (ba_local_max_refinement_change 0: the second without the robust loss, on the
    points changed since the image was triangulated). With rigs of two cameras, the same images
    and points and the mean reprojection error to 1e-9 (not the same bits: where they part is
    not known yet). With sba's global and local adjustments, on two threads, the same images
    registered, the points within 1% and the mean reprojection error pycolmap's or lower
    (1 + 1e-3)."""
    import tempfile
    scenes = (("one shared camera", dict(rigs=1, frames_per_rig=30), (None, 0.0)),
              ("a camera per image", dict(rigs=30, frames_per_rig=1), (None,)),
              ("rigs of two cameras", dict(rigs=2, frames_per_rig=8, cameras_per_rig=2), (None,)))
    for kind, layout, changes in scenes:
        with tempfile.TemporaryDirectory(prefix="pysba-pipeline-") as d:
            database = os.path.join(d, "database.db")
            synthesized_database(pycolmap, database, 5, points=300, **layout)
            for change in changes:
                options = pycolmap.IncrementalPipelineOptions()
                options.num_threads = 1
                options.random_seed = 1
                if change is not None:
                    options.ba_local_max_refinement_change = change
                theirs = pycolmap.incremental_mapping(database, d, os.path.join(d, "pycolmap"), options)
                ours = pysba.colmap.incremental_mapping(database, d, os.path.join(d, "colmap"), options,
                                                        global_adjustment="colmap", local_adjustment="colmap")
                name = "the Python pipeline, %s, ba_local_max_refinement_change %s" % (
                    kind, options.ba_local_max_refinement_change)
                expect(sorted(theirs) == sorted(ours) == [0], "%s: models %s, %s" % (name, sorted(theirs), sorted(ours)))
                a, b = theirs[0], ours[0]
                if "rigs" not in kind:
                    expect(digest(a) == digest(b), "%s: %d images, %d points, %.15g px; pycolmap's %d, %d, %.15g"
                           % (name, b.num_reg_images(), b.num_points3D(), b.compute_mean_reprojection_error(),
                              a.num_reg_images(), a.num_points3D(), a.compute_mean_reprojection_error()))
                    print("PASS %s: pycolmap.incremental_mapping's model bit for bit (%d images, %d points)"
                          % (name, b.num_reg_images(), b.num_points3D()))
                    continue
                ea, eb = a.compute_mean_reprojection_error(), b.compute_mean_reprojection_error()
                expect(set(a.reg_image_ids()) == set(b.reg_image_ids()) and a.num_points3D() == b.num_points3D() and
                       abs(eb / ea - 1) <= 1e-9, "%s: %d images, %d points, %.15g px; pycolmap's %d, %d, %.15g"
                       % (name, b.num_reg_images(), b.num_points3D(), eb, a.num_reg_images(), a.num_points3D(), ea))
                print("PASS %s: pycolmap.incremental_mapping's images and points, its mean reprojection error to "
                      "%.1e (%d images, %d points)" % (name, abs(eb / ea - 1), b.num_reg_images(), b.num_points3D()))
            options = pycolmap.IncrementalPipelineOptions()
            options.num_threads = 2
            sba = pysba.colmap.incremental_mapping(database, d, os.path.join(d, "sba"), options,
                                                   local_adjustment="sba")
            name = "sba's global and local adjustments, %s" % kind
            expect(sorted(sba) == [0], "%s: models %s" % (name, sorted(sba)))
            m = sba[0]
            as_good_as(name, a, m)
            print("PASS %s: %d images, %d points (pycolmap %d), %.6f px (pycolmap %.6f)" % (
                name, m.num_reg_images(), m.num_points3D(), a.num_points3D(), m.compute_mean_reprojection_error(),
                a.compute_mean_reprojection_error()))


def mapping(pycolmap, pysba):
    """incremental_mapping against pycolmap.incremental_mapping on a synthesized database (40
    frames of one camera, 0.5 px of noise): every image pycolmap registers registered, the
    number of points within 1% of pycolmap's, the mean reprojection error at most pycolmap's
    times (1 + 1e-3), with sba's global adjustments and with its local ones too; with the
    mapper's own the Python pipeline gives pycolmap's models (the same points and error)."""
    import tempfile
    with tempfile.TemporaryDirectory(prefix="pysba-mapping-") as d:
        database = os.path.join(d, "database.db")
        synthesized_database(pycolmap, database, 5, 1, 40, 400)
        options = pycolmap.IncrementalPipelineOptions()
        options.num_threads = 2
        theirs = pycolmap.incremental_mapping(database, d, os.path.join(d, "pycolmap"), options)
        timings = {}
        same = pysba.colmap.incremental_mapping(database, d, os.path.join(d, "colmap"), options,
                                                global_adjustment="colmap", local_adjustment="colmap")
        ours = pysba.colmap.incremental_mapping(database, d, os.path.join(d, "sba"), options,
                                                local_adjustment="colmap", timings=timings)
        local_timings = {}  # the default: sba's local adjustments too
        local = pysba.colmap.incremental_mapping(database, d, os.path.join(d, "sba-local"), options,
                                                 timings=local_timings)
        expect(sorted(theirs) == sorted(ours) == sorted(same) == sorted(local) == [0],
               "models: %s, %s, %s" % (sorted(theirs), sorted(ours), sorted(local)))
        a, b, c = theirs[0], ours[0], same[0]
        for what, m in (("sba's global adjustment", b), ("sba's local and global adjustments", local[0])):
            as_good_as(what, a, m)
        expect(local_timings.get("local_calls", 0) > 0 and 0 < local_timings["local_solve"] < local_timings["local"],
               "timings %r" % local_timings)
        expect("local_calls" not in timings, "timings %r: local solves counted without sba's" % timings)
        # Ceres on two threads sums in its own order: the same pipeline, not the same bits.
        expect(set(c.reg_image_ids()) == set(a.reg_image_ids()) and
               abs(c.num_points3D() - a.num_points3D()) <= 0.01 * a.num_points3D() and
               abs(c.compute_mean_reprojection_error() / a.compute_mean_reprojection_error() - 1) <= 1e-4,
               "the Python pipeline with the mapper's adjustment: %d images, %d points, %.9g px; pycolmap's %d, %d, %.9g"
               % (c.num_reg_images(), c.num_points3D(), c.compute_mean_reprojection_error(),
                  a.num_reg_images(), a.num_points3D(), a.compute_mean_reprojection_error()))
        expect(os.path.isfile(os.path.join(d, "sba", "0", "points3D.bin")), "incremental_mapping wrote no model")
        expect(timings["global_calls"] > 0 and 0 < timings["global_read"] < timings["global"] < timings["total"],
               "timings %r" % timings)
        print("PASS incremental_mapping: %d images, %d points (pycolmap %d), %.6f px (pycolmap %.6f), %d global "
              "adjustments; with sba's local adjustments too %d images, %d points, %.6f px (%d local); the mapper's "
              "own gives pycolmap's model" % (
                  b.num_reg_images(), b.num_points3D(), a.num_points3D(), b.compute_mean_reprojection_error(),
                  a.compute_mean_reprojection_error(), timings["global_calls"], local[0].num_reg_images(),
                  local[0].num_points3D(), local[0].compute_mean_reprojection_error(), local_timings["local_calls"]))


def mapping_with_priors(pycolmap, pysba):
    """incremental_mapping with use_prior_position against pycolmap.incremental_mapping on a
    synthesized database with a position prior per frame (1.5 units of noise on them, 0.5 px
    on the keypoints), with and without the robust loss on the priors: every image pycolmap
    registers registered, the points within 1% of pycolmap's, the mean reprojection error at
    most pycolmap's times (1 + 1e-3), and the model in the priors' frame, its camera centres
    (unaligned) as close to the truth's as pycolmap's or closer (RMS, to 5%: the priors hold
    the similarity weakly, and where a solve stops along it is the solver's, not the
    problem's)."""
    import tempfile
    import numpy as np
    with tempfile.TemporaryDirectory(prefix="pysba-mapping-priors-") as d:
        database = os.path.join(d, "database.db")
        truth = synthesized_database(pycolmap, database, 6, 1, 30, 300, prior_position=True)
        db = pycolmap.Database.open(database)
        try:
            expect(db.num_pose_priors() == 30, "the database holds %d priors" % db.num_pose_priors())
        finally:
            db.close()
        centres = {im.name: im.projection_center() for im in truth.images.values()}

        def unaligned(rec):
            d2 = [np.sum(np.square(im.projection_center() - centres[im.name]))
                  for im in rec.images.values() if im.has_pose]
            return float(np.sqrt(np.mean(d2)))

        for robust in (False, True):
            options = pycolmap.IncrementalPipelineOptions()
            options.num_threads = 2
            options.use_prior_position = True
            options.use_robust_loss_on_prior_position = robust
            theirs = pycolmap.incremental_mapping(database, d, os.path.join(d, "pycolmap"), options)
            ours = pysba.colmap.incremental_mapping(database, d, os.path.join(d, "sba"), options)
            expect(sorted(theirs) == sorted(ours) == [0], "models: %s, %s" % (sorted(theirs), sorted(ours)))
            a, b = theirs[0], ours[0]
            name = "incremental_mapping with priors%s" % (", robust" if robust else "")
            expect(set(a.reg_image_ids()) <= set(b.reg_image_ids()), name + ": images pycolmap registers are not")
            expect(abs(b.num_points3D() - a.num_points3D()) <= 0.01 * a.num_points3D(),
                   "%s: %d points, pycolmap %d" % (name, b.num_points3D(), a.num_points3D()))
            ea, eb = a.compute_mean_reprojection_error(), b.compute_mean_reprojection_error()
            expect(eb <= ea * (1 + 1e-3), "%s: mean reprojection error %.9g px, pycolmap's %.9g" % (name, eb, ea))
            ca, cb = unaligned(a), unaligned(b)
            expect(cb <= ca * 1.05, "%s: camera centres %.6g from the truth's, pycolmap's %.6g" % (name, cb, ca))
            print("PASS %s: %d images, %d points (pycolmap %d), %.6f px (pycolmap %.6f), centres %.4g from the "
                  "truth unaligned (pycolmap %.4g)" % (name, b.num_reg_images(), b.num_points3D(), a.num_points3D(),
                                                      eb, ea, cb, ca))


def same_model(a, b):
    """Whether two ColmapModels read of a Reconstruction hold the same bits: images (their
    keypoints and points), points and tracks."""
    pa, pb = a.points3D, b.points3D
    return (len(a.images) == len(b.images) and
            all(x.id == y.id and x.points2D.tobytes() == y.points2D.tobytes() and
                x.point3D_ids.tobytes() == y.point3D_ids.tobytes() for x, y in zip(a.images, b.images)) and
            all(getattr(pa, f).tobytes() == getattr(pb, f).tobytes()
                for f in ("ids", "xyz", "track_offsets", "track_image_ids", "track_point2D_idxs")))


def read_cache(pycolmap, pysba):
    """The mapping's cache of what it read (an image's keypoints are read whole once, a track
    again only where it changed, a part's image's observations again only when its keypoints
    changed): the model read through it is the model read without, bit for bit, after tracks
    grow, change at the same length, change and grow, and points go and come, and after an
    image's observations change; a grown track is read on from the cache's entry, and an
    unchanged track or image taken from it."""
    import numpy as np
    from pysba import _colmap
    rec = scene(pycolmap, "rigs", 6)
    plain, cache = _colmap._from_reconstruction(rec), _colmap._ReadCache()
    cached = _colmap._from_reconstruction(rec, cache)
    expect(same_model(plain, cached) and len(plain.images) > 0, "the cached read differs from the plain one")
    posed = [im.image_id for im in rec.images.values() if im.has_pose]
    expect(sorted(cache.keypoints) == sorted(posed) and
           all(len(cache.keypoints[i]) == rec.images[i].num_points2D() for i in posed),
           "the cache does not hold every keypoint of every image")
    expect(sorted(cache.tracks) == sorted(rec.points3D), "the cache does not hold every track")
    # Keypoints that observe no point (the scene's deleted observations), to observe with.
    free = [(i, k) for i in posed for k in range(rec.images[i].num_points2D())
            if not rec.images[i].point2D(k).has_point3D()]
    expect(len(free) >= 6, "the scene has %d free keypoints, 6 wanted" % len(free))
    ids = sorted(rec.points3D)
    grown, same_length, changed, gone, kept = ids[:5]
    grown_entry = cache.tracks[grown]

    def observe(point_id):
        rec.add_observation(point_id, pycolmap.TrackElement(*free.pop()))

    def drop_first(point_id):
        e = rec.points3D[point_id].track.elements[0]
        rec.delete_observation(e.image_id, e.point2D_idx)

    observe(grown)
    drop_first(same_length)
    observe(same_length)
    drop_first(changed)
    observe(changed)
    observe(changed)
    rec.delete_point3D(gone)
    new = rec.add_point3D(np.array([0.5, 0.25, 4.0]), pycolmap.Track())
    observe(new)
    observe(new)
    again = _colmap._from_reconstruction(rec, cache)
    expect(same_model(again, _colmap._from_reconstruction(rec)), "after tracks changed, the cached read differs "
           "from the plain one")
    expect(cache.tracks[grown] is grown_entry, "a grown track was read again from its start")
    expect(gone not in cache.tracks and new in cache.tracks, "the cache keeps a deleted point or lacks a new one")
    # An unchanged track is the cache's: its entry, its first two elements swapped, is what a
    # read gives.
    for column in cache.tracks[kept][1:]:
        column[0], column[1] = column[1], column[0]
    expect(not same_model(_colmap._from_reconstruction(rec, cache), again),
           "an unchanged track was read again, not taken from the cache")
    first = again.images[0]
    cache.keypoints[first.id] = cache.keypoints[first.id] + 0.25
    shifted = _colmap._from_reconstruction(rec, cache)
    expect(np.array_equal(shifted.images[0].points2D, first.points2D + 0.25) and len(first.points2D) > 0,
           "a second read does not take the cache's keypoints")
    # A part's read (a local adjustment's few images): an image's observations are read again
    # only when its keypoints changed.
    some = sorted((i for i in posed if any(not rec.images[i].point2D(k).has_point3D()
                                           for k in range(rec.images[i].num_points2D()))), reverse=True)[:1]
    some += [i for i in posed if i not in some][:1]
    part, part_cache = (some, [], []), _colmap._ReadCache()

    def part_read(through):
        return _colmap._read_reconstruction(rec, through, part, appearance=False)

    (read_first, held), (plain_first, plain_held) = part_read(part_cache), part_read(None)
    expect(len(some) == 2 and same_model(read_first, plain_first) and held == plain_held and
           sorted(part_cache.observations) == sorted(some), "a part's cached read differs from the plain one")
    image = rec.images[some[0]]
    keypoint = next(k for k in range(image.num_points2D()) if not image.point2D(k).has_point3D())
    unseen = next(i for i in ids[5:] if some[0] not in [e.image_id for e in rec.points3D[i].track.elements])
    rec.add_observation(unseen, pycolmap.TrackElement(some[0], keypoint))
    (read_again, held), (plain_again, plain_held) = part_read(part_cache), part_read(None)
    expect(same_model(read_again, plain_again) and held == plain_held and not same_model(read_again, plain_first),
           "after an image's observations changed, a part's cached read differs from the plain one")
    # An unchanged image's observations are the cache's: its entry, two points swapped, is what
    # a read gives.
    points_seen = part_cache.observations[some[1]][2]
    points_seen[[0, 1]] = points_seen[[1, 0]]
    expect(not same_model(part_read(part_cache)[0], plain_again),
           "an unchanged image's observations were read again, not taken from the cache")
    # The least recently read images dropped beyond the cache's bound, the read the same.
    bounded = _colmap._ReadCache()
    bounded.OBSERVED_IMAGES = 1
    expect(same_model(part_read(bounded)[0], plain_again) and list(bounded.observations) == [max(some)],
           "a cache bounded to one image holds %s" % list(bounded.observations))
    # A mapper's images' keypoints, read from its database: the bits of its images' own.
    import tempfile
    with tempfile.TemporaryDirectory(prefix="pysba-keypoints-") as d:
        database = os.path.join(d, "database.db")
        synthesized_database(pycolmap, database, 3, 1, 6, 100)
        db = pycolmap.Database.open(database)
        try:
            images = pycolmap.DatabaseCache.create(db, pycolmap.DatabaseCacheOptions()).images
        finally:
            db.close()
        from_database = _colmap._ReadCache(database)
        try:
            same = all(from_database.keypoints_of(i, im).tobytes() ==
                       np.array([p.xy for p in im.points2D], np.float64).reshape(-1, 2).tobytes()
                       for i, im in images.items())
            expect(len(images) == 6 and same, "the keypoints read from the database are not the mapper's images' bits")
            # Taken from the database, not the image: an image of as many keypoints, all zero.
            i, im = next(iter(images.items()))
            from_database.keypoints.clear()
            blank = pycolmap.Image(name="blank", keypoints=np.zeros((im.num_points2D(), 2)))
            expect(from_database.keypoints_of(i, blank).tobytes() ==
                   np.array([p.xy for p in im.points2D], np.float64).reshape(-1, 2).tobytes(),
                   "the keypoints were not read from the database")
        finally:
            from_database.close()
    print("PASS the read cache: the same model after tracks grew, changed and came and went; %d images' "
          "keypoints read once (a mapper's from its database, the same bits), grown tracks read on, unchanged "
          "ones taken from the cache, a part's unchanged images' observations too" % len(cache.keypoints))


def refusals(pycolmap, pysba):
    rec = scene(pycolmap, "simple_radial", 3)
    before = state(rec)
    o = options_with(pycolmap)
    # pycolmap keeps Ceres's enums in its pyceres submodule: reached through a value's type.
    o.ceres.solver_options.minimizer_type = type(o.ceres.solver_options.minimizer_type).LINE_SEARCH
    cases = [(o, None, "options.ceres.solver_options.minimizer_type = LINE_SEARCH is not honoured by sba "
                       "(only TRUST_REGION)")]
    o = options_with(pycolmap)
    o.ceres.solver_options.use_inner_iterations = True
    cases.append((o, None, "options.ceres.solver_options.use_inner_iterations = True is not honoured by sba "
                           "(only False, its default, is)"))
    o = options_with(pycolmap)
    o.ceres.solver_options.initial_trust_region_radius = 1.0
    cases.append((o, None, "options.ceres.solver_options.initial_trust_region_radius = 1.0 is not honoured by "
                           "sba (only 10000.0, its default, is)"))
    config = pycolmap.BundleAdjustmentConfig()
    config.add_image(10 ** 6)
    cases.append((options_with(pycolmap), config, "images[0]: no image with a pose has the IMAGE_ID '1000000'"))
    for options, config, message in cases:
        try:
            pysba.colmap.bundle_adjustment(rec, options, config)
            expect(False, "refused options were taken: " + message)
        except ValueError as e:
            expect(str(e) == message, "message %r, not %r" % (str(e), message))
    expect(state(rec) == before, "a refused call changed the reconstruction")
    # How Ceres solves each step changes no result.
    o = options_with(pycolmap)
    o.ceres.solver_options.linear_solver_type = type(o.ceres.solver_options.linear_solver_type).DENSE_SCHUR
    o.ceres.use_gpu = True
    a, b = pycolmap.Reconstruction(rec), pycolmap.Reconstruction(rec)
    pysba.colmap.bundle_adjustment(a, o)
    pysba.colmap.bundle_adjustment(b, options_with(pycolmap))
    expect(state(a) == state(b), "Ceres's linear solver and device changed sba's result")
    print("PASS options sba does not honour are refused by name, the reconstruction untouched; Ceres's choice "
          "of linear solver and device leaves the result as it is")


def main(argv):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--python", default="", help="a Python with pycolmap, used when this one has none")
    args = ap.parse_args(argv)
    if os.environ.get("PYSBA_SANITIZED"):
        print("pycolmap_bundle_adjustment: SKIPPED: a sanitizer build (pycolmap is not built with the sanitizers)")
        return SKIP
    try:
        import pycolmap
    except ImportError as e:
        if args.python and not os.environ.get(REEXEC) and os.access(args.python, os.X_OK):
            os.environ[REEXEC] = "1"
            os.execv(args.python, [args.python, os.path.abspath(__file__)] + argv)
        print("pycolmap_bundle_adjustment: SKIPPED: %s cannot import pycolmap (%s); scripts/deps.sh test makes a "
              "venv with it" % (sys.executable, e))
        return SKIP
    try:
        import pysba
        import pysba.colmap  # noqa: F401
    except ImportError as e:
        print("pycolmap_bundle_adjustment: SKIPPED: %s (Python %s) has pycolmap but cannot import pysba: %s"
              % (sys.executable, sys.version.split()[0], e))
        return SKIP
    print("pycolmap %s, pysba %s, Python %s" % (pycolmap.__version__, pysba.__file__, sys.version.split()[0]))
    try:
        against_pycolmap(pycolmap, pysba)
        points_behind(pycolmap, pysba)
        pose_priors(pycolmap, pysba)
        part_read(pycolmap, pysba)
        mapper_global(pycolmap, pysba)
        mapper_local(pycolmap, pysba)
        pipeline_bits(pycolmap, pysba)
        mapping(pycolmap, pysba)
        mapping_with_priors(pycolmap, pysba)
        read_cache(pycolmap, pysba)
        refusals(pycolmap, pysba)
    except Failure as f:
        print("FAIL %s" % f)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
