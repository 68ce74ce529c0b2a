# SPDX-License-Identifier: BSD-3-Clause
"""sba as COLMAP 4's bundle adjuster, with pycolmap's own options and configuration.

:func:`bundle_adjustment` takes what ``pycolmap.bundle_adjustment`` and
``pycolmap.create_default_bundle_adjuster(options, config, reconstruction).solve()`` take (a
``pycolmap.Reconstruction``, ``pycolmap.BundleAdjustmentOptions`` and
``pycolmap.BundleAdjustmentConfig``; with pose priors, ``pycolmap.PosePriorBundleAdjustmentOptions``
too) and refines the reconstruction in place, in memory, with sba: the same problem, solved by
sba's sparse Levenberg-Marquardt. An option that sba does not honour is refused (ValueError),
never ignored. Needs pycolmap (``pip install pycolmap``).
"""
from __future__ import annotations

import functools
import sys
import time
from typing import Any, Callable, Dict, Optional, Tuple

import numpy as np

from . import Progress, Result, SolveError
from ._colmap import _pycolmap, _read_reconstruction, _ReadCache, _write_into, refine_colmap

__all__ = ["bundle_adjustment", "adjust_global_bundle", "adjust_local_bundle", "incremental_mapping"]

# Ceres's losses as pysba names them (the same functions of the squared residual, of the same
# scale).
_LOSSES = {"TRIVIAL": None, "HUBER": "huber", "SOFT_L1": "soft-l1", "CAUCHY": "cauchy"}
_PRIOR_LOSSES = {"TRIVIAL": "trivial", "CAUCHY": "cauchy"}
_GAUGES = {"UNSPECIFIED": None, "TWO_CAMS_FROM_WORLD": "two-cams", "THREE_POINTS": "three-points"}

# Options that choose how Ceres solves each step (its linear solver, its preconditioner, its
# device, when it goes multi-threaded): sba solves the same steps by its own rules (solver=), so
# any value of them gives the same problem, refined to the same minimum.
_HOW_CERES_SOLVES = {
    "ceres.use_gpu", "ceres.gpu_index", "ceres.min_num_images_gpu_solver",
    "ceres.min_num_residuals_for_cpu_multi_threading", "ceres.max_num_images_direct_dense_cpu_solver",
    "ceres.max_num_images_direct_sparse_cpu_solver", "ceres.max_num_images_direct_dense_gpu_solver",
    "ceres.max_num_images_direct_sparse_gpu_solver", "ceres.auto_select_solver_type",
    "ceres.solver_options.linear_solver_type", "ceres.solver_options.preconditioner_type",
    "ceres.solver_options.visibility_clustering_type", "ceres.solver_options.dense_linear_algebra_library_type",
    "ceres.solver_options.sparse_linear_algebra_library_type", "ceres.solver_options.use_explicit_schur_complement",
    "ceres.solver_options.min_linear_solver_iterations", "ceres.solver_options.max_linear_solver_iterations",
    "ceres.solver_options.eta", "ceres.solver_options.jacobi_scaling",
    "ceres.solver_options.trust_region_problem_dump_directory",
    "ceres.solver_options.trust_region_problem_dump_format_type",
}
# Options that only another choice reads (the line search's with a trust region, the dogleg's
# with Levenberg-Marquardt, ...), and the options of the other backend: unused as Ceres leaves
# them with the choices sba honours.
_UNUSED_PREFIXES = ("caspar.", "ceres.solver_options.line_search_", "ceres.solver_options.max_line_search_",
                    "ceres.solver_options.min_line_search_", "ceres.solver_options.max_num_line_search_")
_UNUSED = {
    "ceres.solver_options.nonlinear_conjugate_gradient_type", "ceres.solver_options.max_lbfgs_rank",
    "ceres.solver_options.use_approximate_eigenvalue_bfgs_scaling", "ceres.solver_options.dogleg_type",
    "ceres.solver_options.max_consecutive_nonmonotonic_steps", "ceres.solver_options.inner_iteration_tolerance",
    "ceres.solver_options.gradient_check_relative_precision",
    "ceres.solver_options.gradient_check_numeric_derivative_relative_step_size",
}
# What sba honours, read below.
_HONOURED = {
    "refine_focal_length", "refine_principal_point", "refine_extra_params", "refine_rig_from_world",
    "refine_sensor_from_rig", "constant_rig_from_world_rotation", "refine_points3D", "min_track_length",
    "print_summary", "backend", "ceres.loss_function_type", "ceres.loss_function_scale",
    "ceres.solver_options.max_num_iterations", "ceres.solver_options.max_solver_time_in_seconds",
    "ceres.solver_options.num_threads", "ceres.solver_options.function_tolerance",
    "ceres.solver_options.gradient_tolerance", "ceres.solver_options.parameter_tolerance",
    "ceres.solver_options.logging_type", "ceres.solver_options.minimizer_progress_to_stdout",
    "ceres.solver_options.minimizer_type", "ceres.solver_options.trust_region_strategy_type",
}


