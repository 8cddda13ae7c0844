"""Refusals that no choice of composition can change, decided before alternatives are tried.

The executable-plan search (``executable.py``) forbids a blocked action and solves again,
so a task whose every composition is blocked costs one joint-path follow per legal
action, and says the same thing once per action. Often the blocker does not depend on
the choice at all: a six-joint arm at a pose is in one of at most eight configurations
(its inverse-kinematics branches; the 2 pi windings change no margin), so when every
branch of a critical configuration violates a margin of the joint check (a singularity,
or a link or tool shape closer to an obstacle or shell than the clearance), every
composition, which must pass through it, is blocked there. :func:`blocked_configurations`
checks each critical configuration's branches (every candidate of its bounded angles)
with the same margins as :class:`~drake_lfd.robot.joint_path.JointPathChecker`, and
says, once per such configuration, which margin each branch breaks and by how much.

:func:`distinct_reasons` merges the segments the search did report into one per distinct
reason, with how many alternatives each blocked.

Not for: following joint paths (``robot/joint_path.py``) or the search itself
(``executable.py``).
"""

from __future__ import annotations

import dataclasses
import re
from collections.abc import Sequence

import numpy as np
from pydrake.math import RigidTransform

from drake_lfd.core.dual_quaternion import matrices_from_dual_quaternion
from drake_lfd.planning.composition import CompositionProblem
from drake_lfd.planning.executable import InfeasibleSegment
from drake_lfd.robot.initial_ik import UnreachableConfigurationError, initial_configuration_candidates
from drake_lfd.robot.joint_path import JointPathChecker, shoulder_singularity_distance

__all__ = ["branch_violation", "blocked_configurations", "distinct_reasons"]


def branch_violation(checker: JointPathChecker, q: np.ndarray, distance_m: float, robot_geometry: str | None,
                     box: str | None) -> tuple[str, str, str] | None:
    """The first margin of ``checker.limits`` that configuration ``q`` (6,) breaks, in the
    order the joint check tests them, as ``(reason, kind, detail)``; None when it keeps
    them all. ``distance_m`` is its least signed distance to the obstacles and shells,
    between ``robot_geometry`` and ``box`` (:meth:`KinematicScene.clearance
    <drake_lfd.robot.scene.KinematicScene.clearance>`). ``kind`` names the margin (the
    same for every branch that breaks it)."""
    limits = checker.limits
    elbow, wrist = abs(float(np.sin(q[2]))), abs(float(np.sin(q[4])))
    shoulder = abs(shoulder_singularity_distance(q))
    if elbow < limits.elbow_margin:
        return "singularity", "elbow", f"elbow straight (|sin q3| = {elbow:.3f} < {limits.elbow_margin:g})"
    if wrist < limits.wrist_margin:
        return "singularity", "wrist", f"wrist aligned (|sin q5| = {wrist:.3f} < {limits.wrist_margin:g})"
    if shoulder < limits.shoulder_margin_m:
        return ("singularity", "shoulder", f"wrist centre {1000 * shoulder:.0f} mm from the shoulder axis "
                f"(< {1000 * limits.shoulder_margin_m:.0f} mm)")
    if distance_m < limits.clearance_m:
        verb = (f"enters {box} by {-1000 * distance_m:.1f} mm" if distance_m < 0 else
                f"passes {1000 * distance_m:.1f} mm from {box} (clearance {1000 * limits.clearance_m:g} mm)")
        return "collision", f"collision {robot_geometry} {box}", f"collision with {box}: {robot_geometry} {verb}"
    return None


