# SPDX-License-Identifier: BSD-3-Clause
"""pysba: sparse bundle adjustment (the sba library) for Python.

numpy arrays in, numpy arrays out::

    import pysba
    problem = pysba.read_eucsbademo("data/orbit-fixedK-cams.txt", "data/orbit-fixedK-pts.txt",
                                    "data/orbit-fixedK-calib.txt")  # in the repository
    result = pysba.solve(problem)
    print(result.initial_mse, "->", result.final_mse, result.reason.name)

- :func:`read_eucsbademo` and :func:`read_bal` read problems into a :class:`Problem`;
  :func:`solve` refines them with the library's own camera models (the C programs'
  eucsbademo and balsba models, at the same speed and with the same results).
- :func:`motstr`, :func:`mot` and :func:`structure` take a camera model written in Python:
  vectorized callbacks over all the observations at once.
- :func:`read_colmap` and :func:`write_colmap` read and write COLMAP sparse models (a
  :class:`ColmapModel`), :func:`refine_colmap` refines one as the sbarefine program does,
  and :func:`from_pycolmap` and :func:`to_pycolmap` convert from and to pycolmap;
  :func:`pysba.colmap.bundle_adjustment` is pycolmap's bundle adjuster, with its options and
  configuration, in place.

Every solve releases the GIL while the library works. Ctrl-C stops it after the current
iteration and raises KeyboardInterrupt with the partial :class:`Result` as its ``result``
attribute; an exception raised in a callback stops it the same way and propagates.
Bad arguments raise ValueError (or TypeError), unreadable files OSError, and a solve that
fails numerically :class:`SolveError`, a RuntimeError that carries the ``result`` too.
"""
from __future__ import annotations

import enum
import itertools
import math
import os
import re
import sys
import warnings
from typing import Any, Callable, Optional, Sequence, Tuple

import numpy as np

from . import _core
from ._core import Progress

__all__ = [
    "Problem", "Result", "Reason", "Progress", "SolveError", "read_eucsbademo", "read_bal",
    "solve", "motstr", "mot", "structure", "solver_names", "strategy_names", "SBA_VERSION",
    "ColmapModel", "ColmapCamera", "ColmapImage", "ColmapPoints3D", "ColmapRig", "ColmapSensor",
    "ColmapFrame", "NO_POINT3D", "read_colmap", "write_colmap", "refine_colmap", "from_pycolmap",
    "to_pycolmap",
]

SBA_VERSION: str = _core.SBA_VERSION

# The library's version, as SBA_VERSION ends with it ("(sba-cpp 0.1.0)"), which the programs'
# --version print and setup.py gives the package.
_version = re.fullmatch(r".*\(sba-cpp ([0-9][0-9A-Za-z.+-]*)\)", SBA_VERSION)
if _version is None:
    raise ImportError(f"pysba cannot read the library's version in SBA_VERSION {SBA_VERSION!r}")
__version__: str = _version.group(1)


class Reason(enum.IntEnum):
    """Why a solve stopped: sba 1.6's info[6] (0, 8 and 9 are this library's), named as
    sba_ext.h's ``SBA_STOP_*``; ``text`` says it in the library's words."""

    NONE = 0
    GRADIENT = 1
    STEP = 2
    ITMAX = 3
    REDUCTION = 4
    ERROR = 5
    DAMPING = 6
    NONFINITE = 7
    SINGULAR = 8
    USER = 9  # the progress callback or Ctrl-C

    @property
    def text(self) -> str:
        """The reason in words (sba_stop_reason_text), e.g. ``"small step: ||dp|| <= eps2 ||p||"``."""
        return _core.stop_reason_text(int(self))


# The library knows the reasons 0, 1, ... up to the first value it calls "unknown"; a Reason
# that is not among them, or one missing, means this file and the library disagree.
if [int(r) for r in Reason] != list(itertools.takewhile(
        lambda v: _core.stop_reason_text(v) != _core.stop_reason_text(-1), itertools.count())):
    raise ImportError("pysba.Reason does not match the library's stop reasons (sba_ext.h)")


class SolveError(RuntimeError):
    """The library failed to solve (or to compute the covariance); ``result`` holds where
    the solve stood (the last accepted estimate)."""

    def __init__(self, message: str, result: Optional["Result"] = None):
        super().__init__(message)
        self.result = result


def solver_names() -> list:
    """The linear solvers the ``solver=`` argument accepts."""
    return _core.solver_names().split()