def _flat(d: Dict[str, Any], prefix: str = "") -> Dict[str, Any]:
    out = {}
    for k, v in d.items():
        if isinstance(v, dict):
            out.update(_flat(v, prefix + k + "."))
        else:
            out[prefix + k] = v
    return out


def _name(value: Any) -> str:
    return getattr(value, "name", str(value))


def _refused(given: Dict[str, Any], default: Dict[str, Any], what: str) -> None:
    """ValueError for the first option of given (flattened) that differs from its default and
    that sba neither honours nor can leave to Ceres's own choices."""
    for key in sorted(given):
        if key in _HONOURED or key in _HOW_CERES_SOLVES or key in _UNUSED or key.startswith(_UNUSED_PREFIXES):
            continue
        if key not in default or given[key] != default[key]:
            raise ValueError(f"{what}.{key} = {_name(given[key])} is not honoured by sba (only "
                             f"{_name(default.get(key))}, its default, is)")


@functools.lru_cache(maxsize=None)
def _default_options(options_type: Any) -> Dict[str, Any]:
    """The defaults of pycolmap's options_type, flattened: read once (todict is slow enough to
    count in a mapper's hundreds of small adjustments)."""
    return _flat(options_type().todict())


def _options(pycolmap: Any, options: Any) -> Tuple[Dict[str, Any], Dict[str, Any]]:
    """refine_colmap's arguments for a pycolmap.BundleAdjustmentOptions, and its values
    flattened."""
    if not isinstance(options, pycolmap.BundleAdjustmentOptions):
        raise TypeError(f"options must be a pycolmap.BundleAdjustmentOptions, got {type(options).__name__}")
    given = _flat(options.todict())
    _refused(given, _default_options(pycolmap.BundleAdjustmentOptions), "options")
    if _name(given["backend"]) != "CERES":
        raise ValueError(f"options.backend = {_name(given['backend'])} is not honoured by sba (only CERES, "
                         "whose problem sba solves)")
    solver = "ceres.solver_options."
    for key, only in (("minimizer_type", "TRUST_REGION"), ("trust_region_strategy_type", "LEVENBERG_MARQUARDT")):
        if _name(given[solver + key]) != only:
            raise ValueError(f"options.{solver}{key} = {_name(given[solver + key])} is not honoured by sba "
                             f"(only {only})")
    loss = _name(given["ceres.loss_function_type"])
    if loss not in _LOSSES:
        raise ValueError(f"options.ceres.loss_function_type = {loss} is not honoured by sba")
    threads = int(given[solver + "num_threads"])
    kw = dict(refine_focal_length=bool(given["refine_focal_length"]),
              refine_principal_point=bool(given["refine_principal_point"]),
              refine_extra_params=bool(given["refine_extra_params"]),
              refine_rig_from_world=bool(given["refine_rig_from_world"]),
              refine_sensor_from_rig=bool(given["refine_sensor_from_rig"]),
              constant_rig_from_world_rotation=bool(given["constant_rig_from_world_rotation"]),
              refine_points3D=bool(given["refine_points3D"]),
              min_track_length=int(given["min_track_length"]),
              loss=_LOSSES[loss], loss_scale=float(given["ceres.loss_function_scale"]),
              itmax=int(given[solver + "max_num_iterations"]),
              function_tolerance=float(given[solver + "function_tolerance"]),
              gradient_tolerance=float(given[solver + "gradient_tolerance"]),
              threads=threads if threads > 0 else 0)
    # Ceres's parameter_tolerance (0: no such test) is sba's eps2 on the step's norm.
    parameter_tolerance = float(given[solver + "parameter_tolerance"])
    if parameter_tolerance > 0:
        kw["opts"] = [1e-3, kw["gradient_tolerance"], parameter_tolerance, 1e-12, kw["function_tolerance"]]
    return kw, given


