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

What the pre-check cannot prove, the search can still learn cheaply:
:class:`PoseBlockers` rules out, without following it, a composition whose poses turn
shoulder_pan through a pan where a pan-only shape is within the clearance, or take the
start's branch deep into the elbow or wrist singularity. The pan's clearance is decided
exactly between the grid's pans (:class:`_PanClearance`), so the pre-check, the rule-out
and the follow agree on a clearance within a hair of the margin.

:func:`distinct_reasons` merges the segments the search did report into one per distinct
reason, with how many alternatives each blocked.

Not for: following joint paths (``robot/joint_path.py``) or the search itself
(``executable.py``).
"""

from __future__ import annotations

import dataclasses
import math
import re
from collections.abc import Sequence

import numpy as np
from pydrake.math import RigidTransform

from drake_lfd.core.dual_quaternion import translation_from_dual_quaternion
from drake_lfd.core.pose_conversions import matrices_from_dual_quaternion
from drake_lfd.planning.composition import CompositionProblem
from drake_lfd.planning.executable import InfeasibleSegment
from drake_lfd.robot.analytic_ik import elbow_and_wrist_sines, shoulder_pan_roots
from drake_lfd.robot.motion_bounds import motion_bounds
from drake_lfd.robot.dh_kinematics import shoulder_singularity_distance
from drake_lfd.robot.joint_path import JointPathChecker
from drake_lfd.robot.joint_path_records import Blocker, describe_clearance_shortfall, singularity_shortfall

__all__ = ["branch_signature", "branch_violation", "blocked_configurations", "distinct_reasons",
           "PoseBlockers"]


def branch_violation(checker: JointPathChecker, q: np.ndarray, distance_m: float, robot_geometry: str | None,
                     box: str | None) -> tuple[str, str, str] | None:
    """The first margin of ``checker.limits`` that configuration ``q`` (6,) breaks, in the
    order the joint check tests them, as ``(reason, kind, detail)``; None when it keeps
    them all. ``distance_m`` is its least signed distance to the obstacles and shells,
    between ``robot_geometry`` and ``box`` (:meth:`KinematicScene.clearance
    <drake_lfd.robot.scene.KinematicScene.clearance>`). ``kind`` names the margin (the
    same for every branch that breaks it)."""
    limits = checker.limits
    singular = singularity_shortfall(abs(float(np.sin(q[2]))), abs(float(np.sin(q[4]))),
                                     abs(shoulder_singularity_distance(q)), limits)
    if singular is not None:
        return "singularity", *singular
    if distance_m < limits.clearance_m:
        assert box is not None  # a distance below the clearance has its nearest box
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
    left: set[tuple[int, int, int]] | None = None  # branches that keep every margin at every configuration so far
    for index, found in enumerate(found_branches):
        here = {signature for signature, violation in found if violation is None}
        kept = here if left is None else left & here
        if not kept:
            assert left is not None  # every configuration has a branch that keeps the margins
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


def _pan_memo(checker: JointPathChecker) -> dict:
    """The checker's pan-only rows' Lipschitz constant in shoulder_pan (the largest
    distance of their points from the pan axis) and its pan sweep (:func:`_pan_sweeps`).
    The rows themselves are the scene's (``scene.pan_only_rows``)."""
    memo = checker.pan_memo  # the trials of a task share its checker
    if "lipschitz" not in memo:
        scene = checker.scene
        plant, inspector = scene.plant, scene.scene_graph.model_inspector()
        ids = scene.geometry.robot_geometry_ids
        memo["lipschitz"] = max((float(motion_bounds(plant, inspector, ids[r])[0]) for r in scene.pan_only_rows),
                                default=0.0)
        memo["sweeps"] = None
    return memo


def _pan_sweeps(checker: JointPathChecker) -> "_PanClearance":
    """The checker's pan-only clearance as a function of shoulder_pan (made once per
    checker), measured at the pan-only configuration (all joints but the pan at zero),
    as the follow measures those shapes (:mod:`~drake_lfd.robot.pan_only`)."""
    memo = _pan_memo(checker)
    if memo.get("sweeps") is None:
        scene, rows = checker.scene, checker.scene.pan_only_rows
        pans = np.linspace(0.0, 2 * np.pi, PAN_GRID, endpoint=False)
        q = np.zeros(6)
        least = _pan_table(scene, q, rows, pans).reshape(PAN_GRID, -1).min(axis=1)
        memo["sweeps"] = _PanClearance(scene, q, rows, pans, least, memo["lipschitz"], checker.limits.clearance_m)
    return memo["sweeps"]