def strategy_names() -> list:
    """The Levenberg-Marquardt strategies the ``strategy=`` argument accepts."""
    return _core.strategy_names().split()


class Problem:
    """A bundle adjustment problem: cameras, points and their observations, as numpy arrays.

    model
        ``"eucsbademo"`` (cameras as rows of eucsbademo's camera files: 7 values
        ``q0 q1 q2 q3 t0 t1 t2`` with the shared ``calibration`` K, or 12 values with the
        intrinsics ``fu u0 v0 ar s`` first, or 17 with the distortion ``kc0..kc4`` after
        them) or ``"bal"`` (9 values ``w1 w2 w3 t1 t2 t3 f k1 k2`` per camera).
    cameras, points
        (m, cnp) and (n, 3) float arrays.
    camera_index, point_index, observations
        One row per observation: which camera sees which point where (observations is
        (nobs, 2), in pixels). Any order; the readers give sba's (point by point, cameras
        ascending). A (camera, point) pair may appear only once. The indices are integers
        (floats that hold integers are taken; a fraction, NaN or Inf is a ValueError).
    covariances
        None, or one 2x2 covariance per observation, (nobs, 2, 2).
    calibration
        The 3x3 K of eucsbademo's 7-value cameras; None otherwise.
    """

    def __init__(self, model: str, cameras: Any, points: Any, camera_index: Any,
                 point_index: Any, observations: Any, covariances: Any = None,
                 calibration: Any = None):
        if not isinstance(model, str):
            raise TypeError(f"model must be a str, got {type(model).__name__}")
        if model not in ("eucsbademo", "bal"):
            raise ValueError(f"model must be 'eucsbademo' or 'bal', got {model!r}")
        self.model = model
        self.cameras = _core.float_array(cameras, "cameras")
        self.points = _core.float_array(points, "points")
        # Checked, not converted by truncation: an index of 2.9999999999999996 is an error, not 2.
        self.camera_index = _core.index_array(camera_index, "camera_index", len(self.cameras))
        self.point_index = _core.index_array(point_index, "point_index", len(self.points))
        self.observations = _core.float_array(observations, "observations")
        self.covariances = None if covariances is None else _core.float_array(covariances, "covariances")
        self.calibration = None if calibration is None else _core.float_array(calibration, "calibration")

    @property
    def ncameras(self) -> int:
        return int(self.cameras.shape[0])

    @property
    def npoints(self) -> int:
        return int(self.points.shape[0])

    @property
    def nobservations(self) -> int:
        return int(self.observations.shape[0])

    def __repr__(self) -> str:
        return (f"Problem(model={self.model!r}, cameras={self.ncameras}, points={self.npoints}, "
                f"observations={self.nobservations})")