def _prior_options(pycolmap: Any, prior_options: Any) -> Dict[str, Any]:
    """refine_colmap's arguments for a pycolmap.PosePriorBundleAdjustmentOptions."""
    if not isinstance(prior_options, pycolmap.PosePriorBundleAdjustmentOptions):
        raise TypeError(f"prior_options must be a pycolmap.PosePriorBundleAdjustmentOptions, got "
                        f"{type(prior_options).__name__}")
    given = _flat(prior_options.todict())
    default = _default_options(pycolmap.PosePriorBundleAdjustmentOptions)
    # The alignment's seed and threads: sba's alignment is deterministic, whatever they are.
    honoured = {"prior_position_fallback_stddev", "alignment_ransac.max_error", "alignment_ransac.random_seed",
                "alignment_ransac.num_threads", "ceres.prior_position_loss_function_type",
                "ceres.prior_position_loss_scale"}
    for key in sorted(given):
        if key not in honoured and (key not in default or given[key] != default[key]):
            raise ValueError(f"prior_options.{key} = {_name(given[key])} is not honoured by sba (only "
                             f"{_name(default.get(key))}, its default, is)")
    loss = _name(given["ceres.prior_position_loss_function_type"])
    if loss not in _PRIOR_LOSSES:
        raise ValueError(f"prior_options.ceres.prior_position_loss_function_type = {loss} is not honoured by sba "
                         "(TRIVIAL or CAUCHY)")
    return dict(prior_position_fallback_stddev=float(given["prior_position_fallback_stddev"]),
                prior_position_loss=_PRIOR_LOSSES[loss],
                prior_position_loss_scale=float(given["ceres.prior_position_loss_scale"]),
                alignment_max_error=float(given["alignment_ransac.max_error"]))


def _config(pycolmap: Any, config: Any) -> Dict[str, Any]:
    """refine_colmap's arguments for a pycolmap.BundleAdjustmentConfig."""
    if not isinstance(config, pycolmap.BundleAdjustmentConfig):
        raise TypeError(f"config must be a pycolmap.BundleAdjustmentConfig, got {type(config).__name__}")
    gauge = _name(config.fixed_gauge)
    if gauge not in _GAUGES:
        raise ValueError(f"config.fixed_gauge = {gauge} is not honoured by sba")
    sensors = config.constant_sensor_from_rig_poses
    return dict(images=sorted(config.images), hold_intrinsics=sorted(config.constant_cam_intrinsics),
                hold_frames=sorted(config.constant_rig_from_world_poses),
                hold_sensor_from_rig=sorted(s.id for s in sensors if _name(s.type) == "CAMERA"),
                hold_points=sorted(config.constant_points), variable_points=sorted(config.variable_points),
                gauge=_GAUGES[gauge])


def _part(pycolmap: Any, reconstruction: Any, config: Any, kw: Dict[str, Any]) -> Optional[Tuple[Any, Any, Any]]:
    """What of reconstruction to read for config (see _read_reconstruction's part): only what
    its images and points see when they are a small part of the model (a mapper's local
    adjustment), everything otherwise (reading a part costs a count of each point's elements)
    and when a minimum track length needs whole tracks to be read."""
    if config is None or kw.get("min_track_length", 0) > 1 or 2 * len(config.images) > reconstruction.num_reg_images():
        return None
    images, variable, constant = config.images, config.variable_points, config.constant_points
    # An id the model does not have: the whole read, whose check names it.
    if not all(reconstruction.exists_image(i) and reconstruction.image(i).has_pose for i in images) or \
            not all(reconstruction.exists_point3D(p) for p in variable | constant):
        return None
    return images, variable, constant


def _timed(seconds: float, progress: Optional[Callable[[Progress], Any]]) -> Optional[Callable[[Progress], Any]]:
    """progress, stopping the solve once it has run for seconds (Ceres's max_solver_time_in_seconds)."""
    if not seconds < 1e9:
        return progress

    def timed(state: Progress) -> Any:
        stop = progress(state) if progress is not None else None
        return stop or state.elapsed >= seconds

    return timed


