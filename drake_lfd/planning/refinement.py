"""Demonstration-guided trajectory optimization of a composed plan (``--refine``), and
the plain optimizer it is compared with.

:func:`refine_plan` takes an executable composed plan (a :class:`PlanResult` with its
joint path) and optimizes a joint trajectory around it (docs/method.rst, Refinement
by trajectory optimization): each critical configuration is pinned at the path
fraction where the composed plan reaches it (its configuration there, on the composed
joint path, fixes the IK branch), and the motion must stay in a tube around the mapped
demonstrations (E within the task's bounds of the composed SE(3) path: by default
``tube_position_m`` and ``tube_rotation_rad`` at the matching path fraction, within each
span matched by arc length; the task file's ``refinement:`` block and its path
constraints bound it span by span, :func:`allowed_deviations`), keep the task's path
constraints, the joint limits, speed and acceleration bounds, the tool speed and the
clearance (:mod:`drake_lfd.robot.trajectory_optimization`), in minimum time. The result
is verified like any plan: sampled at the controller's period, timed as a
:class:`~drake_lfd.core.timing.TimedPlan` (E's poses by forward kinematics, critical
indices at the samples where each critical configuration is due) and followed by the
:class:`~drake_lfd.robot.joint_path.JointPathChecker` holding the task's path
constraints (:mod:`drake_lfd.robot.path_constraints`, the measure the search holds
composed plans to); the task's bounds are checked on the followed joint path, span by
span. So a refined plan never breaks a path constraint or a bound: when the optimizer
fails or any check fails, the composed plan (which the search checked) stands and the
report says why.

Which local solution SNOPT reaches depends on where it starts, and from one start on the
last bits of the plan; so the tube program runs from several deterministic starts
(:func:`_starts`) and the plan takes a fixed choice among the motions that pass
(:func:`_choice`), with a small path-energy cost that makes the minimum of each start
unique where the duration alone leaves the shape free. The solve is bounded by SNOPT's
iteration counts (:class:`SolverBudget`) per solve and a fixed number of solves, never
by time, and the bounds are the task's ``timing:`` limits at its ``limit_fraction``:
the same inputs give the same plan on any machine under any load.

:func:`~drake_lfd.planning.plain_optimizer.plain_plan` is the peer without demonstrations:
the same program and checks, from straight joint-space lines between the composed path's
configurations at the critical configurations, with no tube and a duration cost alone.

Not for: composing demonstrations (``planner.py``), the path-constraint measure
(``robot/path_constraints.py``) or the Drake program itself
(``robot/trajectory_optimization.py``).
"""

from __future__ import annotations

import dataclasses
import functools
import math
import time

import numpy as np
from pydrake.math import BsplineBasis, RotationMatrix
from pydrake.trajectories import BsplineTrajectory, PiecewisePose

from drake_lfd.core.pose_conversions import dual_quaternion_from_matrices
from drake_lfd.core.tasks import (
    DEFAULT_REFINEMENT_POSITION_M,
    DEFAULT_REFINEMENT_ROTATION_RAD,
    DeviationBound,
    RefinementBounds,
)
from drake_lfd.core.timing import TimedPlan, TimingLimits
from drake_lfd.planning.planner import PlanResult
from drake_lfd.robot.joint_path import JointPathChecker
from drake_lfd.robot.path_constraints import allowed_deviation, constraint_rotation, describe_constraint
from drake_lfd.robot.optimization_records import PoseBound, PoseTarget, SolverBudget, TrajectoryLimits
from drake_lfd.robot.optimization_scene import OptimizationScene
from drake_lfd.robot.trajectory_optimization import optimize_joint_trajectory
from drake_lfd.robot.trajectory_sampling import fit_bspline, sample_trajectory

__all__ = [
    "RefinementOptions",
    "RefinementReport",
    "SolverBudget",
    "TrajectoryLimits",
    "OptimizationScene",
    "refine_plan",
    "tube_deviation",
    "path_fractions_of",
    "shape_deviation",
]


