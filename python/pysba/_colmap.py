# SPDX-License-Identifier: BSD-3-Clause
"""COLMAP sparse models in pysba: read, written and refined by the sbarefine program's own
code (the C++ reader and writer, COLMAP's camera models, sbarefine's solve), and converted
to and from pycolmap. The functions and classes are pysba's (see its __init__)."""
from __future__ import annotations

import collections.abc
import copy
import dataclasses
import errno
import math
import numbers
import os
import sys
import tempfile
from typing import Any, Callable, Dict, List, Optional, Sequence, Tuple

import numpy as np

from . import Progress, Result, _core, _finish, _options

NO_POINT3D: int = 2**64 - 1
"""The POINT3D_ID of a keypoint that observes no 3D point (-1 in COLMAP's text files)."""


@dataclasses.dataclass(eq=False)
class ColmapCamera:
    """A COLMAP camera: ``id`` (CAMERA_ID), ``model`` (COLMAP's name: "SIMPLE_PINHOLE",
    "PINHOLE", "OPENCV", ...: all eighteen), ``width`` and ``height`` in pixels, ``params`` in
    COLMAP's order (a float array: f cx cy, fx fy cx cy k1 k2 p1 p2, ...)."""

    id: int
    model: str
    width: int
    height: int
    params: np.ndarray


@dataclasses.dataclass(eq=False, repr=False)
class ColmapImage:
    """A COLMAP image: ``id`` (IMAGE_ID), ``name``, ``camera_id``, its pose ``q`` (qw qx qy qz)
    and ``t``, world to camera (X_cam = R(q) X + t; in a model with rigs and frames, derived from
    its frame: see :class:`ColmapModel`), and its keypoints: ``points2D`` (k, 2) in
    pixels and ``point3D_ids`` (k,) uint64, the 3D point each one observes, or
    :data:`NO_POINT3D` (-1 is taken for it too). ``q`` and ``t`` are both None for an image of a
    frame without a pose (see :class:`ColmapFrame`), which observes no point."""

    id: int
    name: str
    camera_id: int
    q: Optional[np.ndarray]
    t: Optional[np.ndarray]
    points2D: np.ndarray
    point3D_ids: np.ndarray

    def __repr__(self) -> str:
        return (f"ColmapImage(id={self.id}, name={self.name!r}, camera_id={self.camera_id}, "
                f"points2D={len(self.points2D)})")


@dataclasses.dataclass(eq=False, repr=False)
class ColmapPoints3D:
    """A model's 3D points as arrays, one row per point: ``ids`` (n,) uint64 (POINT3D_ID),
    ``xyz`` (n, 3), ``rgb`` (n, 3) uint8, ``error`` (n,) (the mean reprojection error in
    pixels), and their tracks: point k is seen by keypoint ``track_point2D_idxs[e]`` of the
    image ``track_image_ids[e]`` for e in ``track_offsets[k]:track_offsets[k + 1]`` (both
    uint32; track_offsets (n + 1,) rises from 0 to the number of track elements)."""

    ids: np.ndarray
    xyz: np.ndarray
    rgb: np.ndarray
    error: np.ndarray
    track_offsets: np.ndarray
    track_image_ids: np.ndarray
    track_point2D_idxs: np.ndarray

    def __len__(self) -> int:
        return len(self.ids)

    def track(self, k: int) -> Tuple[np.ndarray, np.ndarray]:
        """Point k's track (k a row, not an id): its image ids and their keypoint indices."""
        lo, hi = self.track_offsets[k], self.track_offsets[k + 1]
        return self.track_image_ids[lo:hi], self.track_point2D_idxs[lo:hi]

    def __repr__(self) -> str:
        return f"ColmapPoints3D({len(self)} points, {len(self.track_image_ids)} track elements)"


@dataclasses.dataclass(eq=False)
class ColmapSensor:
    """A sensor of a rig: ``type`` ("CAMERA" or "IMU"), ``id`` (a camera's CAMERA_ID), and its
    pose in the rig ``q``, ``t`` (sensor_from_rig), both None when it has none (the rig's
    reference sensor, first in its rig, never has one)."""

    type: str
    id: int
    q: Optional[np.ndarray] = None
    t: Optional[np.ndarray] = None


@dataclasses.dataclass(eq=False)
class ColmapRig:
    """A rig (COLMAP 4): ``id`` and its ``sensors``, the reference sensor first."""

    id: int
    sensors: List[ColmapSensor]


@dataclasses.dataclass(eq=False)
class ColmapFrame:
    """A frame (COLMAP 4), one pose of a rig: ``id``, ``rig_id``, the pose ``q``, ``t``
    (rig_from_world) and its ``data``, one ``(type, sensor_id, data_id)`` per measurement (a
    camera's data_id is the IMAGE_ID of its image).

    ``q`` and ``t`` are both None for a frame without a pose, which a pycolmap.Reconstruction
    holds (a frame not registered, or deregistered) and COLMAP's files do not; its images have
    none either. Such frames and their images are kept where they are, but neither written by
    :func:`write_colmap`, as COLMAP writes none, nor refined by :func:`refine_colmap`."""

    id: int
    rig_id: int
    q: Optional[np.ndarray]
    t: Optional[np.ndarray]
    data: List[Tuple[str, int, int]]


class ColmapModel:
    """A COLMAP sparse model: ``cameras`` (a list of :class:`ColmapCamera`), ``images`` (of
    :class:`ColmapImage`), ``points3D`` (a :class:`ColmapPoints3D`), and ``rigs`` and
    ``frames`` (lists of :class:`ColmapRig` and :class:`ColmapFrame`, or both None for a model
    without them, as COLMAP 3 wrote them), each in file order with every field of the files.

    With rigs and frames an image's pose is derived, as COLMAP 4 derives it: its frame's
    rig_from_world composed with its camera's pose in the rig. read_colmap and refine_colmap
    give each image that pose (the images file's own bits where they are that pose but for
    rounding, as COLMAP writes them); write_colmap and refine_colmap derive it again from the
    frame whatever the image's q and t hold, and refine_colmap writes its result to the frames
    and rigs. To move an image of a rig, change its frame's pose (or its camera's in the rig):
    its q and t are read-only in effect. A model is
    checked when it is written or refined, as the reader checks files: ValueError or
    TypeError with the message naming the record (``images[3].q``, ``model: image 7 uses
    camera 9, which cameras does not hold``)."""

    def __init__(self, cameras: Sequence[ColmapCamera] = (), images: Sequence[ColmapImage] = (),
                 points3D: Optional[ColmapPoints3D] = None, rigs: Optional[List[ColmapRig]] = None,
                 frames: Optional[List[ColmapFrame]] = None):
        self.cameras = list(cameras)
        self.images = list(images)
        if points3D is None:
            points3D = ColmapPoints3D(np.zeros(0, np.uint64), np.zeros((0, 3)), np.zeros((0, 3), np.uint8),
                                      np.zeros(0), np.zeros(1, np.uint64), np.zeros(0, np.uint32),
                                      np.zeros(0, np.uint32))
        self.points3D = points3D
        self.rigs = rigs
        self.frames = frames

    def __repr__(self) -> str:
        more = "" if self.rigs is None else f", rigs={len(self.rigs)}, frames={len(self.frames or ())}"
        return (f"ColmapModel(cameras={len(self.cameras)}, images={len(self.images)}, "
                f"points3D={len(self.points3D)}{more})")