def bundle_adjustment(reconstruction: Any, options: Any = None, config: Any = None, *,
                      pose_priors: Any = None, prior_options: Any = None, solver: Optional[str] = None,
                      progress: Optional[Callable[[Progress], Any]] = None) -> Result:
    """Bundle-adjusts a pycolmap.Reconstruction in place, as pycolmap's bundle adjuster does with
    the same options and configuration, and returns the :class:`pysba.Result`.

    reconstruction is refined in place, in memory (no file): its frames' poses (rig_from_world),
    cameras' poses in their rigs (sensor_from_rig), cameras' intrinsics and points' coordinates
    where the solve refines them; ids, tracks, keypoints, colours, names, and what is held keep
    their bits. The points' errors are left as they were, as COLMAP's adjusters leave them,
    but for config None without priors: then, as pycolmap.bundle_adjustment does, the
    observations behind their cameras are removed first (and a point left seen once with
    them) and every point's error is updated after. An observation behind its camera that
    stays costs nothing, as in COLMAP's cost. On a KeyboardInterrupt or :class:`pysba.SolveError` the
    reconstruction holds the last accepted estimate.

    options, a pycolmap.BundleAdjustmentOptions (None: its defaults), as COLMAP reads it: the
    refine_* flags, constant_rig_from_world_rotation, min_track_length, the loss (TRIVIAL,
    HUBER, SOFT_L1, CAUCHY) and its scale, and of ceres.solver_options max_num_iterations,
    function_tolerance, gradient_tolerance, parameter_tolerance, num_threads (-1: every core),
    max_solver_time_in_seconds, and logging_type / minimizer_progress_to_stdout (a line per
    iteration, on sys.stderr / sys.stdout); print_summary prints one line on sys.stderr at the
    end. The options that choose how Ceres solves each step (its linear solver and
    preconditioner, its device, auto_select_solver_type, ...) leave the problem as it is, and
    sba solves each step by its own rules (solver, as :func:`pysba.solve`'s); options that only
    another choice of Ceres reads are unused as they are there. Any other option that differs
    from its default (a line search, a dogleg, other trust-region radii, the CASPAR backend,
    inner iterations, ...) is a ValueError that names it.

    config, a pycolmap.BundleAdjustmentConfig: its images, constant intrinsics, constant
    rig_from_world and sensor_from_rig poses, constant and variable points and fixed gauge, as
    COLMAP 4 reads them (see :func:`pysba.refine_colmap`'s hold_frames, images,
    variable_points and gauge). None: pycolmap.bundle_adjustment's, every registered image and
    every point, the gauge TWO_CAMS_FROM_WORLD.

    pose_priors (pycolmap.PosePrior objects, or a database path, as refine_colmap's) with
    prior_options (a pycolmap.PosePriorBundleAdjustmentOptions; None: its defaults) run
    COLMAP 4's pose-prior bundle adjustment (pycolmap.create_pose_prior_bundle_adjuster): the
    model moved onto the priors and refined with them, the gauge left to them.

    progress is called with a :class:`pysba.Progress` after every iteration, as in
    :func:`pysba.refine_colmap`; a true return value stops the solve.
    """
    return _bundle_adjustment(reconstruction, options, config, pose_priors, prior_options, solver, progress, None)


def _bundle_adjustment(reconstruction: Any, options: Any, config: Any, pose_priors: Any, prior_options: Any,
                       solver: Optional[str], progress: Optional[Callable[[Progress], Any]],
                       cache: Optional[_ReadCache]) -> Result:
    """bundle_adjustment, reading the reconstruction through cache (see _read_reconstruction)."""
    pycolmap = _pycolmap()
    if not isinstance(reconstruction, pycolmap.Reconstruction):
        raise TypeError(f"reconstruction must be a pycolmap.Reconstruction, got {type(reconstruction).__name__}")
    kw, given = _options(pycolmap, options if options is not None else pycolmap.BundleAdjustmentOptions())
    solver_options = "ceres.solver_options."
    if config is not None:
        kw.update(_config(pycolmap, config))
    elif pose_priors is None:
        kw["gauge"] = "two-cams"
    if pose_priors is not None:
        kw["pose_priors"] = pose_priors
        kw.update(_prior_options(pycolmap, prior_options if prior_options is not None
                                 else pycolmap.PosePriorBundleAdjustmentOptions()))
        kw["gauge"] = None  # the priors fix it
    elif prior_options is not None:
        raise ValueError("prior_options without pose_priors: give the priors too")
    progress = _timed(float(given[solver_options + "max_solver_time_in_seconds"]), progress)
    logging = _name(given[solver_options + "logging_type"]) != "SILENT"
    to_stdout = bool(given[solver_options + "minimizer_progress_to_stdout"])
    if logging or to_stdout:
        progress = _logged(sys.stdout if to_stdout else sys.stderr, progress)
    start = time.perf_counter()
    # COLMAP's adjusters leave the points' errors as they were; pycolmap.bundle_adjustment (no
    # config, no priors) updates every point's after the solve.
    if config is None and pose_priors is None:
        # pycolmap.bundle_adjustment removes the observations behind their cameras first, as
        # COLMAP's bundle_adjuster does; its adjusters that take a configuration keep them, at
        # no cost (the solve's too).
        pycolmap.ObservationManager(reconstruction).filter_observations_with_negative_depth()
    part = _part(pycolmap, reconstruction, config, kw) if pose_priors is None else None
    read = time.perf_counter()
    model, held = _read_reconstruction(reconstruction, cache, part, appearance=False)
    if cache is not None:
        cache.seconds += time.perf_counter() - read
    if held:
        kw["hold_points"] = np.union1d(np.array(kw["hold_points"], np.uint64), np.array(held, np.uint64))
    try:
        refined, result = refine_colmap(model, solver=solver, progress=progress, point_errors=False,
                                        remove_behind=False, **kw)
    except (KeyboardInterrupt, SolveError) as e:
        partial = getattr(e, "result", None)
        if partial is not None and partial.model is not None:
            _write_into(reconstruction, partial.model, model, errors=False)
            partial.model = reconstruction
        raise
    _write_into(reconstruction, refined, model, errors=False)
    result.model = reconstruction
    if config is None and pose_priors is None:
        reconstruction.update_point_3d_errors()
    if bool(given["print_summary"]):
        print(f"pysba.colmap.bundle_adjustment: RMS {result.rms_initial:.6g} px -> {result.rms_final:.6g} px in "
              f"{result.iterations} iterations, {time.perf_counter() - start:.3f} s: {result.reason.text}",
              file=sys.stderr, flush=True)
    return result


