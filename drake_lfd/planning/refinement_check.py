"""The check of a solved motion: sampled at the controller's period, timed as a
:class:`~drake_lfd.core.timing.TimedPlan`, followed by the
:class:`~drake_lfd.robot.joint_path.JointPathChecker` holding the task's path
constraints (:func:`check_motion`), and checked: every critical configuration met,
executable, within the task's bounds on the deviation from the composed path span by
span (:func:`_excess` words where it goes furthest beyond), shorter than the composed
plan. A motion that fails says why; a refined plan is only ever one that passes.

Not for: the bounds themselves (``refinement_bounds.py``, ``refinement_tube.py``) or
choosing among the motions that pass (``refinement_starts.py``).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from drake_lfd.core.pose_conversions import dual_quaternion_from_matrices
from drake_lfd.core.timing import TimedPlan
from drake_lfd.planning.planner import PlanResult
from drake_lfd.planning.refinement_bounds import AllowedDeviations
from drake_lfd.planning.refinement_options import RefinementOptions
from drake_lfd.planning.refinement_tube import deviations_from_reference, ComposedPathReference, span_deviations
from drake_lfd.robot.joint_path import JointPathChecker
from drake_lfd.robot.optimization_records import OptimizedTrajectory, TrajectoryLimits
from drake_lfd.robot.optimization_scene import OptimizationScene
from drake_lfd.robot.trajectory_sampling import sample_trajectory

__all__ = ["check_motion", "CheckedMotion", "with_iterate"]  # what refinement.py runs


@dataclasses.dataclass(frozen=True)
class CheckedMotion:
    """A solved motion, sampled, followed and checked: ``reason`` None when it passes."""

    reason: str | None
    plan: TimedPlan
    followed: object
    position: float = math.nan
    rotation: float = math.nan
    fractions: np.ndarray | None = None


def check_motion(result: PlanResult, checker: JointPathChecker, scene: OptimizationScene, solved: OptimizedTrajectory,
                  allowed: AllowedDeviations, limits: TrajectoryLimits, options: RefinementOptions,
                  method: str) -> CheckedMotion:
    """Samples the solver's motion at the controller's period (module docstring), follows
    it with ``checker`` holding the task's path constraints (as the search does) and
    checks it: executable, every critical configuration within ``check_fraction`` of the
    success tolerances, within the task's bounds on the deviation from the composed path
    (``refine``; span by span, ``allowed``) and shorter than the composed plan."""
    timed, dt, fractions = result.timed, checker.time_step, allowed.fractions
    assert timed is not None  # a planned result (the refinement refines nothing else)
    t, q, X, indices, s_samples = sample_trajectory(scene, solved.trajectory, fractions, time_step=dt,
                                                    tool_speed_m_s=limits.tool_speed_m_s,
                                                    tool_acceleration_m_s2=limits.tool_acceleration_m_s2,
                                                    pass_speed_m_s=options.pass_speed_m_s,
                                                    pass_acceleration_m_s2=options.pass_acceleration_m_s2)
    poses = dual_quaternion_from_matrices(np.array([x.GetAsMatrix4() for x in X]))
    plan = TimedPlan(t, poses, tuple(indices))
    followed = checker.follow(plan, q[0], path_constraints=result.task.path_constraints)
    duration = plan.duration

    def checked(reason, position=math.nan, rotation=math.nan):
        return CheckedMotion(reason, plan, followed, position, rotation, s_samples)

    # The motion's own critical configurations must be the composed plan's, within the
    # program's tolerances (with room for SNOPT's feasibility tolerance): every later
    # check compares against the motion's own poses, and an iterate SNOPT stopped at its
    # iteration limit need not meet its targets (found by ``paper --refine``'s
    # re-derivation: such plans were followed exactly, 10 deg from the task's con_2).
    allowed_position = options.target_check_slack * math.sqrt(3.0) * options.con_position_tolerance_m
    allowed_rotation = options.target_check_slack * options.con_rotation_tolerance_rad
    composed = timed.X_WE_list()
    for con, (index, X_con) in enumerate(zip(indices, (composed[i] for i in timed.critical_indices)), start=1):
        position = float(np.linalg.norm(X[index].translation() - X_con.translation()))
        rotation = float(X[index].rotation().inverse().multiply(X_con.rotation()).ToAngleAxis().angle())
        if position > allowed_position or rotation > allowed_rotation:
            return checked(f"optimizer: misses con_{con} by {1000 * position:.1f} mm, "
                           f"{math.degrees(rotation):.2f} deg (the program allows "
                           f"{1000 * allowed_position:.1f} mm, {math.degrees(allowed_rotation):.2f} deg)")

    if not followed.executable:
        b = followed.blocker
        assert b is not None  # what makes it not executable
        return checked(f"check: {b.reason}: {b.detail} (t = {b.time_s:.2f} s)")
    tolerances = checker.limits
    for con, (c_position, c_rotation) in enumerate(followed.critical_errors, start=1):
        if c_position > options.check_fraction * tolerances.position_tolerance_m or \
                c_rotation > options.check_fraction * tolerances.rotation_tolerance_rad:
            return checked(f"check: misses con_{con} by {1000 * c_position:.1f} mm, "
                           f"{math.degrees(c_rotation):.2f} deg (allowed: {options.check_fraction:g} of the "
                           f"success tolerances)")
    X_followed = [scene.X_WE(x) for x in followed.q]
    s_followed = np.interp(np.minimum(followed.t, duration), t, s_samples)
    deviation = deviations_from_reference(ComposedPathReference(timed), s_followed, X_followed)
    position, rotation = float(deviation[0].max(initial=0.0)), float(deviation[1].max(initial=0.0))
    if method == "refine":
        shaped = allowed.by_shape[allowed.span_of(s_followed)]
        if shaped.any():
            held = span_deviations(timed, allowed.span_of(s_followed[shaped]), [x for x, k in zip(X_followed, shaped) if k])
            deviation = (deviation[0].copy(), deviation[1].copy())
            deviation[0][shaped] = held[0]
        excess = _excess(allowed, s_followed, *deviation)
        if excess is not None:
            return checked(f"check: {excess}", position, rotation)
    if not duration < timed.duration:
        return checked(f"not shorter ({duration:.2f} s, unrefined {timed.duration:.2f} s)", position, rotation)
    return checked(None, position, rotation)


def _excess(allowed: AllowedDeviations, s: np.ndarray, position: np.ndarray, rotation: np.ndarray) -> str | None:
    """Where the followed motion (at path fractions ``s``, its deviations ``position`` and
    ``rotation`` from the composed path) goes furthest beyond the task's bound, relative
    to the bound, as a reason naming the span and the bound; None when it keeps every
    bound."""
    if not len(s):
        return None
    radius, angle = allowed.at(s)
    over = np.maximum(position / radius, rotation / angle)
    k = int(np.argmax(over))
    if over[k] <= 1.0:
        return None
    j = int(allowed.span_of(s[k]))
    axis = 0 if position[k] / radius[k] >= rotation[k] / angle[k] else 1
    value, limit, unit = ((1000 * position[k], 1000 * radius[k], "mm") if axis == 0 else
                          (math.degrees(rotation[k]), math.degrees(angle[k]), "deg"))
    digits = 0 if axis == 0 else 1
    while digits < 3 and round(value, digits) <= round(limit, digits):  # digits enough to show the excess
        digits += 1
    where = "from the composed span's path" if axis == 0 and allowed.by_shape[j] else "from the composed path"
    return (f"moves {value:.{digits}f} {unit} {where} between con_{j + 1} and con_{j + 2} where "
            f"{allowed.sources[j][axis]} allows {limit:g} {unit}")


def with_iterate(reason: str, solved: OptimizedTrajectory) -> str:
    """A failed check's reason, saying when the motion was SNOPT's last iterate."""
    if solved.budget_spent:
        return f"{reason}; SNOPT's last iterate at its {solved.status}"
    if solved.nearly_feasible:
        return f"{reason}; SNOPT's last iterate, {solved.status}"
    return reason