class Result:
    """What a solve did.

    Attributes: ``cameras`` and ``points`` (refined, laid out as given), ``initial_mse``
    and ``final_mse`` (mean squared reprojection error per observation, as eucsbademo
    prints it: info[0] and info[1] over the number of observations), ``iterations``,
    ``reason`` (a :class:`Reason`: ``.name``, ``.text`` and the 1.6 number), ``info`` (sba's ten
    values), ``nfev``, ``njev``, ``nlinsys``, ``nobs`` (the observations solved for),
    ``threads``, ``solver`` and ``strategy``
    (what ran: with ``solver="auto"``, the default, the solver auto chose),
    ``sq_error_initial``/``sq_error_final`` (plain squared error, also with a
    robust loss), ``rms_initial``/``rms_final`` (the RMS reprojection error in pixels of that
    squared error, as sbarefine reports it), ``outliers`` (observations beyond the loss scale),
    ``projection_cost_initial``/``projection_cost_final`` and
    ``prior_cost_initial``/``prior_cost_final`` (the cost the solve minimizes, info[0] and
    info[1], apart: the projections' robust cost and the priors', 0 without priors),
    ``log`` (the library's warnings), ``model`` (:func:`refine_colmap`'s refined model, of the
    type it returns, else None), ``behind`` (the observations :func:`refine_colmap` removed
    for their depth, as (IMAGE_ID, POINT2D_IDX); else empty)
    and, with ``covariance=True``, ``camera_covariance`` (m, cnp, cnp), ``point_covariance``
    (n, pnp, pnp), ``sigma2``, ``rank`` and ``nfree`` (see sba_ext.h). For eucsbademo
    problems the camera covariance is over the optimized parameters (intrinsics, the
    rotation's local correction v, t), not over the file's quaternion. With
    :func:`refine_colmap`'s ``covariance=True``, ``colmap_covariance`` instead (see there).
    :func:`refine_colmap` with position priors says in ``colmap_priors`` how it used them.
    """

    def __init__(self, report: dict):
        info = np.array(report["info"], dtype=np.float64)
        nobs = max(int(report["nobs"]), 1)
        self.cameras: np.ndarray = report["cameras"]
        self.points: np.ndarray = report["points"]
        self.info: np.ndarray = info
        self.initial_mse = float(info[0]) / nobs
        self.final_mse = float(info[1]) / nobs
        self.iterations = int(info[5])
        self.reason = Reason(int(info[6])) if int(info[6]) in Reason._value2member_map_ else Reason.NONE
        self.nfev, self.njev, self.nlinsys = int(info[7]), int(info[8]), int(info[9])
        self.nobs = int(report["nobs"])
        self.threads: int = report["threads"]
        self.solver: Optional[str] = report["solver"]
        self.strategy: Optional[str] = report["strategy"]
        self.sq_error_initial: float = report["sq_error_initial"]
        self.sq_error_final: float = report["sq_error_final"]
        self.rms_initial = math.sqrt(self.sq_error_initial / nobs)
        self.rms_final = math.sqrt(self.sq_error_final / nobs)
        self.projection_cost_initial: float = report["projection_cost_initial"]
        self.projection_cost_final: float = report["projection_cost_final"]
        self.prior_cost_initial: float = report["prior_cost_initial"]
        self.prior_cost_final: float = report["prior_cost_final"]
        self.model: Any = report.get("model")
        self.behind: list = list(report.get("behind", []))
        self.outliers: int = report["outliers"]
        self.log: list = list(report["warnings"])
        self.camera_covariance: Optional[np.ndarray] = report.get("camera_covariance")
        self.point_covariance: Optional[np.ndarray] = report.get("point_covariance")
        self.sigma2: Optional[float] = report.get("sigma2")
        self.rank: Optional[int] = report.get("rank")
        self.nfree: Optional[int] = report.get("nfree")
        self.colmap_covariance: Optional[dict] = report.get("colmap_covariance")
        self.colmap_priors: str = report.get("priors_said", "").strip()

    def __repr__(self) -> str:
        return (f"Result(final_mse={self.final_mse:g}, initial_mse={self.initial_mse:g}, "
                f"iterations={self.iterations}, reason={self.reason.name})")


def _warn(message: str) -> None:
    """A RuntimeWarning attributed to the line that called pysba (the first frame outside it)."""
    level, frame = 2, sys._getframe(1)
    while frame is not None and os.path.dirname(frame.f_code.co_filename) == os.path.dirname(__file__):
        level, frame = level + 1, frame.f_back
    warnings.warn(message, RuntimeWarning, stacklevel=level)


def _finish(report: dict) -> Result:
    """The Result of a report from _core, or the exception it stands for. The library's
    warnings, which it gives unasked only for an environment variable it ignores, are Python
    warnings too, as the programs print them, in pysba's name rather than the C driver's."""
    for line in dict.fromkeys(report["warnings"]):
        _warn(re.sub(r"^sba_\w+: ", "pysba: ", line))
    result = Result(report)
    error = report["error"]
    if error is not None:
        # A callback's exception (KeyboardInterrupt included), raised again with the
        # traceback it was raised with; the partial result travels with it.
        try:
            error.result = result
        except AttributeError:
            pass
        raise error
    if report["ret"] == -1:
        message = "; ".join(report["errors"]) or f"the solve failed (reason {result.reason.name})"
        if result.reason == Reason.NONE:
            raise ValueError(message)
        raise SolveError(message, result)
    if "covariance_error" in report:
        raise SolveError(report["covariance_error"], result)
    return result


def _readable(path: Any, name: str = "path") -> bytes:
    """path in the file system's encoding, after opening it once: a missing or unreadable
    file raises the usual OSError subclass (FileNotFoundError, PermissionError,
    IsADirectoryError). Bytes, so that any name Python can open reaches the reader, also
    one that is not UTF-8 (a str with lone surrogates, as os.fsdecode gives for it)."""
    if not isinstance(path, (str, bytes, os.PathLike)):
        raise TypeError(f"{name} must be a str, bytes or os.PathLike, got {type(path).__name__}")
    # Opened as given, so that an error names the path as the caller wrote it.
    with open(path, "rb"):
        pass
    return os.fsencode(path)