def _model(d: dict) -> ColmapModel:
    """The ColmapModel of _core's plain values."""
    rigs = frames = None
    if d["rigs"] is not None:
        rigs = [ColmapRig(rig_id, [ColmapSensor(kind, sensor_id, *(pose or (None, None)))
                                   for kind, sensor_id, pose in sensors])
                for rig_id, sensors in d["rigs"]]
        frames = [ColmapFrame(frame_id, rig_id, q, t, data) for frame_id, rig_id, (q, t), data in d["frames"]]
    return ColmapModel([ColmapCamera(*c) for c in d["cameras"]], [ColmapImage(*im) for im in d["images"]],
                       ColmapPoints3D(*d["points3D"]), rigs, frames)


def _path(path: Any) -> bytes:
    """path in the file system's encoding, as _readable in __init__ gives it."""
    if not isinstance(path, (str, bytes, os.PathLike)):
        raise TypeError(f"path must be a str, bytes or os.PathLike, got {type(path).__name__}")
    return os.fsencode(path)


def _directory(path: Any) -> bytes:
    """_path(path), after making sure it is a directory: FileNotFoundError,
    NotADirectoryError or PermissionError otherwise."""
    encoded = _path(path)
    # Looked at as given, so that an error names the path as the caller wrote it.
    os.stat(path)
    if not os.path.isdir(encoded):
        raise NotADirectoryError(errno.ENOTDIR, os.strerror(errno.ENOTDIR), os.fsdecode(encoded))
    return encoded


def _check_model(model: Any) -> None:
    if not isinstance(model, ColmapModel):
        raise TypeError(f"model must be a pysba.ColmapModel, got {type(model).__name__}")


def _is_reconstruction(model: Any) -> bool:
    """Whether model is a pycolmap.Reconstruction, without importing pycolmap."""
    kind = type(model)
    return kind.__name__ == "Reconstruction" and kind.__module__.split(".")[0] == "pycolmap"


def _as_model(model: Any) -> ColmapModel:
    """model as a ColmapModel: itself, or a pycolmap.Reconstruction's conversion."""
    if _is_reconstruction(model):
        return from_pycolmap(model)
    if not isinstance(model, ColmapModel):
        path = isinstance(model, (str, bytes, os.PathLike))
        raise TypeError(f"model must be a pysba.ColmapModel or a pycolmap.Reconstruction, got {type(model).__name__}"
                        + (" (pysba.read_colmap(path) reads the model in a folder)" if path else ""))
    return model


def read_colmap(path: Any) -> ColmapModel:
    """Reads the COLMAP sparse model in the directory path: cameras, images and points3D,
    and rigs and frames when they are there, binary (.bin) or text (.txt; binary first when
    both are there, as COLMAP reads them). OSError for files that cannot be read (or no
    model), ValueError with the reader's ``file:line: message`` (text) or ``file: byte N:
    message`` (binary) for bad content or a model whose files disagree."""
    return _model(_core.read_colmap(_directory(path)))


def write_colmap(model: Any, path: Any, encoding: str = "binary") -> None:
    """Writes the model (a :class:`ColmapModel`, or a pycolmap.Reconstruction, converted by
    :func:`from_pycolmap`) into the directory path (made if missing), as sbarefine writes one:
    cameras, images and points3D, and rigs and frames when the model has them, in the
    encoding ("binary" or "text"), all files or none. The other encoding's model files in
    path are removed, and so are this encoding's rigs and frames when the model has none, so
    that path holds one model. ValueError or TypeError for a model the reader would refuse
    (see :class:`ColmapModel`), OSError for files that cannot be written."""
    model = _as_model(model)
    if not isinstance(encoding, str):
        raise TypeError(f"encoding must be a str, got {type(encoding).__name__}")
    _core.write_colmap(model, _path(path), encoding)


def _hold_items(name: str, given: Any, wanted: str) -> Tuple[bool, List[Any]]:
    """A hold_* argument as (every one, its items, unchecked): "all", or an iterable; wanted
    says what the caller takes, for the messages."""
    if isinstance(given, str):
        if given != "all":
            raise ValueError(f"{name} must be 'all' or a list of {wanted}, got {given!r}")
        return True, []
    # bytes iterate as small ints and a mapping as its keys: read as lists, both would name
    # images or ids their caller never meant.
    items = None
    if not isinstance(given, (bytes, bytearray, memoryview, collections.abc.Mapping)):
        try:
            items = list(given)
        except TypeError:
            pass
    if items is None:
        raise TypeError(f"{name} must be 'all' or a list of {wanted}, got {type(given).__name__}")
    return False, items


def _is_id(item: Any) -> bool:
    # A float or a bool is not an id, even one that holds an integer.
    return isinstance(item, numbers.Integral) and not isinstance(item, (bool, np.bool_))


def _held_images(hold_poses: Any) -> Tuple[bool, List[Any]]:
    """hold_poses checked for its types, as (every image, the items: ints and strs); the
    library looks the items up, by the one rule of every list of images."""
    if hold_poses is None:
        return False, []
    every, items = _hold_items("hold_poses", hold_poses, "IMAGE_IDs (ints) and NAMEs (strs)")
    for k, item in enumerate(items):
        if not isinstance(item, str) and not _is_id(item):
            raise TypeError(f"hold_poses[{k}] must be an IMAGE_ID (int) or a NAME (str), got "
                            f"{type(item).__name__}")
    return every, [item if isinstance(item, str) else int(item) for item in items]


def _held_ids(name: str, kind: str, given: Any) -> Tuple[bool, List[int]]:
    """A hold_* list of identifiers (kind: "CAMERA_IDs", "POINT3D_IDs") checked for its types, as
    (every one, the ids); the library looks the ids up, as sbarefine's --hold-* lists."""
    if given is None:
        return False, []
    if isinstance(given, np.ndarray) and given.ndim == 1 and np.issubdtype(given.dtype, np.integer):
        return False, given.tolist()
    every, items = _hold_items(name, given, f"{kind} (ints)")
    for k, item in enumerate(items):
        if not _is_id(item):
            article = "an" if kind[0] in "AEIOU" else "a"
            raise TypeError(f"{name}[{k}] must be {article} {kind[:-1]} (int), got {type(item).__name__}")
    return every, [int(item) for item in items]


_GAUGES = {None: "", "two-cams": "two-cams", "three-points": "three-points"}


