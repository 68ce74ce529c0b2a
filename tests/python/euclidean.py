# SPDX-License-Identifier: BSD-3-Clause
"""eucsbademo's camera model with fixed intrinsics, written again in numpy as a user would
write a model of their own: the test of the Python-callback drivers compares it with the
library's built-in model (lib/cameras/euclidean.h).

Camera j keeps its input rotation q0_j; the optimizer sees (v, t), v the vector part of a
unit correction qs = (sqrt(1 - |v|^2), v), so that X_c = R(qs) R(q0_j) X + t, and the pixel
is K applied to X_c / Z_c."""
import numpy as np


def rotation_matrices(q):
    """R for unit quaternions q (k, 4), scalar first."""
    w, x, y, z = q[:, 0], q[:, 1], q[:, 2], q[:, 3]
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
        np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
        np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
    ], -2)


def quaternion_product(a, b):
    aw, av = a[:, :1], a[:, 1:]
    bw, bv = b[:, :1], b[:, 1:]
    return np.hstack([aw * bw - np.sum(av * bv, 1, keepdims=True),
                      aw * bv + bw * av + np.cross(av, bv)])


class Euclidean:
    def __init__(self, camera_rows, K):
        q0 = camera_rows[:, :4] / np.linalg.norm(camera_rows[:, :4], axis=1, keepdims=True)
        self.q0 = q0 * np.where(q0[:, :1] < 0, -1.0, 1.0)
        self.R0 = rotation_matrices(self.q0)
        self.K = np.asarray(K, dtype=float)
        # The optimizer's starting cameras: no correction, the file's translations.
        self.initial = np.hstack([np.zeros((len(camera_rows), 3)), camera_rows[:, 4:7]])

    def _camera_frame(self, cams, pts, ci, pi):
        v, t = cams[ci, :3], cams[ci, 3:6]
        w = np.sqrt(1.0 - np.sum(v * v, 1))[:, None]
        Y = np.einsum("kab,kb->ka", self.R0[ci], pts[pi])
        vY = np.cross(v, Y)
        Xc = Y + 2 * w * vY + 2 * np.cross(v, vY) + t
        return v, w, Y, vY, Xc

    def _pixels(self, Xc):
        fu, s, u0, fv, v0 = self.K[0, 0], self.K[0, 1], self.K[0, 2], self.K[1, 1], self.K[1, 2]
        X, Y, Z = Xc[:, 0], Xc[:, 1], Xc[:, 2]
        return np.stack([(fu * X + s * Y) / Z + u0, fv * Y / Z + v0], -1)

    def project(self, cams, pts, ci, pi):
        return self._pixels(self._camera_frame(cams, pts, ci, pi)[4])

    def jacobian(self, cams, pts, ci, pi):
        v, w, Y, vY, Xc = self._camera_frame(cams, pts, ci, pi)
        fu, s, fv = self.K[0, 0], self.K[0, 1], self.K[1, 1]
        X_, Y_, Z = Xc[:, 0], Xc[:, 1], Xc[:, 2]
        zero = np.zeros_like(Z)
        dpix = np.stack([np.stack([fu / Z, s / Z, -(fu * X_ + s * Y_) / Z ** 2], -1),
                         np.stack([zero, fv / Z, -fv * Y_ / Z ** 2], -1)], -2)  # (k, 2, 3)
        dXdv = np.empty((len(ci), 3, 3))
        for k in range(3):
            e = np.zeros_like(v)
            e[:, k] = 1.0
            dw = -v[:, k:k + 1] / w
            dXdv[:, :, k] = (2 * dw * vY + 2 * w * np.cross(e, Y) + 2 * np.cross(e, vY)
                             + 2 * np.cross(v, np.cross(e, Y)))
        dXdcam = np.concatenate([dXdv, np.broadcast_to(np.eye(3), (len(ci), 3, 3))], -1)
        # dX_c/dX = R(qs) R0: the rotation applied to the columns of R0.
        cols = [self.R0[ci][:, :, c] for c in range(3)]
        Rs_R0 = np.stack([c + 2 * w * np.cross(v, c) + 2 * np.cross(v, np.cross(v, c)) for c in cols], -1)
        return dpix @ dXdcam, dpix @ Rs_R0

    def file_cameras(self, cams):
        """Cameras (v, t) as rows of the camera file (q, t), q = qs(v) q0 with w >= 0."""
        v = cams[:, :3]
        qs = np.hstack([np.sqrt(1.0 - np.sum(v * v, 1))[:, None], v])
        q = quaternion_product(qs, self.q0)
        q *= np.where(q[:, :1] < 0, -1.0, 1.0)
        return np.hstack([q, cams[:, 3:6]])