def _configuration_problems(checker: JointPathChecker, poses: np.ndarray, con: int) -> list | None:
    """The violations ``(reason, kind, detail)`` of every inverse-kinematics branch of
    every candidate pose (g, 8) of critical configuration ``con`` (1-based), or None as
    soon as one branch keeps every margin. A candidate no branch reaches adds
    ``("reach", ...)``."""
    problems = []
    for D in poses:
        X_WE = RigidTransform(matrices_from_dual_quaternion(np.asarray(D)[None])[0])
        try:
            branches = initial_configuration_candidates(X_WE, X_WB=checker.X_WB, scene=checker.scene, con=con)
        except UnreachableConfigurationError as error:
            problems.append(("reach", "reach", str(error).rstrip(".")))
            continue
        for branch in branches:
            violation = branch_violation(checker, branch.q, branch.min_distance_m, branch.closest_robot_geometry,
                                         branch.closest_box)
            if violation is None:
                return None
            problems.append(violation)
    return problems


def _actions_through(problem: CompositionProblem, con: int) -> int:
    """How many legal actions (demo, span and candidate angles) reach or pass 0-based
    con ``con``: the alternatives a blocked configuration blocks."""
    return int(sum(np.isfinite(matrix).sum() for (j, k, _d), matrix in problem.cost.items() if j <= con <= k))


def blocked_configurations(problem: CompositionProblem, checker: JointPathChecker) -> list[InfeasibleSegment]:
    """One segment per critical configuration that every inverse-kinematics branch of
    every candidate blocks (module docstring), empty when the choice of composition can
    still matter. Each is reported on the segment arriving at it (con_1 -> con_2 for
    con_1), with the margin each kind of branch breaks: for several branches breaking
    the same margin, the value closest to passing."""
    segments = []
    n = problem.num_cons
    for index, poses in enumerate(problem.candidate_poses):
        number = index + 1
        problems = _configuration_problems(checker, poses, number)
        if problems is None:
            continue
        by_kind: dict[str, list] = {}
        for reason, kind, detail in problems:
            by_kind.setdefault(kind, []).append((reason, detail))
        parts = []
        for kind, found in by_kind.items():
            reason, detail = min(found, key=lambda item: _closeness(item[1]))
            parts.append((len(found), reason, detail))
        parts.sort(key=lambda part: -part[0])
        branches = len(problems)
        detail = "; ".join(f"{detail} on {count} of {branches} branch{'es' if branches > 1 else ''}"
                           for count, _reason, detail in parts)
        segments.append(InfeasibleSegment(
            max(number - 1, 1), min(max(number, 2), n), parts[0][1],
            f"at con_{number}, on every inverse-kinematics branch: {detail}",
            blocked_alternatives=max(_actions_through(problem, index), 1)))
    return segments


def _closeness(detail: str) -> float:
    """Orders details of one margin by how close their measured value is to passing (the
    first number in them: larger is closer for every margin but a penetration)."""
    numbers = re.findall(r"[-+]?\d+(?:\.\d+)?", detail)
    value = float(numbers[0]) if numbers else 0.0
    return value if "enters" in detail else -value


_NUMBER = re.compile(r"[-+]?\d+(?:\.\d+)?(?:e[-+]?\d+)?")


def distinct_reasons(segments: Sequence[InfeasibleSegment]) -> tuple[InfeasibleSegment, ...]:
    """``segments`` with those saying the same thing merged: same span, same reason and the
    same detail but for its measured numbers (``elbow straight (|sin q3| = 0.054 < 0.06)``
    and ``... 0.031 ...``). The first of each kind stands for it (its demo, or none when
    several demos were blocked alike), with ``blocked_alternatives`` summed; first-found
    order is kept."""
    merged: dict[tuple, InfeasibleSegment] = {}
    for segment in segments:
        key = (segment.con_from, segment.con_to, segment.reason, _NUMBER.sub("#", segment.detail))
        if key not in merged:
            merged[key] = segment
            continue
        first = merged[key]
        merged[key] = dataclasses.replace(
            first, demo=first.demo if first.demo == segment.demo else "",
            blocked_alternatives=first.blocked_alternatives + segment.blocked_alternatives)
    return tuple(merged.values())
