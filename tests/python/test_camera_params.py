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
    with pytest.raises(ValueError, match=r"camera_groups must hold one group per camera \(4\), got 3"):
        pysba.motstr(*args, camera_groups=[0] * 3, shared_params=SHARED_F)
    with pytest.raises(TypeError, match="camera_groups must be a 1-D array of ints"):
        pysba.motstr(*args, camera_groups="abc", shared_params=SHARED_F)


# Group numbers are integers an int holds: any integer dtype, Python ints, and floats only when
# they hold integers. Nothing is rounded, wrapped or read as a bool. Which numbers are groups
# is the library's rule (test_the_library_refuses_group_numbers_that_are_no_group).
@pytest.mark.parametrize("groups, error, message", [
    ([0, 0.5, 0, 0], ValueError, "camera_groups[1] must be an integer, got 0.5"),
    (np.array([0, 0, 1.2, 0]), ValueError, "camera_groups[2] must be an integer, got 1.2"),
    ([0, 0, float("nan"), 0], ValueError, "camera_groups[2] must be an integer, got nan"),
    (np.array([0, 0, 0, -np.inf]), ValueError, "camera_groups[3] must be an integer, got -inf"),
    (np.array([0, 0, 2**64 - 1, 0], np.uint64), ValueError,
     "camera_groups[2] must be an integer within [-2147483648, 2147483647], got 18446744073709551615"),
    ([0, 2**31, 0, 0], ValueError, "camera_groups[1] must be an integer within [-2147483648, 2147483647], got 2147483648"),
    ([0, 0, 0, -2**70], ValueError, "camera_groups[3] must be an integer within [-2147483648, 2147483647], got -1180591620717411303424"),
    ([0, -2**31 - 1, 0, 0], ValueError, "camera_groups[1] must be an integer within [-2147483648, 2147483647], got -2147483649"),
    ([0, 0, -2147483649.0, 0], ValueError, "camera_groups[2] must be an integer within [-2147483648, 2147483647], got -2147483649.0"),
    ([0, True, 0, 0], TypeError, "camera_groups[1] must be an integer, got True"),
    (np.zeros(4, bool), TypeError, "camera_groups[0] must be an integer, got False"),
    ([0, 0, "1", 0], TypeError, "camera_groups[2] must be an integer, got '1'"),
    ([0, None, 0, 0], TypeError, "camera_groups[1] must be an integer, got None"),
    (np.array([0, 1, 0, 0], object), TypeError, "camera_groups must be an array of integers, got an array of object"),
    (np.array(["0"] * 4), TypeError, "camera_groups must be an array of integers, got an array of <U1"),
])
def test_group_numbers_that_are_not_integers_are_refused(groups, error, message):
    cams, pts, ci, pi, obs = scene(m=4, n=20)
    with pytest.raises(error) as e:
        pysba.motstr(project, cams, pts, ci, pi, obs, camera_groups=groups, shared_params=SHARED_F)
    assert str(e.value) == message
    assert type(e.value) is error


