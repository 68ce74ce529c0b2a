# SPDX-License-Identifier: BSD-3-Clause
"""Priors in pysba's solves: point priors, linear camera priors and camera priors given by a
Python callback (docs/priors.md), on the 7-camera problem of sba's demo."""
import math

import numpy as np
import pytest

import pysba
from conftest import DEMO, need
from euclidean import Euclidean

SHIFT = np.array([2e-4, -1e-4, 1e-4])  # the scene is about 1e-2 across
SIGMA = 1e-5


@pytest.fixture
def scene(cams7):
    """The problem, its Python model, and the model's optimum (the starting point here)."""
    p = cams7
    m = Euclidean(p.cameras, p.calibration)
    best = pysba.motstr(m.project, m.initial, p.points, p.camera_index, p.point_index, p.observations,
                        jacobian=m.jacobian)
    return p, m, best


def refine(scene, **kw):
    p, m, best = scene
    return pysba.motstr(m.project, best.cameras, best.points, p.camera_index, p.point_index,
                        p.observations, jacobian=m.jacobian, **kw)


def rotated_back(v, w, t):
    """Rs^T t for the unit correction qs = (w, v) of the model."""
    return t - 2 * w * np.cross(v, t) + 2 * np.cross(v, np.cross(v, t))


def centre(m, j, a):
    """Camera j's centre C = -R^T t, R = Rs(v) R0_j, from its parameters (v, t)."""
    v, t = a[:3], a[3:6]
    return -m.R0[j].T @ rotated_back(v, math.sqrt(1.0 - v @ v), t)


def centre_jacobian(m, j, a):
    """dC/d(v, t), (3, 6)."""
    v, t = a[:3], a[3:6]
    w = math.sqrt(1.0 - v @ v)
    J = np.empty((3, 6))
    for k, e in enumerate(np.eye(3)):
        dw = -v[k] / w
        J[:, k] = (-2 * dw * np.cross(v, t) - 2 * w * np.cross(e, t) + 2 * np.cross(e, np.cross(v, t))
                   + 2 * np.cross(v, np.cross(e, t)))
        J[:, 3 + k] = rotated_back(v, w, e)
    return -m.R0[j].T @ J


def gps_priors(scene, with_jac, **more):
    p, m, best = scene
    fixes = [centre(m, j, best.cameras[j]) + SHIFT for j in range(p.ncameras)]
    return [dict(camera=j, dim=3, func=lambda j, a: centre(m, j, a) - fixes[j], sigma=[SIGMA] * 3,
                 jac=(lambda j, a: centre_jacobian(m, j, a)) if with_jac else None, **more)
            for j in range(p.ncameras)]


def test_point_priors_pull_the_scene_to_their_means(scene):
    p, m, best = scene
    means = best.points + SHIFT
    priors = [dict(point=i, mean=means[i], sigma=[SIGMA] * 3) for i in range(p.npoints)]
    r = refine(scene, point_priors=priors)
    assert np.all(np.abs(r.points - means) < SIGMA)
    # A translation of the whole scene: the projections are as good as at the optimum.
    assert r.projection_cost_final == pytest.approx(best.info[1], rel=1e-3)
    assert r.prior_cost_initial > 1e3 * r.prior_cost_final


def test_a_linear_prior_moves_an_intrinsic_to_its_mean():
    p = pysba.read_eucsbademo(need(DEMO / "7camsvarK.txt"), DEMO / "7pts.txt")
    free = pysba.solve(p)
    mean = free.cameras[3, 0] + 5.0  # fu of camera 3, in pixels
    r = pysba.solve(p, camera_linear_priors=[dict(camera=3, params=[0], mean=[mean], sigma=[1e-6])])
    assert abs(r.cameras[3, 0] - mean) < 1e-4 and abs(free.cameras[3, 0] - mean) > 4


def test_a_camera_centre_prior_by_callback_with_and_without_its_jacobian(scene):
    p, m, best = scene
    # Trust-region: sba's strategy stops on a small relative reduction (eps4) before the scene's
    # rotation, which the centres hold only weakly, has settled to 1e-9.
    with_jac = refine(scene, camera_priors=gps_priors(scene, True), strategy="trust-region")
    without = refine(scene, camera_priors=gps_priors(scene, False), strategy="trust-region")
    for j in range(p.ncameras):
        fix = centre(m, j, best.cameras[j]) + SHIFT
        assert np.all(np.abs(centre(m, j, with_jac.cameras[j]) - fix) < SIGMA)
    assert np.allclose(with_jac.cameras, without.cameras, rtol=0, atol=1e-9)
    assert np.allclose(with_jac.points, without.points, rtol=0, atol=1e-9)
    assert with_jac.info[1] == pytest.approx(without.info[1], rel=1e-9)