def _config(model: ColmapModel, hold_frames: Any, images: Any, variable_points: Any, min_track_length: Any,
            refine_points3D: Any, gauge: Any) -> dict:
    """refine_colmap's BundleAdjustmentConfig arguments, checked for their types, as _core takes
    them (the library looks the ids up)."""
    every, frames = _held_ids("hold_frames", "FRAME_IDs", hold_frames)
    if every:
        frames = [f.id for f in model.frames or () if f.q is not None]
    every, points = _held_ids("variable_points", "POINT3D_IDs", variable_points)
    if every:
        points = model.points3D.ids.tolist()
    out = dict(hold_frames=frames, variable_points=points)
    if images is not None:
        every, ids = _held_ids("images", "IMAGE_IDs", images)
        out["images"] = [im.id for im in model.images if im.q is not None] if every else ids
    if isinstance(min_track_length, (bool, np.bool_)) or not isinstance(min_track_length, numbers.Integral):
        raise TypeError(f"min_track_length must be an int, got {type(min_track_length).__name__}")
    out["min_track_length"] = max(int(min_track_length), 0) if int(min_track_length) < 2**31 else 2**31 - 1
    if not isinstance(refine_points3D, (bool, np.bool_)):
        raise TypeError(f"refine_points3D must be a bool, got {type(refine_points3D).__name__}")
    out["refine_points3D"] = bool(refine_points3D)
    if not isinstance(gauge, (str, type(None))) or gauge not in _GAUGES:
        raise ValueError(f"gauge must be None, 'two-cams' or 'three-points', got {gauge!r}")
    out["gauge"] = _GAUGES[gauge]
    return out


def _colmap_stop(strategy: Any, opts: Any, function_tolerance: Any, gradient_tolerance: Any) -> Tuple[Any, Any]:
    """strategy and opts as sbarefine sets them for a COLMAP model, by COLMAP's stopping rule
    (the library's colmap_stop_rule: a function tolerance sets eps4 and, unless a strategy is
    given, the trust-region strategy; without one, COLMAP's default 0 holds unless a strategy
    or an eps4 is given; a gradient tolerance sets eps1, and without one COLMAP 4's 1e-4 holds
    where the rule does, unless opts give an eps1 of their own). opts that are not 5 values go
    on as given, for _core to say what is wrong with them."""
    values = None
    if opts is not None and not isinstance(opts, (str, bytes)):
        try:
            values = list(opts)
        except TypeError:
            pass
    if opts is not None and (values is None or len(values) != 5):
        return strategy, opts
    for name, tolerance in (("function_tolerance", function_tolerance), ("gradient_tolerance", gradient_tolerance)):
        if tolerance is not None and not (0 <= _real(name, tolerance) < math.inf):
            raise ValueError(f"{name} must be finite and >= 0, got {tolerance}")
    defaults = [1e-3, 1e-12, 1e-12, 1e-12, 0.0]  # sba's opts
    values = values if values is not None else list(defaults)
    eps = {}
    for k, tolerance in ((1, gradient_tolerance), (4, function_tolerance)):
        eps[k] = values[k]
        if not isinstance(eps[k], numbers.Real):
            if tolerance is None:
                return strategy, opts  # given, and _core says what is wrong with it
            eps[k] = defaults[k]  # replaced by the tolerance
    rule, values[1], values[4] = _core.colmap_stop_rule(
        -1.0 if function_tolerance is None else float(function_tolerance),
        -1.0 if gradient_tolerance is None else float(gradient_tolerance),
        strategy is not None, float(eps[1]), float(eps[4]))
    if rule is None and gradient_tolerance is None:
        return strategy, opts
    return (strategy if strategy is not None else rule), values