# Flags are bools, or integers that are 0 or 1: a str, a float (even 1.0), None or an object
# array is refused, never read by its truth value.
@pytest.mark.parametrize("kw, error, message", [
    (dict(fixed_params=["0"] * 7), TypeError, "fixed_params[0] must be 0 or 1 (or a bool), got '0'"),
    (dict(fixed_params=[0] * 6 + [0.5]), TypeError, "fixed_params[6] must be 0 or 1 (or a bool), got 0.5"),
    (dict(fixed_params=[0] * 6 + [float("nan")]), TypeError, "fixed_params[6] must be 0 or 1 (or a bool), got nan"),
    (dict(fixed_params=np.ones(7)), TypeError, "fixed_params[0] must be 0 or 1 (or a bool), got 1.0"),
    (dict(fixed_params=np.full((4, 7), 0.5)), TypeError, "fixed_params[0, 0] must be 0 or 1 (or a bool), got 0.5"),
    (dict(fixed_params=[0, 0, None, 0, 0, 0, 0]), TypeError, "fixed_params[2] must be 0 or 1 (or a bool), got None"),
    (dict(fixed_params=[0] * 6 + [2]), ValueError, "fixed_params[6] must be 0 or 1 (or a bool), got 2"),
    (dict(fixed_params=np.array([0, 0, 0, -1, 0, 0, 0], np.int8)), ValueError,
     "fixed_params[3] must be 0 or 1 (or a bool), got -1"),
    (dict(fixed_params=np.array([2**64 - 1] + [0] * 6, np.uint64)), ValueError,
     "fixed_params[0] must be 0 or 1 (or a bool), got 18446744073709551615"),
    (dict(fixed_params=np.zeros(7, object)), TypeError,
     "fixed_params must be an array of bools or integers, got an array of object"),
    (dict(fixed_params=np.array(["0"] * 7)), TypeError,
     "fixed_params must be an array of bools or integers, got an array of <U1"),
    (dict(fixed_params=True), TypeError, "fixed_params must be an array of bools or integers, got bool"),
    (dict(camera_groups=[0] * 4, shared_params=["1"] * 7), TypeError,
     "shared_params[0] must be 0 or 1 (or a bool), got '1'"),
    (dict(camera_groups=[0] * 4, shared_params=[0.0] * 6 + [1.0]), TypeError,
     "shared_params[0] must be 0 or 1 (or a bool), got 0.0"),
    (dict(camera_groups=[0] * 4, shared_params=[0] * 6 + [3]), ValueError,
     "shared_params[6] must be 0 or 1 (or a bool), got 3"),
])
def test_flags_that_are_not_bools_are_refused(kw, error, message):
    cams, pts, ci, pi, obs = scene(m=4, n=20)
    with pytest.raises(error) as e:
        pysba.motstr(project, cams, pts, ci, pi, obs, **kw)
    assert str(e.value) == message
    assert type(e.value) is error


def test_integer_groups_and_flags_of_any_integer_dtype_are_taken():
    cams, pts, ci, pi, obs = scene(m=4, n=20)
    args = (project, cams, pts, ci, pi, obs)
    held = np.zeros((4, 7), bool)
    held[0, :6] = True
    ref = pysba.motstr(*args, fixed_params=held, camera_groups=[0, 0, 1, 1], shared_params=SHARED_F)
    assert ref.cameras[0, 6] == ref.cameras[1, 6] and ref.cameras[2, 6] == ref.cameras[3, 6]
    assert ref.cameras[0, 6] != ref.cameras[2, 6]
    for fixed, groups, shared in [
        (held.astype(np.uint8), np.array([0, 0, 1, 1], np.int8), np.array(SHARED_F, np.int64)),
        (held.astype(int).tolist(), np.array([0, 0, 1, 1], np.uint64), [int(s) for s in SHARED_F]),
        ([[bool(x) for x in row] for row in held], [0.0, 0.0, 1.0, 1.0], np.array(SHARED_F)),
        (held, np.array([0, 0, 1, 1], np.float32), [np.bool_(s) for s in SHARED_F]),
        (held, [np.int16(0), np.int16(0), np.int64(1), 1], [0, 0, 0, 0, 0, False, np.int8(1)]),
    ]:
        r = pysba.motstr(*args, fixed_params=fixed, camera_groups=groups, shared_params=shared)
        assert np.array_equal(r.cameras, ref.cameras) and np.array_equal(r.points, ref.points)
    # -1 is no group, as an integer or a float.
    alone = pysba.motstr(*args, camera_groups=np.array([-1.0, 0, 0, -1]), shared_params=SHARED_F)
    assert alone.cameras[1, 6] == alone.cameras[2, 6] and alone.cameras[0, 6] != alone.cameras[1, 6]


def _value_text(e):
    """An entry as pysba's messages show it: ints and floats by their value as Python numbers."""
    if isinstance(e, (bool, np.bool_)):
        return repr(bool(e))
    if isinstance(e, (int, np.integer)):
        return repr(int(e))
    if isinstance(e, (float, np.floating)):
        return repr(float(e))
    return repr(e)