def test_the_costs_add_up_to_the_total(scene):
    p, m, best = scene
    points = [dict(point=i, mean=best.points[i] + SHIFT, sigma=[SIGMA] * 3, loss="cauchy", loss_scale=3)
              for i in range(0, p.npoints, 7)]
    r = refine(scene, point_priors=points, camera_priors=gps_priors(scene, True), loss="huber", loss_scale=2)
    assert r.prior_cost_final > 0 and r.projection_cost_final > 0
    assert r.projection_cost_initial + r.prior_cost_initial == pytest.approx(r.info[0], rel=1e-12)
    assert r.projection_cost_final + r.prior_cost_final == pytest.approx(r.info[1], rel=1e-12)
    assert best.prior_cost_initial == best.prior_cost_final == 0
    assert best.projection_cost_final == best.info[1]


def test_camera_priors_in_mot_and_point_priors_in_structure(scene):
    p, m, best = scene
    args = (best.cameras, best.points, p.camera_index, p.point_index, p.observations)
    a = pysba.mot(m.project, *args, jacobian=lambda *x: (m.jacobian(*x)[0], None),
                  camera_linear_priors=[dict(camera=2, params=[3], mean=[best.cameras[2, 3] + 1e-3],
                                             sigma=[1e-9])])
    assert a.cameras[2, 3] == pytest.approx(best.cameras[2, 3] + 1e-3, abs=1e-8)
    s = pysba.structure(m.project, *args, jacobian=lambda *x: (None, m.jacobian(*x)[1]),
                        point_priors=[dict(point=4, mean=best.points[4] + SHIFT, covariance=np.eye(3) * 1e-20)])
    assert np.allclose(s.points[4], best.points[4] + SHIFT, rtol=0, atol=1e-9)


LIBRARY_REFUSALS = [
    (dict(point_priors=[dict(point=5, mean=[0, math.nan, 0])]), "point prior 0 (point 5): mean[1] is not finite"),
    (dict(point_priors=[dict(point=1, mean=[0, 0, 0]), dict(point=5, mean=[0, 0, 0], sigma=[1, 1, -0.2])]),
     "point prior 1 (point 5): weight.sigma[2] (a standard deviation) must be finite and positive (got -0.2)"),
    (dict(point_priors=[dict(point=1000, mean=[0, 0, 0])]), "point prior 0 (point 1000): there is no such point"),
    (dict(point_priors=[dict(point=0, mean=[0, 0, 0])], ncon=1),
     "point prior 0 (point 0): the point is fixed (below ncon = 1)"),
    (dict(camera_linear_priors=[dict(camera=2, params=[1], mean=[0])], fixed_params=[0, 1, 0, 0, 0, 0]),
     "camera linear prior 0 (camera 2): params[0] = 1 is held (cam_fixed): a prior on a held parameter would "
     "change nothing"),
    (dict(camera_linear_priors=[dict(camera=0, params=[1], mean=[0], loss="hubber")]),
     'camera linear prior 0 (camera 0): unknown loss "hubber"'),
    (dict(camera_priors=[dict(camera=0, dim=0, func=lambda j, a: a[:0])]),
     "camera prior 0 (camera 0): dim must be in 1..64 (got 0)"),
]


@pytest.mark.parametrize("kw, message", LIBRARY_REFUSALS)
def test_bad_priors_are_the_librarys_value_errors(scene, kw, message):
    with pytest.raises(ValueError) as e:
        refine(scene, **kw)
    assert str(e.value).startswith("sba_motstr_levmar_x_vis: " + message)


def centre_of_two(j, a):
    return a[:2]


