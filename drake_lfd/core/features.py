"""Features of demonstrations and task segments (Eq. 12-13, 16-18).

A feature is the sequence of relative poses ``delta_i = D_i* (x) D_m`` of every sample
with respect to the last one, so it does not change when the whole motion is moved
rigidly. Demonstrations are first resampled by arc length (translation and rotation
together) so that matching does not depend on the recording rate; task segments are
used as given (their critical configurations are the samples). See ``docs/method.rst``,
*Demonstrations and features* and *Tasks*.

Every public function and :class:`Feature` check that they are handed unit dual
quaternions of the right shape (ValueError otherwise); the private kernels beside them
do not, so that callers which have checked once (``mapping.py``) pay nothing more.

Not for: reading logs, forward kinematics (the caller hands in poses), comparing
features (``similarity.py``) or timing (keep the raw samples for that).
"""

from __future__ import annotations

import dataclasses

import numpy as np
from numpy.typing import ArrayLike, NDArray

from drake_lfd.core.dual_quaternion import (
    check_unit_dual_quaternions,
    dual_quaternion_canonical,
    dual_quaternion_conjugate,
    dual_quaternion_multiply,
    dual_quaternion_relative,
    translation_from_dual_quaternion,
)
from drake_lfd.core.screw_motion import dual_quaternion_sclerp, exponential_coordinates_from_dual_quaternion
from drake_lfd.core.read_only_arrays import read_only_array

__all__ = [
    "DEFAULT_NUM_SAMPLES",
    "DEFAULT_ROTATION_LENGTH_M",
    "deltas_from_poses",
    "arc_lengths_from_poses",
    "resample_by_arc_length",
    "Feature",
    "task_feature_from_poses",
    "poses_from_deltas",
]

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


def _checked_pose_sequence(D: ArrayLike, name: str) -> NDArray[np.float64]:
    """``D`` as a float array of shape (m >= 2, 8) of unit dual quaternions, or ValueError."""
    D = np.asarray(D, dtype=float)
    if D.ndim != 2 or D.shape[1] != 8 or D.shape[0] < 2:
        raise ValueError(f"{name} must have shape (m >= 2, 8), got {D.shape}")
    return check_unit_dual_quaternions(D, name)


def deltas_from_poses(D: ArrayLike) -> NDArray[np.float64]:
    """Relative poses to the final pose, ``delta_i = D_i* (x) D_m`` (Eq. 12, 18).

    The deltas of a :class:`Feature`, as a plain array: no resampling (that is
    :meth:`Feature.from_poses`).

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

    Raises
    ------
    ValueError
        If ``D`` is not a sequence of at least two unit dual quaternions.
    """
    return _deltas_from_poses(_checked_pose_sequence(D, "poses"))


def _deltas_from_poses(D):
    """:func:`deltas_from_poses` without the input check, ``D`` a float array (m, 8)."""
    return dual_quaternion_canonical(dual_quaternion_relative(D[:-1], D[-1]))


def arc_lengths_from_poses(
    D: ArrayLike, rotation_length_m: float = DEFAULT_ROTATION_LENGTH_M
) -> NDArray[np.float64]:
    """Cumulative arc length along a pose sequence.

    Consecutive samples are joined by their screw motion (ScLERP), along which the body
    velocity is constant: the step's exponential coordinates ``(omega, v)``. Each step
    has length ``sqrt(|v|^2 + (rotation_length_m * |omega|)^2)``: the tool origin's path length
    combined with the rotation angle (for a pure translation, the distance).

    Parameters
    ----------
    D : array-like, shape (m, 8)
        Unit dual quaternions, m >= 2.
    rotation_length_m : float
        Metres per radian of rotation.

    Returns
    -------
    s : array, shape (m,)
        ``s[0] = 0``, non-decreasing.

    Raises
    ------
    ValueError
        If ``D`` is not a sequence of at least two unit dual quaternions.
    """
    return _arc_lengths_from_poses(_checked_pose_sequence(D, "poses"), rotation_length_m)


def _arc_lengths_from_poses(D, rotation_length_m):
    """:func:`arc_lengths_from_poses` without the input check."""
    steps = exponential_coordinates_from_dual_quaternion(dual_quaternion_relative(D[:-1], D[1:]))
    step_length = np.hypot(np.linalg.norm(steps[:, 3:], axis=1),
                           rotation_length_m * np.linalg.norm(steps[:, :3], axis=1))
    return np.concatenate([[0.0], np.cumsum(step_length)])