def refine_colmap(model: Any, *, refine_focal_length: bool = True, refine_principal_point: bool = False,
                  refine_extra_params: bool = True, refine_rig_from_world: bool = True,
                  refine_sensor_from_rig: bool = True, constant_rig_from_world_rotation: bool = False,
                  hold_poses: Any = None, hold_intrinsics: Any = None, hold_sensor_from_rig: Any = None,
                  hold_points: Any = None, solver: Optional[str] = None, threads: int = 0,
                  strategy: Optional[str] = None, loss: Optional[str] = None,
                  loss_scale: float = 1.0, itmax: int = 100, opts: Optional[Sequence[float]] = None,
                  function_tolerance: Optional[float] = None, gradient_tolerance: Optional[float] = None,
                  mcon: int = 0, ncon: int = 0,
                  progress: Optional[Callable[[Progress], Any]] = None, verbose: bool = False,
                  covariance: bool = False, covariance_points: bool = False,
                  covariance_damping: float = 1e-8, pose_priors: Any = None,
                  prior_position_fallback_stddev: float = 1.0, prior_position_loss: str = "trivial",
                  prior_position_loss_scale: float = 2.7954834829151074,
                  alignment_max_error: float = 0.0, in_place: bool = False, hold_frames: Any = None,
                  images: Any = None, variable_points: Any = None, min_track_length: int = 0,
                  refine_points3D: bool = True, gauge: Optional[str] = None,
                  point_errors: bool = True, remove_behind: bool = True) -> Tuple[Any, Result]:
    """Bundle-adjusts a COLMAP model as sbarefine does (the same numbers, bit for bit, as
    ``sbarefine MODEL --write OUT`` with the same options), with COLMAP's camera models and
    COLMAP's defaults, and returns ``(refined model, Result)``; the model is left unchanged.
    model is a :class:`ColmapModel` or a pycolmap.Reconstruction. A Reconstruction is read
    through pycolmap's API, in memory (no file: its cameras, rigs, frames, poses, points and
    the keypoints that observe them), and the refined values are written into a copy of it
    (pycolmap.Reconstruction(model)), returned; with ``in_place=True`` into the given
    Reconstruction itself, returned: its refined frame poses, poses in rigs, intrinsics, and
    points' coordinates and errors, everything else (ids, tracks, keypoints, colors, names,
    what was held) untouched. The values are those of refining the files pycolmap writes of
    it, bit for bit.

    Every image that sees a point is refined (its pose), with its camera's parameters: a camera
    shared by several images once for all of them; every 3D point is refined, and its
    ``error`` becomes its mean reprojection error. An image that sees no point is left as it
    is. With rigs and frames, as COLMAP 4 refines them: a frame's pose (rig_from_world) once
    for its images, a camera's pose in its rig (sensor_from_rig) once for all the frames of the
    rig (the rig's reference camera at the identity), written back to the frames and the rigs
    and composed into the images (an image that sees no point too: it keeps its place in its
    frame, and moves with it unless it is held). A frame without a pose (not registered, see
    :class:`ColmapFrame`) and its images are left out of the solve and given back as they were.

    refine_focal_length, refine_principal_point, refine_extra_params
        COLMAP's bundle adjustment options (the focal length and the parameters after the
        principal point refined, the principal point held, by default).
    hold_poses
        Images whose pose is held (COLMAP's constant poses): "all", or a list of IMAGE_IDs
        (ints) and NAMEs (strs, every image of that name); an item that names no image is a
        ValueError; bytes and dicts are TypeErrors, not lists of their bytes or keys. With rigs
        and frames, holding an image (one that sees no point too) holds its frame's pose and
        its camera's pose in the rig, so that it comes back as read.
    hold_intrinsics, hold_sensor_from_rig, hold_points
        COLMAP's other constants, as sbarefine's --hold-intrinsics, --hold-sensor-from-rig and
        --hold-points: "all", or a list of ids (ints): CAMERA_IDs whose every parameter is held,
        in all their images; CAMERA_IDs whose pose in their rig is held, for all the frames (a
        rig's reference camera is at the identity, held anyway; nothing without rigs); POINT3D_IDs
        whose coordinates are held (with ncon, the points of both). An id the model does not have
        is a ValueError (``hold_points[2]: no point has the POINT3D_ID '5'``); bools, floats,
        bytes and dicts are TypeErrors.
    itmax, function_tolerance, gradient_tolerance
        COLMAP's max_num_iterations (100) and function_tolerance (Ceres's relative cost
        change; None: COLMAP's 0, unless strategy or opts[4] is given, which then keep sba's
        tests). A tolerance sets opts[4] to it (at least 4 ulp) and the strategy, unless
        given, to "trust-region". gradient_tolerance (Ceres's: the largest entry of the
        gradient J^T e) sets opts[1]; None: COLMAP 4's 1e-4 where COLMAP's rule holds, unless
        opts give an eps1 other than sba's 1e-12. itmax 0 returns the model as given.
    strategy, solver
        As :func:`solve`'s, but strategy None runs "trust-region" (COLMAP's
        Levenberg-Marquardt), whatever $SBA_STRATEGY says, unless opts[4] is given without
        function_tolerance: then solve()'s default ($SBA_STRATEGY, else "sba"). solver None:
        $SBA_LINSOLVER, else "auto", as solve()'s.
    mcon, ncon
        The first mcon images that see a point (their cameras' parameters too, in all their
        images) and the first ncon points are held.

    hold_frames, images, variable_points, min_track_length, refine_points3D, gauge
        The rest of COLMAP 4's BundleAdjustmentConfig and options, as its bundle adjuster takes
        them (:func:`pysba.colmap.bundle_adjustment` passes pycolmap's on). hold_frames: "all",
        or FRAME_IDs (ints) whose pose (rig_from_world) alone is held, their cameras' poses in
        the rigs refined as the options say. images: None (every image), or the IMAGE_IDs (ints)
        of the images whose observations are refined, each with its pose, its camera's pose in
        its rig and its intrinsics; an image outside them has its pose held, and its camera's
        pose in the rig and intrinsics too unless one of them refines it. variable_points:
        POINT3D_IDs refined with every observation of theirs, in any image; hold_points (COLMAP's
        constant points) are held with their observations in the images and in any image that
        has something refined. Any other point that the images see is refined when its whole
        track is in them, held otherwise. A point whose track is shorter than min_track_length
        is left out (and left as it is). refine_points3D=False holds every point. gauge: None,
        "two-cams" (COLMAP's TWO_CAMS_FROM_WORLD: the images by IMAGE_ID, the first one's frame
        pose held and one coordinate of the next one's frame translation, the one along which
        its centre lies farthest from the first one's, unless two images' poses are held
        already; three points when no two images can be) or "three-points" (the points seen by
        the most observations held until three are). An id the model does not have is a
        ValueError.
    point_errors
        True: every refined point's ``error`` becomes its mean reprojection error, as
        sbarefine writes it; False: the points keep the errors they had, as COLMAP's bundle
        adjusters leave them (:func:`pysba.colmap.bundle_adjustment`), and the refinement
        saves a pass over the observations.
    remove_behind
        True: the observations whose point is behind its image's camera (its depth there
        below the epsilon of doubles) are removed from the model before the solve, and a point
        left with fewer than two observations with them, as COLMAP's bundle_adjuster and
        pycolmap.bundle_adjustment remove them (and sbarefine); the result's model is without
        them (with in_place=True, the Reconstruction given too), and ``Result.behind`` lists
        them as (IMAGE_ID, POINT2D_IDX). False: they stay, and cost nothing, as in COLMAP's
        cost (pycolmap's bundle adjusters that take a configuration keep them so).
    progress, verbose
        progress, as :func:`solve`'s, is called with a :class:`Progress` after every iteration
        (its ``error`` is the sum of squared reprojection errors, in pixels squared: the RMS
        is sqrt(error / observations)); a true return value stops the solve, an exception
        stops it and propagates. verbose=True shows the progress on sys.stderr: the
        problem's size, a line per iteration (the RMS reprojection error in pixels, or the
        cost with a robust loss) and the end, whatever progress does.

    covariance, covariance_points, covariance_damping
        covariance=True also computes, at the result, the covariances sbarefine's --covariance
        writes (docs/formats.md, "Covariances"): the Result's ``colmap_covariance``, a dict
        with ``images`` ({IMAGE_ID: (k, k) array}, each image's cam_from_world; with rigs also
        ``frames`` {FRAME_ID: ...}, rig_from_world, and ``sensors`` {CAMERA_ID: ...},
        sensor_from_rig), ``cameras`` ({CAMERA_ID: array} over its refined
        parameters), ``points`` ({POINT3D_ID: (3, 3) array}, marginal, with covariance_points),
        ``coords`` (for each of those kinds, {id: the block's coordinates}: "rx".."tz", a
        camera's parameter indices, "x" "y" "z"), ``sigma2``, ``rank`` and ``nfree``. The
        blocks are pycolmap's estimate_ba_covariance's: (J^T J)^-1 for unit pixel noise (times
        sigma2 for the model's), poses over [rotation, translation] with COLMAP's rotation
        tangent, held coordinates left out, a block all of whose coordinates are held left out
        (a held pose, held intrinsics). covariance_damping (sbarefine's --covariance-damping)
        is added to each point's block of J^T J first, as pycolmap's
        BACovarianceOptions.damping, whose default it shares (0: (J^T J)^-1 itself). A covariance the library refuses (a point its
        projections do not determine) raises SolveError with the result.

    pose_priors, prior_position_fallback_stddev, prior_position_loss, prior_position_loss_scale,
    alignment_max_error
        COLMAP 4's pose-prior bundle adjustment, as sbarefine's --database-path (docs/priors.md):
        pose_priors is the path of COLMAP's database (its pose_priors table), or a sequence of
        position priors, each a pycolmap.PosePrior (those of cameras: corr_data_id.id is the
        IMAGE_ID) or a dict with ``image_id``, ``position`` (3 values), optionally
        ``covariance`` (3 x 3) and ``coordinate_system`` ("CARTESIAN", the default, or
        "WGS84"). WGS84 positions become metres east, north and up of the first WGS84 prior,
        as COLMAP's database cache converts them. Priors of images the model does not hold, or
        that see no point, are left out. With at least 3, the model is moved onto them by a
        robust similarity (its inlier distance alignment_max_error, 0: three times the priors'
        RMS standard deviation) and on to the similarity at which the priors' cost is least,
        then refined with each image's projection centre drawn to its
        prior, weighted by its covariance (prior_position_fallback_stddev in each axis without
        one), with the loss prior_position_loss ("trivial" or "cauchy", of scale
        prior_position_loss_scale); the result is in the priors' frame, and its
        ``prior_cost_*`` and ``projection_cost_*`` are the two parts of the cost. With fewer,
        the model is refined as without priors. The Result's ``colmap_priors`` says which.

    A model whose reprojection error at the start is not finite (a parameter that overflows
    the projection) is a ValueError naming the first such observation's image, camera and point.

    The other arguments are :func:`solve`'s. The Result's ``model`` is the refined model, the
    one returned (a pycolmap.Reconstruction for one given; also on the ``result`` of a
    KeyboardInterrupt or SolveError: the last accepted estimate), ``rms_initial`` and
    ``rms_final`` are sbarefine's RMS reprojection errors in pixels, ``cameras`` and
    ``points`` the sba parameters (rotation, translation and the camera parameters refined,
    in COLMAP's order, of each image that sees a point; the points' coordinates).
    """
    reconstruction = _is_reconstruction(model)
    if not isinstance(in_place, (bool, np.bool_)):
        raise TypeError(f"in_place must be a bool, got {type(in_place).__name__}")
    if in_place and not reconstruction:
        raise TypeError(f"in_place=True refines a pycolmap.Reconstruction, got {type(model).__name__}")
    colmap_model = _from_reconstruction(model) if reconstruction else _as_model(model)
    flags = (("refine_focal_length", refine_focal_length),
             ("refine_principal_point", refine_principal_point),
             ("refine_extra_params", refine_extra_params),
             ("refine_rig_from_world", refine_rig_from_world),
             ("refine_sensor_from_rig", refine_sensor_from_rig),
             ("constant_rig_from_world_rotation", constant_rig_from_world_rotation))
    for name, flag in flags + (("verbose", verbose), ("covariance", covariance),
                               ("covariance_points", covariance_points), ("point_errors", point_errors),
                               ("remove_behind", remove_behind)):
        if not isinstance(flag, (bool, np.bool_)):
            raise TypeError(f"{name} must be a bool, got {type(flag).__name__}")
    hold_all, held = _held_images(hold_poses)
    constants = dict(hold_intrinsics=_held_ids("hold_intrinsics", "CAMERA_IDs", hold_intrinsics),
                     hold_sensor_from_rig=_held_ids("hold_sensor_from_rig", "CAMERA_IDs", hold_sensor_from_rig),
                     hold_points=_held_ids("hold_points", "POINT3D_IDs", hold_points))
    config = _config(colmap_model, hold_frames, images, variable_points, min_track_length, refine_points3D, gauge)
    strategy, opts = _colmap_stop(strategy, opts, function_tolerance, gradient_tolerance)
    if verbose:
        progress = _shown(colmap_model, loss not in (None, "none"), progress)
    kw = _options(solver, threads, strategy, loss, loss_scale, itmax, opts, mcon, ncon, progress,
                  covariance=bool(covariance))
    database_path, priors = _pose_priors(pose_priors)
    if prior_position_loss not in ("trivial", "cauchy"):
        raise ValueError(f"prior_position_loss must be 'trivial' or 'cauchy', got {prior_position_loss!r}")
    for name, value in (("prior_position_fallback_stddev", prior_position_fallback_stddev),
                        ("prior_position_loss_scale", prior_position_loss_scale)):
        if not (_real(name, value) > 0 and math.isfinite(value)):
            raise ValueError(f"{name} must be finite and > 0, got {value!r}")
    if not (_real("alignment_max_error", alignment_max_error) >= 0 and math.isfinite(alignment_max_error)):
        raise ValueError(f"alignment_max_error must be finite and >= 0, got {alignment_max_error!r}")
    report = _core.refine_colmap(colmap_model, hold_all, held, *(bool(flag) for _, flag in flags), **constants,
                                 covariance_points=bool(covariance_points),
                                 covariance_damping=float(covariance_damping), database_path=database_path,
                                 pose_priors=priors,
                                 prior_position_fallback_stddev=float(prior_position_fallback_stddev),
                                 prior_position_loss="" if prior_position_loss == "trivial" else "cauchy",
                                 prior_position_loss_scale=float(prior_position_loss_scale),
                                 alignment_max_error=float(alignment_max_error), point_errors=bool(point_errors),
                                 remove_behind=bool(remove_behind), **config, **kw)
    behind = report["behind"]
    # The Result's model, also on an exception's result, is of the type returned.
    if reconstruction:
        target = model if in_place else _pycolmap().Reconstruction(model)
        for image_id, point2D_idx in behind:  # pycolmap deletes a point left seen once with it
            target.delete_observation(image_id, point2D_idx)
        _write_into(target, _model(report["model"]), colmap_model, errors=bool(point_errors))
        report["model"] = target
    else:
        report["model"] = _with_unposed(_model(report["model"]), colmap_model)
    result = _finish(report)
    if verbose:
        print(f"refine_colmap: RMS {result.rms_initial:.6g} px -> {result.rms_final:.6g} px in {result.iterations} "
              f"iterations: {result.reason.text}", file=sys.stderr, flush=True)
    return result.model, result


