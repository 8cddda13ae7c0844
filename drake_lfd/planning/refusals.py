"""Refusals that no choice of composition can change, decided before anything is forbidden.

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

Two more refusals of the kind follow from the same branches. A branch is the signs of
``sin q3``, ``sin q5`` and the wrist centre's distance from the shoulder axis
(:func:`branch_signature`), each zero only at a singularity: a path that keeps the
margins keeps its branch, so when no branch keeps every margin at every critical
configuration, the first configuration where none is left blocks every composition.
And shapes whose clearance depends on shoulder_pan alone must pass every pan between
two consecutive configurations' branches, one way round or the other: when both ways
come within the clearance, that span blocks every composition.

:func:`distinct_reasons` merges the segments the search did report into one per distinct
reason, with how many alternatives each blocked.

Not for: following joint paths (``robot/joint_path.py``) or the search itself
(``executable.py``).
"""

from __future__ import annotations

import dataclasses
import re
import weakref
from collections.abc import Sequence

import numpy as np
from pydrake.math import RigidTransform

from drake_lfd.core.dual_quaternion import matrices_from_dual_quaternion, translation_from_dual_quaternion
from drake_lfd.core.exact_memo import ExactMemo, exact_key
from drake_lfd.planning.composition import CompositionProblem
from drake_lfd.planning.executable import InfeasibleSegment
from drake_lfd.robot.joint_path import (
    JointPathChecker, describe_clearance_shortfall, describe_shoulder_shortfall, shoulder_singularity_distance,
)

__all__ = ["branch_signature", "branch_violation", "blocked_configurations", "distinct_reasons"]


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
        return "singularity", "shoulder", describe_shoulder_shortfall(shoulder, limits.shoulder_margin_m)
    if distance_m < limits.clearance_m:
        verb = describe_clearance_shortfall(box, distance_m, limits.clearance_m)
        return "collision", f"collision {robot_geometry} {box}", f"{robot_geometry} {verb}"
    return None


def branch_signature(q: np.ndarray) -> tuple[int, int, int]:
    """The inverse-kinematics branch of configuration ``q`` (6,): the signs of ``sin q3``
    (elbow), of ``sin q5`` (wrist) and of the wrist centre's distance from the shoulder
    axis. Each is zero only at one of the three singularities, so a joint path that
    keeps the singularity margins keeps its branch."""
    return (int(np.sign(np.sin(q[2]))), int(np.sign(np.sin(q[4]))), int(np.sign(shoulder_singularity_distance(q))))


def _configuration_problems(checker: JointPathChecker, poses: np.ndarray, con: int) -> tuple[list, list, list]:
    """The violations ``(reason, kind, detail)`` of the inverse-kinematics branches of
    every candidate pose (g, 8) of critical configuration ``con`` (1-based), the branches
    (q, shape (6,)) that keep every margin, and ``(signature, violation)`` of every branch
    found. A candidate no branch reaches adds ``("reach", ...)``."""
    problems, good, branches_found = [], [], []
    for D in poses:
        X_WE = RigidTransform(matrices_from_dual_quaternion(np.asarray(D)[None])[0])
        branches = checker.branches(X_WE)
        if not branches:
            problems.append(("reach", "reach", "no inverse-kinematics solution reaches it"))
            continue
        for branch in branches:
            violation = branch_violation(checker, branch.q, branch.min_distance_m, branch.closest_robot_geometry,
                                         branch.closest_box)
            branches_found.append((branch_signature(branch.q), violation))
            if violation is None:
                good.append(branch.q)
            else:
                problems.append(violation)
    return problems, good, branches_found


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
    good_branches, found_branches = [], []
    for index, poses in enumerate(problem.candidate_poses):
        number = index + 1
        problems, good, found = _configuration_problems(checker, poses, number)
        good_branches.append(good)
        found_branches.append(found)
        if good:
            continue
        p = np.round(translation_from_dual_quaternion(poses[0]), 3).tolist()
        if all(reason == "reach" for reason, _kind, _detail in problems):
            detail = f"at con_{number} (p = {p} m): out of the UR5e's reach, no inverse-kinematics solution"
            reason = "reach"
        else:
            reason, summary = _summary(problems)
            detail = f"at con_{number} (p = {p} m), on every inverse-kinematics branch: {summary}"
        segments.append(InfeasibleSegment(
            max(number - 1, 1), min(max(number, 2), n), reason, detail,
            blocked_alternatives=max(_actions_through(problem, index), 1)))
    if not segments:
        segments = _branch_changes(problem, found_branches)
    if not segments:
        segments = _blocked_pan_sweeps(problem, checker, good_branches)
    return segments