def resample_by_arc_length(
    D: ArrayLike,
    num_samples: int = DEFAULT_NUM_SAMPLES,
    rotation_length_m: float = DEFAULT_ROTATION_LENGTH_M,
) -> NDArray[np.float64]:
    """Resample poses to samples equally spaced in arc length.

    See ``docs/method.rst``, *Demonstrations and features*.

    The arc length combines translation (m) and rotation (rad times
    ``rotation_length_m``, see :func:`arc_lengths_from_poses`), so pure rotations and
    pure translations resample alike. Between two neighbouring raw samples the pose is
    ScLERPed; arc length is linear in the ScLERP parameter (constant body velocity), so the
    output is evenly spaced along that piecewise-screw path. The first and last
    samples are the raw ones exactly. A motion with zero total arc length (a constant
    pose) returns ``num_samples`` copies of its first pose.

    Parameters
    ----------
    D : array-like, shape (m, 8)
        Raw poses in time order (unit dual quaternions), m >= 2. Pauses (repeated
        poses) are fine.
    num_samples : int
        Number of output samples, >= 2.
    rotation_length_m : float
        Metres per radian of rotation, > 0.

    Returns
    -------
    D_resampled : array, shape (num_samples, 8)
        A new array.

    Raises
    ------
    ValueError
        If ``D`` is not a sequence of at least two unit dual quaternions, or
        ``num_samples`` or ``rotation_length_m`` is out of range.
    """
    D = _checked_pose_sequence(D, "poses")
    if num_samples < 2:
        raise ValueError(f"num_samples must be >= 2, got {num_samples}")
    if not rotation_length_m > 0.0:
        raise ValueError(f"rotation_length_m must be > 0, got {rotation_length_m}")
    return _resample_by_arc_length(D, num_samples, rotation_length_m)


def _resample_by_arc_length(D, num_samples, rotation_length_m):
    """:func:`resample_by_arc_length` without the input checks."""
    cumulative = _arc_lengths_from_poses(D, rotation_length_m)
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
    """A feature ``HD = {delta_1, ..., delta_(n-1)}`` (Eq. 13) and its parts.

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

    Notes
    -----
    Arrays are read-only: the constructor keeps read-only float arrays that own their
    data as they are and stores read-only copies of anything else. It checks the shapes above (n >= 2) and
    that ``deltas`` and ``poses`` are unit dual quaternions, and raises ValueError
    otherwise; it does not check that the parts agree with each other (build features
    with :meth:`from_poses`, :meth:`from_deltas` or :func:`task_feature_from_poses`).
    """

    rotations: NDArray[np.float64]
    translations: NDArray[np.float64]
    deltas: NDArray[np.float64]
    poses: NDArray[np.float64] | None = None

    def __post_init__(self) -> None:
        for field in dataclasses.fields(self):
            value = getattr(self, field.name)
            if value is None and field.name == "poses":
                continue
            # An owned read-only array cannot change under us; a read-only view could.
            already_read_only = (isinstance(value, np.ndarray) and value.dtype == np.float64
                                 and not value.flags.writeable and value.base is None)
            if not already_read_only:
                object.__setattr__(self, field.name, read_only_array(value))
        num_deltas = len(self.deltas) if self.deltas.ndim == 2 else 0
        expected = {"rotations": (num_deltas, 4), "translations": (num_deltas, 3), "deltas": (num_deltas, 8)}
        if self.poses is not None:
            expected["poses"] = (num_deltas + 1, 8)
        for name, shape in expected.items():
            if num_deltas < 1 or getattr(self, name).shape != shape:
                raise ValueError(
                    "a feature of n - 1 >= 1 deltas needs rotations (n - 1, 4), translations (n - 1, 3), "
                    "deltas (n - 1, 8) and poses (n, 8) or None; got "
                    + ", ".join(f"{key} {getattr(self, key).shape}" for key in expected))
        check_unit_dual_quaternions(self.deltas, "deltas")
        if self.poses is not None:
            check_unit_dual_quaternions(self.poses, "poses")

    @classmethod
    def from_deltas(cls, deltas: ArrayLike, poses: ArrayLike | None = None) -> Feature:
        """Feature of deltas, optionally with the poses they came from.

        Parameters
        ----------
        deltas : array-like, shape (n - 1, 8)
            Relative poses ``D_i* (x) D_n`` (unit dual quaternions, either sign).
        poses : array-like, shape (n, 8), optional
            The poses ``D_1 .. D_n``.

        Returns
        -------
        feature : Feature
            Deltas in canonical sign, arrays read-only copies.

        Raises
        ------
        ValueError
            If the shapes do not fit or the dual quaternions are not unit.
        """
        deltas = np.asarray(deltas, dtype=float)
        if deltas.ndim != 2 or deltas.shape[1] != 8:
            raise ValueError(f"deltas must have shape (n - 1, 8), got {deltas.shape}")
        deltas = dual_quaternion_canonical(deltas)
        return cls(
            rotations=read_only_array(deltas[:, :4]),
            translations=read_only_array(translation_from_dual_quaternion(deltas)),
            deltas=read_only_array(deltas),
            poses=None if poses is None else read_only_array(poses),
        )

    @classmethod
    def from_poses(
        cls,
        D: ArrayLike,
        num_samples: int = DEFAULT_NUM_SAMPLES,
        rotation_length_m: float = DEFAULT_ROTATION_LENGTH_M,
    ) -> Feature:
        """Feature of a demonstration: resample by arc length, then Eq. 12.

        Parameters
        ----------
        D : array-like, shape (m, 8)
            Raw demonstration poses (unit dual quaternions), m >= 2.
        num_samples : int
            Samples after resampling, n (the feature has n - 1 deltas).
        rotation_length_m : float
            See :func:`resample_by_arc_length`.

        Returns
        -------
        feature : Feature
            With ``poses`` the resampled poses, shape (n, 8).

        Raises
        ------
        ValueError
            As :func:`resample_by_arc_length`.
        """
        poses = resample_by_arc_length(D, num_samples, rotation_length_m)
        return cls.from_deltas(_deltas_from_poses(poses), poses)

    def __len__(self) -> int:
        """Number of deltas, n - 1."""
        return self.deltas.shape[0]