_SYSTEMS = {"UNDEFINED": -1, "WGS84": 0, "CARTESIAN": 1}


def _real(name: str, value: Any) -> float:
    """value as a float, a TypeError naming it unless it is a real number (a bool is not)."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Real):
        raise TypeError(f"{name} must be a number, got {type(value).__name__}")
    return float(value)


def _pose_priors(given: Any) -> Tuple[str, list]:
    """refine_colmap's pose_priors as _core takes them: (a database path, or ""), and a list of
    (IMAGE_ID, position, covariance (9 values, row-major) or None, coordinate system) tuples."""
    if given is None:
        return "", []
    if isinstance(given, (str, os.PathLike)):
        return os.fspath(given), []
    if isinstance(given, (bytes, dict)) or not isinstance(given, collections.abc.Iterable):
        raise TypeError(f"pose_priors must be a database path or a sequence of priors, got {type(given).__name__}")
    out = []
    for k, p in enumerate(given):
        where = f"pose_priors[{k}]"
        if isinstance(p, dict):
            unknown = set(p) - {"image_id", "position", "covariance", "coordinate_system"}
            if unknown:
                raise ValueError(f"{where} has an unknown key {sorted(unknown)[0]!r}")
            if "image_id" not in p or "position" not in p:
                raise ValueError(f"{where} needs 'image_id' and 'position'")
            image_id, position = p["image_id"], p["position"]
            covariance, system = p.get("covariance"), p.get("coordinate_system", "CARTESIAN")
        elif hasattr(p, "corr_data_id") and hasattr(p, "position"):  # a pycolmap.PosePrior
            if getattr(p.corr_data_id.sensor_id.type, "name", "CAMERA") != "CAMERA":
                continue  # a prior of another sensor places no image
            image_id, position = p.corr_data_id.id, p.position
            covariance, system = p.position_covariance, p.coordinate_system.name
        else:
            raise TypeError(f"{where} must be a pycolmap.PosePrior or a dict, got {type(p).__name__}")
        if isinstance(image_id, (bool, np.bool_)) or not isinstance(image_id, numbers.Integral) \
                or not 0 <= int(image_id) <= 0xFFFFFFFF:
            raise ValueError(f"{where}: image_id must be an IMAGE_ID (an int in 0..4294967295), got {image_id!r}")
        position = np.asarray(position, dtype=np.float64)
        if position.size != 3:
            raise ValueError(f"{where}: position must have 3 values, got {position.size}")
        if covariance is not None:
            covariance = np.asarray(covariance, dtype=np.float64)
            if covariance.size != 9:
                raise ValueError(f"{where}: covariance must be 3 x 3, got {covariance.size} values")
            covariance = covariance.reshape(9).tolist()
        if system not in _SYSTEMS:
            raise ValueError(f"{where}: coordinate_system must be 'CARTESIAN' or 'WGS84', got {system!r}")
        out.append((int(image_id), position.reshape(3).tolist(), covariance, _SYSTEMS[system]))
    return "", out


def _shown(model: ColmapModel, robust: bool,
           progress: Optional[Callable[[Progress], Any]]) -> Callable[[Progress], Any]:
    """refine_colmap's verbose: the problem's size on sys.stderr now, and a progress callback
    that shows each iteration there before it calls progress (if any)."""
    observations = len(model.points3D.track_image_ids)
    images = sum(im.q is not None for im in model.images)
    print(f"refine_colmap: {images} images, {len(model.cameras)} cameras, {len(model.points3D)} points, "
          f"{observations} observations", file=sys.stderr, flush=True)

    def show(state: Progress) -> Any:
        error = f"cost {state.error:.6g}" if robust else f"RMS {math.sqrt(state.error / observations):.6g} px"
        print(f"refine_colmap: iteration {state.iteration}: {error}, mu {state.mu:.3g}, step {state.dp_norm:.3g}, "
              f"{state.elapsed:.2f} s", file=sys.stderr, flush=True)
        return None if progress is None else progress(state)

    return show


def _with_unposed(refined: ColmapModel, given: ColmapModel) -> ColmapModel:
    """refined, the images and frames of given that have a pose refined, with given's images and
    frames without one put back (as copies) where given has them."""
    for name in ("images", "frames"):
        records = getattr(given, name)
        if records is not None and any(r.q is None for r in records):
            solved = iter(getattr(refined, name))
            setattr(refined, name, [copy.deepcopy(r) if r.q is None else next(solved) for r in records])
    return refined


def _pycolmap() -> Any:
    try:
        import pycolmap
    except ImportError as e:
        raise ImportError(f"pysba's conversions to and from pycolmap need pycolmap (pip install pycolmap), "
                          f"which cannot be imported: {e}") from e
    return pycolmap


def _pose_of(rigid: Any) -> Tuple[np.ndarray, np.ndarray]:
    """A pycolmap.Rigid3d as (q, t): qw qx qy qz, the bits pycolmap holds."""
    xyzw = np.array(rigid.rotation.quat, np.float64)
    return xyzw[[3, 0, 1, 2]], np.array(rigid.translation, np.float64)


class _ReadCache:
    """What a caller that reads the same Reconstruction again and again (a mapper's, at each of
    its adjustments) keeps from one read to the next, so that each read asks pycolmap only for
    what changed: pycolmap hands a track over one Python object per element, and a model of
    long tracks costs more to read element by element than to solve.

    keypoints, for images whose keypoints do not change between reads (a mapper's come from its
    database): every keypoint of each image by IMAGE_ID, (k, 2), each image's read whole once,
    from the database at database_path (the mapper's, whose float keypoints are its images'),
    opened at the first read and kept open until close(), where it has as many as the image,
    from the image otherwise.

    tracks: by POINT3D_ID, a copy of the point's pycolmap.Track as last read, with its IMAGE_IDs
    and keypoint indices in its order (see _read_track). A point whose track compares equal to
    the copy, or to the copy with the new elements appended (one comparison in pycolmap,
    whatever the track's length), takes the rest from here, so an entry is right whatever
    happened to the point since.

    observations: by IMAGE_ID, for the images a part's read takes its observations from, a copy
    of the image's keypoints (its pycolmap.Point2DList, which holds each keypoint's POINT3D_ID)
    and the indices and POINT3D_IDs of those that observe a point. An image whose keypoints
    compare equal to the copy (one comparison in pycolmap) takes them from here: the mapper's
    local adjustments read the same few images again and again, most of them unchanged. Only
    the OBSERVED_IMAGES images read last are kept, the least recently read dropped first, so that
    the copies stay a small part of the mapper's own model however many images it holds."""

    OBSERVED_IMAGES = 64

    def __init__(self, database_path: Any = None) -> None:
        self.database_path = database_path
        self.database: Any = None
        self.keypoints: Dict[int, np.ndarray] = {}
        self.tracks: Dict[int, Tuple[Any, List[int], List[int]]] = {}
        self.observations: Dict[int, Tuple[Any, np.ndarray, np.ndarray]] = collections.OrderedDict()
        self.seconds = 0.0  # in the adjustments' reads through this cache, for the caller's timings

    def close(self) -> None:
        if self.database is not None:
            self.database.close()
            self.database = None

    def keypoints_of(self, image_id: int, image: Any) -> np.ndarray:
        """Every keypoint of the image, (k, 2)."""
        every = self.keypoints.get(image_id)
        if every is None:
            k = image.num_points2D()
            if self.database is None and self.database_path is not None:
                self.database = _pycolmap().Database.open(os.fspath(self.database_path))
            if self.database is not None and self.database.exists_image(image_id):
                read = np.asarray(self.database.read_keypoints(image_id))
                if read.ndim == 2 and read.shape[1] >= 2:
                    every = read[:, :2].astype(np.float64)
            if every is None or len(every) != k:
                every = np.array([p.xy for p in image.points2D], np.float64).reshape(-1, 2)
            self.keypoints[image_id] = every
        return every