PYSBA_REFUSALS = [
    (dict(point_priors=5), TypeError, "point_priors must be a sequence of dicts, got int"),
    (dict(point_priors={"point": 0}), TypeError, "point_priors must be a sequence of dicts, got dict"),
    (dict(point_priors=[(0, [0, 0, 0])]), TypeError, "point_priors[0] must be a dict, got tuple"),
    (dict(point_priors=[dict(point=0, mean=[0, 0, 0], sigmas=[1, 1, 1])]), TypeError,
     "point_priors[0] has an unknown key 'sigmas' (known: point, mean, sigma, covariance, sqrt_info, loss, "
     "loss_scale)"),
    (dict(point_priors=[dict(point=0)]), TypeError, "point_priors[0] needs 'mean'"),
    (dict(point_priors=[dict(point=1.5, mean=[0, 0, 0])]), TypeError,
     "point_priors[0]['point'] must be an int, got float"),
    (dict(point_priors=[dict(point=0, mean="abc")]), TypeError, "point_priors[0]['mean']"),
    (dict(point_priors=[dict(point=0, mean=[0, 0])]), ValueError,
     "point_priors[0]['mean'] must have shape (3,), got (2,)"),
    (dict(point_priors=[dict(point=0, mean=[0, 0, 0], covariance=np.eye(2))]), ValueError,
     "point_priors[0]['covariance'] must have shape (3, 3), got (2, 2)"),
    (dict(camera_linear_priors=[dict(camera=0, params=[0, 1], mean=[0])]), ValueError,
     "camera_linear_priors[0]['mean'] must have shape (2,), got (1,)"),
    (dict(camera_linear_priors=[dict(camera=0, params=[0.5], mean=[0])]), ValueError,
     "camera_linear_priors[0]['params'][0] must be an integer, got 0.5"),
    (dict(camera_priors=[dict(camera=0, dim=3, func=1)]), TypeError,
     "camera_priors[0]['func'] must be callable, got int"),
    (dict(camera_priors=[dict(camera=0, dim=3, func=centre_of_two)]), ValueError,
     "camera_priors[0]['func']'s result must have shape (3,), got (2,)"),
    (dict(camera_priors=[dict(camera=0, dim=2, func=centre_of_two, jac=lambda j, a: np.zeros((2, 5)))]),
     ValueError, "camera_priors[0]['jac']'s result must have shape (2, 6), got (2, 5)"),
    (dict(camera_priors=[dict(camera=0, dim=2, func=centre_of_two, sigma=[1, 1, 1])]), ValueError,
     "camera_priors[0]['sigma'] must have shape (2,), got (3,)"),
]


@pytest.mark.parametrize("kw, error, message", PYSBA_REFUSALS)
def test_bad_types_and_shapes_are_pysbas_errors(scene, kw, error, message):
    with pytest.raises(error) as e:
        refine(scene, **kw)
    assert str(e.value).startswith(message)


@pytest.mark.parametrize("where", ["func", "jac"])
def test_an_exception_in_a_prior_callback_propagates(scene, where):
    calls = []
    # func runs at every evaluation of the cost, jac once per linearization: how many
    # linearizations a solve from the optimum makes is the BLAS's and the build's, the first is not.
    raise_at = 3 if where == "func" else 1

    def raising(j, a):
        calls.append(j)
        if len(calls) == raise_at:
            raise ZeroDivisionError("from the prior")
        return a[3:6] if where == "func" else np.hstack([np.zeros((3, 3)), np.eye(3)])

    prior = dict(camera=1, dim=3, func=raising, sigma=[1.0] * 3)
    if where == "jac":
        prior.update(func=lambda j, a: a[3:6], jac=raising)
    with pytest.raises(ZeroDivisionError, match="from the prior") as e:
        refine(scene, camera_priors=[prior])
    assert len(calls) == raise_at and e.traceback[-1].name == "raising"
    assert e.value.result.reason == pysba.Reason.USER


def test_priors_in_solve_reach_the_builtin_models(cams7):
    free = pysba.solve(cams7)
    means = free.points[:3] + SHIFT
    r = pysba.solve(cams7, point_priors=[dict(point=i, mean=means[i], sigma=[SIGMA] * 3) for i in range(3)])
    assert r.prior_cost_final > 0
    assert r.projection_cost_final + r.prior_cost_final == pytest.approx(r.info[1], rel=1e-12)


def test_camera_priors_in_solve_with_threads(cams7):
    # solve's own model runs on several threads; the priors' Python callbacks still run on the
    # calling thread, with the GIL, and the thread count changes nothing.
    free = pysba.solve(cams7)
    targets = free.cameras[:, 4:7] + SHIFT  # t of the file's rows: the last three parameters

    def t_prior(j, a):
        return a[3:6] - targets[j]

    priors = [dict(camera=j, dim=3, func=t_prior, sigma=[SIGMA] * 3) for j in range(1, cams7.ncameras)]
    one = pysba.solve(cams7, threads=1, camera_priors=priors)
    two = pysba.solve(cams7, threads=2, camera_priors=priors)
    assert np.array_equal(one.cameras, two.cameras) and one.prior_cost_final == two.prior_cost_final
    assert one.prior_cost_final < one.prior_cost_initial
