# SPDX-License-Identifier: BSD-3-Clause
"""COLMAP's incremental mapping driven from Python through pycolmap's IncrementalMapper, with
the global bundle adjustment pluggable: pysba.colmap.incremental_mapping's engine.

The steps are COLMAP's incremental algorithm as its pipeline takes them: an initial pair, then
image after image registered, triangulated and refined locally; a global refinement each time
the model has grown by the pipeline's ratios or frequencies (tracks completed and merged,
retriangulated, adjusted, normalized, points filtered, until few observations change), and
once more at the end; several models when the scene graph breaks.
"""
from __future__ import annotations

import copy
import os
import time
from typing import Any, Callable, Dict


class Timings(dict):
    """Seconds by step: "local" (the local refinements), "local_solve" (their adjustments'
    solves alone), "global" (the global adjustments alone), "total"; and "local_calls",
    "global_calls"."""

    def add(self, key: str, seconds: float) -> None:
        self[key] = self.get(key, 0.0) + seconds


def _status(pycolmap: Any, name: str) -> Any:
    return getattr(pycolmap.IncrementalPipelineStatus, name)


class _Pipeline:
    def __init__(self, pycolmap: Any, options: Any, database: Any, adjust: Callable[..., Any],
                 adjust_local: Callable[..., Any], timings: Timings) -> None:
        self.pycolmap, self.options, self.timings = pycolmap, options, timings
        self.adjust, self.adjust_local = adjust, adjust_local
        self.manager = pycolmap.ReconstructionManager()
        # pycolmap's own pipeline object, for its initialization and its test of growth, made
        # from the database: it loads the database's cache as pycolmap's incremental_mapping
        # does, and the mapper takes that cache. Given a cache made here instead, it copies it,
        # which costs more than the loading.
        self.colmap = pycolmap.IncrementalPipeline(options, database, self.manager)
        self.cache = self.colmap.database_cache
        # With use_prior_position, the database's position priors (in ENU when they were GPS).
        self.pose_priors = self.cache.pose_priors if options.use_prior_position else None

    def global_refinement(self, mapper: Any, mapper_options: Any) -> None:
        """The mapper's iterative global refinement, each adjustment by self.adjust."""
        o, tri = self.options, self.options.get_triangulation()
        rec = mapper.reconstruction
        mapper.complete_and_merge_tracks(tri)
        mapper.retriangulate(tri)
        for _ in range(o.ba_global_max_refinements):
            observations = rec.compute_num_observations()
            start = time.perf_counter()
            self.adjust(mapper, mapper_options, o.get_global_bundle_adjustment(), self.pose_priors)
            self.timings.add("global", time.perf_counter() - start)
            self.timings.add("global_calls", 1)
            if not o.use_prior_position:
                rec.normalize()
            changed = mapper.complete_and_merge_tracks(tri) + mapper.filter_points(mapper_options)
            if observations == 0 or changed / observations < o.ba_global_max_refinement_change:
                break
        mapper.filter_frames(mapper_options)

    def local_refinement(self, mapper: Any, mapper_options: Any, image_id: int) -> None:
        """The mapper's iterative local refinement of image_id, each adjustment by
        self.adjust_local: local adjustments (merging, completing and filtering tracks) until few
        observations change, the robust loss only in the first."""
        o = self.options
        ba_options, tri = o.get_local_bundle_adjustment(), o.get_triangulation()
        start = time.perf_counter()
        # Each round refines the points changed since the image was triangulated, those of the
        # rounds before too.
        for refinement in range(o.ba_local_max_refinements):
            report = self.adjust_local(mapper, mapper_options, ba_options, tri, image_id,
                                       mapper.get_modified_points3D())
            changed = report.num_merged_observations + report.num_completed_observations + \
                report.num_filtered_observations
            adjusted = report.num_adjusted_observations
            if adjusted == 0 or changed / adjusted < o.ba_local_max_refinement_change:
                break
            if refinement == 0:
                ba_options = copy.copy(ba_options)
                ba_options.ceres.loss_function_type = self.pycolmap.LossFunctionType.TRIVIAL
        mapper.clear_modified_points3D()
        self.timings.add("local", time.perf_counter() - start)
        mapper.filter_frames(mapper_options)

    def triangulate_frame(self, mapper: Any, image_id: int) -> None:
        rec = mapper.reconstruction
        frame = rec.frames[rec.images[image_id].frame_id]
        for data in frame.data_ids:
            if data.sensor_id.type.name == "CAMERA" and data.id in rec.images:
                mapper.triangulate_image(self.options.get_triangulation(), data.id)

    def sub_model(self, mapper: Any, mapper_options: Any, rec: Any) -> Any:
        pycolmap, o = self.pycolmap, self.options
        mapper.begin_reconstruction(rec)
        if rec.num_reg_frames() == 0:
            status = self.colmap.initialize_reconstruction(mapper, mapper_options, rec)
            if status != _status(pycolmap, "SUCCESS"):
                return status
        ba_frames, ba_points = rec.num_reg_frames(), rec.num_points3D()
        registered = previous = True
        while registered or previous:
            previous, registered = registered, False
            for structure_less in (False, True):
                if structure_less and (registered or not o.structure_less_registration_fallback):
                    break
                for image_id in mapper.find_next_images(mapper_options, structure_less):
                    register = mapper.register_next_structure_less_image if structure_less \
                        else mapper.register_next_image
                    if not register(mapper_options, image_id):
                        continue
                    registered = True
                    self.triangulate_frame(mapper, image_id)
                    self.local_refinement(mapper, mapper_options, image_id)
                    if self.colmap.check_run_global_refinement(rec, ba_frames, ba_points):
                        self.global_refinement(mapper, mapper_options)
                        ba_frames, ba_points = rec.num_reg_frames(), rec.num_points3D()
                    break
            if mapper.num_shared_reg_images() >= o.max_model_overlap:
                break
            if not registered and previous:
                self.global_refinement(mapper, mapper_options)
        if rec.num_reg_frames() >= 2 and rec.num_reg_frames() != ba_frames and rec.num_points3D() != ba_points:
            self.global_refinement(mapper, mapper_options)
        return _status(pycolmap, "SUCCESS")

    def reconstruct(self, mapper_options: Any) -> None:
        pycolmap, o = self.pycolmap, self.options
        mapper = pycolmap.IncrementalMapper(self.cache)
        for _ in range(o.init_num_trials):
            index = self.manager.add()
            rec = self.manager.get(index)
            status = self.sub_model(mapper, mapper_options, rec)
            if status == _status(pycolmap, "NO_INITIAL_PAIR"):
                mapper.end_reconstruction(True)
                self.manager.delete(index)
                return
            if status != _status(pycolmap, "SUCCESS"):
                mapper.end_reconstruction(True)
                self.manager.delete(index)
                continue
            min_model_size = min(0.8 * self.cache.num_images(), o.min_model_size)
            if (o.multiple_models and self.manager.size() > 1 and rec.num_reg_images() < min_model_size) \
                    or rec.num_reg_images() == 0:
                mapper.end_reconstruction(True)
                self.manager.delete(index)
            else:
                mapper.end_reconstruction(False)
            if not o.multiple_models or self.manager.size() >= o.max_num_models \
                    or mapper.num_total_reg_images() >= self.cache.num_images() - 1:
                return

    def run(self) -> None:
        mapper_options = self.options.get_mapper()
        self.reconstruct(mapper_options)
        # As COLMAP: with no model, the initialization relaxed twice.
        for relax in ("init_min_num_inliers", "init_min_tri_angle"):
            if self.manager.size() > 0:
                break
            if relax == "init_min_num_inliers":
                mapper_options.init_min_num_inliers //= 2
            else:
                mapper_options.init_min_tri_angle /= 2
            self.reconstruct(mapper_options)


