"""Bounded stretching: a mapping whose correction is large against its span is illegal.

The mapping (``core/mapping.py``) bends a demonstration exactly through every critical
configuration of its span; where the demonstration does not fit them, the correction
spread over the span takes up the difference. The fidelity cost's terms
(``core/fidelity.py``) each see one allocated pair, so they cannot see what a short
demonstration stretched over a long span does to its later configurations: a 16 cm
descent with a turn, allocated to a 67 cm carry and the descent after it, is scaled
4x and then pulled 66 cm back through the intermediate configuration, at a cost
below the honest composition's (docs/method.rst, Shape fidelity).

The measure is the mapping's largest position correction over the span's length (the
polyline through its critical configurations): a span's action is legal only while

    max_correction_position_m <= max(STRETCH_BOUND * span_length_m, MIN_ALLOWED_CORRECTION_M)

with :data:`STRETCH_BOUND` 0.25 and :data:`MIN_ALLOWED_CORRECTION_M` 2 cm (docs/method.rst,
Bounded stretching). A mapping within it keeps the demonstrated shape to within a
quarter of the span's length, and the planners choose among those only; the bound is
checked lazily, like the joint-space check (``executable.py``): the chosen
composition's steps are mapped, a step beyond the bound is forbidden and the planner
solves again.

Not for: the mapping itself (``core/mapping.py``), the fidelity cost's terms.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from drake_lfd.core.dual_quaternion import translation_from_dual_quaternion
from drake_lfd.planning.composition import CompositionProblem, Step

__all__ = ["STRETCH_BOUND", "MIN_ALLOWED_CORRECTION_M", "MAX_STRETCH_ROUNDS", "BOUND_DECISION_MARGIN_M",
           "span_length_m", "allowed_correction_m", "solve_within_stretch_bound"]

# On the bundled paper tasks (seeds 0-9) and the 60 tasks of benchmarks/bench_fidelity.py,
# fidelity plans correct at most 0.27 of a span's length (13.6 mm over a 51 mm span; all
# others at most 0.12) and 20 mm in absolute terms; the stretched case of
# tests/test_stretching.py corrects 0.79 (660 mm over 831 mm).
STRETCH_BOUND = 0.25
# A span whose configurations nearly coincide (a screw turn) has no length to compare
# with; its mapping may still correct this much, the size of the smallest demonstrated
# motions.
MIN_ALLOWED_CORRECTION_M = 0.02
# Steps forbidden for stretching before the planner is given up on.
MAX_STRETCH_ROUNDS = 40
# How far beyond the bound a lower bound on a correction must be to decide without the
# mapping (the two computations differ by rounding, some 1e-16 m).
BOUND_DECISION_MARGIN_M = 1e-9


def span_length_m(problem: CompositionProblem, step: Step) -> float:
    """Length (m) of the polyline through the positions of ``step``'s critical
    configurations con_j .. con_k (candidates share their position)."""
    positions = np.array([translation_from_dual_quaternion(problem.candidate_poses[l][0])
                          for l in range(step.j, step.k + 1)])
    return float(np.linalg.norm(np.diff(positions, axis=0), axis=1).sum())


def allowed_correction_m(length_m: float) -> float:
    """The largest position correction (m) a mapping over a span of ``length_m`` may make."""
    return max(STRETCH_BOUND * length_m, MIN_ALLOWED_CORRECTION_M)


def solve_within_stretch_bound(problem: CompositionProblem, solve: Callable[[CompositionProblem], list | None],
                               correction_of: Callable[[Step], float],
                               least_correction_of: Callable[[Step], float] | None = None) -> list[Step] | None:
    """``solve(problem)``'s composition with every step within the bound (module
    docstring): steps whose ``correction_of(step)`` (the mapped span's largest position
    correction, m) exceeds :func:`allowed_correction_m` are forbidden in ``problem`` and
    the planner solves again. None when nothing within the bound covers the task.

    ``least_correction_of(step)``, a lower bound on it that costs less (the anchors'
    residuals, :func:`~drake_lfd.core.mapping.least_anchor_correction_m`), is asked
    first: a step it puts beyond the bound by more than :data:`BOUND_DECISION_MARGIN_M`
    is stretched whatever its mapping, and is forbidden without being mapped. The
    verdicts are those of ``correction_of`` alone."""

    def stretched(step: Step) -> bool:
        allowed = allowed_correction_m(span_length_m(problem, step))
        if least_correction_of is not None and least_correction_of(step) > allowed + BOUND_DECISION_MARGIN_M:
            return True
        return correction_of(step) > allowed

    for _ in range(MAX_STRETCH_ROUNDS):
        steps = solve(problem)
        if steps is None:
            return None
        stretched_steps = [s for s in steps if stretched(s)]
        if not stretched_steps:
            return steps
        for step in stretched_steps:
            problem.forbid(step)
    return None