@dataclasses.dataclass(frozen=True)
class RefinementOptions:
    """The refinement's settings (docs/method.rst, Refinement by trajectory
    optimization, justifies the defaults).

    Attributes
    ----------
    tube_position_m, tube_rotation_rad : float
        The tube: E within this distance and angle of the composed path at the matching
        path fraction (0.15 m, 30 deg), checked on the followed joint path, where the
        task file does not bound it (its ``refinement:`` block and path constraints,
        :func:`allowed_deviations`).
    tube_margin : float
        The program bounds the tube at this fraction of it (0.8): its samples leave
        room for the path between them and for the controller.
    tube_samples : int
        The tube is constrained at this many path fractions evenly spread in ``s`` and
        as many evenly spread along the composed path's arc length (15 + 15). Evenly in
        ``s`` alone (20), 7 of 20 filling-and-pouring plans strayed 151-173 mm from the
        composed path between samples where a span is passed quickly for its length;
        over 36 paper-task plans (3 tasks, 6 seeds, both costs) 20 in ``s`` refined 27,
        20 or 30 along the arc 20 and 26, 15 + 15 refined 30.
    con_position_tolerance_m, con_rotation_tolerance_rad : float
        Each critical configuration, in the program: position within this along each
        axis (0.7 mm; at most 1.2 mm away), rotation within this (0.3 deg).
    target_check_slack : float
        The motion itself (before it is followed) must meet each critical configuration
        within this multiple of the program's tolerances (1.5: 1.8 mm, 0.45 deg): SNOPT
        meets its constraints only to its feasibility tolerance, and its iterate at an
        iteration limit not at all.
    check_fraction : float
        The followed joint path must meet each critical configuration within this
        fraction of the success tolerances (0.5: 2.5 mm, 1 deg), the rest being the
        closed loop's: its servos lag the command, and the motion passes the
        intermediate critical configurations at speed.
    pass_speed_m_s : float, optional
        E passes each intermediate critical configuration at most this fast (0.4 m/s;
        the motion is slowed along its path around it). The closed loop's servos lag
        the command by about 5 ms, so at 0.6 m/s E is 3 mm behind when the
        configuration is due; at 0.4 m/s, 2 mm. None: as optimized.
    pass_acceleration_m_s2 : float, optional
        And with at most this acceleration (1.5 m/s^2): accelerating through one at
        5 m/s^2 and 0.4 m/s, a trial missed it by 4.6 mm; the lag grows with both.
        None: not limited.
    program_pass_speed_m_s : float, optional
        The program's own bound on E's speed at each inner critical configuration,
        along each world axis (0.4 m/s: the optimizer plans a slow passage, and the
        retiming above brings the magnitude, up to sqrt(3) times that, within
        ``pass_speed_m_s``; 0.4 / sqrt(3) per axis, which keeps the magnitude within
        it in the program already, makes the refined motions markedly slower). None, or
        ``pass_speed_m_s`` None: no such bound.
    path_constraint_margin_rad : float
        The program holds each path constraint to what the check allows
        (:func:`~drake_lfd.robot.path_constraints.allowed_deviation`, the measure the
        search uses: its tolerance less the closed loop's tracking margin) less this
        (1.5 deg), but at least half of that: the constraint holds only at the program's
        samples, and the motion between them must keep it too.
    path_constraint_samples : int
        Path fractions each path constraint is constrained at, per span it covers (9;
        with 6, 2 of 10 transferring plans tilted 9.0-9.4 deg between samples); also the
        tube's extra samples in each span the task bounds more tightly than the whole.
    num_control_points : int, optional
        B-spline control points (cubic; None: 6 plus 3 per span, so that after the ends'
        zero velocity and acceleration each span keeps about 3 free ones; when SNOPT
        finds that program infeasible or its motion fails a check, once more with 1.5
        times as many).
    clearance_samples : int
        Path fractions the clearance is constrained at (15).
    budget : SolverBudget
        SNOPT's work per attempt, in iterations (never seconds: the same plan on any
        machine under any load). When SNOPT stops at an iteration limit, its last
        iterate is sampled and checked like a solution, and refines the plan when it
        passes every check.
    limits : TrajectoryLimits, optional
        The program's bounds (None: the task's ``timing:`` block at its
        ``limit_fraction``, :meth:`TrajectoryLimits.of_timing`, so the refined motion
        uses the same share of the limits as the composed plan's timing, with
        ``clearance_m``).
    clearance_m : float
        The program's clearance when ``limits`` is None (3 cm; the check demands 1 cm on
        the followed path, which lags the motion where it is fast and passes between the
        program's samples, so the program keeps more).
    repair_clearance_m : float
        A tube program's motion that fails the check for a collision is solved once more
        from itself with this much more clearance (2 cm; 0: never): otherwise whether a
        start passes a shell a hair inside or outside the clearance decides, with the
        plan's last bits, which start the plan takes.
    starts, fallback_starts : tuple of str
        The tube program's starts, in order, and those tried only when none of them gives
        a motion that passes (``_starts``).
    energy_weight : float
        Weight of the path-energy cost beside the duration's in the tube program and
        the plain program that starts it (1e-3, in seconds per rad^2 of the control
        points' steps: a tie-breaker, not a trade). Without it the minimum-time program
        leaves the shape free where the duration does not bind it, so starts reached
        equal durations along shapes the slow passage of the critical configurations
        retimes differently.
    equal_duration : float
        Program durations within this fraction of the shortest are equal for the choice
        among starts (``_choice``; 0.005).
    """

    tube_position_m: float = DEFAULT_REFINEMENT_POSITION_M
    tube_rotation_rad: float = DEFAULT_REFINEMENT_ROTATION_RAD
    tube_margin: float = 0.8
    tube_samples: int = 15
    con_position_tolerance_m: float = 0.0007
    con_rotation_tolerance_rad: float = math.radians(0.3)
    check_fraction: float = 0.5
    target_check_slack: float = 1.5
    pass_speed_m_s: float | None = 0.4
    pass_acceleration_m_s2: float | None = 1.5
    program_pass_speed_m_s: float | None = 0.4
    path_constraint_margin_rad: float = math.radians(1.5)
    path_constraint_samples: int = 9
    num_control_points: int | None = None
    clearance_samples: int = 15
    budget: SolverBudget = SolverBudget()
    limits: TrajectoryLimits | None = None
    clearance_m: float = 0.03
    repair_clearance_m: float = 0.02
    starts: tuple = ("plain motion", "lines")
    fallback_starts: tuple = ("composed",)
    energy_weight: float = 1e-3
    equal_duration: float = 0.005