def _group_verdict(e):
    """What pysba must do with the group number e: None (take it) or (exception, message tail)."""
    if isinstance(e, (int, np.integer)) and not isinstance(e, (bool, np.bool_)):
        value = int(e)
    elif isinstance(e, (float, np.floating)):
        x = float(e)
        if not np.isfinite(x) or x != np.floor(x):
            return ValueError, f"must be an integer, got {_value_text(e)}"
        value = x
    else:
        return TypeError, f"must be an integer, got {_value_text(e)}"
    if -2**31 <= value <= 2**31 - 1:
        return None
    return ValueError, f"must be an integer within [-2147483648, 2147483647], got {_value_text(e)}"


def _flag_verdict(e):
    if isinstance(e, (bool, np.bool_)):
        return None
    if isinstance(e, (int, np.integer)):
        return None if int(e) in (0, 1) else (ValueError, f"must be 0 or 1 (or a bool), got {_value_text(e)}")
    return TypeError, f"must be 0 or 1 (or a bool), got {_value_text(e)}"


_POOL = [-2, -1, 0, 1, 2, 2**31 - 1, 2**31, 2**63 - 1, -2**63, 2**64 - 1, 2**70, -2**70,
         0.0, -0.0, 1.0, 2.0, 0.5, -1.0, -1.5, float("nan"), float("inf"), -float("inf"), 1e300, 2147483648.0,
         True, False, None, "1", b"1", 1 + 0j, np.int64(1), np.uint64(2**64 - 1), np.int8(-1), np.float32(0.5),
         np.float16(2.0), np.bool_(True), np.bool_(False)]
_DTYPES = [np.int8, np.int16, np.int32, np.int64, np.uint8, np.uint16, np.uint32, np.uint64, np.float16,
           np.float32, np.float64, np.longdouble, bool, object, "U2"]


def _draw(rng, size, valid):
    """size entries as a list, a tuple or an array of a random dtype: mostly valid entries."""
    vals = [valid[rng.integers(len(valid))] if rng.random() < 0.8 else _POOL[rng.integers(len(_POOL))]
            for _ in range(size)]
    kind = rng.integers(3)
    if kind == 0:
        return vals
    if kind == 1:
        return tuple(vals)
    dtype = _DTYPES[rng.integers(len(_DTYPES))]
    numbers = rng.integers(-3, 4, size)
    return np.array([str(v) for v in numbers] if dtype == "U2" else numbers.tolist()).astype(dtype)


def _expected(obj, name, verdict, of):
    """The error pysba must raise for obj as the option name, or None."""
    if isinstance(obj, np.ndarray):
        if obj.dtype.kind not in "biuf":
            return TypeError, f"{name} must be an array of {of}, got an array of {obj.dtype}"
        entries = [e.item() if obj.dtype.kind != "f" else float(e) for e in obj.flat]
    else:
        entries = list(obj)
    for k, e in enumerate(entries):
        v = verdict(e)
        if v is not None:
            return v[0], f"{name}[{k}] {v[1]}"
    return None


def test_random_option_entries_are_judged_by_the_rules():
    """pysba's reading of Python values (lists, tuples, arrays of every dtype, numpy scalars,
    None, strs, huge ints, NaN) against the rules written out in Python: each value is taken,
    or refused with the exception and the message the rules give."""
    cams, pts, ci, pi, obs = scene(m=3, n=6)
    args = (project, cams, pts, ci, pi, obs)
    rng = np.random.default_rng(11)
    taken = refused = 0
    for _ in range(300):
        which = rng.integers(3)
        if which == 0:
            value = _draw(rng, 3, [-1, 0, 1, 2, 0.0, 2.0, np.int32(1)])
            kw = dict(camera_groups=value, shared_params=SHARED_F)
            want = _expected(value, "camera_groups", _group_verdict, "integers")
        else:
            name = "fixed_params" if which == 1 else "shared_params"
            value = _draw(rng, 7, [0, 1, True, False, np.bool_(True), np.uint8(1)])
            kw = {name: value}
            if name == "shared_params":
                kw["camera_groups"] = [-1, -1, -1]
            want = _expected(value, name, _flag_verdict, "bools or integers")
        try:
            pysba.motstr(*args, itmax=0, **kw)
        except (TypeError, ValueError) as e:
            got = (type(e), str(e))
        else:
            got = None
        if want is None:
            # Taken by pysba; the library may still refuse a group number of no camera.
            assert got is None or (got[0] is ValueError and not got[1].startswith(tuple(kw))), (kw, got)
            taken += 1
        else:
            assert got == want, kw
            refused += 1
    assert taken > 50 and refused > 50


