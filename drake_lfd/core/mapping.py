"""Map a demonstration onto a task segment (Eq. 22-25), then bend it exactly
through the segment's critical configurations (``docs/method.rst``, *Mapping*).

Given a demo whose feature is similar to a segment con_j .. con_k (an ``Allocation``
from ``similarity.py``), the demo suffix from the first allocated sample ``i_1`` is
turned into an SE(3) path that ends exactly at ``D_k``:

1. ``delta_i = D_i* (x) D_m`` for the suffix (Eq. 12; identity for the last sample).
2. ``q_align`` rotates the demo's first translation ``t_demo`` (of ``delta_i1``) onto the
   task's first translation ``t_task`` (of ``D_j* (x) D_k``) by the shortest rotation
   (Eq. 22), optionally followed by a turn of ``twist_rad`` about ``t_task`` (the free
   twist of *Mapping*).
3. Each delta keeps its rotation (Eq. 24); its translation becomes
   ``scale * q_align t_i q_align*`` with ``scale = |t_task| / |t_demo|`` (Eq. 23 with
   the paper's factor inverted, see *Departures from the paper*). Both translations are
   in the frame of the pose they start from (the body frame at sample i, at con_j), as
   in the paper.
4. ``MP_i = D_k (x) mp_i*`` (Eq. 25): ``mp_i`` is the mapped pose of the final frame
   in frame i, so ``mp_i*`` is its inverse and ``MP_i`` is the world pose of frame i.
   For the last sample ``mp = identity`` and ``MP = D_k``. Mapping a demo onto its own
   poses reproduces them.

Then, beyond the paper, at every allocated anchor ``i_l`` the mapped pose ``M_l`` misses
the task pose ``T_l = D_(j+l-1)`` by the tolerance at most. The residual is taken in the
body frame, ``B_l = M_l* (x) T_l`` (so ``M_l (x) B_l = T_l``), with ``B = identity`` at
the end; between consecutive anchors ``B`` is ScLERPed with the sample-index fraction
(samples are equally spaced in arc length) and applied on the right, ``MP_i (x) B_i``.
A body-frame correction moves each pose by exactly ``|translation(B_i)|`` and turns it
about its own origin, so the reported maxima are the true displacement of the path.

Conventions for degenerate translations (``min_length_m``, default 1 mm as in
*Similarity*):
if either first translation is shorter, there is no alignment rotation (identity) and
the twist, which needs a task axis, applies only when ``t_task`` is long enough; if
``t_demo`` is shorter, the scale is 1 (a demo that returns to its start has no size to
compare). Anti-parallel translations turn by pi about a deterministic perpendicular
axis (``t_demo x e`` with ``e`` the coordinate axis least aligned with ``t_demo``).

The public functions check their inputs (shapes, unit dual quaternions and quaternions)
and raise ValueError; :func:`map_segment` checks once and then uses the unchecked
kernels.

Not for: choosing the demo or the allocation (``similarity.py``, planners), timing the
path, or checking it against obstacles.
"""

from __future__ import annotations

import dataclasses
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray

from drake_lfd.core.dual_quaternion import (
    IDENTITY_DUAL_QUATERNION,
    check_unit_dual_quaternions,
    check_unit_quaternions,
    dual_quaternion_from_translation_rotation,
    dual_quaternion_multiply,
    dual_quaternion_relative,
    translation_from_dual_quaternion,
)
from drake_lfd.core.quaternion import (
    axis_angle_from_quaternion,
    quaternion_from_axis_angle,
    quaternion_multiply,
    vector_rotated_by_quaternion,
)
from drake_lfd.core.screw_motion import dual_quaternion_sclerp
# The features' unchecked kernels (Eq. 12 and its inverse): map_segment has checked.
from drake_lfd.core.features import _deltas_from_poses, _poses_from_deltas
from drake_lfd.core.similarity import MIN_TRANSLATION_M

if TYPE_CHECKING:
    from drake_lfd.core.similarity import Allocation

__all__ = ["MappedSegment", "alignment_from_translations", "mapped_poses_from_deltas", "map_segment",
           "map_segment_twists", "least_anchor_correction_m"]

_IDENTITY_QUATERNION = np.array([1.0, 0.0, 0.0, 0.0])
_IDENTITY_QUATERNION.flags.writeable = False  # shared by every caller: returned as a copy


