"""How far the refinement may move E from the composed path, by the task file: one
distance and one angle per span from the task's ``refinement:`` block (the whole task's
``max_deviation``, its ``spans``) and its path constraints (:func:`allowed_deviations`,
docs/task_files.rst, The refinement block), with the name of the bound that sets each;
and the path constraints as the program's pose bounds.

Not for: the tube those bounds shape in the program (``refinement_tube.py``), the
path-constraint measure itself (``robot/path_constraints.py``).
"""

from __future__ import annotations

import dataclasses

import numpy as np
from pydrake.math import RotationMatrix

from drake_lfd.core.tasks import DeviationBound, RefinementBounds
from drake_lfd.planning.planner import PlanResult
from drake_lfd.planning.refinement_options import RefinementOptions
from drake_lfd.robot.path_constraints import allowed_deviation, constraint_rotation, describe_constraint
from drake_lfd.robot.optimization_records import PoseBound

__all__ = ["allowed_deviations", "AllowedDeviations", "allowed_at_fractions", "path_constraint_bounds"]


def path_constraint_bounds(result: PlanResult, fractions: np.ndarray, options: RefinementOptions) -> list[PoseBound]:
    """Each path constraint at ``path_constraint_samples`` fractions per span it covers:
    within what the check allows (:func:`~drake_lfd.robot.path_constraints.allowed_deviation`)
    less ``path_constraint_margin_rad``, but at least half of that."""
    bounds = []
    for constraint in result.task.path_constraints:
        if constraint.kind != "orientation":
            continue
        R = RotationMatrix(constraint_rotation(constraint))
        checked = allowed_deviation(constraint)
        angle = max(checked - options.path_constraint_margin_rad, 0.5 * checked)
        a, b = fractions[constraint.con_from - 1], fractions[constraint.con_to - 1]
        count = options.path_constraint_samples * (constraint.con_to - constraint.con_from) + 1
        bounds += [PoseBound(float(s), R_WE=R, angle_rad=angle) for s in np.linspace(a, b, count)]
    return bounds


@dataclasses.dataclass(frozen=True)
class AllowedDeviations:
    """How far the refined motion may move E from the composed path: one distance and
    one angle per span (con_j to con_j+1, arrays (n - 1,)), and which bound of the task
    sets each (``sources``: (position, rotation) names per span)."""

    fractions: np.ndarray
    position_m: np.ndarray
    rotation_rad: np.ndarray
    sources: tuple

    def at(self, s) -> tuple[np.ndarray, np.ndarray]:
        """The distance and angle allowed at path fractions ``s`` (m,): their span's; at
        a critical configuration between two spans, the tighter of the two."""
        s = np.atleast_1d(np.asarray(s, dtype=float))
        last = len(self.position_m) - 1
        j = np.clip(np.searchsorted(self.fractions, s, side="right") - 1, 0, last)
        position, rotation = self.position_m[j].copy(), self.rotation_rad[j].copy()
        on = (j > 0) & (np.abs(s - self.fractions[j]) <= 1e-12)
        position[on] = np.minimum(position[on], self.position_m[j[on] - 1])
        rotation[on] = np.minimum(rotation[on], self.rotation_rad[j[on] - 1])
        return position, rotation

    def span_of(self, s) -> np.ndarray:
        """The span (0-based) of each path fraction of ``s``."""
        return np.clip(np.searchsorted(self.fractions, s, side="right") - 1, 0, len(self.position_m) - 1)

    @property
    def by_shape(self) -> np.ndarray:
        """Per span: its position bound is the task's for that span (a ``spans`` entry or
        a path constraint), held to the composed span's shape (E within the distance of
        the composed span's path, wherever along it) rather than to where the composed
        plan is at the same path fraction, as the whole task's tube is. A tight bound at
        matching fractions would hold the timing along the span too: a motion that must
        come to rest at a critical configuration lags a reference moving uniformly in the
        path fraction, and no faster motion keeps a tight bound there."""
        return np.array([not source[0].startswith(("refinement.max_deviation", "the default"))
                         for source in self.sources], dtype=bool)


def allowed_deviations(task, options: RefinementOptions | None = None) -> tuple[np.ndarray, np.ndarray]:
    """How far refinement may move E from the composed path over each span of ``task``
    (con_j to con_j+1): distances and angles (n - 1,), from the task's ``refinement``
    block, its path constraints and ``options``' tube (docs/task_files.rst)."""
    allowed = allowed_at_fractions(task, np.linspace(0.0, 1.0, len(task.critical_configurations)),
                       options or RefinementOptions())
    return allowed.position_m, allowed.rotation_rad


def allowed_at_fractions(task, fractions: np.ndarray, options: RefinementOptions) -> AllowedDeviations:
    """The task file's bounds on the refinement (docs/task_files.rst): ``refinement.max_deviation``
    for the whole task (absent fields: ``options``' tube), replaced over a span by each
    entry of ``refinement.spans`` that covers it (the tighter of several), then tightened by
    each path constraint over its spans (its ``max_deviation``; its rotation within its
    tolerance unless that says otherwise)."""
    spans = len(fractions) - 1
    bounds = getattr(task, "refinement", None) or RefinementBounds()
    whole = bounds.max_deviation
    values = [np.full(spans, whole.position_m if whole.position_m is not None else options.tube_position_m),
              np.full(spans, whole.rotation_rad if whole.rotation_rad is not None else options.tube_rotation_rad)]
    sources = [["refinement.max_deviation" if value is not None else "the default"] * spans
               for value in (whole.position_m, whole.rotation_rad)]
    replaced = [np.full(spans, np.inf), np.full(spans, np.inf)]
    replaced_by: list[list[str | None]] = [[None] * spans, [None] * spans]
    for index, span in enumerate(bounds.spans):
        for axis, value in enumerate((span.position_m, span.rotation_rad)):
            for j in range(span.con_from - 1, span.con_to - 1):
                if value is not None and value < replaced[axis][j]:
                    replaced[axis][j], replaced_by[axis][j] = value, f"refinement.spans[{index}]"
    for axis in range(2):
        for j in range(spans):
            source = replaced_by[axis][j]
            if source is not None:
                values[axis][j], sources[axis][j] = replaced[axis][j], source
    for constraint in task.path_constraints:
        bound = constraint.max_deviation or DeviationBound()
        rotation = bound.rotation_rad if bound.rotation_rad is not None else constraint.tolerance_rad
        for axis, value in enumerate((bound.position_m, rotation)):
            for j in range(constraint.con_from - 1, constraint.con_to - 1):
                if value is not None and value < values[axis][j]:
                    values[axis][j], sources[axis][j] = value, describe_constraint(constraint)
    return AllowedDeviations(np.asarray(fractions, dtype=float), values[0], values[1],
                    tuple(zip(sources[0], sources[1])))