# param_groups: camera j's group number for each of its parameters, groupings that differ
# from one parameter to the next.

def as_param_groups(groups, shared):
    """camera_groups and shared_params written as param_groups."""
    return np.array([[g if s else -1 for s in shared] for g in groups])


def test_param_groups_as_camera_groups_and_shared_params_give_the_same_bits():
    cams, pts, ci, pi, obs = scene()
    args = (project, cams, pts, ci, pi, obs)
    groups = [0, 0, 1, 1, -1, 5, 5, 5]
    held = np.zeros((8, 7), bool)
    held[0, :6] = True
    for run in (pysba.motstr, pysba.mot):
        one = run(*args, fixed_params=held, camera_groups=groups, shared_params=SHARED_F)
        per = run(*args, fixed_params=held, param_groups=as_param_groups(groups, SHARED_F))
        assert np.array_equal(per.cameras, one.cameras) and np.array_equal(per.points, one.points)
        assert np.array_equal(per.info, one.info)
        assert per.cameras[5, 6] == per.cameras[7, 6] and per.cameras[4, 6] != per.cameras[5, 6]


def test_solve_takes_param_groups():
    # A BAL problem (rotation, translation, f, k1, k2): six images of one lens.
    rng = np.random.default_rng(7)
    m, n = 6, 40
    cams = np.zeros((m, 9))
    cams[:, 3], cams[:, 5], cams[:, 6] = np.linspace(-2, 2, m), -10, 500
    pts = rng.uniform(-1, 1, (n, 3))
    ci, pi = np.tile(np.arange(m), n), np.repeat(np.arange(n), m)
    P = pts[pi] + cams[ci, 3:6]
    obs = 500 * -P[:, :2] / P[:, 2:3] + rng.normal(0, 0.5, (len(ci), 2))
    cams[:, 3:6] += rng.normal(0, 1e-3, (m, 3))
    cams[:, 6] = 510
    problem = pysba.Problem("bal", cams, pts, ci, pi, obs)
    lens = [0] * 6 + [1] * 3
    one = pysba.solve(problem, camera_groups=[0] * m, shared_params=lens)
    per = pysba.solve(problem, param_groups=as_param_groups([0] * m, lens))
    assert np.array_equal(per.cameras, one.cameras) and np.array_equal(per.points, one.points)
    assert np.all(per.cameras[:, 6:] == per.cameras[0, 6:])


def stereo_rig(frames=4, n=60, seed=5):
    """A stereo rig (two cameras of one lens side by side, looking the same way) over
    `frames` positions: images 2k and 2k + 1 are frame k's, with one rotation, and every image
    has the focal length TRUE_F. The start: every image's rotation and translation moved, the
    focal lengths 2% long."""
    rng = np.random.default_rng(seed)
    pts = rng.uniform(-1, 1, (n, 3))
    m = 2 * frames
    cams = np.zeros((m, 7))
    for k in range(frames):
        a = 0.8 * (k / (frames - 1) - 0.5)
        r = np.array([0.05 * np.sin(k), a, 0.0])
        C = np.array([-4 * np.sin(a), 0.1 * k, -4 * np.cos(a)])
        t = -rotation(r) @ C
        cams[2 * k] = np.concatenate([r, t, [TRUE_F]])
        cams[2 * k + 1] = np.concatenate([r, t - [0.5, 0.0, 0.0], [TRUE_F]])
    ci, pi = np.tile(np.arange(m), n), np.repeat(np.arange(n), m)
    obs = project(cams, pts, ci, pi) + rng.normal(0, 0.5, (len(ci), 2))
    start = cams.copy()
    start[:, :3] += rng.normal(0, 0.01, (m, 3))
    start[:, 3:6] += rng.normal(0, 0.02, (m, 3))
    start[:, 6] = 1.02 * TRUE_F
    return start, pts + rng.normal(0, 0.01, pts.shape), ci, pi, obs