@dataclasses.dataclass(frozen=True, eq=False)
class MappedSegment:
    """An SE(3) path for one task segment con_j .. con_k.

    Attributes
    ----------
    poses : array, shape (N, 8)
        World poses ``X_WE``; ``poses[0]`` is ``D_j`` and ``poses[-1]`` is ``D_k``
        exactly. No sign (double cover) normalisation between samples.
    anchor_indices : array of int, shape (p + 1,)
        Indices into ``poses`` where con_j .. con_k are met; first 0, last N - 1.
    max_correction_position_m : float
        Largest displacement of a pose by the anchor correction.
    max_correction_rotation_rad : float
        Largest rotation of a pose by the anchor correction.
    uncorrected_poses : array, shape (N, 8)
        The path of Eq. 22-25 before the correction (ends at ``D_k``).
    scale : float
        ``|t_task| / |t_demo|`` applied to the demo translations.
    alignment : array, shape (4,)
        Unit quaternion applied to the demo translations (alignment, then twist).

    The arrays belong to this segment alone (none is shared with another object);
    ``anchor_indices`` is read-only.
    """

    poses: NDArray[np.float64]
    anchor_indices: NDArray[np.int_]
    max_correction_position_m: float
    max_correction_rotation_rad: float
    uncorrected_poses: NDArray[np.float64]
    scale: float
    alignment: NDArray[np.float64]


def alignment_from_translations(
    t_demo: ArrayLike,
    t_task: ArrayLike,
    twist_rad: float = 0.0,
    min_length_m: float = MIN_TRANSLATION_M,
) -> NDArray[np.float64]:
    """Rotation aligning the demo's first translation with the task's (Eq. 22).

    Parameters
    ----------
    t_demo, t_task : array-like, shape (3,)
        The demo's and the task's first translations (m).
    twist_rad : float
        Extra rotation about ``t_task``'s direction after the alignment (the free
        twist of ``docs/method.rst``, *Mapping*).
    min_length_m : float
        Shorter translations have no direction (see the module docstring).

    Returns
    -------
    q : array, shape (4,)
        Unit quaternion with ``q t_demo q*`` parallel to ``t_task`` (when both are long
        enough).

    Raises
    ------
    ValueError
        If a translation is not one finite 3-vector.
    """
    t_demo = np.asarray(t_demo, dtype=float)
    t_task = np.asarray(t_task, dtype=float)
    if t_demo.shape != (3,) or t_task.shape != (3,) or not np.all(np.isfinite(t_demo) & np.isfinite(t_task)):
        raise ValueError(
            f"t_demo and t_task must be finite vectors of shape (3,), got {t_demo!r} and {t_task!r}")
    demo_length = np.linalg.norm(t_demo)
    task_length = np.linalg.norm(t_task)
    if demo_length < min_length_m or task_length < min_length_m:
        q = _IDENTITY_QUATERNION.copy()
    else:
        a = t_demo / demo_length
        b = t_task / task_length
        cosine = float(np.dot(a, b))
        if cosine < -1.0 + 1e-9:
            # Anti-parallel: pi about a perpendicular axis, built from the coordinate
            # axis least aligned with a so the cross product is well conditioned.
            axis = np.cross(a, np.eye(3)[np.argmin(np.abs(a))])
            q = np.concatenate([[0.0], axis / np.linalg.norm(axis)])
        else:
            # Half-angle form of cos(phi/2) + n sin(phi/2), exact without acos.
            q = np.concatenate([[1.0 + cosine], np.cross(a, b)])
            q = q / np.linalg.norm(q)
    if twist_rad != 0.0 and task_length >= min_length_m:
        twist = quaternion_from_axis_angle(t_task / task_length, twist_rad)
        q = quaternion_multiply(twist, q)
    return q


def mapped_poses_from_deltas(
    deltas: ArrayLike, D_final: ArrayLike, alignment: ArrayLike, scale: float
) -> NDArray[np.float64]:
    """Eq. 23-25: rotate and scale the delta translations, keep their rotations, place.

    Parameters
    ----------
    deltas : array-like, shape (N - 1, 8)
        Demo deltas ``D_i* (x) D_m`` of the samples before the last (unit dual
        quaternions).
    D_final : array-like, shape (8,)
        The segment's last pose ``D_k`` (a unit dual quaternion).
    alignment : array-like, shape (4,)
        Unit quaternion applied to the translations.
    scale : float
        Factor applied to the translations, finite and >= 0.

    Returns
    -------
    poses : array, shape (N, 8)
        ``D_k (x) mp_i*`` for each delta, then ``D_k``.

    Raises
    ------
    ValueError
        If a shape differs from the above, a (dual) quaternion is not unit or
        ``scale`` is negative or not finite.
    """
    deltas = check_unit_dual_quaternions(deltas, "deltas")
    D_final = check_unit_dual_quaternions(D_final, "D_final")
    alignment = check_unit_quaternions(alignment, "alignment")
    if deltas.ndim != 2 or D_final.shape != (8,) or alignment.shape != (4,):
        raise ValueError(f"deltas, D_final and alignment must have shapes (N - 1, 8), (8,) and (4,), "
                         f"got {deltas.shape}, {D_final.shape} and {alignment.shape}")
    if not (np.isfinite(scale) and scale >= 0.0):
        raise ValueError(f"scale must be finite and >= 0, got {scale}")
    return _mapped_poses_from_deltas(deltas, D_final, alignment, scale)