def _observations(image: Any, cache: Optional[_ReadCache]) -> Tuple[np.ndarray, np.ndarray]:
    """The image's keypoints that observe a 3D point, in their order: their indices and their
    POINT3D_IDs (uint64), through cache when there is one."""
    if cache is not None:
        known = cache.observations.get(image.image_id)
        if known is not None and image.points2D == known[0]:
            cache.observations.move_to_end(image.image_id)
            return known[1], known[2]
    keypoint = np.array(image.get_observation_point2D_idxs(), np.uint64)
    point = np.array([p.point3D_id for p in image.get_observation_points2D()], np.uint64)
    if cache is not None:
        cache.observations[image.image_id] = (_pycolmap().Point2DList(image.points2D), keypoint, point)
        cache.observations.move_to_end(image.image_id)
        while len(cache.observations) > cache.OBSERVED_IMAGES:
            cache.observations.popitem(last=False)
    return keypoint, point


def _read_track(track: Any, known: Optional[Tuple[Any, List[int], List[int]]]) -> Tuple[Any, List[int], List[int]]:
    """A pycolmap.Track as a _ReadCache keeps it: a copy, its IMAGE_IDs and keypoint indices.
    known, the point's entry of the last read, is returned (updated in place) when the track is
    the same or that track with elements appended (a mapper's tracks grow at their end as
    images are registered), so that only the new elements are read."""
    if known is not None:
        copied, image_ids, keypoints = known
        had = len(image_ids)
        grown = track.length() - had
        if grown == 0 and track == copied:
            return known
        if grown > 0:
            new = [track.element(i) for i in range(had, had + grown)]
            copied.add_elements(new)
            if track == copied:
                image_ids += [e.image_id for e in new]
                keypoints += [e.point2D_idx for e in new]
                return known
    elements = track.elements
    # A copy: the Track pycolmap returns can be a view of the point's own.
    return track.__copy__(), [e.image_id for e in elements], [e.point2D_idx for e in elements]


def _from_reconstruction(reconstruction: Any, cache: Optional[_ReadCache] = None) -> ColmapModel:
    """_read_reconstruction's model of the whole reconstruction."""
    return _read_reconstruction(reconstruction, cache)[0]