@pytest.mark.parametrize("solver, strategy", [
    ("chol", "sba"), ("sparse-chol", "sba"), ("iterative-schur", "sba"), ("chol", "trust-region")])
def test_a_stereo_rig_shares_the_rotation_by_frame_and_the_focal_length_by_all(solver, strategy):
    cams, pts, ci, pi, obs = stereo_rig()
    args = (project, cams, pts, ci, pi, obs)
    groups = np.full((8, 7), -1)
    groups[:, :3] = np.arange(8)[:, None] // 2  # the rotation: frame k's two images
    groups[:, 6] = 0                            # the focal length: every image
    # The gauge held (frame 0's pose, and the baseline's length through image 1's x), or the
    # solve crawls along it and where it stops depends on the solver's rounding.
    cams[1, :3] = cams[0, :3]
    held = np.zeros((8, 7), bool)
    held[:2, :3], held[0, 3:6], held[1, 3] = True, True, True
    rig = pysba.motstr(*args, param_groups=groups, fixed_params=held, solver=solver,
                       strategy=strategy)
    assert np.array_equal(rig.cameras[0::2, :3], rig.cameras[1::2, :3])
    assert np.all(rig.cameras[:, 6] == rig.cameras[0, 6])
    assert len(np.unique(rig.cameras[0::2, 0])) == 4 and len(np.unique(rig.cameras[:, 3])) == 8
    assert rig.cameras[0, 6] == pytest.approx(799.07487, abs=1e-4)  # 816 at the start
    assert rig.info[1] == pytest.approx(184.4516184, rel=1e-9)
    assert 5 <= rig.info[5] <= 18
    # One grouping for both (camera_groups: the rotation and the focal length shared by every
    # image) makes the four frames look one way: a far worse fit.
    one = pysba.motstr(*args, camera_groups=[0] * 8, shared_params=[True] * 3 + [False] * 3 + [True])
    assert one.info[1] == pytest.approx(208427.927, rel=1e-6)
    # Nothing shared: each image on its own fits the noise a little closer, the rig apart.
    own = pysba.motstr(*args)
    assert not np.array_equal(own.cameras[0::2, :3], own.cameras[1::2, :3])
    assert own.info[1] < rig.info[1] < one.info[1]


@pytest.mark.parametrize("groups, error, message", [
    ([0] * 7, ValueError, "param_groups must have shape (4, 7), got (7,)"),
    (np.zeros(28, int), ValueError, "param_groups must have shape (4, 7), got (28,)"),
    ("abc", TypeError, "param_groups must be a 2-D array of ints, got str"),
    (3, TypeError, "param_groups must be a 2-D array of ints, got int"),
    (np.zeros((4, 7, 1), int), ValueError, "param_groups must have shape (4, 7), got (4, 7, 1)"),
    (np.array([["0"] * 7] * 4), TypeError, "param_groups must be an array of integers, got an array of <U1"),
    (np.zeros((4, 7), object), TypeError,
     "param_groups must be an array of integers, got an array of object"),
    (np.ones((4, 7), bool), TypeError, "param_groups[0, 0] must be an integer, got True"),
    ([[0] * 7] * 3 + [[0] * 6 + [None]], TypeError, "param_groups[3, 6] must be an integer, got None"),
    ([[0] * 7] * 3 + [[0] * 6 + [0.5]], ValueError, "param_groups[3, 6] must be an integer, got 0.5"),
    ([[0] * 7, [0, 0, -2**31 - 1, 0, 0, 0, 0]] + [[0] * 7] * 2, ValueError,
     "param_groups[1, 2] must be an integer within [-2147483648, 2147483647], got -2147483649"),
    (np.full((4, 7), 2**31, np.int64), ValueError, "param_groups[0, 0] must be an integer within [-2147483648, 2147483647], got 2147483648"),
    (np.zeros((4, 6), int), ValueError, "param_groups must have shape (4, 7), got (4, 6)"),
    (np.zeros((7, 4), int), ValueError, "param_groups must have shape (4, 7), got (7, 4)"),
    ([[0] * 7] * 3, ValueError, "param_groups must have shape (4, 7), got (3, 7)"),
])
def test_param_groups_of_another_type_or_shape_are_refused(groups, error, message):
    cams, pts, ci, pi, obs = scene(m=4, n=20)
    with pytest.raises(error) as e:
        pysba.motstr(project, cams, pts, ci, pi, obs, param_groups=groups)
    assert str(e.value) == message
    assert type(e.value) is error


