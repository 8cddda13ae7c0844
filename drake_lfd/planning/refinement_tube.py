"""The tube around the mapped demonstrations: the composed plan's SE(3) path as a function
of the path fraction ``s`` (:class:`ComposedPathReference`, arc length within each span), a path's
deviations from it (at matching path fractions, from a span's path as a shape, from the
path as a set), and the tube's pose bounds in the program (E within the allowed
deviation of the composed path at sampled path fractions).

Not for: how far the task allows (``refinement_bounds.py``), the checks of a solved
motion (``refinement_check.py``).
"""

from __future__ import annotations

import numpy as np
from pydrake.trajectories import PiecewisePose

from drake_lfd.core.timing import TimedPlan
from drake_lfd.planning.refinement_bounds import AllowedDeviations
from drake_lfd.planning.refinement_options import RefinementOptions
from drake_lfd.robot.optimization_records import PoseBound

__all__ = ["path_fractions_of", "tube_deviation", "shape_deviation", "ComposedPathReference", "deviations_from_reference",
           "span_deviations", "tube_bounds"]


class ComposedPathReference:
    """The composed plan's SE(3) path as a function of the path fraction ``s``: the
    critical configurations at their fractions ``t_i / T``; within each span, the pose
    at the same fraction of the span's arc length (translation plus 0.1 m per radian of
    rotation), so a uniform progress in ``s`` is a uniform progress along the path."""

    ROTATION_WEIGHT_M_PER_RAD = 0.1

    def __init__(self, plan: TimedPlan):
        T = plan.duration
        self.fractions = np.array([plan.times[i] / T for i in plan.critical_indices])
        X = plan.X_WE_list()
        p = np.array([x.translation() for x in X])
        steps = np.linalg.norm(np.diff(p, axis=0), axis=1)
        rotation = np.array([X[k].rotation().inverse().multiply(X[k + 1].rotation()).ToAngleAxis().angle()
                             for k in range(len(X) - 1)])
        length = np.concatenate([[0.0], np.cumsum(steps + self.ROTATION_WEIGHT_M_PER_RAD * rotation)])
        # Each sample's path fraction: by arc length within its span.
        s = np.zeros(len(X))
        for j in range(len(plan.critical_indices) - 1):
            a, b = plan.critical_indices[j], plan.critical_indices[j + 1]
            span = length[b] - length[a]
            local = (length[a:b + 1] - length[a]) / span if span > 0 else np.linspace(0.0, 1.0, b - a + 1)
            s[a:b + 1] = self.fractions[j] + local * (self.fractions[j + 1] - self.fractions[j])
        self.sample_fractions = s
        keep = np.concatenate([[True], np.diff(s) > 1e-12])
        self._s = s[keep]
        self._length = length[keep]
        self._pose = PiecewisePose.MakeLinear(list(self._s), [x for x, k in zip(X, keep) if k])
        self.critical_poses = [X[i] for i in plan.critical_indices]

    def pose(self, s: float):
        return self._pose.GetPose(float(np.clip(s, 0.0, self._s[-1])))

    def evenly_along(self, count: int) -> np.ndarray:
        """``count`` inner path fractions evenly spread along the path's arc length
        (not evenly in ``s``: a span passed quickly for its length gets its share)."""
        lengths = np.linspace(0.0, self._length[-1], count + 2)[1:-1]
        return np.interp(lengths, self._length, self._s)


def path_fractions_of(plan: TimedPlan) -> np.ndarray:
    """The path fraction of each sample of a composed plan (by arc length within each
    span, see :class:`ComposedPathReference`): the fractions the tube is defined at."""
    return ComposedPathReference(plan).sample_fractions


def tube_deviation(reference_plan: TimedPlan, fractions: np.ndarray, X_WE: list) -> tuple[float, float]:
    """Largest distance and angle of the poses ``X_WE`` at path fractions ``fractions``
    from ``reference_plan``'s path at the same fractions (see :class:`ComposedPathReference`)."""
    position, rotation = deviations_from_reference(ComposedPathReference(reference_plan), fractions, X_WE)
    return float(position.max(initial=0.0)), float(rotation.max(initial=0.0))


def deviations_from_reference(reference: ComposedPathReference, fractions: np.ndarray, X_WE: list) -> tuple[np.ndarray, np.ndarray]:
    """The distance and the angle (m,) of each pose of ``X_WE`` from the reference path at
    its path fraction."""
    position, rotation = np.zeros(len(X_WE)), np.zeros(len(X_WE))
    for k, (s, X) in enumerate(zip(fractions, X_WE)):
        R = reference.pose(s)
        position[k] = np.linalg.norm(X.translation() - R.translation())
        rotation[k] = X.rotation().inverse().multiply(R.rotation()).ToAngleAxis().angle()
    return position, rotation