def _pan_table(scene, q: np.ndarray, rows: np.ndarray, pans: np.ndarray) -> np.ndarray:
    """The signed distances (pans, rows, boxes) of the pan-only ``rows`` with ``q``'s
    shoulder_pan turned to each of ``pans``."""
    q = np.array(q, dtype=float)
    table = []
    for pan in pans:
        q[0] = pan
        table.append(scene.signed_distances(q)[rows])
    return np.array(table)


class _PanClearance:
    """The least clearance of the pan-only shapes as a function of shoulder_pan, decided
    exactly over any arc.

    ``f(pan)`` is the least signed distance of the pan-only rows to the boxes, measured as
    the follow measures it (Drake's signed distances). On the grid it is known; between
    two pans ``x0 < x1`` with values ``v0, v1`` it is at least ``(v0 + v1) / 2 - L (x1 -
    x0) / 2``, ``L`` the largest distance of those shapes' points from the pan axis (a
    signed distance to a fixed box changes no faster than the shape's points move). A
    piece whose bound clears the clearance is clear; a measured value below it is a
    witness that the piece is blocked; otherwise the piece is halved and measured at its
    middle, down to :data:`PAN_RESOLUTION_RAD`. So a sweep passing 9.96 mm from a shell
    between two grid pans is blocked here as in the follow, whichever the grid.

    Values are ``(least, pan)``: the least clearance measured and where."""

    def __init__(self, scene, q: np.ndarray, rows: np.ndarray, pans: np.ndarray, least: np.ndarray,
                 lipschitz: float, clearance: float):
        self._scene, self._q, self._rows = scene, np.array(q, dtype=float), rows
        self.pans, self.least, self.step = pans, least, float(pans[1] - pans[0])
        self.lipschitz, self.clearance = lipschitz, clearance
        self._measured: dict[float, float] = {}
        count = len(pans)
        # Each grid cell k = [pans[k], pans[k + 1]]: the least found in it, where, blocked.
        v0, v1 = least, np.roll(least, -1)
        self.cell_least = np.minimum(v0, v1)
        self.cell_pan = np.where(v0 <= v1, pans, np.roll(pans, -1))
        self.cell_blocked = self.cell_least < clearance
        uncertain = (0.5 * (v0 + v1) - 0.5 * lipschitz * self.step < clearance) & ~self.cell_blocked
        for k in np.flatnonzero(uncertain):
            (value, pan), blocked = self.piece(float(pans[k]), float(v0[k]), float(pans[k]) + self.step, float(v1[k]))
            self.cell_least[k], self.cell_pan[k], self.cell_blocked[k] = value, pan, blocked
        self._blocked_before = np.concatenate([[0], np.cumsum(np.tile(self.cell_blocked, 2))])
        self._count = count

    def nearest_pair(self, pan: float) -> tuple:
        """The pan-only shape and the box closest together with shoulder_pan at ``pan``:
        ``(robot GeometryId, box GeometryId)``."""
        q = self._q.copy()
        q[0] = pan
        distances = self._scene.signed_distances(q)[self._rows]
        row, box = np.unravel_index(np.argmin(distances), distances.shape)
        geometry = self._scene.geometry
        return geometry.robot_geometry_ids[self._rows[row]], geometry.keep_out_geometry_ids[box]

    def f(self, pan: float) -> float:
        """The least signed distance of the pan-only rows with shoulder_pan at ``pan``."""
        if pan not in self._measured:
            q = self._q.copy()
            q[0] = pan
            self._measured[pan] = float(self._scene.signed_distances(q)[self._rows].min())
        return self._measured[pan]

    def piece(self, x0: float, v0: float, x1: float, v1: float) -> tuple[tuple[float, float], bool]:
        """``((least, pan), blocked)`` over ``[x0, x1]``, given ``f(x0) >= v0`` and ``f(x1) >=
        v1`` (the values themselves where measured)."""
        found = min((v0, x0), (v1, x1))
        stack = [(x0, v0, x1, v1)]
        while stack:
            a, va, b, vb = stack.pop()
            if min(va, vb) < self.clearance:
                return min(found, (va, a), (vb, b)), True
            if 0.5 * (va + vb) - 0.5 * self.lipschitz * (b - a) >= self.clearance or b - a < PAN_RESOLUTION_RAD:
                continue
            middle = 0.5 * (a + b)
            value = self.f(middle % (2 * np.pi))
            found = min(found, (value, middle))
            stack += [(a, va, middle, value), (middle, value, b, vb)]
        return found, False

    def arc(self, x: float, y: float) -> tuple[tuple[float, float], bool]:
        """``((least, pan), blocked)`` turning forward (increasing pan) from ``x`` to ``y``
        (both in [0, 2 pi), each a branch's pan: clear there)."""
        turn = 2 * np.pi
        length = (y - x) % turn
        kx = int(x // self.step) % self._count
        up = (kx + 1) * self.step
        if length <= up - x:
            return self.piece(x, self.clearance, x + length, self.clearance)
        ky = int(y // self.step) % self._count
        first, first_blocked = self.piece(x, self.clearance, up, float(self.least[(kx + 1) % self._count]))
        last, last_blocked = self.piece(ky * self.step, float(self.least[ky]), y, self.clearance)
        end = ky if ky > kx else ky + self._count  # the full cells kx + 1 .. end - 1, going round
        cells = np.arange(kx + 1, end) % self._count
        least = min(first, last)
        if len(cells):
            k = cells[int(np.argmin(self.cell_least[cells]))]
            least = min(least, (float(self.cell_least[k]), float(self.cell_pan[k])))
        blocked = first_blocked or last_blocked or self._blocked_before[end] > self._blocked_before[kx + 1]
        return least, bool(blocked)


# Pieces of a pan sweep narrower than this are not halved further (a clearance within a
# hair of the margin between two such pans is taken as kept).
PAN_RESOLUTION_RAD = 1e-6


def _blocked_pan_sweeps(problem: CompositionProblem, checker: JointPathChecker,
                        good_branches: list[list[np.ndarray]]) -> list[InfeasibleSegment]:
    """Spans con_i -> con_(i+1) that every way of turning shoulder_pan blocks.

    Between consecutive critical configurations the arm moves continuously, so
    shoulder_pan turns from its value on a branch of con_i to its value on a branch of
    con_(i+1), one way round or the other (or further). A shape whose distances depend on
    the pan alone has, at each pan, one clearance; when on both ways round, for every pair
    of branches, some pan brings such a shape within the clearance, every composition is
    blocked on that span (the per-configuration check already kept only branches that
    keep every margin). Each way round is decided exactly (:class:`_PanClearance`), not
    on the grid alone, so the pre-check and the follow agree on a clearance within a hair
    of the margin."""
    scene = checker.scene
    if not scene.geometry.keep_out_geometry_ids or any(not good for good in good_branches):
        return []
    memo = _pan_memo(checker)
    rows, lipschitz = scene.pan_only_rows, memo["lipschitz"]
    if not len(rows) or not np.isfinite(lipschitz):
        return []
    clearance = checker.limits.clearance_m
    sweeps = _pan_sweeps(checker)
    names = scene.geometry
    segments = []
    for i in range(problem.num_cons - 1):
        closest = _closest_blocked_sweep(sweeps, good_branches[i], good_branches[i + 1])
        if closest is None:
            continue
        value, pan = closest
        robot_id, box_id = sweeps.nearest_pair(pan)
        robot, what = names.names[robot_id], names.describe(box_id)
        verb = describe_clearance_shortfall(what, value, clearance)
        segments.append(InfeasibleSegment(
            i + 1, i + 2, "collision",
            f"{robot} {verb} whichever way shoulder_pan turns from con_{i + 1} to con_{i + 2}, on every "
            "inverse-kinematics branch",
            blocked_alternatives=max(_actions_through(problem, i), 1)))
    return segments


def _closest_blocked_sweep(sweeps: _PanClearance, starts: list[np.ndarray], ends: list[np.ndarray]):
    """None when some pair of branches (one of ``starts``, one of ``ends``, the same
    branch) has a clear way round; else ``(least, pan)`` of the pair and way that come
    closest to passing."""
    closest = None
    for qa in starts:
        for qb in ends:
            if branch_signature(qa) != branch_signature(qb):
                continue  # a path keeps its branch
            a, b = float(np.mod(qa[0], 2 * np.pi)), float(np.mod(qb[0], 2 * np.pi))
            (forward, forward_blocked), (backward, backward_blocked) = sweeps.arc(a, b), sweeps.arc(b, a)
            if not (forward_blocked and backward_blocked):
                return None
            better = max(forward, backward)
            closest = better if closest is None else max(closest, better)
    return closest


class PoseBlockers:
    """Rules out, unfollowed, the compositions whose poses alone show the follow would be
    blocked: turning shoulder_pan through a pan where a pan-only shape is within the
    clearance, or driving the elbow or the wrist deep into its singularity.

    A path keeps the inverse-kinematics branch it starts on (changing it crosses a
    singularity), and on a branch the joints follow from the tool's poses in closed
    form (:mod:`~drake_lfd.robot.analytic_ik`): the pan (the branch's shoulder root) and
    ``|sin q3|``, ``|sin q5|``. So:

    - a shape whose clearance depends on shoulder_pan alone (:mod:`~drake_lfd.robot.pan_only`) and
      is within the clearance at pan ``p`` (:class:`_PanClearance`: Drake's signed
      distances on the 1-degree grid, decided exactly between) blocks every path whose
      poses over a span turn the pan across ``p`` by more than
      :data:`PAN_REPEAT_MARGIN_RAD` either side (the follow lags its poses a little);
    - poses that put ``|sin q3|`` or ``|sin q5|`` below :data:`SINGULARITY_DEPTH` of the
      check's margin, or out of the branch's reach (past its singularity), take the
      follow there or make it fall behind its plan: blocked.

    Such a composition is blocked where its poses say, with the follow's wording. It
    wakes at the first blocked follow (:meth:`record`), taking the branch of that path's
    start: a task whose first composition runs pays nothing. One instance serves one
    start branch of one search."""

    def __init__(self, checker: JointPathChecker):
        self._checker = checker
        memo = _pan_memo(checker)
        self._pans_usable = bool(len(checker.scene.pan_only_rows) and np.isfinite(memo["lipschitz"])
                                 and len(checker.scene.geometry.keep_out_geometry_ids))
        kinematics = checker.kinematics
        self._X_BW = kinematics.X_WB.inverse().GetAsMatrix4()
        self._X_E_tool0 = kinematics.X_tool0_E.inverse().GetAsMatrix4()
        self._sweeps: _PanClearance | None = None
        self._branch: tuple[int, int] | None = None  # (shoulder root, wrist sign)
        self.ruled_out = 0

    def _tool0_poses(self, dual_quaternions) -> np.ndarray:
        """X_B_tool0 (n, 4, 4) of the poses X_WE (n, 8)."""
        return self._X_BW @ matrices_from_dual_quaternion(dual_quaternions) @ self._X_E_tool0

    @property
    def awake(self) -> bool:
        """Whether it judges compositions yet (after the first blocked follow)."""
        return self._branch is not None

    def record(self, plan, path) -> None:
        """Learns from a blocked follow of ``plan``: wakes, and takes the branch of the
        path's start."""
        if path.executable or not len(path.q) or self._branch is not None:
            return
        first = shoulder_pan_roots(self._tool0_poses(plan.poses[:1]))[0]
        q0 = path.q[0]
        if np.isnan(first).any() or math.sin(q0[4]) == 0.0:
            return
        root = int(np.argmin(np.abs(np.remainder(first - q0[0] + np.pi, 2 * np.pi) - np.pi)))
        self._branch = (root, 1 if math.sin(q0[4]) > 0.0 else -1)
        if self._pans_usable:
            self._sweeps = _pan_sweeps(self._checker)

    def blocker_of(self, plan, spans: range | None = None) -> Blocker | None:
        """The blocker ``plan``'s poses show in the first span (of ``spans``, 0-based; all by
        default) where they show one; else None."""
        if self._branch is None:
            return None
        due = [int(i) for i in plan.critical_indices]
        return self._first_blocker(plan.poses, plan.times, due, range(len(due) - 1) if spans is None else spans, 0)

    def blocks_segment(self, poses: np.ndarray, anchors, first_span: int) -> bool:
        """Whether a step's own mapped poses (``poses`` (n, 8), its critical configurations at
        ``anchors``, the first of them con ``first_span + 1``) show a blocker: then the
        step's mapping cannot get the arm past its spans, and need not be composed."""
        if self._branch is None:
            return False
        anchors = [int(a) for a in anchors]
        return self._first_blocker(np.asarray(poses), np.arange(len(poses), dtype=float), anchors,
                                   range(len(anchors) - 1), first_span) is not None

    def _first_blocker(self, dual_quaternions, times, due: list[int], spans, first_span: int) -> Blocker | None:
        """The first blocker the poses (n, 8) at ``times`` show in ``spans`` (windows between
        the ``due`` indices; reported as spans ``first_span`` on)."""
        assert self._branch is not None  # the callers return early without a branch
        root, wrist = self._branch
        poses = self._tool0_poses(dual_quaternions)
        pans = shoulder_pan_roots(poses)[:, root]
        # Poses the branch cannot reach (NaN) lie past the singularity (said so below).
        elbow, wrist_sine = elbow_and_wrist_sines(poses, root, wrist)
        limits = self._checker.limits
        for local in spans:
            span = first_span + local
            window = slice(due[local], due[local + 1] + 1)
            for sines, margin, what, joint in ((elbow[window], limits.elbow_margin, "elbow straight", 3),
                                               (wrist_sine[window], limits.wrist_margin, "wrist aligned", 5)):
                below = np.isnan(sines) | (sines < margin)
                if len(sines) and (np.isnan(sines).any() or np.nanmin(sines) < SINGULARITY_DEPTH * margin):
                    k = int(np.flatnonzero(below)[0])
                    self.ruled_out += 1
                    detail = (f"{what}: the poses leave the reach of the arm's branch past it (|sin q{joint}| "
                              f"would pass 0 < {margin:g})" if np.isnan(sines).any() else
                              f"{what} (|sin q{joint}| = {float(np.nanmin(sines)):.3f} < {margin:g})")
                    return Blocker("singularity", detail, max(float(times[due[local] + k]), 1e-9), span)
            if self._sweeps is not None:
                blocker = self._pan_blocker(pans[window], times[window], span)
                if blocker is not None:
                    self.ruled_out += 1
                    return blocker
        return None

    def _pan_blocker(self, sweep: np.ndarray, times: np.ndarray, span: int) -> Blocker | None:
        """The blocker of a pan sweep (one span's pans and times) across a blocked cell."""
        sweeps = self._sweeps
        assert sweeps is not None  # called only with the pan sweeps computed
        if not len(sweep) or np.isnan(sweep).any():
            return None
        sweep = np.unwrap(sweep)
        low, high = sweep.min() + PAN_REPEAT_MARGIN_RAD, sweep.max() - PAN_REPEAT_MARGIN_RAD
        first, last = math.ceil(low / sweeps.step), math.floor(high / sweeps.step) - 1
        if last < first:
            return None
        cells = np.arange(first, last + 1) % len(sweeps.pans)
        blocked = cells[sweeps.cell_blocked[cells]]
        if not len(blocked):
            return None
        # The blocked cell the path meets first, as the follow would.
        k = blocked[0] if sweep[-1] >= sweep[0] else blocked[-1]
        value, pan = float(sweeps.cell_least[k]), float(sweeps.cell_pan[k])
        crossing = int(np.argmin(np.abs(np.remainder(sweep - pan + np.pi, 2 * np.pi) - np.pi)))
        return self._blocker(value, pan, max(float(times[crossing]), 1e-9), span)

    def _blocker(self, value: float, pan: float, time_s: float, span: int) -> Blocker:
        """The follow's wording for the pan-only shape nearest a box at ``pan``."""
        assert self._sweeps is not None  # called only with the pan sweeps computed
        robot_id, box_id = self._sweeps.nearest_pair(pan)
        names = self._checker.scene.geometry
        what = names.describe(box_id)
        verb = describe_clearance_shortfall(what, value, self._checker.limits.clearance_m)
        return Blocker("collision", f"collision with {what}: {names.names.get(robot_id, robot_id)} {verb}", time_s,
                       span, pair=(robot_id, box_id))


# How deep below the check's margin a singularity's sine must go on a path's poses for it
# to rule the path out unfollowed (the follow tracks its poses closely, so it meets the
# margin too, or falls behind its plan trying).
SINGULARITY_DEPTH = 0.5


# How far past a blocked grid cell a path's poses must turn for it to count as crossing it
# (the follow lags its poses by far less).
PAN_REPEAT_MARGIN_RAD = math.radians(1.0)


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