def _read_reconstruction(reconstruction: Any, cache: Optional[_ReadCache] = None,
                         part: Optional[Tuple[Any, Any, Any]] = None,
                         appearance: bool = True) -> Tuple[ColmapModel, List[int]]:
    """What refine_colmap reads of a pycolmap.Reconstruction, through pycolmap's API (no file),
    and the POINT3D_IDs it must hold: every camera, rig and frame (a frame without a pose, and
    its images, without one as in from_pycolmap), every image with its pose as pycolmap
    composes it and only its keypoints that observe a 3D point (in their order), and every
    point with its track in its order, the track's keypoint indices into those. The solve of it
    is the solve of what pycolmap writes: it reads nothing of the keypoints that observe no
    point.

    part, (IMAGE_IDs, variable POINT3D_IDs, constant POINT3D_IDs) of a bundle adjustment's
    configuration, reads only what that adjustment sees, for a configuration of a few images
    in a large model (the mapper's local adjustment): the points those images see, each with
    its whole track when every element of it is in them, with their elements only otherwise
    (such a point is held, as the configuration holds it, and its id returned); the variable
    and constant points with their whole tracks; the images of those tracks, the other images
    of their frames, and their frames, rigs and cameras. The problem is the one of the whole
    model with that configuration.

    cache, a _ReadCache this reads from and updates: the same model as without it, bit for bit,
    for a caller whose images' keypoints do not change between reads.

    appearance False leaves the points' colours and errors zero, for a caller that neither
    uses nor writes them back (a bundle adjustment)."""
    points = reconstruction.points3D
    held: List[int] = []
    looked: Dict[int, Any] = {}  # the points already looked up, by POINT3D_ID
    span: Dict[int, Tuple[int, int]] = {}  # a held point's elements in part's images: its rows of seen_*
    if part is None:
        ids = np.array(sorted(points.keys()), np.uint64)
    else:
        config_images, variable, constant = part
        # The config images' observations, by point (each point's in ascending image order).
        by_image = []
        for image_id in sorted(config_images):
            keypoint, point = _observations(reconstruction.image(image_id), cache)
            by_image.append((point, np.full(len(keypoint), image_id, np.uint64), keypoint))
        columns = [np.concatenate(c) for c in zip(*by_image)] if by_image else [np.empty(0, np.uint64)] * 3
        order = np.argsort(columns[0], kind="stable")
        seen_point, seen_image, seen_keypoint = (c[order] for c in columns)
        seen_ids, first, count = np.unique(seen_point, return_index=True, return_counts=True)
        whole = set(variable) | set(constant)
        for point_id, a, c in zip(seen_ids.tolist(), first.tolist(), count.tolist()):
            if point_id not in whole:
                p = looked[point_id] = points[point_id]
                if p.track.length() != c:
                    held.append(point_id)
                    span[point_id] = (a, a + c)
        ids = np.array(sorted(whole.union(seen_ids.tolist())), np.uint64)
    n = len(ids)
    rgb, error = np.zeros((n, 3), np.uint8), np.zeros(n)
    # The tracks, in their order: (point, image, keypoint) per element. A held point of part
    # gets its config images' elements (its rows of seen_*), and neither colour nor error
    # (nothing of a held point is written back).
    rows_xyz: List[Any] = []
    lengths: List[int] = []
    image_ids: List[int] = []
    keypoints: List[int] = []
    known = cache.tracks if cache is not None else {}
    kept: Dict[int, Tuple[Any, List[int], List[int]]] = {}
    for k, point_id in enumerate(ids.tolist()):
        p = looked.get(point_id) or points[point_id]
        rows_xyz.append(p.xyz)
        if point_id in span:
            lengths.append(0)
            continue
        if appearance:
            rgb[k], error[k] = p.color, p.error
        entry = kept[point_id] = _read_track(p.track, known.get(point_id))
        image_ids += entry[1]
        keypoints += entry[2]
        lengths.append(len(entry[1]))
    xyz = np.array(rows_xyz, np.float64).reshape(n, 3)
    if cache is not None:
        # A whole read forgets the points gone from the model; a part's, nothing.
        if part is None:
            cache.tracks = kept
        else:
            cache.tracks.update(kept)
    track_points_a = np.repeat(ids, np.array(lengths, np.int64))
    track_images = np.array(image_ids, np.uint64)
    track_keypoints = np.array(keypoints, np.uint64)
    if span:
        rows = np.isin(seen_point, np.array(held, np.uint64))
        track_points_a = np.concatenate([track_points_a, seen_point[rows]])
        track_images = np.concatenate([track_images, seen_image[rows]])
        track_keypoints = np.concatenate([track_keypoints, seen_keypoint[rows]])
        # By point, each point's elements in the order read.
        order = np.argsort(track_points_a, kind="stable")
        track_points_a, track_images, track_keypoints = (a[order] for a in (track_points_a, track_images,
                                                                             track_keypoints))
    offsets = np.zeros(n + 1, np.uint64)
    offsets[1:] = np.searchsorted(track_points_a, ids, side="right")
    # The images, frames, rigs and cameras read: all of them, or those of part's tracks, the
    # frames of their images and those frames' other images.
    if part is None:
        image_list = sorted(reconstruction.images.keys())
        frame_list = sorted(reconstruction.frames.keys())
        rig_list = sorted(reconstruction.rigs.keys())
        camera_list = sorted(reconstruction.cameras.keys())
    else:
        frame_set = {reconstruction.image(i).frame_id for i in set(np.unique(track_images).tolist()) | set(config_images)}
        frame_list = sorted(frame_set)
        image_set = set()
        rig_set = set()
        for frame_id in frame_list:
            frame = reconstruction.frame(frame_id)
            rig_set.add(frame.rig_id)
            image_set.update(d.id for d in frame.data_ids if d.sensor_id.type.name == "CAMERA")
        image_list = sorted(image_set)
        rig_list = sorted(rig_set)
        camera_set = {reconstruction.image(i).camera_id for i in image_list}
        for rig_id in rig_list:
            rig = reconstruction.rig(rig_id)
            camera_set.update(s.id for s in [rig.ref_sensor_id, *rig.non_ref_sensors] if s.type.name == "CAMERA")
        camera_list = sorted(camera_set)
    cameras = []
    for camera_id in camera_list:
        c = reconstruction.camera(camera_id)
        cameras.append(ColmapCamera(camera_id, c.model.name, c.width, c.height, np.array(c.params, np.float64)))
    rigs = []
    for rig_id in rig_list:
        rig = reconstruction.rig(rig_id)
        ref = rig.ref_sensor_id
        sensors = [ColmapSensor(ref.type.name, ref.id)]
        others = rig.non_ref_sensors
        for sensor in sorted(others, key=lambda s: (int(s.type.value), s.id)):  # as pycolmap's files
            pose = others[sensor]
            sensors.append(ColmapSensor(sensor.type.name, sensor.id, *(_pose_of(pose) if pose is not None
                                                                      else (None, None))))
        rigs.append(ColmapRig(rig_id, sensors))
    frames = []
    for frame_id in frame_list:
        frame = reconstruction.frame(frame_id)
        data = [(d.sensor_id.type.name, d.sensor_id.id, d.id)
                for d in sorted(frame.data_ids, key=lambda d: (int(d.sensor_id.type.value), d.sensor_id.id, d.id))]
        q, t = _pose_of(frame.rig_from_world) if frame.has_pose() else (None, None)
        frames.append(ColmapFrame(frame_id, frame.rig_id, q, t, data))
    observer = np.repeat(ids, np.diff(offsets).astype(np.int64))
    # Each image's observing keypoints, ascending, and each track element's index among them.
    # A keypoint observes one point at most, so the keys are distinct and any sort gives this
    # order: an unstable one takes a fraction of a stable one's time on a few million keys.
    order = np.argsort((track_images << np.uint64(32)) | track_keypoints)
    by_image = track_images[order]
    starts = np.searchsorted(by_image, by_image, side="left")
    compact = np.empty(len(order), np.uint64)
    compact[order] = np.arange(len(order), dtype=np.uint64) - starts.astype(np.uint64)
    images = []
    for image_id in image_list:
        im = reconstruction.image(image_id)
        key = np.uint64(image_id)  # of the array's type: a Python int would convert the array to float
        rows = order[np.searchsorted(by_image, key, "left"):np.searchsorted(by_image, key, "right")]
        if cache is None:
            xy = np.array([im.point2D(k).xy for k in track_keypoints[rows].tolist()], np.float64).reshape(-1, 2)
        else:
            xy = cache.keypoints_of(image_id, im)[track_keypoints[rows].astype(np.intp)]
        if im.has_pose:
            q, t = _pose_of(im.cam_from_world())
        else:
            q = t = None
        images.append(ColmapImage(image_id, im.name, im.camera_id, q, t, xy, observer[rows]))
    model = ColmapModel(cameras, images,
                        ColmapPoints3D(ids, xyz, rgb, error, offsets.astype(np.uint32),
                                       track_images.astype(np.uint32), compact.astype(np.uint32)),
                        rigs, frames)
    return model, sorted(held)