def shape_deviation(reference_plan: TimedPlan, X_WE: list) -> tuple[float, float]:
    """How far a path's poses ``X_WE`` stray from ``reference_plan``'s path as a set:
    for each pose the nearest reference pose (by distance plus 0.1 m per radian, the
    arc length's weighting of :class:`ComposedPathReference`; by position alone a twist in place
    would pair a pose with the wrong turn of it), and the largest distance and angle
    to it over the poses."""
    X_ref = reference_plan.X_WE_list()
    p_ref = np.array([x.translation() for x in X_ref])
    q_ref = np.array([x.rotation().ToQuaternion().wxyz() for x in X_ref])
    position, rotation = 0.0, 0.0
    for X in X_WE:
        d = np.linalg.norm(p_ref - X.translation(), axis=1)
        angle = 2.0 * np.arccos(np.clip(np.abs(q_ref @ X.rotation().ToQuaternion().wxyz()), 0.0, 1.0))
        k = int(np.argmin(d + ComposedPathReference.ROTATION_WEIGHT_M_PER_RAD * angle))
        position, rotation = max(position, float(d[k])), max(rotation, float(angle[k]))
    return position, rotation


def span_deviations(composed: TimedPlan, spans: np.ndarray, X_WE: list) -> tuple[np.ndarray, np.ndarray]:
    """The distance (m,) of each pose of ``X_WE`` from the composed plan's path over its
    span (``spans``, 0-based: the segments between the composed samples from one critical
    configuration to the next), and the angle to the composed rotation at the nearest
    sample."""
    X_ref = composed.X_WE_list()
    p_ref = np.array([x.translation() for x in X_ref])
    position, rotation = np.zeros(len(X_WE)), np.zeros(len(X_WE))
    indices = composed.critical_indices
    for k, (j, X) in enumerate(zip(spans, X_WE)):
        a, b = indices[j], indices[j + 1]
        start, end = p_ref[a:b], p_ref[a + 1:b + 1]
        if not len(start):
            start = end = p_ref[a:a + 1]
        step = end - start
        p = X.translation()
        lengths = np.einsum("ij,ij->i", step, step)
        u = np.clip(np.einsum("ij,ij->i", p - start, step) / np.where(lengths > 0, lengths, 1.0), 0.0, 1.0)
        distances = np.linalg.norm(start + u[:, None] * step - p, axis=1)
        m = int(np.argmin(distances))
        position[k] = distances[m]
        nearest = X_ref[a + m + (1 if u[m] > 0.5 else 0)] if b > a else X_ref[a]
        rotation[k] = X.rotation().inverse().multiply(nearest.rotation()).ToAngleAxis().angle()
    return position, rotation


def tube_bounds(reference: ComposedPathReference, options: RefinementOptions, allowed: AllowedDeviations | None = None) -> list[PoseBound]:
    """The tube in the program: E within ``tube_margin`` of the allowed deviation from the
    composed path at ``tube_samples`` fractions evenly in ``s`` and as many evenly along
    its arc length, and at ``path_constraint_samples`` inner fractions of each span the
    task bounds more tightly than the whole (a short span with its own bound would
    otherwise hold hardly a sample)."""
    if allowed is None:
        allowed = AllowedDeviations(reference.fractions, np.full(len(reference.fractions) - 1, options.tube_position_m),
                           np.full(len(reference.fractions) - 1, options.tube_rotation_rad), ())
    evenly_in_s = np.linspace(0.0, 1.0, options.tube_samples + 2)[1:-1]
    samples = np.union1d(evenly_in_s, reference.evenly_along(options.tube_samples))
    widest = (allowed.position_m.max(), allowed.rotation_rad.max())
    for j in range(len(allowed.position_m)):
        if allowed.position_m[j] < widest[0] or allowed.rotation_rad[j] < widest[1]:
            a, b = allowed.fractions[j], allowed.fractions[j + 1]
            samples = np.union1d(samples, np.linspace(a, b, options.path_constraint_samples + 2)[1:-1])
    position, rotation = allowed.at(samples)
    shaped = allowed.by_shape[allowed.span_of(samples)] if allowed.sources else np.zeros(len(samples), bool)
    bounds = []
    for s, radius, angle, along in zip(samples, position, rotation, shaped):
        X = reference.pose(s)
        line = {}
        if along:
            # Along the composed span's local direction, as far as the span is long.
            j = int(allowed.span_of(s))
            a, b = reference.pose(allowed.fractions[j]), reference.pose(allowed.fractions[j + 1])
            ds = 0.01 * (allowed.fractions[j + 1] - allowed.fractions[j])
            tangent = reference.pose(min(s + ds, allowed.fractions[j + 1])).translation() - \
                reference.pose(max(s - ds, allowed.fractions[j])).translation()
            length = float(np.linalg.norm(b.translation() - a.translation()))
            if np.linalg.norm(tangent) > 1e-9 and length > 0.0:
                line = {"direction_W": tangent / np.linalg.norm(tangent), "along_m": length}
        bounds.append(PoseBound(float(s), p_W=X.translation(), radius_m=options.tube_margin * float(radius),
                                R_WE=X.rotation(), angle_rad=options.tube_margin * float(angle), **line))
    return bounds