def incremental_mapping(pycolmap: Any, database_path: Any, image_path: Any, output_path: Any, options: Any,
                        adjust: Callable[..., Any], adjust_local: Callable[..., Any],
                        timings: Timings) -> Dict[int, Any]:
    """The models of COLMAP's incremental mapping of the database, each global adjustment by
    adjust(mapper, mapper_options, ba_options, pose_priors) (pose_priors: the database's with
    options.use_prior_position, None otherwise), each local one by adjust_local(mapper,
    mapper_options, ba_options, tri_options, image_id, point3D_ids) (a
    LocalBundleAdjustmentReport, as the mapper's adjust_local_bundle), written to output_path/<index> as pycolmap
    writes them; timings gets the seconds of the steps."""
    start = time.perf_counter()
    db = pycolmap.Database.open(os.fspath(database_path))
    try:
        pipeline = _Pipeline(pycolmap, options, db, adjust, adjust_local, timings)
        pipeline.run()
    finally:
        db.close()
    out = {}
    for index in range(pipeline.manager.size()):
        rec = pipeline.manager.get(index)
        if options.extract_colors:
            rec.extract_colors_for_all_images(os.fspath(image_path))
        path = os.path.join(os.fspath(output_path), str(index))
        os.makedirs(path, exist_ok=True)
        rec.write(path)
        out[index] = rec
    timings["total"] = time.perf_counter() - start
    return out