@dataclasses.dataclass(frozen=True)
class RefinementReport:
    """What the optimization did.

    Attributes
    ----------
    method : str
        ``"refine"`` (seeded by the demonstrations, in the tube) or ``"plain"``.
    status : str
        ``"refined"`` (the plan is the optimized one) or ``"failed"`` (the unrefined
        plan stands).
    reason : str
        Why it failed ("" when refined).
    solve_time_s : float
        The solver's time (0 when it did not run).
    total_time_s : float
        Setting up, solving and checking.
    duration_s : float
        The optimized motion's duration (nan when the solver failed).
    unrefined_duration_s : float
    tube_max_position_m, tube_max_rotation_rad : float
        Largest deviation of the optimized (followed) path from the composed path at
        matching path fractions (nan when the solver failed).
    path_fractions : array, optional
        The path fraction of each sample of the optimized plan (when the solver
        succeeded): with it an executed run is measured against the tube
        (:func:`tube_deviation`). Not in the JSON.
    evaluations : int
        Evaluations of the programs by SNOPT, all solves (the work done: the same on
        any machine, and the same when the scene remembered a solve).
    attempts : int
        SNOPT solves: the plain program, then the tube program from each start (one more
        for each motion repaired for its clearance), twice that with a second round
        (``plain``: 1 or 2).
    budget_spent : bool
        The motion is SNOPT's last iterate at its iteration limit (checked like a
        solution).
    """

    method: str
    status: str
    reason: str
    solve_time_s: float
    total_time_s: float
    duration_s: float
    unrefined_duration_s: float
    tube_max_position_m: float
    tube_max_rotation_rad: float
    path_fractions: np.ndarray | None = dataclasses.field(default=None, compare=False, repr=False)
    evaluations: int = 0
    attempts: int = 0
    budget_spent: bool = False

    @property
    def refined(self) -> bool:
        return self.status == "refined"

    def describe(self) -> str:
        """One line for a person (``refined by trajectory optimization: 2.2 s instead of
        6.3 s ...`` or why not)."""
        if self.refined:
            return (f"refined by trajectory optimization: {self.duration_s:.2f} s instead of "
                    f"{self.unrefined_duration_s:.2f} s, at most {1000 * self.tube_max_position_m:.0f} mm / "
                    f"{math.degrees(self.tube_max_rotation_rad):.1f} deg from the composed path "
                    f"(solved in {self.solve_time_s:.2f} s)")
        return f"refinement failed, the unrefined plan stands: {self.reason}"

    def to_json(self, *, wall_times: bool = True) -> dict:
        """The ``refinement`` object of ``plan --json`` and of each ``simulate`` trial
        (docs/cli.rst). ``wall_times=False`` leaves out the two wall-time measurements
        (``solve_time_s``, ``total_time_s``): the rest depends on the inputs only, so a
        plan's document is the same bytes on any machine."""
        def number(x):
            return None if not math.isfinite(x) else float(x)

        document = {"method": self.method, "status": self.status, "reason": self.reason}
        if wall_times:
            document.update(solve_time_s=float(self.solve_time_s), total_time_s=float(self.total_time_s))
        document.update(duration_s=number(self.duration_s), unrefined_duration_s=number(self.unrefined_duration_s),
                        tube_max_position_m=number(self.tube_max_position_m),
                        tube_max_rotation_rad=number(self.tube_max_rotation_rad),
                        evaluations=int(self.evaluations), attempts=int(self.attempts),
                        budget_spent=bool(self.budget_spent))
        return document