def _logged(stream: Any, progress: Optional[Callable[[Progress], Any]]) -> Callable[[Progress], Any]:
    def logged(state: Progress) -> Any:
        print(f"iteration {state.iteration}: cost {state.error / 2:.6e}, mu {state.mu:.3g}, step {state.dp_norm:.3g}, "
              f"{state.elapsed:.3f} s", file=stream, flush=True)
        return None if progress is None else progress(state)

    return logged


def adjust_global_bundle(mapper: Any, mapper_options: Any, ba_options: Any, *, pose_priors: Any = None,
                         prior_options: Any = None, solver: Optional[str] = None,
                         progress: Optional[Callable[[Progress], Any]] = None) -> Result:
    """The global bundle adjustment of pycolmap's incremental mapper, with sba: what
    ``mapper.adjust_global_bundle(mapper_options, ba_options)`` does, on ``mapper.reconstruction``
    in place, for a Python pipeline that drives a pycolmap.IncrementalMapper. Returns the
    :class:`pysba.Result`.

    As COLMAP 4's mapper takes it: the observations behind their cameras are filtered first
    (the mapper's ObservationManager), then every image of every registered frame is adjusted,
    with mapper_options' constant_cameras (intrinsics held), constant_rigs (their cameras'
    poses in the rigs held) and fix_existing_frames (the frames of the reconstruction the mapper
    began with held), the gauge fixed by two images' poses (TWO_CAMS_FROM_WORLD), and
    ba_options (a pycolmap.BundleAdjustmentOptions, usually the pipeline's
    get_global_bundle_adjustment()) read as :func:`bundle_adjustment` reads them. With
    pose_priors (and prior_options), the pose-prior adjustment instead, its gauge the priors'.
    A ValueError when fewer than two frames are registered, or for an option that is not
    honoured (mapper_options.ba_global_ignore_redundant_points3D, which selects points by a
    coverage of COLMAP's own, is refused).
    """
    return _adjust_global_bundle(mapper, mapper_options, ba_options, pose_priors, prior_options, solver, progress,
                                 None)


def _hold_mapper_constants(rec: Any, mapper_options: Any, config: Any) -> None:
    """The mapper options' constant cameras (intrinsics) and constant rigs (their cameras' poses
    in the rigs) held in config, as each of the mapper's adjustments holds them."""
    for camera_id in mapper_options.constant_cameras:
        config.set_constant_cam_intrinsics(camera_id)
    for rig_id in mapper_options.constant_rigs:
        for sensor in rec.rigs[rig_id].non_ref_sensors:
            config.set_constant_sensor_from_rig_pose(sensor)