def _summary(problems: list) -> tuple[str, str]:
    """The reason of the most common margin broken, and one line: each margin broken, by
    how many branches, with the value closest to passing."""
    by_kind: dict[str, list] = {}
    for reason, kind, detail in problems:
        by_kind.setdefault(kind, []).append((reason, detail))
    parts = []
    for kind, found in by_kind.items():
        reason, detail = min(found, key=lambda item: _closeness(item[1]))
        parts.append((len(found), reason, detail))
    parts.sort(key=lambda part: -part[0])
    return parts[0][1], "; ".join(f"{detail} on {count} of {len(problems)}" for count, _reason, detail in parts)


def _branch_changes(problem: CompositionProblem, found_branches: list[list]) -> list[InfeasibleSegment]:
    """The critical configuration where no branch is left that keeps the margins at every
    configuration before it (a path keeps its branch, :func:`branch_signature`), as one
    segment, or none."""
    left = None  # branches that keep every margin at every configuration so far
    for index, found in enumerate(found_branches):
        here = {signature for signature, violation in found if violation is None}
        kept = here if left is None else left & here
        if not kept:
            number = index + 1
            problems = [violation for signature, violation in found if signature in left and violation is not None]
            p = np.round(translation_from_dual_quaternion(problem.candidate_poses[index][0]), 3).tolist()
            if problems:
                reason, summary = _summary(problems)
            else:
                reason, summary = "reach", "no inverse-kinematics solution there"
            detail = (f"at con_{number} (p = {p} m), on every branch the arm can keep from con_1 (changing "
                      f"branch crosses a singularity): {summary}")
            return [InfeasibleSegment(number - 1, number, reason, detail,
                                      blocked_alternatives=max(_actions_through(problem, index), 1))]
        left = kept
    return []


# The shoulder-pan sweep is checked on a grid of this many angles per turn (1 deg).
PAN_GRID = 360


def _pan_only_rows(checker: JointPathChecker) -> np.ndarray:
    """Indices of the robot geometries whose distances to the boxes depend on
    shoulder_pan alone (the shoulder link, and shapes of the upper arm round about the
    shoulder_lift axis), found by moving every other joint at two pans."""
    scene, rng = checker.scene, np.random.default_rng(0)
    lower, upper = checker.law.position_lower, checker.law.position_upper
    same = None
    for pan in (0.3, 2.1):
        samples = rng.uniform(np.maximum(lower, -np.pi), np.minimum(upper, np.pi), size=(4, 6))
        samples[:, 0] = pan
        distances = np.array([scene.signed_distances(q) for q in samples])  # (4, geometries, boxes)
        unchanged = np.all(np.abs(distances - distances[0]) < 1e-5, axis=(0, 2))  # FCL: ~1e-6 noise
        same = unchanged if same is None else same & unchanged
    return np.flatnonzero(same)


# Per checker: its pan-only rows and the pan tables computed (by the exact configuration
# whose pan turns), which trials of a task with a fixed con_1 share.
_PAN_MEMOS: "weakref.WeakKeyDictionary[JointPathChecker, dict]" = weakref.WeakKeyDictionary()


def _pan_table(scene, q: np.ndarray, rows: np.ndarray, pans: np.ndarray) -> np.ndarray:
    """The signed distances (pans, rows, boxes) of the pan-only ``rows`` with ``q``'s
    shoulder_pan turned to each of ``pans``."""
    q = np.array(q, dtype=float)
    table = []
    for pan in pans:
        q[0] = pan
        table.append(scene.signed_distances(q)[rows])
    return np.array(table)