def _write_into(reconstruction: Any, refined: ColmapModel, given: ColmapModel, errors: bool = True) -> None:
    """refined's values, where they differ from given's (the model _from_reconstruction read of
    reconstruction), written into reconstruction: cameras' parameters, frames' poses, cameras'
    poses in their rigs, points' coordinates and (with errors) errors. An image's pose is its
    frame's and its camera's in the rig, which pycolmap composes."""
    pycolmap = _pycolmap()

    def differ(a: Any, b: Any) -> bool:
        return a is not None and (b is None or a.tobytes() != b.tobytes())

    def rigid(q: np.ndarray, t: np.ndarray) -> Any:
        return pycolmap.Rigid3d(pycolmap.Rotation3d(np.asarray(q, np.float64)[[1, 2, 3, 0]]),
                                np.asarray(t, np.float64))

    for c, before in zip(refined.cameras, given.cameras):
        if differ(c.params, before.params):
            reconstruction.cameras[c.id].params = c.params
    for f, before in zip(refined.frames or (), given.frames or ()):
        if differ(f.q, before.q) or differ(f.t, before.t):
            reconstruction.frames[f.id].rig_from_world = rigid(f.q, f.t)
    for r, before in zip(refined.rigs or (), given.rigs or ()):
        for s, b in zip(r.sensors, before.sensors):
            if differ(s.q, b.q) or differ(s.t, b.t):
                sensor = pycolmap.sensor_t(getattr(pycolmap.SensorType, s.type), s.id)
                reconstruction.rigs[r.id].set_sensor_from_rig(sensor, rigid(s.q, s.t))
    new, old = refined.points3D, given.points3D
    moved = np.any(new.xyz.view(np.uint64) != old.xyz.view(np.uint64), axis=1)
    if errors:
        moved |= new.error.view(np.uint64) != old.error.view(np.uint64)
    points = reconstruction.points3D
    for k in np.flatnonzero(moved).tolist():
        p = points[int(new.ids[k])]
        p.xyz = new.xyz[k]
        if errors:
            p.error = float(new.error[k])


def from_pycolmap(reconstruction: Any) -> ColmapModel:
    """The :class:`ColmapModel` of a pycolmap.Reconstruction, every field as pycolmap writes
    it (through a binary model in a temporary directory), and the frames pycolmap holds without
    a pose (not registered) with their images, which its files leave out, taken from the
    Reconstruction: every image, frame, rig and camera, in pycolmap's order (by id).

    The model goes through files: pycolmap writes it into a temporary directory, and pysba
    reads it, a model's disk space and time, and a copy in memory beside pycolmap's.
    :func:`refine_colmap` of a Reconstruction reads it in memory instead, only what the solve
    needs."""
    pycolmap = _pycolmap()
    if not isinstance(reconstruction, pycolmap.Reconstruction):
        raise TypeError(f"reconstruction must be a pycolmap.Reconstruction, got "
                        f"{type(reconstruction).__name__}")
    with tempfile.TemporaryDirectory(prefix="pysba-") as d:
        reconstruction.write_binary(d)
        model = read_colmap(d)
    unposed = [f for f in reconstruction.frames.values() if not f.has_pose()]
    for frame in unposed:
        data = sorted((d.sensor_id.type.name, d.sensor_id.id, d.id) for d in frame.data_ids)
        model.frames.append(ColmapFrame(frame.frame_id, frame.rig_id, None, None, data))
        for kind, _, image_id in data:
            if kind == "CAMERA":
                im = reconstruction.images[image_id]
                points = list(im.points2D)
                model.images.append(ColmapImage(
                    im.image_id, im.name, im.camera_id, None, None,
                    np.array([p.xy for p in points], np.float64).reshape(-1, 2),
                    np.array([p.point3D_id for p in points], np.uint64)))
    if unposed:
        model.frames.sort(key=lambda f: f.id)
        model.images.sort(key=lambda im: im.id)
    return model


def to_pycolmap(model: ColmapModel) -> Any:
    """The pycolmap.Reconstruction of a :class:`ColmapModel` (through a binary model in a
    temporary directory, which pycolmap reads), with its frames without a pose and their images
    added to it unregistered. ValueError or TypeError for a model the reader would refuse.

    The model goes through files, as in :func:`from_pycolmap`. :func:`refine_colmap` of a
    Reconstruction writes its result into one (a copy, or the one given) in memory instead."""
    pycolmap = _pycolmap()
    _check_model(model)
    with tempfile.TemporaryDirectory(prefix="pysba-") as d:
        write_colmap(model, d, "binary")
        reconstruction = pycolmap.Reconstruction(d)
    # write_colmap checked the frames without a pose: each image of one has none either.
    frame_of = {}
    for f in model.frames or ():
        if f.q is None:
            frame = pycolmap.Frame(frame_id=f.id, rig_id=f.rig_id)
            for kind, sensor_id, data_id in f.data:
                sensor = pycolmap.sensor_t(getattr(pycolmap.SensorType, kind), sensor_id)
                frame.add_data_id(pycolmap.data_t(sensor, data_id))
                if kind == "CAMERA":
                    frame_of[data_id] = f.id
            reconstruction.add_frame(frame)
    for im in model.images:
        if im.q is None:
            image = pycolmap.Image(name=im.name, keypoints=np.asarray(im.points2D, np.float64).reshape(-1, 2),
                                   camera_id=im.camera_id, image_id=im.id)
            image.frame_id = frame_of[im.id]
            reconstruction.add_image(image)
    return reconstruction