def _mapper_config(pycolmap: Any, mapper: Any, mapper_options: Any, gauge: bool) -> Tuple[Any, Any]:
    """The mapper's Reconstruction and the configuration of its global adjustment, as COLMAP 4's
    mapper makes it, after the observations behind their cameras are filtered: every image of
    every registered frame, the mapper options' constant cameras, rigs and existing frames held,
    and (with gauge) two images' poses."""
    if not isinstance(mapper, pycolmap.IncrementalMapper):
        raise TypeError(f"mapper must be a pycolmap.IncrementalMapper, got {type(mapper).__name__}")
    if not isinstance(mapper_options, pycolmap.IncrementalMapperOptions):
        raise TypeError(f"mapper_options must be a pycolmap.IncrementalMapperOptions, got "
                        f"{type(mapper_options).__name__}")
    if mapper_options.ba_global_ignore_redundant_points3D:
        raise ValueError("mapper_options.ba_global_ignore_redundant_points3D = True is not honoured by sba "
                         "(only False, its default, is)")
    rec = mapper.reconstruction
    frames = [f for f in rec.frames.values() if f.has_pose()]
    if len(frames) < 2:
        raise ValueError(f"global bundle adjustment needs two registered frames, the reconstruction has {len(frames)}")
    mapper.observation_manager.filter_observations_with_negative_depth()
    config = pycolmap.BundleAdjustmentConfig()
    for frame in frames:
        for data in frame.data_ids:
            if _name(data.sensor_id.type) == "CAMERA":
                config.add_image(data.id)
    _hold_mapper_constants(rec, mapper_options, config)
    if mapper_options.fix_existing_frames:
        for frame_id in mapper.existing_frame_ids:
            if frame_id in rec.frames and rec.frames[frame_id].has_pose():
                config.set_constant_rig_from_world_pose(frame_id)
    if gauge:
        config.fix_gauge(pycolmap.BundleAdjustmentGauge.TWO_CAMS_FROM_WORLD)
    return rec, config


def _adjust_global_bundle(mapper: Any, mapper_options: Any, ba_options: Any, pose_priors: Any, prior_options: Any,
                          solver: Optional[str], progress: Optional[Callable[[Progress], Any]],
                          cache: Optional[_ReadCache]) -> Result:
    """adjust_global_bundle, reading the reconstruction through cache (see _read_reconstruction)."""
    rec, config = _mapper_config(_pycolmap(), mapper, mapper_options, pose_priors is None)
    return _bundle_adjustment(rec, ba_options, config, pose_priors, prior_options, solver, progress, cache)


# The longest track of a point the local adjustment refines with all its observations: longer
# tracks are stable by then, and refining them would make the local adjustment nearly global.
_LOCAL_MAX_TRACK_LENGTH = 15


def adjust_local_bundle(mapper: Any, mapper_options: Any, ba_options: Any, tri_options: Any, image_id: int,
                        point3D_ids: Any, *, solver: Optional[str] = None) -> Any:
    """The local bundle adjustment of pycolmap's incremental mapper, with sba: what
    ``mapper.adjust_local_bundle(mapper_options, ba_options, tri_options, image_id,
    point3D_ids)`` does, on ``mapper.reconstruction`` in place. Returns the
    pycolmap.LocalBundleAdjustmentReport.

    As COLMAP 4's mapper takes it: the image and its local bundle
    (``mapper.find_local_bundle``, the images that share the most points with it) are
    adjusted, with the points of point3D_ids whose tracks are short (at most 15 observations)
    refined with all their observations; a camera is held unless every registered image of it
    is in the bundle, as are mapper_options' constant_cameras, constant_rigs and (with
    fix_existing_frames) existing frames; the gauge is fixed by three points (THREE_POINTS).
    Then the refined points' tracks are merged and completed, the image's observations
    completed, and the points of the adjusted images and of point3D_ids filtered by
    mapper_options' filter_max_reproj_error and filter_min_tri_angle, as the report counts
    them. Nothing is adjusted when the image shares no point with another. ba_options (a
    pycolmap.BundleAdjustmentOptions, usually the pipeline's get_local_bundle_adjustment())
    is read as :func:`bundle_adjustment` reads it.
    """
    pycolmap = _pycolmap()

    def solve(rec: Any, config: Any) -> int:
        return _bundle_adjustment(rec, ba_options, config, None, None, solver, None, None).nobs

    return _adjust_local_bundle(pycolmap, mapper, mapper_options, tri_options, image_id, point3D_ids, solve)


def _local_config(pycolmap: Any, mapper: Any, mapper_options: Any, image_id: int, local_bundle: Any,
                  point3D_ids: Any) -> Any:
    """The configuration of the mapper's local adjustment of image_id and its local bundle."""
    rec = mapper.reconstruction
    config = pycolmap.BundleAdjustmentConfig()
    for i in [image_id, *local_bundle]:
        config.add_image(i)
    registered = mapper.num_reg_images_per_camera
    in_bundle: Dict[int, int] = {}
    for i in config.images:
        camera_id = rec.image(i).camera_id
        in_bundle[camera_id] = in_bundle.get(camera_id, 0) + 1
    # A camera whose other images stay out keeps its intrinsics: they are theirs too.
    for camera_id, count in in_bundle.items():
        if count < registered.get(camera_id, 0):
            config.set_constant_cam_intrinsics(camera_id)
    _hold_mapper_constants(rec, mapper_options, config)
    if mapper_options.fix_existing_frames:
        existing = mapper.existing_frame_ids
        for i in config.images:
            if rec.image(i).frame_id in existing:
                config.set_constant_rig_from_world_pose(rec.image(i).frame_id)
    config.fix_gauge(pycolmap.BundleAdjustmentGauge.THREE_POINTS)
    for point_id in point3D_ids:
        if rec.exists_point3D(point_id) and rec.point3D(point_id).track.length() <= _LOCAL_MAX_TRACK_LENGTH:
            config.add_variable_point(point_id)
    return config