def read_eucsbademo(cams: Any, pts: Any, calib: Any = None) -> Problem:
    """Reads eucsbademo's camera and point files (and the calibration file that goes with
    7-value cameras). OSError for a file that cannot be read, ValueError with the reader's
    ``file:line: message`` for bad content."""
    paths = [_readable(cams, "cams"), _readable(pts, "pts"), b"" if calib is None else _readable(calib, "calib")]
    d = _core.read_eucsbademo(*paths)
    return Problem("eucsbademo", **d)


def read_bal(path: Any) -> Problem:
    """Reads a BAL ("Bundle Adjustment in the Large") problem file, plain or
    bzip2-compressed. Observations come in sba's order (point by point). OSError for a
    file that cannot be read, ValueError naming the line for bad content."""
    d = _core.read_bal(_readable(path))
    return Problem("bal", **d)


def _options(solver, threads, strategy, loss, loss_scale, itmax, opts, mcon, ncon, progress, **more) -> dict:
    # Passed on as given: _core checks each one's type and value and names it in the error.
    return dict(solver=solver, threads=threads, strategy=strategy, loss=loss, loss_scale=loss_scale,
                itmax=itmax, opts=opts, mcon=mcon, ncon=ncon, progress=progress, **more)


def solve(problem: Problem, *, solver: Optional[str] = None, threads: int = 0,
          strategy: Optional[str] = None,
          loss: Optional[str] = None, loss_scale: float = 1.0, itmax: int = 150,
          opts: Optional[Sequence[float]] = None, mcon: int = 0, ncon: int = 0,
          progress: Optional[Callable[[Progress], Any]] = None, covariance: bool = False,
          nccalib: int = 2, ncdist: int = 3, fixed_params: Any = None, camera_groups: Any = None,
          shared_params: Any = None, param_groups: Any = None, point_priors: Any = None,
          camera_linear_priors: Any = None, camera_priors: Any = None) -> Result:
    """Refines the cameras and points of a problem (motion and structure) with the library's
    camera model for it, as the eucsbademo and balsba programs do, and returns a
    :class:`Result`; the problem is left unchanged.

    solver
        The linear solver (:func:`solver_names`); None: $SBA_LINSOLVER, else "auto" (chol,
        sparse-chol or iterative-schur, chosen from the problem: docs/solvers.md); the
        result's ``solver`` names the one that ran.
    threads
        0: the library's choice; results do not depend on it.
    strategy
        How LM damps, accepts steps and stops (:func:`strategy_names`): "sba" (sba 1.6's
        algorithm), "sba-clean-retry" (the same, each retry damping the undamped normal
        equations, as the sba paper states it) or "trust-region" (Marquardt's scaled
        damping; usually fewer iterations). None: $SBA_STRATEGY, else "sba" (refine_colmap:
        "trust-region", COLMAP's, see there), in solve, motstr, mot and structure alike.
    loss, loss_scale
        Robust loss ("huber", "cauchy", "soft-l1", "tukey"; None: least squares) and its
        scale in pixels.
    itmax, opts
        Most iterations; sba's (tau, eps1, eps2, eps3, eps4), None for the defaults
        (1e-3, 1e-12, 1e-12, 1e-12, 0).
    mcon, ncon
        The first mcon cameras and ncon points are held fixed.
    progress
        Called with a :class:`Progress` after every iteration; a true return value stops
        the solve (reason USER), an exception stops it and propagates.
    covariance
        Also compute the covariance blocks of every camera and point at the result. Ctrl-C
        interrupts it too: the KeyboardInterrupt's ``result`` is then the finished solve.
    nccalib, ncdist
        eucsbademo cameras with intrinsics: how many trailing intrinsics (of fu u0 v0 ar s)
        and distortion terms (of kc0..kc4) are held fixed, as eucsbademo's options.
    fixed_params
        Camera parameters held at their initial values: bools (or integers 0 and 1) of shape
        (cnp,) for every camera, or (m, cnp) camera by camera. None: only mcon's.
    camera_groups, shared_params
        Camera parameters shared by groups of cameras (one lens for several images): a group
        number per camera (integers, -1: none; [0, m-1]: a group) and the cnp flags of the
        parameters a group shares; give both. A group's shared parameters start from its
        first camera's and are solved as one. Other values (strs, fractions, NaN, bools as
        group numbers) raise TypeError or ValueError naming the entry; the library's refusals
        (a number that is no group, one of the two without the other) are ValueErrors with
        its message.
    param_groups
        Camera parameters shared parameter by parameter, for groupings that differ from one
        parameter to the next (a rig: the focal length by physical camera, the pose by
        frame): an (m, cnp) array of group numbers, ``param_groups[j, c]`` camera j's for
        parameter c, -1 for a parameter of its own. Cameras whose numbers for a parameter
        are equal (and not -1) share it as one unknown; the numbers of different parameters
        are unrelated. Read as camera_groups' numbers are. Not with camera_groups and
        shared_params (which mean ``param_groups[j, c] = camera_groups[j]`` where
        ``shared_params[c]``, else -1); the library's refusals (that one, a shared parameter
        held in only some of its cameras, a camera below mcon in a group) are ValueErrors
        with its message.
    point_priors, camera_linear_priors, camera_priors
        Priors: residuals beside the projections that keep a point near a known position, some
        camera parameters near known values, or any function of a camera's parameters (its
        centre: a GPS fix) near zero; each a sequence of dicts (docs/priors.md, docs/python.md):

        - point prior: ``point`` (index), ``mean`` (pnp values);
        - camera linear prior: ``camera`` (index), ``params`` (indices of the camera's
          parameters, k of them) and ``mean`` (k values), the residual ``a_j[params] - mean``;
        - camera prior: ``camera``, ``dim``, ``func(j, a_j)`` returning the residual (dim
          values) from camera j's parameters (cnp floats, as the solve sees them: for
          eucsbademo problems the optimized ones, see ``camera_covariance``), optionally
          ``jac(j, a_j)`` returning its derivatives (dim, cnp) (None: forward differences),
          called from the calling thread; an exception in them stops the solve and propagates;

        and in each at most one weight: ``sigma`` (k standard deviations), ``covariance``
        (k x k) or ``sqrt_info`` (k x k upper-triangular L with L^T L the inverse covariance),
        none meaning the residual is weighted already; and optionally ``loss`` and
        ``loss_scale`` (as loss= and loss_scale=, for this prior alone). Wrong types and
        shapes are TypeErrors and ValueErrors naming the entry; values the library refuses (a
        point that does not exist or is held by ncon, a NaN mean, a negative sigma, a prior on
        a held parameter) are ValueErrors with its message, which names the prior. The
        result's ``projection_cost_*`` and ``prior_cost_*`` give the cost apart.
    """
    if not isinstance(problem, Problem):
        raise TypeError("problem must be a pysba.Problem")
    kw = _options(solver, threads, strategy, loss, loss_scale, itmax, opts, mcon, ncon, progress,
                  covariance=covariance, fixed_params=fixed_params, camera_groups=camera_groups,
                  shared_params=shared_params, param_groups=param_groups, point_priors=point_priors,
                  camera_linear_priors=camera_linear_priors, camera_priors=camera_priors)
    if problem.model == "bal":
        report = _core.solve_bal(problem.cameras, problem.points, problem.camera_index,
                                 problem.point_index, problem.observations, problem.covariances, **kw)
    else:
        report = _core.solve_eucsbademo(problem.cameras, problem.points, problem.camera_index,
                                        problem.point_index, problem.observations,
                                        problem.covariances, problem.calibration, nccalib=nccalib,
                                        ncdist=ncdist, **kw)
    return _finish(report)


