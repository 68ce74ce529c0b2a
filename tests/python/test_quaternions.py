# SPDX-License-Identifier: BSD-3-Clause
"""pysba's eucsbademo cameras take a quaternion of any nonzero size, as the files do: one
whose squared norm overflows (components near 1e308) or underflows (near 1e-200) is the
same rotation as the unit quaternion, and the zero quaternion is refused by camera."""
from pathlib import Path

import numpy as np
import pytest

pysba = pytest.importorskip("pysba")

DATA = Path(__file__).resolve().parents[2] / "data"


def orbit():
    return pysba.read_eucsbademo(DATA / "orbit-fixedK-cams.txt", DATA / "orbit-fixedK-pts.txt",
                                 DATA / "orbit-fixedK-calib.txt")


def scaled(problem, scale):
    cameras = problem.cameras.copy()
    cameras[:, :4] *= scale  # 7-value cameras: q, then t
    return pysba.Problem("eucsbademo", cameras, problem.points, problem.camera_index, problem.point_index,
                         problem.observations, calibration=problem.calibration)


@pytest.mark.parametrize("scale", [1e308, 1e-200])
def test_any_nonzero_size_is_the_rotation(scale):
    unit = pysba.solve(orbit(), itmax=20)
    big = pysba.solve(scaled(orbit(), scale), itmax=20)
    assert np.isfinite(big.cameras).all()
    assert big.final_mse == pytest.approx(unit.final_mse, rel=1e-9)
    np.testing.assert_allclose(big.cameras, unit.cameras, rtol=0, atol=1e-9)


def test_a_zero_quaternion_is_refused_by_camera():
    problem = orbit()
    problem.cameras[3, :4] = 0
    with pytest.raises(ValueError, match="^camera 3 has a zero quaternion$"):
        pysba.solve(problem)