def _adjust_local_bundle(pycolmap: Any, mapper: Any, mapper_options: Any, tri_options: Any, image_id: int,
                         point3D_ids: Any, solve: Callable[[Any, Any], int]) -> Any:
    """adjust_local_bundle, the solve by solve(reconstruction, config), which returns the number
    of observations it adjusted."""
    if not isinstance(mapper, pycolmap.IncrementalMapper):
        raise TypeError(f"mapper must be a pycolmap.IncrementalMapper, got {type(mapper).__name__}")
    if not isinstance(mapper_options, pycolmap.IncrementalMapperOptions):
        raise TypeError(f"mapper_options must be a pycolmap.IncrementalMapperOptions, got "
                        f"{type(mapper_options).__name__}")
    report = pycolmap.LocalBundleAdjustmentReport()
    local_bundle = mapper.find_local_bundle(mapper_options, image_id)
    if not local_bundle:
        return report
    rec = mapper.reconstruction
    point3D_ids = set(point3D_ids)
    config = _local_config(pycolmap, mapper, mapper_options, image_id, local_bundle, point3D_ids)
    report.num_adjusted_observations = solve(rec, config)
    refined = set(config.variable_points)
    tri = mapper.triangulator
    report.num_merged_observations = tri.merge_tracks(tri_options, refined)
    # Observations that failed to triangulate before the poses and intrinsics were refined.
    report.num_completed_observations = tri.complete_tracks(tri_options, refined) + \
        tri.complete_image(tri_options, image_id)
    observations = mapper.observation_manager
    report.num_filtered_observations = observations.filter_points3D_in_images(
        mapper_options.filter_max_reproj_error, mapper_options.filter_min_tri_angle, set(config.images)) + \
        observations.filter_points3D(mapper_options.filter_max_reproj_error, mapper_options.filter_min_tri_angle,
                                     point3D_ids)
    return report


def _pipeline_prior_options(pycolmap: Any, options: Any) -> Any:
    """The pose-prior options of a pipeline's use_prior_position: a Cauchy loss of the
    pipeline's scale on the priors' positions with use_robust_loss_on_prior_position, none
    otherwise."""
    prior_options = pycolmap.PosePriorBundleAdjustmentOptions()
    if options.use_robust_loss_on_prior_position:
        prior_options.ceres.prior_position_loss_function_type = pycolmap.LossFunctionType.CAUCHY
        prior_options.ceres.prior_position_loss_scale = options.prior_position_loss_scale
    return prior_options


# IncrementalPipelineOptions that the Python pipeline does not honour, with the value it takes.
_PIPELINE_ONLY = {"snapshot_frames_freq": 0, "max_runtime_seconds": -1, "structure_less_registration_only": False}