def _blocked_pan_sweeps(problem: CompositionProblem, checker: JointPathChecker,
                        good_branches: list[list[np.ndarray]]) -> list[InfeasibleSegment]:
    """Spans con_i -> con_(i+1) that every way of turning shoulder_pan blocks.

    Between consecutive critical configurations the arm moves continuously, so
    shoulder_pan turns from its value on a branch of con_i to its value on a branch of
    con_(i+1), one way round or the other (or further). A shape whose distances depend on
    the pan alone has, at each pan, one clearance; when on both ways round, for every pair
    of branches, some pan brings such a shape within the clearance, every composition is
    blocked on that span (the per-configuration check already kept only branches that
    keep every margin)."""
    scene = checker.scene
    if not scene.geometry.keep_out_geometry_ids or any(not good for good in good_branches):
        return []
    memo = _PAN_MEMOS.setdefault(checker, {})
    if "rows" not in memo:
        memo["rows"], memo["tables"] = _pan_only_rows(checker), ExactMemo(maxsize=8)
    rows = memo["rows"]
    if not len(rows):
        return []
    pans = np.linspace(0.0, 2 * np.pi, PAN_GRID, endpoint=False)
    q = np.array(good_branches[0][0], dtype=float)
    table = memo["tables"].get(exact_key(q), lambda: _pan_table(scene, q, rows, pans))
    least = table.reshape(PAN_GRID, -1).min(axis=1)
    clearance = checker.limits.clearance_m
    segments = []
    for i in range(problem.num_cons - 1):
        a = np.mod([b[0] for b in good_branches[i]], 2 * np.pi)
        b = np.mod([b[0] for b in good_branches[i + 1]], 2 * np.pi)
        worst = _sweep_minimum(least, pans, a, b)  # (len a, len b): the better way round's least
        # A path keeps its branch: only pairs of the same branch can be joined.
        same = np.array([[branch_signature(qa) == branch_signature(qb) for qb in good_branches[i + 1]]
                         for qa in good_branches[i]])
        worst = np.where(same, worst, -np.inf)
        if worst.max() >= clearance:
            continue
        # The pair of branches and the way round that comes closest to passing.
        k = int(np.argmax(worst))
        best = float(worst.flat[k])
        pan_at = int(np.flatnonzero(least <= best + 1e-12)[0])
        row, box = np.unravel_index(np.argmin(table[pan_at]), table[pan_at].shape)
        names = scene.geometry
        robot = names.names[names.robot_geometry_ids[rows[row]]]
        what = names.describe(names.keep_out_geometry_ids[box])
        verb = describe_clearance_shortfall(what, best, clearance)
        segments.append(InfeasibleSegment(
            i + 1, i + 2, "collision",
            f"{robot} {verb} whichever way shoulder_pan turns from con_{i + 1} to con_{i + 2}, on every "
            "inverse-kinematics branch",
            blocked_alternatives=max(_actions_through(problem, i), 1)))
    return segments


def _sweep_minimum(least: np.ndarray, pans: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """For each pan pair (a_r, b_c), shape (len a, len b): the least of ``least`` (the
    clearance at each grid pan) over the arc from a_r to b_c, on the way round where that
    least is larger (the arc's grid pans strictly between the ends)."""
    turn = 2 * np.pi
    forward = np.mod(pans[None, None, :] - a[:, None, None], turn)  # pans ahead of a
    length = np.mod(b[None, :] - a[:, None], turn)[:, :, None]
    inside_forward = (forward > 0) & (forward < length)
    inside_backward = (forward > length) & (forward < turn)
    values = least[None, None, :]
    ccw = np.where(inside_forward, values, np.inf).min(axis=-1)
    cw = np.where(inside_backward, values, np.inf).min(axis=-1)
    return np.maximum(ccw, cw)


def _closeness(detail: str) -> float:
    """Orders details of one margin by how close their measured value is to passing (the
    first number in them: larger is closer for every margin but a penetration)."""
    numbers = re.findall(r"[-+]?\d+(?:\.\d+)?", detail)
    value = float(numbers[0]) if numbers else 0.0
    return value if "enters" in detail else -value


_NUMBER = re.compile(r"[-+]?\d+(?:\.\d+)?(?:e[-+]?\d+)?")


def distinct_reasons(segments: Sequence[InfeasibleSegment]) -> tuple[InfeasibleSegment, ...]:
    """``segments`` with those saying the same thing merged: the same reason and the same
    detail but for its measured numbers (``elbow straight (|sin q3| = 0.054 < 0.06)`` and
    ``... 0.031 ...``; the link and box a collision names are kept), on whichever span.
    The first of each kind stands for it (its span; its demo, or none when several demos
    were blocked alike), with ``blocked_alternatives`` summed; first-found order is kept."""
    merged: dict[tuple, InfeasibleSegment] = {}
    for segment in segments:
        key = (segment.reason, _NUMBER.sub("#", segment.detail))
        if key not in merged:
            merged[key] = segment
            continue
        first = merged[key]
        merged[key] = dataclasses.replace(
            first, demo=first.demo if first.demo == segment.demo else "",
            blocked_alternatives=first.blocked_alternatives + segment.blocked_alternatives)
    return tuple(merged.values())
