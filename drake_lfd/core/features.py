"""Features of demonstrations and task segments (Eq. 12-13, 16-18; SPEC 3, 4).

A feature is the sequence of relative poses ``delta_i = D_i* (x) D_m`` of every sample
with respect to the last one, so it does not change when the whole motion is moved
rigidly. Demonstrations are first resampled by arc length (translation and rotation
together) so that matching does not depend on the recording rate; task segments are
used as given (their critical configurations are the samples).

Not for: reading logs, forward kinematics (the caller hands in poses), comparing
features (``similarity.py``) or timing (keep the raw samples for that).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from drake_lfd.core.dual_quaternion import (
    dual_quaternion_canonical,
    dual_quaternion_conjugate,
    dual_quaternion_multiply,
    dual_quaternion_relative,
    dual_quaternion_sclerp,
    translation_from_dual_quaternion,
    twist_from_dual_quaternion,
)
from drake_lfd.core.read_only_arrays import read_only_array

# Samples per resampled demonstration. 100 samples put consecutive samples about 1 % of
# the motion apart: for a 0.3 m / 90 deg demonstration that is ~3 mm and ~1 deg, far
# below the matching tolerance (d_alpha = 0.5 is ~58 deg) and below what a hand-guided
# UR5e reproduces, while the allocation DP stays O(p * 100) and a mapped segment stays
# a compact 100-pose path that the trajectory stage densifies with ScLERP anyway.
DEFAULT_NUM_SAMPLES = 100

# Characteristic length (m per rad) that makes rotation commensurable with translation
# in the arc length: a rotation of 1 rad counts like moving a point 0.1 m from the tool
# frame's origin, about the reach of a gripper plus a held part.
DEFAULT_ROTATION_LENGTH_M = 0.1


def feature_from_poses(D):
    """Relative poses to the final pose, ``delta_i = D_i* (x) D_m`` (Eq. 12, 18).

    Parameters
    ----------
    D : array-like, shape (m, 8)
        Poses ``D_1 .. D_m`` as unit dual quaternions, m >= 2.

    Returns
    -------
    deltas : array, shape (m - 1, 8)
        ``delta_i`` for i = 1..m-1 (the pose of frame m in frame i: rotation
        ``r_i* r_m``, translation ``R_i^T (p_m - p_i)``), in canonical sign
        (``r_w >= 0``) so equal relative poses give equal arrays.
    """
    D = np.asarray(D, dtype=float)
    if D.ndim != 2 or D.shape[1] != 8 or D.shape[0] < 2:
        raise ValueError(f"poses must have shape (m >= 2, 8), got {D.shape}")
    return dual_quaternion_canonical(dual_quaternion_relative(D[:-1], D[-1]))


def arc_lengths_from_poses(D, rotation_length_m=DEFAULT_ROTATION_LENGTH_M):
    """Cumulative arc length along a pose sequence.

    Consecutive samples are joined by their screw motion (ScLERP), whose body twist
    ``(omega, v)`` is constant, so each step has length
    ``sqrt(|v|^2 + (rotation_length_m * |omega|)^2)``: the tool origin's path length
    combined with the rotation angle (for a pure translation, the distance).

    Parameters
    ----------
    D : array-like, shape (m, 8)
    rotation_length_m : float
        Metres per radian of rotation.

    Returns
    -------
    s : array, shape (m,)
        ``s[0] = 0``, non-decreasing.
    """
    D = np.asarray(D, dtype=float)
    twists = twist_from_dual_quaternion(dual_quaternion_relative(D[:-1], D[1:]))
    step_length = np.hypot(np.linalg.norm(twists[:, 3:], axis=1),
                           rotation_length_m * np.linalg.norm(twists[:, :3], axis=1))
    return np.concatenate([[0.0], np.cumsum(step_length)])


def resample_by_arc_length(D, num_samples=DEFAULT_NUM_SAMPLES, rotation_length_m=DEFAULT_ROTATION_LENGTH_M):
    """Resample poses to samples equally spaced in arc length (SPEC 3).

    The arc length combines translation (m) and rotation (rad times
    ``rotation_length_m``, see :func:`arc_lengths_from_poses`), so pure rotations and
    pure translations resample alike. Between two neighbouring raw samples the pose is
    ScLERPed; arc length is linear in the ScLERP parameter (constant body twist), so the
    output is evenly spaced along that piecewise-screw path. The first and last
    samples are the raw ones exactly. A motion with zero total arc length (a constant
    pose) returns ``num_samples`` copies of its first pose.

    Parameters
    ----------
    D : array-like, shape (m, 8)
        Raw poses in time order, m >= 2. Pauses (repeated poses) are fine.
    num_samples : int
        Number of output samples, >= 2.
    rotation_length_m : float
        Metres per radian of rotation, > 0.

    Returns
    -------
    D_resampled : array, shape (num_samples, 8)
    """
    D = np.asarray(D, dtype=float)
    if D.ndim != 2 or D.shape[1] != 8 or D.shape[0] < 2:
        raise ValueError(f"poses must have shape (m >= 2, 8), got {D.shape}")
    if num_samples < 2:
        raise ValueError(f"num_samples must be >= 2, got {num_samples}")
    if not rotation_length_m > 0.0:
        raise ValueError(f"rotation_length_m must be > 0, got {rotation_length_m}")
    cumulative = arc_lengths_from_poses(D, rotation_length_m)
    total = cumulative[-1]
    if total <= 0.0:
        return np.repeat(D[:1], num_samples, axis=0)
    targets = np.linspace(0.0, total, num_samples)
    # Segment k holds cumulative[k] <= target < cumulative[k+1]; zero-length segments
    # (pauses) are skipped because side="right" picks the last of equal values.
    segment = np.clip(np.searchsorted(cumulative, targets, side="right") - 1, 0, len(D) - 2)
    length = cumulative[segment + 1] - cumulative[segment]
    moving = length > 0.0
    fraction = np.where(moving, (targets - cumulative[segment]) / np.where(moving, length, 1.0), 1.0)
    resampled = dual_quaternion_sclerp(D[segment], D[segment + 1], np.clip(fraction, 0.0, 1.0))
    resampled[0] = D[0]
    resampled[-1] = D[-1]
    return resampled


@dataclasses.dataclass(frozen=True, eq=False)
class Feature:
    """A feature ``HD = {delta_1 .. delta_(n-1)}`` (Eq. 13) and its parts.

    Attributes
    ----------
    rotations : array, shape (n - 1, 4)
        Rotation parts ``r_i* r_n`` of the deltas (canonical sign, w >= 0).
    translations : array, shape (n - 1, 3)
        Translations ``R_i^T (p_n - p_i)`` of the deltas (in frame i).
    deltas : array, shape (n - 1, 8)
        The relative poses ``D_i* (x) D_n``.
    poses : array, shape (n, 8), or None
        The (resampled) poses the deltas came from; the mapping needs them.
        None when the feature was built from deltas alone.

    Arrays are read-only.
    """

    rotations: np.ndarray
    translations: np.ndarray
    deltas: np.ndarray
    poses: np.ndarray | None = None

    @classmethod
    def from_deltas(cls, deltas, poses=None):
        """Feature of deltas, shape (n - 1, 8), optionally with their poses (n, 8)."""
        deltas = dual_quaternion_canonical(deltas)
        return cls(
            rotations=read_only_array(deltas[:, :4]),
            translations=read_only_array(translation_from_dual_quaternion(deltas)),
            deltas=read_only_array(deltas),
            poses=None if poses is None else read_only_array(poses),
        )

    @classmethod
    def from_poses(cls, D, num_samples=DEFAULT_NUM_SAMPLES, rotation_length_m=DEFAULT_ROTATION_LENGTH_M):
        """Feature of a demonstration: resample by arc length, then Eq. 12.

        Parameters
        ----------
        D : array-like, shape (m, 8)
            Raw demonstration poses.
        num_samples : int
            Samples after resampling, n (the feature has n - 1 deltas).
        rotation_length_m : float
            See :func:`resample_by_arc_length`.
        """
        poses = resample_by_arc_length(D, num_samples, rotation_length_m)
        return cls.from_deltas(feature_from_poses(poses), poses)

    def __len__(self):
        return self.deltas.shape[0]


def task_feature_from_poses(D_task):
    """Feature of a task segment con_j .. con_k (Eq. 16-18), without resampling.

    Parameters
    ----------
    D_task : array-like, shape (p + 1, 8)
        Poses ``D_j .. D_k`` of the segment's critical configurations.

    Returns
    -------
    feature : Feature
        p deltas ``delta_l = D_l* (x) D_k``, l = j..k-1, with ``poses = D_task``.
    """
    D_task = np.asarray(D_task, dtype=float)
    return Feature.from_deltas(feature_from_poses(D_task), D_task)


def poses_from_feature(deltas, D_final):
    """Inverse of Eq. 12: poses ``D_i = D_final (x) delta_i*`` plus ``D_final``.

    Parameters
    ----------
    deltas : array-like, shape (n - 1, 8)
    D_final : array-like, shape (8,)

    Returns
    -------
    D : array, shape (n, 8)
    """
    D_final = np.asarray(D_final, dtype=float)
    D = dual_quaternion_multiply(D_final, dual_quaternion_conjugate(deltas))
    return np.concatenate([D, D_final[None]], axis=0)