def _mapped_poses_from_deltas(deltas, D_final, alignment, scale):
    """:func:`mapped_poses_from_deltas` without the input checks."""
    translations = scale * vector_rotated_by_quaternion(alignment, translation_from_dual_quaternion(deltas))
    mapped = dual_quaternion_from_translation_rotation(translations, deltas[:, :4])  # Eq. 24
    return _poses_from_deltas(mapped, D_final)  # Eq. 25


def map_segment(
    demo_poses: ArrayLike,
    allocation: Allocation,
    task_poses: ArrayLike,
    twist_rad: float = 0.0,
    min_length_m: float = MIN_TRANSLATION_M,
) -> MappedSegment:
    """Map a demonstration onto a segment through all its critical configurations.

    Parameters
    ----------
    demo_poses : array-like, shape (m, 8)
        The (resampled) demo poses whose feature the allocation indexes (unit dual
        quaternions).
    allocation : similarity.Allocation
        Demo indices ``i_1 < ... < i_p`` allocated to the segment's p deltas.
    task_poses : array-like, shape (p + 1, 8)
        ``D_j .. D_k``, the segment's critical configurations (unit dual quaternions).
    twist_rad : float
        Free twist about the task's first translation (``docs/method.rst``, *Mapping*).
    min_length_m : float
        Translation length below which a direction is undefined.

    Returns
    -------
    segment : MappedSegment
        ``N = m - i_1`` poses.

    Raises
    ------
    ValueError
        If a shape differs from the above, the poses are not unit dual quaternions, the
        allocation indices are not strictly increasing delta indices of the demo, or
        ``twist_rad`` is not finite.
    """
    demo_poses = check_unit_dual_quaternions(demo_poses, "demo_poses")
    task_poses = check_unit_dual_quaternions(task_poses, "task_poses")
    indices = np.asarray(allocation.indices, dtype=int)
    p = len(indices)
    if demo_poses.ndim != 2:
        raise ValueError(f"demo_poses must have shape (m, 8), got {demo_poses.shape}")
    if task_poses.shape != (p + 1, 8):
        raise ValueError(f"task_poses must have shape ({p + 1}, 8) for {p} allocated deltas, "
                         f"got {task_poses.shape}")
    if p == 0 or np.any(np.diff(indices) <= 0) or indices[0] < 0 or indices[-1] >= len(demo_poses) - 1:
        raise ValueError(f"allocation indices {indices} are not strictly increasing demo "
                         f"delta indices below {len(demo_poses) - 1}")
    if not np.isfinite(twist_rad):
        raise ValueError(f"twist_rad must be finite, got {twist_rad}")

    suffix, deltas, t_demo, t_task, scale = _segment_parts(demo_poses, indices, task_poses, min_length_m)
    alignment = alignment_from_translations(t_demo, t_task, twist_rad, min_length_m)
    anchors = np.append(indices - indices[0], len(suffix) - 1)
    uncorrected, corrections, poses = _mapped_through_anchors(deltas, task_poses, alignment, scale, anchors)

    _, correction_angle = axis_angle_from_quaternion(corrections[:, :4])
    correction_distance = np.linalg.norm(translation_from_dual_quaternion(corrections), axis=-1)
    anchors.flags.writeable = False
    return MappedSegment(
        poses=poses,
        anchor_indices=anchors,
        max_correction_position_m=float(correction_distance.max()),
        max_correction_rotation_rad=float(correction_angle.max()),
        uncorrected_poses=uncorrected,
        scale=scale,
        alignment=alignment,
    )


def _segment_parts(demo_poses, indices, task_poses, min_length_m):
    """What a mapping needs besides its alignment: the demo suffix, its deltas, the
    demo's and the task's first translations and the scale (Eq. 23)."""
    suffix = demo_poses[indices[0]:]
    deltas = _deltas_from_poses(suffix)
    t_demo = translation_from_dual_quaternion(deltas[0])
    t_task = translation_from_dual_quaternion(dual_quaternion_relative(task_poses[0], task_poses[-1]))
    demo_length = np.linalg.norm(t_demo)
    scale = 1.0 if demo_length < min_length_m else float(np.linalg.norm(t_task) / demo_length)
    return suffix, deltas, t_demo, t_task, scale