ProjectFn = Callable[[np.ndarray, np.ndarray, np.ndarray, np.ndarray], Any]
JacobianFn = Callable[[np.ndarray, np.ndarray, np.ndarray, np.ndarray], Tuple[Any, Any]]


def _python_model(refine, project, cameras, points, camera_index, point_index, observations,
                  jacobian, covariances, kw) -> Result:
    report = _core.solve_python(refine, project, jacobian, cameras, points, camera_index,
                                point_index, observations, covariances, **kw)
    return _finish(report)


def motstr(project: ProjectFn, cameras: Any, points: Any, camera_index: Any, point_index: Any,
           observations: Any, *, jacobian: Optional[JacobianFn] = None, covariances: Any = None,
           solver: Optional[str] = None, threads: int = 0,
           strategy: Optional[str] = None,
           loss: Optional[str] = None, loss_scale: float = 1.0, itmax: int = 150,
           opts: Optional[Sequence[float]] = None, mcon: int = 0, ncon: int = 0,
           progress: Optional[Callable[[Progress], Any]] = None,
           covariance: bool = False, fixed_params: Any = None, camera_groups: Any = None,
           shared_params: Any = None, param_groups: Any = None, point_priors: Any = None,
           camera_linear_priors: Any = None, camera_priors: Any = None) -> Result:
    """Refines cameras (m, cnp) and points (n, pnp) under a camera model written in Python
    (sba_motstr_levmar_x): observation k is camera ``camera_index[k]``'s view of point
    ``point_index[k]``, measured as ``observations[k]`` (mnp values).

    project(cameras, points, cam_idx, pt_idx)
        Returns the predicted observations of the listed (camera, point) pairs, an array
        (len(cam_idx), mnp). It gets copies of the current estimate; cam_idx and pt_idx
        are int64 arrays.
    jacobian(cameras, points, cam_idx, pt_idx)
        Optional; returns (A, B), the derivatives of each prediction by its camera's
        parameters (len, mnp, cnp) and by its point's (len, mnp, pnp). None: forward
        differences (cnp + pnp calls of project per iteration).

    An exception raised by a callback stops the solve and propagates, with the partial
    result as its ``result`` attribute. The other arguments are those of :func:`solve`
    (fixed_params, camera_groups, shared_params, param_groups and the priors included).
    The callbacks are called from the calling thread, one at a time.
    """
    kw = _options(solver, threads, strategy, loss, loss_scale, itmax, opts, mcon, ncon, progress,
                  covariance=covariance, fixed_params=fixed_params, camera_groups=camera_groups,
                  shared_params=shared_params, param_groups=param_groups, point_priors=point_priors,
                  camera_linear_priors=camera_linear_priors, camera_priors=camera_priors)
    return _python_model("motstr", project, cameras, points, camera_index, point_index,
                         observations, jacobian, covariances, kw)


