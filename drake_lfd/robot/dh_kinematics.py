"""The UR5e's forward kinematics, Jacobian, shoulder singularity and reach from its DH table.

The joint-path check (``joint_path.py``) steps the differential-IK law some 1,500 times
per plan. On the plant, each step's pose and Jacobian cost several pybind calls and
numpy conversions; :class:`DHArm` computes both from Universal Robots' DH table
(``analytic_ik.py``) in plain Python floats, in E's base frame B (``base_link``, the DH
base; the chain ends at ``tool0``, E fixed in it by ``X_tool0_E``). The URDF's forward
kinematics equals the table's to 2e-16; ``tests/test_dh_kinematics.py`` checks the pose
and the Jacobian (Drake's ``CalcJacobianSpatialVelocity`` of E's origin, rows
``[omega; v]``) against the plant's to 1e-14. :func:`rotation_error` is the law's
rotation error (``differential_ik_law.pose_error``'s first half) on such rows.

Working in B instead of W changes nothing the law computes but the frame its vectors
are written in: the pose error and the desired velocity are rotated into B with the
Jacobian, so ``J^-1 V`` and its scale under the joint limits are the same.

:meth:`DHArm.poses_batch` is the same table for many configurations at once in numpy:
the timing's tool-deviation figure and the re-derivation of logged runs
(``experiments/rederive.py``) use it.

From the same table: :func:`shoulder_singularity_distance`, the wrist centre's distance
from the shoulder axis (the Jacobian's determinant is ``a2 a3 sin q3 sin q5`` times it,
so it vanishes at the shoulder singularity), and :func:`ur5e_reach_m`, a bound on how far
E can be from the shoulder; the joint-path check, its refusals and the trajectory
optimization keep to the one and the planner refuses beyond the other.

Not for: inverse kinematics (``analytic_ik.py``), collision geometry (``scene.py``).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from pydrake.math import RigidTransform

from drake_lfd.robot.analytic_ik import UR5E_DH_A, UR5E_DH_D

__all__ = ["DHArm", "rotation_error", "rotation_matrices", "shoulder_singularity_distance", "ur5e_reach_m"]

# Standard DH twist of each link: sin of alpha = pi/2, 0, 0, pi/2, -pi/2, 0.
_SIN_ALPHA = (1.0, 0.0, 0.0, 1.0, -1.0, 0.0)
# UR5e DH parameters (m): the shoulder singularity's distance and the reach bound.
_A2, _A3 = UR5E_DH_A[1], UR5E_DH_A[2]
_D4, _D5, _D6 = UR5E_DH_D[3], UR5E_DH_D[4], UR5E_DH_D[5]


class DHArm:
    """E's pose and Jacobian in the base frame B, one UR5e configuration at a time, in
    plain Python floats (for six joints they beat numpy's per-call cost several times).

    Parameters
    ----------
    X_tool0_E : RigidTransform, optional
        E in ``tool0`` (identity by default).
    """

    def __init__(self, X_tool0_E: RigidTransform | None = None):
        X_tool0_E = RigidTransform() if X_tool0_E is None else X_tool0_E
        self._R_tool0_E = X_tool0_E.rotation().matrix().tolist()
        self._p_tool0_E = X_tool0_E.translation().tolist()
        self._X_tool0_E = X_tool0_E.GetAsMatrix4()

    def pose_and_jacobian(self, q: Sequence[float]):
        """``(R_BE, p_BE, J)`` at ``q`` (six floats): R_BE as nine floats, row by row,
        p_BE three floats, J (6, 6) rows ``[omega; v]`` of E's origin in B, as lists."""
        xx, xy, xz, yx, yy, yz, zx, zy, zz = 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0
        px = py = pz = 0.0
        axes, origins = [], []
        for angle, a, d, sin_alpha in zip(q, UR5E_DH_A, UR5E_DH_D, _SIN_ALPHA):
            axes.append((zx, zy, zz))
            origins.append((px, py, pz))
            c, s = math.cos(angle), math.sin(angle)
            nx, ny, nz = c * xx + s * yx, c * xy + s * yy, c * xz + s * yz
            tx, ty, tz = c * yx - s * xx, c * yy - s * xy, c * yz - s * xz
            px, py, pz = px + d * zx + a * nx, py + d * zy + a * ny, pz + d * zz + a * nz
            if sin_alpha == 0.0:  # alpha = 0
                yx, yy, yz = tx, ty, tz
            elif sin_alpha > 0.0:  # alpha = pi/2: y <- z, z <- -y
                yx, yy, yz, zx, zy, zz = zx, zy, zz, -tx, -ty, -tz
            else:  # alpha = -pi/2: y <- -z, z <- y
                yx, yy, yz, zx, zy, zz = -zx, -zy, -zz, tx, ty, tz
            xx, xy, xz = nx, ny, nz
        (r00, r01, r02), (r10, r11, r12), (r20, r21, r22) = self._R_tool0_E
        ex, ey, ez = self._p_tool0_E
        # R_BE = [x y z] R_tool0_E (rows), p_BE = p + [x y z] p_tool0_E.
        R = [xx * r00 + yx * r10 + zx * r20, xx * r01 + yx * r11 + zx * r21, xx * r02 + yx * r12 + zx * r22,
             xy * r00 + yy * r10 + zy * r20, xy * r01 + yy * r11 + zy * r21, xy * r02 + yy * r12 + zy * r22,
             xz * r00 + yz * r10 + zz * r20, xz * r01 + yz * r11 + zz * r21, xz * r02 + yz * r12 + zz * r22]
        p0, p1, p2 = px + xx * ex + yx * ey + zx * ez, py + xy * ex + yy * ey + zy * ez, pz + xz * ex + yz * ey + zz * ez
        J = [[], [], [], [], [], []]
        for (wx, wy, wz), (ox, oy, oz) in zip(axes, origins):
            lx, ly, lz = p0 - ox, p1 - oy, p2 - oz
            J[0].append(wx)
            J[1].append(wy)
            J[2].append(wz)
            J[3].append(wy * lz - wz * ly)
            J[4].append(wz * lx - wx * lz)
            J[5].append(wx * ly - wy * lx)
        return R, [p0, p1, p2], J

    def poses_batch(self, q: np.ndarray) -> np.ndarray:
        """Homogeneous matrices of X_BE, shape (m, 4, 4), for joint angles ``q`` (m, 6):
        the same table as :meth:`pose_and_jacobian`, one numpy product per joint for all
        samples (several hundred samples in a fraction of a millisecond)."""
        q = np.atleast_2d(np.asarray(q, dtype=float))
        X = np.broadcast_to(np.eye(4), (len(q), 4, 4)).copy()
        for j, (a, d, sin_alpha) in enumerate(zip(UR5E_DH_A, UR5E_DH_D, _SIN_ALPHA)):
            # The link's transform: Rot_z(q_j) Trans_z(d) Trans_x(a) Rot_x(alpha).
            c, s = np.cos(q[:, j]), np.sin(q[:, j])
            cos_alpha = 1.0 if sin_alpha == 0.0 else 0.0
            link = np.zeros((len(q), 4, 4))
            link[:, 0, 0], link[:, 0, 1], link[:, 0, 2], link[:, 0, 3] = c, -s * cos_alpha, s * sin_alpha, a * c
            link[:, 1, 0], link[:, 1, 1], link[:, 1, 2], link[:, 1, 3] = s, c * cos_alpha, -c * sin_alpha, a * s
            link[:, 2, 1], link[:, 2, 2], link[:, 2, 3] = sin_alpha, cos_alpha, d
            link[:, 3, 3] = 1.0
            X = X @ link
        return X @ self._X_tool0_E


def rotation_error(R_desired: Sequence[float], R: Sequence[float]) -> list[float] | None:
    """The rotation vector of ``R_desired R^T``, as three floats; each matrix nine floats,
    row by row (of ``R_desired``, the first nine are read: the checker keeps a sample's
    whole desired motion in one tuple). None beyond 90 degrees (where the caller uses
    Drake's angle-axis instead)."""
    a00, a01, a02, a10, a11, a12, a20, a21, a22 = R_desired[:9]
    b00, b01, b02, b10, b11, b12, b20, b21, b22 = R
    # M = R_desired R^T: M_ij = row i of R_desired . row j of R.
    m01, m10 = a00 * b10 + a01 * b11 + a02 * b12, a10 * b00 + a11 * b01 + a12 * b02
    m02, m20 = a00 * b20 + a01 * b21 + a02 * b22, a20 * b00 + a21 * b01 + a22 * b02
    m12, m21 = a10 * b20 + a11 * b21 + a12 * b22, a20 * b10 + a21 * b11 + a22 * b12
    trace = (a00 * b00 + a01 * b01 + a02 * b02) + (a10 * b10 + a11 * b11 + a12 * b12) + (a20 * b20 + a21 * b21 + a22 * b22)
    wx, wy, wz = 0.5 * (m21 - m12), 0.5 * (m02 - m20), 0.5 * (m10 - m01)
    cosine = 0.5 * (trace - 1.0)
    if cosine < 0.0:
        return None
    sine = math.sqrt(wx * wx + wy * wy + wz * wz)
    scale = 1.0 if sine < 1e-300 else math.atan2(sine, cosine) / sine
    return [scale * wx, scale * wy, scale * wz]


def rotation_matrices(quaternions: np.ndarray) -> np.ndarray:
    """Rotation matrices (n, 3, 3) of unit quaternions (n, 4), ``[w, x, y, z]``."""
    w, x, y, z = np.asarray(quaternions, dtype=float).T
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], axis=-1),
        np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], axis=-1),
        np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], axis=-1),
    ], axis=1)


def shoulder_singularity_distance(q: np.ndarray) -> float:
    """Signed distance of the UR5e's wrist point from the shoulder axis, m (zero at the
    shoulder singularity)."""
    return _A2 * math.cos(q[1]) + _A3 * math.cos(q[1] + q[2]) + _D5 * math.sin(q[1] + q[2] + q[3])


def ur5e_reach_m(X_tool0_E: RigidTransform | None = None) -> float:
    """An upper bound on the distance from the shoulder joint's centre to E, m: the
    links' lengths and offsets plus the tool's."""
    tool = 0.0 if X_tool0_E is None else float(np.linalg.norm(X_tool0_E.translation()))
    return abs(_A2) + abs(_A3) + _D4 + _D5 + _D6 + tool