# -- the composed path at path fractions ------------------------------------------------

class _Reference:
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
    span, see :class:`_Reference`): the fractions the tube is defined at."""
    return _Reference(plan).sample_fractions


def tube_deviation(reference_plan: TimedPlan, fractions: np.ndarray, X_WE: list) -> tuple[float, float]:
    """Largest distance and angle of the poses ``X_WE`` at path fractions ``fractions``
    from ``reference_plan``'s path at the same fractions (see :class:`_Reference`)."""
    position, rotation = _deviations(_Reference(reference_plan), fractions, X_WE)
    return float(position.max(initial=0.0)), float(rotation.max(initial=0.0))


def _deviations(reference: _Reference, fractions: np.ndarray, X_WE: list) -> tuple[np.ndarray, np.ndarray]:
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
    arc length's weighting of :class:`_Reference`; by position alone a twist in place
    would pair a pose with the wrong turn of it), and the largest distance and angle
    to it over the poses."""
    X_ref = reference_plan.X_WE_list()
    p_ref = np.array([x.translation() for x in X_ref])
    q_ref = np.array([x.rotation().ToQuaternion().wxyz() for x in X_ref])
    position, rotation = 0.0, 0.0
    for X in X_WE:
        d = np.linalg.norm(p_ref - X.translation(), axis=1)
        angle = 2.0 * np.arccos(np.clip(np.abs(q_ref @ X.rotation().ToQuaternion().wxyz()), 0.0, 1.0))
        k = int(np.argmin(d + _Reference.ROTATION_WEIGHT_M_PER_RAD * angle))
        position, rotation = max(position, float(d[k])), max(rotation, float(angle[k]))
    return position, rotation


# -- the program and its check ------------------------------------------------------------

def _path_constraint_bounds(result: PlanResult, fractions: np.ndarray, options: RefinementOptions) -> list[PoseBound]:
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
class _Allowed:
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


def allowed_deviations(task, options: RefinementOptions = None) -> tuple[np.ndarray, np.ndarray]:
    """How far refinement may move E from the composed path over each span of ``task``
    (con_j to con_j+1): distances and angles (n - 1,), from the task's ``refinement``
    block, its path constraints and ``options``' tube (docs/task_files.rst)."""
    allowed = _allowed(task, np.linspace(0.0, 1.0, len(task.critical_configurations)),
                       options or RefinementOptions())
    return allowed.position_m, allowed.rotation_rad