def incremental_mapping(database_path: Any, image_path: Any, output_path: Any, options: Any = None, *,
                        global_adjustment: str = "sba", local_adjustment: str = "sba",
                        timings: Optional[Dict[str, float]] = None) -> Dict[int, Any]:
    """COLMAP's incremental mapping of a database, as ``pycolmap.incremental_mapping`` runs it,
    driven from Python through pycolmap's IncrementalMapper, with sba's global and local bundle
    adjustments (:func:`adjust_global_bundle`, :func:`adjust_local_bundle`). Returns the
    reconstructions by index, each written to output_path/<index>, as
    pycolmap.incremental_mapping does.

    options is a pycolmap.IncrementalPipelineOptions (None: its defaults); its global and local
    adjustments are get_global_bundle_adjustment() and get_local_bundle_adjustment(), read as
    :func:`bundle_adjustment` reads them. global_adjustment "colmap" runs the mapper's own
    instead, the same pipeline otherwise (to compare), and local_adjustment "colmap" the
    mapper's own local adjustments (``mapper.adjust_local_bundle``). timings, a dict, gets the
    seconds of the local refinements ("local"; with sba's, its solves alone,
    "local_solve", and their number, "local_calls"), of the global adjustments alone
    ("global", and their number, "global_calls"; with sba's, the part of it spent reading the
    model through pycolmap's API, "global_read") and of the whole ("total").
    With use_prior_position, each global adjustment is the pose-prior adjustment with the
    database's position priors (:func:`adjust_global_bundle` with pose_priors; a Cauchy loss of
    prior_position_loss_scale on them with use_robust_loss_on_prior_position), and the model is
    not normalized. Options the pipeline does not honour (snapshots, a maximum runtime,
    structure-less registration only) are refused unless at their defaults.
    """
    pycolmap = _pycolmap()
    options = options if options is not None else pycolmap.IncrementalPipelineOptions()
    if not isinstance(options, pycolmap.IncrementalPipelineOptions):
        raise TypeError(f"options must be a pycolmap.IncrementalPipelineOptions, got {type(options).__name__}")
    for key, default in _PIPELINE_ONLY.items():
        if getattr(options, key) != default:
            raise ValueError(f"options.{key} = {getattr(options, key)} is not honoured by pysba's pipeline "
                             f"(only {default}, its default, is)")
    if global_adjustment not in ("sba", "colmap"):
        raise ValueError(f"global_adjustment must be 'sba' or 'colmap', got {global_adjustment!r}")
    if local_adjustment not in ("sba", "colmap"):
        raise ValueError(f"local_adjustment must be 'sba' or 'colmap', got {local_adjustment!r}")
    return _incremental_mapping(pycolmap, database_path, image_path, output_path, options, global_adjustment,
                                local_adjustment, timings)


def _incremental_mapping(pycolmap: Any, database_path: Any, image_path: Any, output_path: Any, options: Any,
                         global_adjustment: str, local_adjustment: str, timings: Optional[Dict[str, float]]) -> Dict[int, Any]:
    """incremental_mapping, its local adjustments also "ceres": the mapper's local adjustment
    step by step in Python with COLMAP's solve (pycolmap's adjuster), which times the solves
    apart from the rest (the same problem as the mapper's; the order in which Ceres is given
    the variable points can differ, and with it the rounding)."""
    from . import _mapping
    # Refused now, not after an hour of mapping.
    if global_adjustment == "sba":
        _options(pycolmap, options.get_global_bundle_adjustment())
    if local_adjustment == "sba":
        _options(pycolmap, options.get_local_bundle_adjustment())
    # An image's keypoints are the database's, whatever model the mapper holds it in: read once
    # for the whole mapping, from the database; a track, again only once it has changed.
    cache = _ReadCache(database_path)
    clock = _mapping.Timings()
    if global_adjustment == "sba":
        def adjust(mapper: Any, mapper_options: Any, ba_options: Any, pose_priors: Any) -> Any:
            prior_options = None if pose_priors is None else _pipeline_prior_options(pycolmap, options)
            before = cache.seconds
            try:
                return _adjust_global_bundle(mapper, mapper_options, ba_options, pose_priors, prior_options, None,
                                             None, cache)
            finally:
                clock.add("global_read", cache.seconds - before)
    else:
        def adjust(mapper: Any, mapper_options: Any, ba_options: Any, pose_priors: Any) -> Any:
            if pose_priors is None:
                return mapper.adjust_global_bundle(mapper_options, ba_options)
            # The mapper's own adjustment takes no priors: with them, COLMAP's pose-prior adjuster.
            rec, config = _mapper_config(pycolmap, mapper, mapper_options, False)
            return pycolmap.create_pose_prior_bundle_adjuster(ba_options, _pipeline_prior_options(pycolmap, options),
                                                              config, pose_priors, rec).solve()

    def adjust_local(mapper: Any, mapper_options: Any, ba_options: Any, tri_options: Any, image_id: int,
                     point3D_ids: Any) -> Any:
        if local_adjustment == "colmap":
            return mapper.adjust_local_bundle(mapper_options, ba_options, tri_options, image_id, point3D_ids)

        def solve(rec: Any, config: Any) -> int:
            start = time.perf_counter()
            if local_adjustment == "sba":
                adjusted = _bundle_adjustment(rec, ba_options, config, None, None, None, None, cache).nobs
            else:
                adjusted = pycolmap.create_default_bundle_adjuster(ba_options, config, rec).solve().num_residuals // 2
            clock.add("local_solve", time.perf_counter() - start)
            clock.add("local_calls", 1)
            return adjusted

        return _adjust_local_bundle(pycolmap, mapper, mapper_options, tri_options, image_id, point3D_ids, solve)

    try:
        return _mapping.incremental_mapping(pycolmap, database_path, image_path, output_path, options, adjust,
                                            adjust_local, clock)
    finally:
        cache.close()
        if timings is not None:
            timings.update(clock)