def mot(project: ProjectFn, cameras: Any, points: Any, camera_index: Any, point_index: Any,
        observations: Any, *, jacobian: Optional[JacobianFn] = None, covariances: Any = None,
        solver: Optional[str] = None, threads: int = 0,
        strategy: Optional[str] = None,
        loss: Optional[str] = None, loss_scale: float = 1.0, itmax: int = 100,
        opts: Optional[Sequence[float]] = None, mcon: int = 0,
        progress: Optional[Callable[[Progress], Any]] = None, fixed_params: Any = None,
        camera_groups: Any = None, shared_params: Any = None, param_groups: Any = None,
        camera_linear_priors: Any = None, camera_priors: Any = None) -> Result:
    """As :func:`motstr`, refining the cameras only (sba_mot_levmar_x): the points are data.
    jacobian may return (A, None). Camera priors only: the points are not refined."""
    kw = _options(solver, threads, strategy, loss, loss_scale, itmax, opts, mcon, 0, progress,
                  fixed_params=fixed_params, camera_groups=camera_groups, shared_params=shared_params,
                  param_groups=param_groups, camera_linear_priors=camera_linear_priors,
                  camera_priors=camera_priors)
    return _python_model("mot", project, cameras, points, camera_index, point_index,
                         observations, jacobian, covariances, kw)


def structure(project: ProjectFn, cameras: Any, points: Any, camera_index: Any, point_index: Any,
              observations: Any, *, jacobian: Optional[JacobianFn] = None, covariances: Any = None,
              solver: Optional[str] = None, threads: int = 0, strategy: Optional[str] = None,
              loss: Optional[str] = None, loss_scale: float = 1.0, itmax: int = 100,
              opts: Optional[Sequence[float]] = None, ncon: int = 0,
              progress: Optional[Callable[[Progress], Any]] = None, point_priors: Any = None) -> Result:
    """As :func:`motstr`, refining the points only (sba_str_levmar_x, "str" in sba's names,
    which pysba also answers to as ``pysba.str``): the cameras are data. jacobian may return
    (None, B). Point priors only: the cameras are not refined."""
    kw = _options(solver, threads, strategy, loss, loss_scale, itmax, opts, 0, ncon, progress,
                  point_priors=point_priors)
    return _python_model("str", project, cameras, points, camera_index, point_index,
                         observations, jacobian, covariances, kw)


def __getattr__(name: str) -> Any:
    # pysba.str, sba's name for structure(), for the code written with it: an attribute of the
    # module only when asked for, so that no `from pysba import *` shadows the builtin.
    if name == "str":
        return structure
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


# COLMAP models: after everything above, which they use.
from ._colmap import (NO_POINT3D, ColmapCamera, ColmapFrame, ColmapImage, ColmapModel,  # noqa: E402
                      ColmapPoints3D, ColmapRig, ColmapSensor, from_pycolmap, read_colmap, refine_colmap,
                      to_pycolmap, write_colmap)
from . import colmap  # noqa: E402,F401  (pysba.colmap: pycolmap's adjuster; imports pycolmap when called)