def task_feature_from_poses(D_task: ArrayLike) -> Feature:
    """Feature of a task segment con_j .. con_k (Eq. 16-18), without resampling.

    Parameters
    ----------
    D_task : array-like, shape (p + 1, 8)
        Poses ``D_j .. D_k`` of the segment's critical configurations.

    Returns
    -------
    feature : Feature
        p deltas ``delta_l = D_l* (x) D_k``, l = j..k-1, with ``poses = D_task``.

    Raises
    ------
    ValueError
        If ``D_task`` is not a sequence of at least two unit dual quaternions.
    """
    D_task = _checked_pose_sequence(D_task, "D_task")
    return Feature.from_deltas(_deltas_from_poses(D_task), D_task)


def poses_from_deltas(deltas: ArrayLike, D_final: ArrayLike) -> NDArray[np.float64]:
    """Inverse of Eq. 12: poses ``D_i = D_final (x) delta_i*`` plus ``D_final``.

    Parameters
    ----------
    deltas : array-like, shape (n - 1, 8)
        Unit dual quaternions.
    D_final : array-like, shape (8,)
        A unit dual quaternion.

    Returns
    -------
    D : array, shape (n, 8)

    Raises
    ------
    ValueError
        If the shapes differ from the above or the dual quaternions are not unit.
    """
    deltas = check_unit_dual_quaternions(deltas, "deltas")
    D_final = check_unit_dual_quaternions(D_final, "D_final")
    if deltas.ndim != 2 or D_final.shape != (8,):
        raise ValueError(f"deltas must have shape (n - 1, 8) and D_final (8,), got {deltas.shape} "
                         f"and {D_final.shape}")
    return _poses_from_deltas(deltas, D_final)


def _poses_from_deltas(deltas, D_final):
    """:func:`poses_from_deltas` without the input checks, ``D_final`` a float array;
    ``deltas`` (..., N - 1, 8) may carry leading dimensions."""
    D = dual_quaternion_multiply(D_final, dual_quaternion_conjugate(deltas))
    return np.concatenate([D, np.broadcast_to(D_final, D.shape[:-2] + (1, 8))], axis=-2)
