"""Where the optimization program starts, and which of its motions the plan takes: the
composed joint path at path fractions, straight joint-space lines through the critical
configurations, a duration each guess keeps the bounds at, the starts in their fixed
order (:func:`start_guesses`: the plain program's motion, the lines, the composed path as the
fallback) and the fixed choice among the motions that pass (:func:`best_start`). Which
local solution SNOPT reaches from one start moves with the last bits of the plan; the
choice among several starts far less (docs/method.rst, Several starts, one fixed
choice).

Not for: the program itself (``robot/trajectory_optimization.py``) or the checks that
decide which motions pass (``refinement_check.py``).
"""

from __future__ import annotations

import math

import numpy as np
from pydrake.math import BsplineBasis
from pydrake.trajectories import BsplineTrajectory

from drake_lfd.planning.refinement_options import RefinementOptions
from drake_lfd.robot.optimization_records import TrajectoryLimits

__all__ = ["STARTS", "START_NAMES", "start_guesses", "best_start", "duration_guess", "fractions_by_joint_arc_length",
           "in_path_fraction", "through_critical_configurations"]


def fractions_by_joint_arc_length(t: np.ndarray, q: np.ndarray, due: list, fractions: np.ndarray) -> np.ndarray:
    """Path fractions (m,) of the composed joint path's samples (times ``t`` (m,), joints
    ``q`` (m, 6)): each critical configuration at its fraction, and within each span
    by joint-space arc length (the time fraction where a span does not move). The
    composed timing rests and slows where the path turns; by time its spline guess
    would speed up and slow down along ``s``, its second derivative would be large, and
    so would the duration the guess needs to keep within the acceleration bound."""
    arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(q, axis=0), axis=1))])
    arc_due = np.interp(due, t, arc)
    s = t / t[-1]
    for j in range(len(due) - 1):
        inside = (t >= due[j] - 1e-9) & (t <= due[j + 1] + 1e-9)
        length = arc_due[j + 1] - arc_due[j]
        if length > 1e-9:
            s[inside] = fractions[j] + (arc[inside] - arc_due[j]) / length * (fractions[j + 1] - fractions[j])
    return np.clip(s, 0.0, 1.0)


def through_critical_configurations(fractions: np.ndarray, q_start: np.ndarray, q_due: list,
                                     q_goal: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The plain optimizer's guess: straight in joint space from each critical
    configuration to the next (the composed path's configurations there), at their
    path fractions; samples (m,) and (m, 6)."""
    knots = np.vstack([q_start, *q_due, q_goal])
    s = np.linspace(0.0, 1.0, 200)
    return s, np.column_stack([np.interp(s, fractions, knots[:, j]) for j in range(knots.shape[1])])


def duration_guess(guess, limits: TrajectoryLimits) -> float:
    """The shortest duration at which the guess ``q(s)`` keeps every joint within its
    speed and acceleration bounds (``|q'(s)| / T`` and ``|q''(s)| / T^2`` on 201 path
    fractions), at least 0.5 s: the guess starts within the bounds the convex hull
    enforces, and no slower than it must be."""
    s = np.linspace(0.0, 1.0, 201)
    velocity, acceleration = guess.MakeDerivative(1), guess.MakeDerivative(2)
    dq = np.max(np.abs(np.hstack([velocity.value(float(x)) for x in s])))
    ddq = np.max(np.abs(np.hstack([acceleration.value(float(x)) for x in s])))
    return max(dq / limits.joint_speed_rad_s, math.sqrt(ddq / limits.acceleration_rad_s2), 0.5)


# How a failure reason names the start it comes from (``start_guesses``).
START_NAMES = {"plain motion": "from the plain program's motion", "composed": "from the composed path",
                "lines": "from straight joint-space lines"}
#: Every start the tube program knows (``start_guesses``).
STARTS = tuple(START_NAMES)


def start_guesses(method: str, line_guess, composed_guess, limits: TrajectoryLimits, solve, path_bounds,
            starts=("plain motion", "lines"), fallback=("composed",), passed=()):
    """The program's starts, in order, as ``(label, guess, duration, None)``, or
    ``(label, None, None, answer)`` when the solve that makes a start gave no motion
    (``answer``: that solve's). Lazy: a start is made when the consumer asks for it.

    ``plain``: ``line_guess`` (straight joint-space lines through the composed path's
    configurations at the critical configurations). ``refine``: each of ``starts``, then
    each of ``fallback`` while ``passed`` (the consumer's list of motions that passed the
    checks) is empty. ``plain motion``: the plain program's motion (the program without
    the tube, the same limits, targets and path constraints, solved from ``line_guess``
    with ``solve(guess, duration, path_bounds)``); ``lines``: ``line_guess`` itself;
    ``composed``: the composed joint path (``composed_guess()``). Which local solution
    SNOPT reaches from one start moves with the last bits of the plan; the choice among
    several starts moves far less (``best_start``). From the composed path SNOPT lands in
    poor local solutions where the demonstrations detour, and where another start passed
    it was not the one chosen: it is the fallback, where neither of the others gives a
    motion that passes (docs/method.rst, Several starts, one fixed choice)."""
    if method == "plain":
        yield "plain", line_guess, duration_guess(line_guess, limits), None
        return
    for label in tuple(starts) + tuple(fallback):
        if label in fallback and label not in starts and passed:
            return
        if label == "plain motion":
            plain = solve(line_guess, duration_guess(line_guess, limits), path_bounds)
            if plain.trajectory is None:
                yield label, None, None, plain
            else:
                yield (label,) + in_path_fraction(plain.trajectory) + (None,)
        elif label == "composed":
            guess = composed_guess()
            yield label, guess, duration_guess(guess, limits), None
        elif label == "lines":
            yield label, line_guess, duration_guess(line_guess, limits), None
        else:
            raise ValueError(f"unknown start {label!r} (known: {', '.join(STARTS)})")


def in_path_fraction(trajectory: BsplineTrajectory) -> tuple[BsplineTrajectory, float]:
    """A solved ``q(t)`` as the guess ``q(s)``, ``s = t / T``, and its duration ``T``."""
    T = float(trajectory.end_time())
    basis = trajectory.basis()
    return BsplineTrajectory(BsplineBasis(basis.order(), np.asarray(basis.knots()) / T),
                             trajectory.control_points()), T


def best_start(passed: list, options: RefinementOptions) -> tuple:
    """The motion the plan takes among ``passed`` (``(solved, checked)`` in the starts'
    order, each passing every check): the first whose program duration is within
    ``equal_duration`` of the shortest.

    Not the shortest outright, nor by the retimed plan's duration: local solutions of
    equal program duration (the same minimum reached along different shapes where the
    duration does not bind them) are retimed differently by the slow passage of the
    critical configurations, and which of them is the shortest flips with the last bits
    of the plan; the starts' order does not."""
    shortest = min(solved.duration for solved, _ in passed)
    return next(pair for pair in passed if pair[0].duration <= (1.0 + options.equal_duration) * shortest)
