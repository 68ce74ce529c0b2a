# SPDX-License-Identifier: BSD-3-Clause
"""Camera parameters held (fixed_params) and shared by groups (camera_groups, shared_params)
through pysba, with a camera model written in Python: rotation vector, translation and one
focal length per camera, eight images of one lens whose focal length starts 2% long."""
import numpy as np
import pytest

import pysba

TRUE_F = 800.0


def rotation(r):
    th = np.linalg.norm(r)
    if th < 1e-12:
        return np.eye(3)
    k = r / th
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + np.sin(th) * K + (1 - np.cos(th)) * K @ K


def project(cams, pts, ci, pi):
    R = np.stack([rotation(c[:3]) for c in cams])
    X = np.einsum("kab,kb->ka", R[ci], pts[pi]) + cams[ci, 3:6]
    f = cams[ci, 6]
    return np.stack((f * X[:, 0] / X[:, 2] + 320.0, f * X[:, 1] / X[:, 2] + 240.0), axis=1)


def scene(m=8, n=60, seed=3):
    rng = np.random.default_rng(seed)
    pts = rng.uniform(-1, 1, (n, 3))
    cams = np.zeros((m, 7))
    for j in range(m):
        a = 1.2 * (j / (m - 1) - 0.5)
        cams[j, :3] = (0.0, a, 0.0)
        C = np.array([-4 * np.sin(a), 0.0, -4 * np.cos(a)])
        cams[j, 3:6] = -rotation(cams[j, :3]) @ C
        cams[j, 6] = TRUE_F
    ci = np.repeat(np.arange(m), n)
    pi = np.tile(np.arange(n), m)
    order = np.lexsort((ci, pi))
    ci, pi = ci[order], pi[order]
    obs = project(cams, pts, ci, pi) + rng.normal(0, 0.5, (len(ci), 2))
    start = cams.copy()
    start[:, 6] = 1.02 * TRUE_F
    start[:, 3:6] += rng.normal(0, 0.02, (m, 3))
    return start, pts + rng.normal(0, 0.01, pts.shape), ci, pi, obs


SHARED_F = [False] * 6 + [True]


def test_a_shared_focal_length_is_one_and_comes_back():
    cams, pts, ci, pi, obs = scene()
    r = pysba.motstr(project, cams, pts, ci, pi, obs, camera_groups=[0] * 8, shared_params=SHARED_F)
    f = r.cameras[:, 6]
    assert np.all(f == f[0])
    assert abs(f[0] - TRUE_F) < 3.0  # 16 at the start
    alone = pysba.motstr(project, cams, pts, ci, pi, obs)
    assert np.ptp(alone.cameras[:, 6]) > 1.0


def test_held_parameters_keep_their_bits():
    cams, pts, ci, pi, obs = scene()
    held = np.zeros((8, 7), bool)
    held[0, :6] = True  # camera 0's pose: the gauge
    held[:, 6] = True   # every focal length
    r = pysba.motstr(project, cams, pts, ci, pi, obs, fixed_params=held)
    assert np.array_equal(r.cameras[0, :6], cams[0, :6])
    assert np.array_equal(r.cameras[:, 6], cams[:, 6])
    assert not np.array_equal(r.cameras[1, :6], cams[1, :6])
    # One row for every camera.
    r = pysba.mot(project, cams, pts, ci, pi, obs, fixed_params=[0, 0, 0, 0, 0, 0, 1])
    assert np.array_equal(r.cameras[:, 6], cams[:, 6])


def test_bad_shapes_are_value_errors():
    cams, pts, ci, pi, obs = scene(m=4, n=20)
    args = (project, cams, pts, ci, pi, obs)
    with pytest.raises(ValueError, match=r"fixed_params must have shape \(7,\) or \(4, 7\), got \(6,\)"):
        pysba.motstr(*args, fixed_params=[0] * 6)
    with pytest.raises(ValueError, match="camera_groups and shared_params go together"):
        pysba.motstr(*args, camera_groups=[0] * 4)
    with pytest.raises(ValueError, match=r"camera_groups must hold one group per camera \(4\), got 3"):
        pysba.motstr(*args, camera_groups=[0] * 3, shared_params=SHARED_F)
    with pytest.raises(ValueError, match=r"camera_groups\[1\] must be -1 or a group number >= 0, got -5"):
        pysba.motstr(*args, camera_groups=[0, -5, 0, 0], shared_params=SHARED_F)
    with pytest.raises(TypeError, match="camera_groups must be a 1-D array of ints"):
        pysba.motstr(*args, camera_groups="abc", shared_params=SHARED_F)