def _mapped_through_anchors(deltas, task_poses, alignment, scale, anchors):
    """The mapped poses before and after the correction through the anchors, and the
    corrections, for one alignment (4,) or several (a, 1, 4): (..., N, 8) each."""
    uncorrected = _mapped_poses_from_deltas(deltas, task_poses[-1], alignment, scale)
    lead = uncorrected.shape[:-2]
    residuals = np.concatenate(
        [dual_quaternion_relative(uncorrected[..., anchors[:-1], :], task_poses[:-1]),
         np.broadcast_to(IDENTITY_DUAL_QUATERNION, lead + (1, 8))], axis=-2)
    corrections = _corrections_between_anchors(residuals, anchors)
    # At an anchor the correction is the residual itself (ScLERP at s = 0 is exact), so
    # the pose there is M (x) M* (x) T = T to rounding, with T's sign.
    return uncorrected, corrections, dual_quaternion_multiply(uncorrected, corrections)


def map_segment_twists(demo_poses: ArrayLike, allocation: Allocation, task_poses: ArrayLike,
                       twists_rad: ArrayLike, min_length_m: float = MIN_TRANSLATION_M) -> NDArray[np.float64]:
    """The poses of :func:`map_segment` for each of the twists ``twists_rad`` (a,) at once:
    shape (a, N, 8), the same numbers as one call per twist (the alignments differ, the
    rest is shared). Inputs as :func:`map_segment`'s, unchecked."""
    demo_poses, task_poses = np.asarray(demo_poses, dtype=float), np.asarray(task_poses, dtype=float)
    indices = np.asarray(allocation.indices, dtype=int)
    suffix, deltas, t_demo, t_task, scale = _segment_parts(demo_poses, indices, task_poses, min_length_m)
    alignments = _twisted_alignments(t_demo, t_task, np.asarray(twists_rad, dtype=float), min_length_m)
    anchors = np.append(indices - indices[0], len(suffix) - 1)
    return _mapped_through_anchors(deltas, task_poses, alignments[:, None, :], scale, anchors)[2]


def _twisted_alignments(t_demo, t_task, twists: np.ndarray, min_length_m: float) -> np.ndarray:
    """:func:`alignment_from_translations` for each of ``twists`` (a,): shape (a, 4), the
    same numbers."""
    base = alignment_from_translations(t_demo, t_task, 0.0, min_length_m)
    alignments = np.broadcast_to(base, twists.shape + (4,)).copy()
    task_length = np.linalg.norm(t_task)
    turning = twists != 0.0
    if task_length >= min_length_m and turning.any():
        alignments[turning] = quaternion_multiply(
            quaternion_from_axis_angle(t_task / task_length, twists[turning]), base)
    return alignments


def least_anchor_correction_m(demo_poses: ArrayLike, allocation: Allocation, task_poses: ArrayLike,
                              twists_rad: ArrayLike, min_length_m: float = MIN_TRANSLATION_M) -> float:
    """A lower bound on :func:`map_segment`'s ``max_correction_position_m`` for every twist
    of ``twists_rad``, from the anchors alone: the least, over the twists, of the largest
    position residual at an anchor. At an anchor the correction is the residual itself
    (ScLERP at 0), so no sample of the mapping is needed but the p anchors': a mapping
    this bound already shows beyond a limit need not be made. Inputs as
    :func:`map_segment_twists`', unchecked."""
    demo_poses, task_poses = np.asarray(demo_poses, dtype=float), np.asarray(task_poses, dtype=float)
    indices = np.asarray(allocation.indices, dtype=int)
    # The suffix's deltas at the anchors (Eq. 12 for those samples only) and Eq. 23's parts.
    deltas = _deltas_from_poses(np.concatenate([demo_poses[indices], demo_poses[-1:]]))
    t_demo = translation_from_dual_quaternion(deltas[0])
    t_task = translation_from_dual_quaternion(dual_quaternion_relative(task_poses[0], task_poses[-1]))
    demo_length = np.linalg.norm(t_demo)
    scale = 1.0 if demo_length < min_length_m else float(np.linalg.norm(t_task) / demo_length)
    alignments = _twisted_alignments(t_demo, t_task, np.asarray(twists_rad, dtype=float), min_length_m)
    at_anchors = _mapped_poses_from_deltas(deltas, task_poses[-1], alignments[:, None, :], scale)[:, :-1]
    residuals = dual_quaternion_relative(at_anchors, task_poses[:-1])  # (twists, p, 8)
    return float(np.min(np.max(np.linalg.norm(translation_from_dual_quaternion(residuals), axis=-1), axis=-1)))


def _corrections_between_anchors(residuals, anchors):
    """ScLERP residuals (..., p + 1, 8) between anchor indices (p + 1,) -> (...,
    anchors[-1] + 1, 8)."""
    samples = np.arange(anchors[-1] + 1)
    interval = np.clip(np.searchsorted(anchors, samples, side="right") - 1, 0, len(anchors) - 2)
    fraction = (samples - anchors[interval]) / (anchors[interval + 1] - anchors[interval])
    return dual_quaternion_sclerp(residuals[..., interval, :], residuals[..., interval + 1, :], fraction)