def _allowed(task, fractions: np.ndarray, options: RefinementOptions) -> _Allowed:
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
    replaced_by = [[None] * spans, [None] * spans]
    for index, span in enumerate(bounds.spans):
        for axis, value in enumerate((span.position_m, span.rotation_rad)):
            for j in range(span.con_from - 1, span.con_to - 1):
                if value is not None and value < replaced[axis][j]:
                    replaced[axis][j], replaced_by[axis][j] = value, f"refinement.spans[{index}]"
    for axis in range(2):
        for j in range(spans):
            if replaced_by[axis][j] is not None:
                values[axis][j], sources[axis][j] = replaced[axis][j], replaced_by[axis][j]
    for constraint in task.path_constraints:
        bound = constraint.max_deviation or DeviationBound()
        rotation = bound.rotation_rad if bound.rotation_rad is not None else constraint.tolerance_rad
        for axis, value in enumerate((bound.position_m, rotation)):
            for j in range(constraint.con_from - 1, constraint.con_to - 1):
                if value is not None and value < values[axis][j]:
                    values[axis][j], sources[axis][j] = value, describe_constraint(constraint)
    return _Allowed(np.asarray(fractions, dtype=float), values[0], values[1],
                    tuple(zip(sources[0], sources[1])))


def _tube_bounds(reference: _Reference, options: RefinementOptions, allowed: _Allowed | None = None) -> list[PoseBound]:
    """The tube in the program: E within ``tube_margin`` of the allowed deviation from the
    composed path at ``tube_samples`` fractions evenly in ``s`` and as many evenly along
    its arc length, and at ``path_constraint_samples`` inner fractions of each span the
    task bounds more tightly than the whole (a short span with its own bound would
    otherwise hold hardly a sample)."""
    if allowed is None:
        allowed = _Allowed(reference.fractions, np.full(len(reference.fractions) - 1, options.tube_position_m),
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


def _fractions_by_joint_arc_length(t: np.ndarray, q: np.ndarray, due: list, fractions: np.ndarray) -> np.ndarray:
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


def _through_critical_configurations(fractions: np.ndarray, q_start: np.ndarray, q_due: list,
                                     q_goal: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The plain optimizer's guess: straight in joint space from each critical
    configuration to the next (the composed path's configurations there), at their
    path fractions; samples (m,) and (m, 6)."""
    knots = np.vstack([q_start, *q_due, q_goal])
    s = np.linspace(0.0, 1.0, 200)
    return s, np.column_stack([np.interp(s, fractions, knots[:, j]) for j in range(knots.shape[1])])


def _duration_guess(guess, limits: TrajectoryLimits) -> float:
    """The shortest duration at which the guess ``q(s)`` keeps every joint within its
    speed and acceleration bounds (``|q'(s)| / T`` and ``|q''(s)| / T^2`` on 201 path
    fractions), at least 0.5 s: the guess starts within the bounds the convex hull
    enforces, and no slower than it must be."""
    s = np.linspace(0.0, 1.0, 201)
    velocity, acceleration = guess.MakeDerivative(1), guess.MakeDerivative(2)
    dq = np.max(np.abs(np.hstack([velocity.value(float(x)) for x in s])))
    ddq = np.max(np.abs(np.hstack([acceleration.value(float(x)) for x in s])))
    return max(dq / limits.joint_speed_rad_s, math.sqrt(ddq / limits.acceleration_rad_s2), 0.5)


def _optimize(result: PlanResult, checker: JointPathChecker, scene: OptimizationScene | None,
              options: RefinementOptions, method: str) -> PlanResult:
    start = time.perf_counter()
    unrefined = result.timed.duration if result.timed is not None else math.nan

    work = {"evaluations": 0, "attempts": 0, "budget_spent": False}

    def report(status, reason, solve=0.0, duration=math.nan, position=math.nan, rotation=math.nan, fractions=None):
        return RefinementReport(method, status, reason, solve, time.perf_counter() - start, duration,
                                unrefined, position, rotation, fractions, **work)

    if not result.planned or result.joint_path is None or not result.joint_path.executable:
        return dataclasses.replace(result, refinement=report("failed", "no executable composed plan to refine"))
    timed, path = result.timed, result.joint_path
    scene = OptimizationScene(checker.scene.workcell) if scene is None else scene
    reference = _Reference(timed)
    fractions = reference.fractions
    dt = checker.time_step
    # The composed joint path at path fractions (its samples after the plan's end are the settling).
    within = path.t <= timed.duration + 1e-9
    q_path = path.q[within]
    q_goal = path.q[min(int(round(timed.duration / dt)), len(path.q) - 1)]
    q_path[-1] = q_goal
    s_path = _fractions_by_joint_arc_length(path.t[within], q_path, [timed.times[i] for i in timed.critical_indices],
                                            fractions)
    path_bounds = _path_constraint_bounds(result, fractions, options)
    allowed = _allowed(result.task, fractions, options)
    bounds = path_bounds + (_tube_bounds(reference, options, allowed) if method == "refine" else [])
    # Each inner critical configuration's configuration on the composed joint path (the
    # pass-speed bound is linearized there).
    q_due = [q_path[min(int(np.searchsorted(s_path, f)), len(q_path) - 1)] for f in fractions[1:-1]]
    pass_speed = options.program_pass_speed_m_s if options.pass_speed_m_s is not None else None
    targets = [PoseTarget(float(s), X, options.con_position_tolerance_m, options.con_rotation_tolerance_rad,
                          pass_speed, q)
               for s, X, q in zip(fractions[1:-1], reference.critical_poses[1:-1], q_due)]
    limits = options.limits or TrajectoryLimits.of_timing(result.task.timing or TimingLimits(),
                                                          clearance_m=options.clearance_m)
    count = options.num_control_points or 6 + 3 * (len(fractions) - 1)
    pins = list(zip(fractions[1:-1], q_due))
    lines = _through_critical_configurations(fractions, q_path[0], q_due, q_goal)
    solve_time = 0.0

    def solve(guess, duration, program_bounds, program_limits=None):
        nonlocal solve_time
        solved = optimize_joint_trajectory(
            scene, guess, guess_duration_s=duration, targets=targets, bounds=program_bounds,
            clearance_samples=options.clearance_samples, limits=program_limits or limits, budget=options.budget,
            energy_weight=options.energy_weight if method == "refine" else 0.0)
        solve_time += solved.solve_time_s
        work["evaluations"] += solved.evaluations
        work["attempts"] += 1
        return solved

    # Up to two rounds, the second with 1.5 times the control points (a spline too stiff
    # for the tube is a usual cause of an infeasible program; and a different program is
    # a fresh chance where SNOPT ended in poor local solutions). In each, the program from
    # every start of ``_starts`` (a motion through the clearance once more, with more
    # clearance), then the choice among the motions that pass every check (``_choice``).
    # A fixed number of solves at most, each within the iteration budget, so the work
    # stays bounded and the answer deterministic.
    rounds = (count,) if options.num_control_points else (count, count + count // 2)
    repair_limits = dataclasses.replace(limits, clearance_m=limits.clearance_m + options.repair_clearance_m)
    for attempt in rounds:
        failures, passed = [], []
        line_guess = fit_bspline(*lines, attempt, rest_ends=True, pins=pins)
        composed = functools.partial(fit_bspline, s_path, q_path, attempt, rest_ends=True, pins=pins)
        for label, guess, duration, first in _starts(method, line_guess, composed, limits, solve, path_bounds,
                                                     options.starts, options.fallback_starts, passed):
            solved = first if guess is None else solve(guess, duration, bounds)
            checked = None
            if solved.trajectory is not None and not solved.safety_stopped:
                work["budget_spent"] = solved.budget_spent
                checked = _check_motion(result, checker, scene, solved, allowed, limits, options, method)
                if method == "refine" and options.repair_clearance_m > 0 and \
                        (checked.reason or "").startswith("check: collision"):
                    # Through the clearance where the program does not look (between its
                    # samples, or where the followed path lags the motion).
                    repaired = solve(*_in_path_fraction(solved.trajectory), bounds, repair_limits)
                    if repaired.trajectory is not None and not repaired.safety_stopped:
                        again = _check_motion(result, checker, scene, repaired, allowed, limits, options, method)
                        if again.reason is None:
                            solved, checked = repaired, again
                    elif repaired.safety_stopped:
                        solved = repaired
            if solved.safety_stopped:
                return dataclasses.replace(result, refinement=report("failed", f"error: {solved.status}", solve_time))
            if checked is None:
                failures.append((label, f"optimizer: {solved.status}", None))
            elif checked.reason is None:
                passed.append((solved, checked))
            else:
                failures.append((label, _with_iterate(checked.reason, solved), checked))
        if passed:
            solved, checked = _choice(passed, options)
            work["budget_spent"] = solved.budget_spent
            return dataclasses.replace(result, timed=checked.plan, joint_path=checked.followed,
                                       refinement=report("refined", "", solve_time, checked.plan.duration,
                                                         checked.position, checked.rotation, checked.fractions))
    # The last round's failures, in the starts' order: the first as it is, each other one
    # with the start it comes from.
    reason = "; ".join([failures[0][1]] + [f"{_START_NAMES[label]}: {text}" for label, text, _ in failures[1:]])
    checked = failures[0][2]
    if checked is None:
        return dataclasses.replace(result, refinement=report("failed", reason, solve_time))
    return dataclasses.replace(result, refinement=report("failed", reason, solve_time, checked.plan.duration,
                                                         checked.position, checked.rotation, checked.fractions))


def _choice(passed: list, options: RefinementOptions) -> tuple:
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


def _with_iterate(reason: str, solved) -> str:
    """A failed check's reason, saying when the motion was SNOPT's last iterate."""
    if solved.budget_spent:
        return f"{reason}; SNOPT's last iterate at its {solved.status}"
    if solved.nearly_feasible:
        return f"{reason}; SNOPT's last iterate, {solved.status}"
    return reason


# How a failure reason names the start it comes from (``_starts``).
_START_NAMES = {"plain motion": "from the plain program's motion", "composed": "from the composed path",
                "lines": "from straight joint-space lines"}
#: Every start the tube program knows (``_starts``).
STARTS = tuple(_START_NAMES)


def _starts(method: str, line_guess, composed_guess, limits: TrajectoryLimits, solve, path_bounds,
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
    several starts moves far less (``_choice``). From the composed path SNOPT lands in
    poor local solutions where the demonstrations detour, and where another start passed
    it was not the one chosen: it is the fallback, where neither of the others gives a
    motion that passes (docs/method.rst, Several starts, one fixed choice)."""
    if method == "plain":
        yield "plain", line_guess, _duration_guess(line_guess, limits), None
        return
    for label in tuple(starts) + tuple(fallback):
        if label in fallback and label not in starts and passed:
            return
        if label == "plain motion":
            plain = solve(line_guess, _duration_guess(line_guess, limits), path_bounds)
            if plain.trajectory is None:
                yield label, None, None, plain
            else:
                yield (label,) + _in_path_fraction(plain.trajectory) + (None,)
        elif label == "composed":
            guess = composed_guess()
            yield label, guess, _duration_guess(guess, limits), None
        elif label == "lines":
            yield label, line_guess, _duration_guess(line_guess, limits), None
        else:
            raise ValueError(f"unknown start {label!r} (known: {', '.join(STARTS)})")


def _in_path_fraction(trajectory: BsplineTrajectory) -> tuple[BsplineTrajectory, float]:
    """A solved ``q(t)`` as the guess ``q(s)``, ``s = t / T``, and its duration ``T``."""
    T = float(trajectory.end_time())
    basis = trajectory.basis()
    return BsplineTrajectory(BsplineBasis(basis.order(), np.asarray(basis.knots()) / T),
                             trajectory.control_points()), T


@dataclasses.dataclass(frozen=True)
class _Checked:
    """A solved motion, sampled, followed and checked: ``reason`` None when it passes."""

    reason: str | None
    plan: TimedPlan
    followed: object
    position: float = math.nan
    rotation: float = math.nan
    fractions: np.ndarray | None = None


def _check_motion(result: PlanResult, checker: JointPathChecker, scene: OptimizationScene, solved,
                  allowed: _Allowed, limits: TrajectoryLimits, options: RefinementOptions,
                  method: str) -> _Checked:
    """Samples the solver's motion at the controller's period (module docstring), follows
    it with ``checker`` holding the task's path constraints (as the search does) and
    checks it: executable, every critical configuration within ``check_fraction`` of the
    success tolerances, within the task's bounds on the deviation from the composed path
    (``refine``; span by span, ``allowed``) and shorter than the composed plan."""
    timed, dt, fractions = result.timed, checker.time_step, allowed.fractions
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
        return _Checked(reason, plan, followed, position, rotation, s_samples)

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
    deviation = _deviations(_Reference(timed), s_followed, X_followed)
    position, rotation = float(deviation[0].max(initial=0.0)), float(deviation[1].max(initial=0.0))
    if method == "refine":
        shaped = allowed.by_shape[allowed.span_of(s_followed)]
        if shaped.any():
            held = _span_deviations(timed, allowed.span_of(s_followed[shaped]), [x for x, k in zip(X_followed, shaped) if k])
            deviation = (deviation[0].copy(), deviation[1].copy())
            deviation[0][shaped] = held[0]
        excess = _excess(allowed, s_followed, *deviation)
        if excess is not None:
            return checked(f"check: {excess}", position, rotation)
    if not duration < timed.duration:
        return checked(f"not shorter ({duration:.2f} s, unrefined {timed.duration:.2f} s)", position, rotation)
    return checked(None, position, rotation)


def _span_deviations(composed: TimedPlan, spans: np.ndarray, X_WE: list) -> tuple[np.ndarray, np.ndarray]:
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


def _excess(allowed: _Allowed, s: np.ndarray, position: np.ndarray, rotation: np.ndarray) -> str | None:
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


def refine_plan(result: PlanResult, checker: JointPathChecker, *, scene: OptimizationScene | None = None,
                options: RefinementOptions = RefinementOptions()) -> PlanResult:
    """``result`` with its timed plan and joint path replaced by the demonstration-guided
    optimization's, or unchanged; either way with ``refinement`` (a
    :class:`RefinementReport`).

    Parameters
    ----------
    result : PlanResult
        A plan made with ``checker`` (it has an executable joint path).
    checker : JointPathChecker
        The plan-time check of the task's work cell (also: the controller's period).
    scene : OptimizationScene, optional
        The work cell for the program (built from the checker's when not given; pass one
        to reuse it across plans of the same work cell).
    options : RefinementOptions
    """
    return _optimize(result, checker, scene, options, "refine")