def test_param_groups_of_any_integer_dtype_are_taken():
    cams, pts, ci, pi, obs = scene(m=4, n=20)
    args = (project, cams, pts, ci, pi, obs)
    groups = as_param_groups([0, 0, 1, -1], SHARED_F)
    ref = pysba.motstr(*args, param_groups=groups)
    assert ref.cameras[0, 6] == ref.cameras[1, 6] != ref.cameras[2, 6]
    for given in (groups.astype(np.int8), groups.astype(np.float32), groups.tolist(),
                  [[np.int16(g) if c else float(g) for c, g in enumerate(row)] for row in groups]):
        r = pysba.motstr(*args, param_groups=given)
        assert np.array_equal(r.cameras, ref.cameras) and np.array_equal(r.points, ref.points)
    unsigned = pysba.motstr(*args, param_groups=np.where(groups < 0, 7, groups).astype(np.uint64))
    assert unsigned.cameras[0, 6] == unsigned.cameras[1, 6] != unsigned.cameras[2, 6]


def test_the_library_refusals_of_param_groups_are_value_errors_with_its_message():
    cams, pts, ci, pi, obs = scene(m=4, n=20)
    args = (project, cams, pts, ci, pi, obs)
    groups = as_param_groups([0, 0, 1, 1], [True] * 3 + [False] * 3 + [True])
    with pytest.raises(ValueError) as e:
        pysba.motstr(*args, param_groups=groups, camera_groups=[0] * 4, shared_params=SHARED_F)
    assert str(e.value) == ("sba_motstr_levmar_x_vis: cam_param_group and cam_group/cam_shared are given "
                            "together: give one of the two")
    held = np.zeros((4, 7), bool)
    held[1, 2] = True  # in one of the two images that share it
    with pytest.raises(ValueError) as e:
        pysba.mot(*args, param_groups=groups, fixed_params=held)
    assert str(e.value) == ("sba_mot_levmar_x_vis: parameter 2 is shared by cameras 0 and 1 "
                            "(cam_param_group 0) but held (cam_fixed) in only one of them")
    with pytest.raises(ValueError) as e:
        pysba.motstr(*args, param_groups=groups, mcon=1)
    assert str(e.value) == ("sba_motstr_levmar_x_vis: cam_param_group[0] = 0: camera 0 is below mcon = 1 "
                            "(held whole) and shares nothing")
    groups[1, 2] = -2
    with pytest.raises(ValueError) as e:
        pysba.motstr(*args, param_groups=groups)
    assert str(e.value) == ("sba_motstr_levmar_x_vis: cam_param_group[9] = -2 is neither -1 nor a group "
                            "number >= 0")


# pysba passes the group numbers an int holds and the arrays it is given, whichever are given:
# the library says which are groups and which go together, and its message is the error.
@pytest.mark.parametrize("kw, message", [
    (dict(camera_groups=[0] * 4), "cam_group is given but cam_shared is NULL"),
    (dict(shared_params=SHARED_F), "cam_shared is given but cam_group is NULL"),
    (dict(camera_groups=[0, -5, 0, 0], shared_params=SHARED_F),
     "cam_group[1] = -5 is neither -1 nor a group number in [0, m-1]"),
    (dict(camera_groups=[0, 0, -2.0, 0], shared_params=SHARED_F),
     "cam_group[2] = -2 is neither -1 nor a group number in [0, m-1]"),
    (dict(camera_groups=np.array([0, 0, 0, 4], np.uint8), shared_params=SHARED_F),
     "cam_group[3] = 4 is neither -1 nor a group number in [0, m-1]"),
])
def test_the_library_refuses_group_numbers_that_are_no_group(kw, message):
    cams, pts, ci, pi, obs = scene(m=4, n=20)
    with pytest.raises(ValueError) as e:
        pysba.motstr(project, cams, pts, ci, pi, obs, **kw)
    assert str(e.value) == "sba_motstr_levmar_x_vis: " + message
