"""Drake's kinematic trajectory optimization of a UR5e joint path in a work cell.

:func:`optimize_joint_trajectory` sets up and solves one
``KinematicTrajectoryOptimization`` (a clamped B-spline ``q(s)``, ``s`` in [0, 1], with a
free duration ``T``; docs/method.rst, Refinement by trajectory optimization):

- minimum duration (``AddDurationCost``), duration within bounds; optionally plus a small
  path-energy cost (``AddPathEnergyCost``, ``energy_weight``), which makes the minimum unique
  where the duration leaves the shape free;
- joint position bounds: the UR5e's limits, narrowed for the elbow (q3) and the wrist
  (q5) to the singularity-free interval (``|sin q| >= margin``) the initial guess lies
  in; bounds on the control points hold on the whole path (convex hull);
- joint speed and acceleration bounds (on the whole path, by the same property):
  :class:`TrajectoryLimits`, by default a task's ``timing:`` limits at its
  ``limit_fraction`` (:meth:`TrajectoryLimits.of_timing`);
- zero path velocity and acceleration at both ends (the arm starts and ends at rest);
- pose targets (:class:`PoseTarget`: a position box of E and, for its rotation, position
  boxes of two points 1 m out on its axes (well scaled, unlike a trace bound) at a
  fixed path fraction, and optionally a bound on E's speed there, linear in the control
  points and the duration), pose bounds along the path (:class:`PoseBound`: E's distance
  to a point and its angle to a rotation, at a fixed path fraction: the task's
  orientation constraints and the demonstration tube);
- the shoulder singularity: the wrist centre at least ``shoulder_margin_m`` from the
  shoulder axis, on the side both ends are on, at the clearance's path fractions (a
  one-sided ``PositionConstraint`` of the wrist centre in the shoulder link's frame);
- clearance: ``MinimumDistanceLowerBoundConstraint`` at evenly spread path fractions on
  :class:`OptimizationScene`, the work cell's geometry with every robot and tool
  geometry checked against every obstacle, shell and the table (the base and shoulder
  links, which stand on the table, excepted).

SNOPT's work is bounded by iteration counts (:class:`SolverBudget`), never by a clock;
at an iteration limit its last iterate is returned for the caller to check.

A scene remembers its last solutions by the program's exact inputs (the guess, its
duration, the targets, bounds, limits and budget, every number by its bits;
:mod:`~drake_lfd.core.exact_memo`): SNOPT keeps nothing between solves, so solving the
same program again gives the same bits, and a remembered answer is that answer (but
for its wall time, a measurement: 0). Every assembling trial (a task
without variables) asks the same programs; each worker solves them once.

Constraints at path fractions hold at those samples only: callers sample densely and
keep margins, and check the result (``planning/refinement_check.py`` runs the joint-path
check on it). :func:`sample_trajectory` turns the solution into 10 ms samples, with
every target on a sample and the tool speed bounded.

Not for: choosing targets, tubes or seeds from a plan (``planning/refinement.py``,
``refinement_tube.py``, ``refinement_starts.py``),
following a plan with the controller's law (``joint_path.py``).
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Sequence

import numpy as np
from pydrake.geometry import CollisionFilterDeclaration, GeometrySet
from pydrake.math import BsplineBasis, RigidTransform, RotationMatrix
from pydrake.multibody.inverse_kinematics import (
    MinimumDistanceLowerBoundConstraint,
    OrientationConstraint,
    PointToPointDistanceConstraint,
    PositionConstraint,
)
from pydrake.multibody.plant import AddMultibodyPlantSceneGraph
from pydrake.multibody.tree import JacobianWrtVariable
from pydrake.planning import KinematicTrajectoryOptimization
from pydrake.solvers import SnoptSolver, SolverOptions
from pydrake.systems.framework import DiagramBuilder
from pydrake.trajectories import BsplineTrajectory

from drake_lfd.core.exact_memo import ExactMemo, exact_key
from drake_lfd.core.timing import TimingLimits
from drake_lfd.robot.joint_path import shoulder_singularity_distance
from drake_lfd.robot.kinematics import END_EFFECTOR_FRAME_NAME, add_ur5e
from drake_lfd.robot.scene import add_scene
from drake_lfd.robot.workcell import Workcell

__all__ = [
    "TrajectoryLimits",
    "SolverBudget",
    "PoseTarget",
    "PoseBound",
    "OptimizationScene",
    "OptimizedTrajectory",
    "fit_bspline",
    "optimize_joint_trajectory",
    "sample_trajectory",
]

# A loose optimality tolerance: a feasible, nearly minimum-time motion is the goal, and
# SNOPT's default (1e-6) spends most of the solve shaving the last hundredths of a second.
# No option here reads a clock ("Time limit" is left unset; the SNOPT in Drake's wheel
# ignores it anyway): the solve is bounded by :class:`SolverBudget`'s iteration counts.
_SNOPT_OPTIONS = {"Major optimality tolerance": 1e-2}
# SNOPT's exit codes that end a solve at its work budget: its last iterate is returned
# and may be used when the caller's own check accepts it.
_BUDGET_SPENT = {31: "iteration limit", 32: "major iteration limit"}
# SNOPT's "infeasible" exit (info 13: nonlinear infeasibilities minimized): its last
# iterate is returned for the caller to check when no constraint is violated by more than
# _NEARLY_FEASIBLE (in the constraints' own units: metres, radians, rad/s). Measured on
# filling and pouring (exact planner, seed 4): SNOPT gave up with one target off by
# 4.6e-5, far inside the check's margins, while its second round ended 0.18 off.
_INFEASIBLE = 13
_NEARLY_FEASIBLE = 1e-4
# What the safety stop's callback raises (Drake re-raises it from Solve as a RuntimeError
# whose message holds this text).
_SAFETY_STOP_MESSAGE = "wall-clock safety stop (SNOPT stopped)"


class _SafetyStop(Exception):
    pass


@dataclasses.dataclass(frozen=True)
class SolverBudget:
    """How much work SNOPT may spend: counts of iterations, never seconds, so the same
    program gives the same answer bit for bit on any machine under any load.

    Attributes
    ----------
    major_iterations : int
        SNOPT's ``Major iterations limit``.
    minor_iterations : int
        SNOPT's ``Minor iterations limit`` (per major iteration's QP subproblem).
    iterations : int
        SNOPT's ``Iterations limit`` (all minor iterations together).
    safety_stop_s : float, optional
        Wall time after which SNOPT is stopped regardless (None: never). Not a budget:
        it only guards against a solver that hangs, far beyond any solve the iteration
        limits allow; when it fires the answer is an error (``status``
        ``wall-clock safety stop ...``, ``safety_stopped`` set), never a quiet plan.
    """

    major_iterations: int = 100
    minor_iterations: int = 500
    iterations: int = 20000
    safety_stop_s: float | None = 600.0


# Links standing on the table: never checked against it (as in joint_path.py).
_ON_TABLE_LINKS = ("base_link", "shoulder_link")


@dataclasses.dataclass(frozen=True)
class TrajectoryLimits:
    """What the optimized motion keeps to. :meth:`of_timing` gives the limits of a
    task's ``timing:`` block at its ``limit_fraction``, as the composed plan's timing
    uses them (``robot/path_timing.py``); the defaults are those of the default block.

    Attributes
    ----------
    joint_speed_rad_s : float
        Every joint's speed bound (0.9 pi).
    acceleration_rad_s2 : float
        Every joint's acceleration bound (0.9 of 8 rad/s^2).
    tool_speed_m_s : float
        E's speed (0.9 of 1.5 m/s), enforced on the samples by slowing the motion
        uniformly.
    tool_acceleration_m_s2 : float, optional
        E's acceleration magnitude (None: not limited), enforced like the tool speed.
    clearance_m : float
        Least signed distance of any robot or tool geometry to any box or the table at
        the clearance samples (0.02: the check demands 0.01 everywhere, and the path
        between samples may come closer).
    singularity_margin : float
        Least ``|sin q3|`` and ``|sin q5|`` (0.15; the check demands 0.06, and the
        controller's path near a singularity strays from the optimized joints).
    shoulder_margin_m : float
        Least distance of the wrist centre from the shoulder axis at the clearance
        samples, m (0.07: the check demands 0.05, and the path between samples may come
        closer).
    min_duration_s, max_duration_s : float
        Bounds of the duration.
    """

    joint_speed_rad_s: float = 0.9 * math.pi
    acceleration_rad_s2: float = 0.9 * 8.0
    tool_speed_m_s: float = 0.9 * 1.5
    tool_acceleration_m_s2: float | None = None
    clearance_m: float = 0.02
    singularity_margin: float = 0.15
    shoulder_margin_m: float = 0.07
    min_duration_s: float = 0.2
    max_duration_s: float = 60.0

    @classmethod
    def of_timing(cls, timing: TimingLimits, **overrides) -> "TrajectoryLimits":
        """The speed, acceleration and tool bounds of ``timing`` (a task's ``timing:``
        block) at its ``limit_fraction``; ``overrides`` set the other fields."""
        f = timing.limit_fraction
        a = timing.tool_acceleration_m_s2
        return cls(joint_speed_rad_s=f * timing.joint_speed_rad_s,
                   acceleration_rad_s2=f * timing.joint_acceleration_rad_s2,
                   tool_speed_m_s=f * timing.tool_speed_m_s,
                   tool_acceleration_m_s2=None if a is None else f * a, **overrides)


@dataclasses.dataclass(frozen=True)
class PoseTarget:
    """E at ``X_WE`` at path fraction ``s``: position within ``position_tolerance_m``
    along each axis of W, rotation within ``rotation_tolerance_rad`` (at worst; see
    ``_add_rotation_target``); with
    ``pass_speed_m_s`` and ``q_nominal`` (6,), a configuration at E's pose, E passes
    there at most that fast along each axis of W (linearized at ``q_nominal``: the
    target pins the configuration within a millimetre of it)."""

    s: float
    X_WE: RigidTransform
    position_tolerance_m: float
    rotation_tolerance_rad: float
    pass_speed_m_s: float | None = None
    q_nominal: np.ndarray | None = None


@dataclasses.dataclass(frozen=True)
class PoseBound:
    """At path fraction ``s``: E within ``radius_m`` of ``p_W`` (None: free) and within
    ``angle_rad`` of ``R_WE`` (None: free). With ``direction_W`` (a unit vector), E within
    ``radius_m`` of the line through ``p_W`` along it instead (a square of that half
    diagonal across the line), at most ``along_m`` from ``p_W`` along it: a bound on
    where E goes that leaves free how far along the way it is at ``s``."""

    s: float
    p_W: np.ndarray | None = None
    radius_m: float | None = None
    R_WE: RotationMatrix | None = None
    angle_rad: float | None = None
    direction_W: np.ndarray | None = None
    along_m: float | None = None


class OptimizationScene:
    """The work cell on a plant whose collision filters leave exactly the pairs to keep
    clear: robot and tool against obstacles, shells and (but for the links standing on
    it) the table; robot geometries among themselves are not checked.

    Attributes
    ----------
    plant, scene_graph, model, diagram, context, plant_context, frame_E
    solutions : ExactMemo
        The last solutions of programs on this scene, by their exact inputs (module
        docstring); ``solutions.clear()`` forgets them.
    """

    #: Programs remembered per scene (a refinement solves at most 14, two rounds of the plain
    #: program and three starts, each repaired once).
    REMEMBERED_SOLUTIONS = 16

    def __init__(self, workcell: Workcell):
        builder = DiagramBuilder()
        self.plant, self.scene_graph = AddMultibodyPlantSceneGraph(builder, time_step=0.0)
        self.model = add_ur5e(self.plant, X_WB=workcell.X_WB, X_tool0_E=workcell.X_tool0_E)
        # Shells join the obstacles here: in the station they are filtered out of contact,
        # which would hide them from the distance constraint.
        shells = tuple(dataclasses.replace(box, name=f"shell_{i}_{box.name}")
                       for i, box in enumerate(workcell.safety_shells))
        geometry = add_scene(self.plant, self.scene_graph, model=self.model,
                             obstacles=tuple(workcell.obstacles) + shells, table=workcell.table,
                             tool=workcell.tool)
        manager = self.scene_graph.collision_filter_manager()
        robot = GeometrySet(list(geometry.robot_geometry_ids))
        manager.Apply(CollisionFilterDeclaration().ExcludeWithin(robot))
        if geometry.table_geometry_id is not None:
            on_table = [g for g in geometry.robot_geometry_ids
                        if geometry.names.get(g, "").split("/")[0] in _ON_TABLE_LINKS]
            if on_table:
                manager.Apply(CollisionFilterDeclaration().ExcludeBetween(
                    GeometrySet(on_table), GeometrySet([geometry.table_geometry_id])))
        self.has_boxes = bool(geometry.keep_out_geometry_ids) or geometry.table_geometry_id is not None
        self.plant.Finalize()
        self.diagram = builder.Build()
        self.context = self.diagram.CreateDefaultContext()
        self.plant_context = self.plant.GetMyMutableContextFromRoot(self.context)
        self.frame_E = self.plant.GetFrameByName(END_EFFECTOR_FRAME_NAME)
        self.solutions = ExactMemo(maxsize=self.REMEMBERED_SOLUTIONS)

    def translational_jacobian(self, q: np.ndarray) -> np.ndarray:
        """d p_WE / d v at configuration ``q`` (6,): (3, 6)."""
        self.plant.SetPositions(self.plant_context, self.model, np.asarray(q, dtype=float))
        return self.plant.CalcJacobianTranslationalVelocity(
            self.plant_context, JacobianWrtVariable.kV, self.frame_E, np.zeros(3), self.plant.world_frame(),
            self.plant.world_frame())

    def X_WE(self, q: np.ndarray) -> RigidTransform:
        """E's pose at configuration ``q`` (6,)."""
        self.plant.SetPositions(self.plant_context, self.model, np.asarray(q, dtype=float))
        return self.plant.CalcRelativeTransform(self.plant_context, self.plant.world_frame(), self.frame_E)


@dataclasses.dataclass(frozen=True)
class OptimizedTrajectory:
    """The solver's answer.

    Attributes
    ----------
    trajectory : BsplineTrajectory or None
        ``q(t)``, t in [0, duration]: the solution, or when SNOPT spent its work budget
        (``budget_spent``) its last iterate, for the caller to check; None otherwise.
    success : bool
        SNOPT reported success.
    status : str
        The solver's result (``SNOPT info 1``, ``... (SNOPT info 13)``), for a reason.
    solve_time_s : float
        Wall time of the solve (a measurement only: nothing depends on it; 0 when the
        scene remembered the answer).
    evaluations : int
        Evaluations of the program SNOPT made (deterministic, like the answer).
    budget_spent : bool
        SNOPT stopped at an iteration limit of :class:`SolverBudget`.
    safety_stopped : bool
        The wall-clock safety stop ended the solve (an error; ``trajectory`` is None).
    nearly_feasible : bool
        SNOPT reported the program infeasible (info 13) at an iterate that violates no
        constraint by more than 1e-4; ``trajectory`` is that iterate, for the caller to
        check.
    """

    trajectory: BsplineTrajectory | None
    success: bool
    status: str
    solve_time_s: float
    evaluations: int = 0
    budget_spent: bool = False
    safety_stopped: bool = False
    nearly_feasible: bool = False

    @property
    def duration(self) -> float:
        return float(self.trajectory.end_time()) if self.trajectory is not None else math.nan


def fit_bspline(s: np.ndarray, q: np.ndarray, num_control_points: int, order: int = 4, *,
                rest_ends: bool = False, pins: Sequence[tuple[float, np.ndarray]] = ()) -> BsplineTrajectory:
    """The clamped uniform B-spline in ``s`` (on [0, 1]) with ``num_control_points``
    control points closest (least squares) to the samples ``q`` (m, 6) at ``s`` (m,),
    its ends on the first and last sample.

    With ``rest_ends`` the first and last ``order - 1`` control points are the ends
    themselves (zero velocity and acceleration there, as the program demands); each pin
    ``(s_k, q_k)`` is met exactly (least squares under equality constraints), so the
    guess starts on every critical configuration. A guess that breaks those constraints
    starts SNOPT far from feasibility: fitted freely, a filling-and-pouring guess had a
    path acceleration of 423 rad at its ends where the program demands 0, and missed
    its critical configurations by up to 16 mm."""
    basis = BsplineBasis(order, num_control_points)

    def rows(x):
        return np.array([[basis.EvaluateBasisFunctionI(i, float(v)) for i in range(num_control_points)] for v in x])

    q = np.asarray(q, dtype=float)
    fixed = order - 1 if rest_ends else 1
    free = slice(fixed, num_control_points - fixed)
    A = rows(s)
    ends = np.zeros((num_control_points, q.shape[1]))
    ends[:fixed], ends[num_control_points - fixed:] = q[0], q[-1]
    target = q - A @ ends
    A_free = A[:, free]
    if pins:
        B = rows([p for p, _ in pins])
        d = np.array([x for _, x in pins]) - B @ ends
        B_free = B[:, free]
        k, m = A_free.shape[1], B_free.shape[0]
        kkt = np.block([[A_free.T @ A_free, B_free.T], [B_free, np.zeros((m, m))]])
        solution = np.linalg.lstsq(kkt, np.vstack([A_free.T @ target, d]), rcond=None)[0]
        inner = solution[:k]
    else:
        inner = np.linalg.lstsq(A_free, target, rcond=None)[0]
    control = ends.copy()
    control[free] = inner
    return BsplineTrajectory(basis, [c.reshape(-1, 1) for c in control])


def _add_pass_speed_bound(trajopt: KinematicTrajectoryOptimization, J: np.ndarray, s: float,
                          speed_m_s: float) -> None:
    """E's velocity ``J q'(s) / T`` at path fraction ``s`` within ``speed_m_s`` along each
    axis, for a fixed Jacobian ``J`` (3, n): as ``|J q'(s)| <= speed T``, linear in the
    control points and the duration ``T`` (``q'(s)`` is a fixed combination of the
    control points). Drake's ``AddVelocityConstraintAtNormalizedTime`` would take a
    general constraint on (q, v) and differentiate it through the whole spline at
    every evaluation, which makes each evaluation of the program several times dearer."""
    basis = trajopt.basis()
    count = trajopt.num_control_points()
    weights = np.array([
        BsplineTrajectory(basis, [np.array([[1.0 if k == i else 0.0]]) for k in range(count)]).MakeDerivative()
        .value(float(s))[0, 0] for i in range(count)])
    control = np.asarray(trajopt.control_points())  # (n, count) of variables
    n = control.shape[0]
    variables = [control[j, i] for i in range(count) for j in range(n)] + [trajopt.duration()]
    A = np.zeros((3, count * n + 1))
    for i in range(count):
        A[:, i * n:(i + 1) * n] = weights[i] * J
    upper, lower = A.copy(), A.copy()
    upper[:, -1], lower[:, -1] = -speed_m_s, speed_m_s
    prog = trajopt.get_mutable_prog()
    prog.AddLinearConstraint(upper, np.full(3, -np.inf), np.zeros(3), variables)
    prog.AddLinearConstraint(lower, np.zeros(3), np.full(3, np.inf), variables)


# The wrist centre's signed distance from the shoulder axis
# (``joint_path.shoulder_singularity_distance``) is the x coordinate, in the shoulder
# link's frame, of the wrist-2 link's origin (tests/test_trajectory_optimization.py
# checks this on random configurations).
SHOULDER_FRAME_NAME, WRIST_CENTRE_FRAME_NAME = "shoulder_link", "wrist_2_link"


def _add_shoulder_margin(trajopt: KinematicTrajectoryOptimization, scene: OptimizationScene,
                         q_ends: Sequence[np.ndarray], fractions: np.ndarray, margin_m: float) -> bool:
    """The wrist centre at least ``margin_m`` from the shoulder axis at each path
    fraction of ``fractions``, on the side the ends ``q_ends`` (two (6,) configurations)
    lie on. "Outside a cylinder" is not convex, but on a fixed side it is a half space
    in the shoulder link's frame (which turns with q1): one Drake ``PositionConstraint``
    with a one-sided bound on x, evaluated in C++ like the other path constraints. The
    margin is lowered to the ends' own distance where that is less (the ends are fixed).
    False (nothing added) when the ends lie on opposite sides or there is no fraction."""
    ends = [shoulder_singularity_distance(q) for q in q_ends]
    if ends[0] * ends[1] <= 0.0 or not len(fractions):
        return False
    margin_m = min(margin_m, abs(ends[0]), abs(ends[1]))
    lower, upper = np.full(3, -np.inf), np.full(3, np.inf)
    if ends[0] > 0:
        lower[0] = margin_m
    else:
        upper[0] = -margin_m
    plant = scene.plant
    constraint = PositionConstraint(plant, plant.GetFrameByName(SHOULDER_FRAME_NAME, scene.model), lower, upper,
                                    plant.GetFrameByName(WRIST_CENTRE_FRAME_NAME, scene.model), np.zeros(3),
                                    scene.plant_context)
    for s in fractions:
        trajopt.AddPathPositionConstraint(constraint, float(s))
    return True


# The lever of a rotation target's points (m): E's rotation is held through the positions
# of points this far along E's x and y axes.
_ROTATION_LEVER_M = 1.0


def _add_rotation_target(trajopt: KinematicTrajectoryOptimization, scene: OptimizationScene,
                         target: PoseTarget) -> None:
    """E's rotation within about ``target.rotation_tolerance_rad`` of the target's at its
    path fraction, as position boxes of the points 1 m along E's x and y axes.

    An ``OrientationConstraint`` bounds ``trace(R_error)``, whose gradient vanishes as
    the error does: at 0.3 deg a violation of 4.6e-5 in it is 0.49 deg, so SNOPT
    declared filling and pouring (exact planner, seed 4) infeasible with con_4 0.49 deg
    off, and iterates at the iteration limit missed con_2 by 5 deg while nearly
    feasible in its measure. A point 1 m out moves 1 m per radian, as E's position does.
    With both points and E's origin within ``delta`` and ``epsilon`` of their targets on
    each axis, the rotation error is at most ``sqrt(6) (delta + epsilon) / lever``: the
    box half-width ``delta`` makes that the tolerance."""
    plant, world, frame_E = scene.plant, scene.plant.world_frame(), scene.frame_E
    lever = _ROTATION_LEVER_M
    delta = max(target.rotation_tolerance_rad * lever / math.sqrt(6.0) - target.position_tolerance_m,
                target.position_tolerance_m)
    X = target.X_WE
    for axis in (0, 1):
        p_EP = np.zeros(3)
        p_EP[axis] = lever
        p_WP = X.multiply(p_EP)
        trajopt.AddPathPositionConstraint(
            PositionConstraint(plant, world, p_WP - delta, p_WP + delta, frame_E, p_EP, scene.plant_context),
            target.s)


def _singularity_free_interval(values: np.ndarray, margin: float) -> tuple[float, float] | None:
    """The interval ``[k pi + asin(margin), (k + 1) pi - asin(margin)]`` holding every
    value, or None when the values cross a singularity."""
    a = math.asin(margin)
    k = np.floor(np.asarray(values) / math.pi)
    if not np.all(k == k[0]):
        return None
    low, high = k[0] * math.pi + a, (k[0] + 1) * math.pi - a
    if np.min(values) < low or np.max(values) > high:
        return None
    return float(low), float(high)


def optimize_joint_trajectory(
    scene: OptimizationScene,
    guess: BsplineTrajectory,
    guess_duration_s: float,
    *,
    targets: Sequence[PoseTarget] = (),
    bounds: Sequence[PoseBound] = (),
    clearance_samples: int = 40,
    limits: TrajectoryLimits = TrajectoryLimits(),
    budget: SolverBudget = SolverBudget(),
    energy_weight: float = 0.0,
) -> OptimizedTrajectory:
    """Solves the program of the module docstring from ``guess`` (a B-spline in path
    fraction, on [0, 1], its ends the fixed start and goal configurations).

    Parameters
    ----------
    scene : OptimizationScene
    guess : BsplineTrajectory
        Initial guess ``q(s)``; its number of control points and order are the program's.
    guess_duration_s : float
    targets, bounds : sequences of PoseTarget, PoseBound
    clearance_samples : int
        Path fractions (evenly spread, ends included) the clearance is constrained at.
    limits : TrajectoryLimits
    budget : SolverBudget
        SNOPT's iteration limits (and the wall-clock safety stop). SNOPT runs single
        threaded and writes no print or summary file, so the answer depends on the
        program and these counts only. The SNOPT shipped with Drake ignores its own
        ``Time limit`` option, so the safety stop is an exception raised in a
        visualization callback (called at each evaluation of the program), which Drake
        turns into SNOPT's "terminated during function evaluation".
    energy_weight : float
        Weight of ``AddPathEnergyCost`` beside the duration's (0: the duration alone).

    A program this scene solved before (the same inputs to the bit) is answered from
    ``scene.solutions``: the same answer, ``evaluations`` included (SNOPT's work for the
    program), with ``solve_time_s`` 0 (no solve ran). A solve the safety stop ended is
    not remembered.
    """
    key = _program_key(guess, guess_duration_s, targets, bounds, clearance_samples, limits, budget) + \
        _numbers([energy_weight])
    solved = []

    def solve():
        solved.append(True)
        return _solve(scene, guess, guess_duration_s, targets, bounds, clearance_samples, limits, budget,
                      energy_weight)

    # A safety-stopped solve depends on the clock: returned, not remembered.
    answer = scene.solutions.get(key, solve, keep=lambda answer: not answer.safety_stopped)
    return answer if solved else dataclasses.replace(answer, solve_time_s=0.0)


def _numbers(values) -> tuple:
    """The exact key of a sequence of numbers, arrays, transforms or Nones: each one's
    shape (None for None) and all their float64 bits (so ``-0.0`` is not ``0.0``)."""
    shapes, parts = [], []
    for value in values:
        if value is None:
            shapes.append(None)
            continue
        if isinstance(value, RigidTransform):
            value = value.GetAsMatrix4()
        elif isinstance(value, RotationMatrix):
            value = value.matrix()
        array = np.asarray(value, dtype=np.float64)
        shapes.append(array.shape)
        parts.append(array.ravel())
    return (tuple(shapes),) + exact_key(np.concatenate(parts) if parts else np.zeros(0))


def _program_key(guess: BsplineTrajectory, guess_duration_s: float, targets: Sequence[PoseTarget],
                 bounds: Sequence[PoseBound], clearance_samples: int, limits: TrajectoryLimits,
                 budget: SolverBudget) -> tuple:
    """Everything :func:`_solve` reads besides the scene, exactly."""
    fields = [guess.basis().order(), np.asarray(guess.basis().knots()), np.hstack(guess.control_points()),
              guess_duration_s, clearance_samples, len(targets), len(bounds)]
    for target in targets:
        fields += [target.s, target.X_WE, target.position_tolerance_m, target.rotation_tolerance_rad,
                   target.pass_speed_m_s, target.q_nominal]
    for bound in bounds:
        fields += [bound.s, bound.p_W, bound.radius_m, bound.R_WE, bound.angle_rad, bound.direction_W,
                   bound.along_m]
    fields += list(dataclasses.astuple(limits)) + list(dataclasses.astuple(budget))
    return _numbers(fields)


def _solve(scene: OptimizationScene, guess: BsplineTrajectory, guess_duration_s: float,
           targets: Sequence[PoseTarget], bounds: Sequence[PoseBound], clearance_samples: int,
           limits: TrajectoryLimits, budget: SolverBudget, energy_weight: float = 0.0) -> OptimizedTrajectory:
    """:func:`optimize_joint_trajectory` without the memo."""
    plant, context, frame_E = scene.plant, scene.plant_context, scene.frame_E
    world = plant.world_frame()
    n = plant.num_positions()
    control = np.hstack(guess.control_points())  # (n, num_control_points)
    trajopt = KinematicTrajectoryOptimization(n, control.shape[1], guess.basis().order(), guess_duration_s)
    trajopt.AddDurationCost(1.0)
    if energy_weight > 0.0:
        trajopt.AddPathEnergyCost(energy_weight)
    trajopt.AddDurationConstraint(limits.min_duration_s, limits.max_duration_s)
    lower, upper = plant.GetPositionLowerLimits().copy(), plant.GetPositionUpperLimits().copy()
    for j in (2, 4):  # elbow and wrist: stay on the side of the singularity both ends are on
        interval = _singularity_free_interval(control[j, [0, -1]], limits.singularity_margin)
        if interval is not None:
            lower[j], upper[j] = max(lower[j], interval[0]), min(upper[j], interval[1])
    trajopt.AddPositionBounds(lower, upper)
    control = np.clip(control, lower[:, None], upper[:, None])
    speed = np.minimum(limits.joint_speed_rad_s, plant.GetVelocityUpperLimits())
    trajopt.AddVelocityBounds(-speed, speed)
    trajopt.AddAccelerationBounds(np.full(n, -limits.acceleration_rad_s2), np.full(n, limits.acceleration_rad_s2))
    q_start, q_goal = control[:, 0], control[:, -1]
    trajopt.AddPathPositionConstraint(q_start, q_start, 0.0)
    trajopt.AddPathPositionConstraint(q_goal, q_goal, 1.0)
    trajopt.AddPathVelocityConstraint(np.zeros(n), np.zeros(n), 0.0)
    trajopt.AddPathVelocityConstraint(np.zeros(n), np.zeros(n), 1.0)
    # Zero acceleration too: the servos start and settle without a jolt (the goal is
    # judged the moment it is due).
    trajopt.AddPathAccelerationConstraint(np.zeros(n), np.zeros(n), 0.0)
    trajopt.AddPathAccelerationConstraint(np.zeros(n), np.zeros(n), 1.0)
    for target in targets:
        p = target.X_WE.translation()
        tolerance = np.full(3, target.position_tolerance_m)
        trajopt.AddPathPositionConstraint(
            PositionConstraint(plant, world, p - tolerance, p + tolerance, frame_E, np.zeros(3), context), target.s)
        _add_rotation_target(trajopt, scene, target)
        if target.pass_speed_m_s is not None and target.q_nominal is not None:
            _add_pass_speed_bound(trajopt, scene.translational_jacobian(target.q_nominal), target.s,
                                  target.pass_speed_m_s)
    for bound in bounds:
        if bound.p_W is not None and bound.direction_W is not None:
            # A frame on the line, its z along it: E in a box there.
            X_WL = RigidTransform(RotationMatrix.MakeFromOneVector(np.asarray(bound.direction_W, dtype=float), 2),
                                  np.asarray(bound.p_W, dtype=float))
            half = bound.radius_m / math.sqrt(2.0)
            trajopt.AddPathPositionConstraint(
                PositionConstraint(plant, world, X_WL, np.array([-half, -half, -bound.along_m]),
                                   np.array([half, half, bound.along_m]), frame_E, np.zeros(3), context), bound.s)
        elif bound.p_W is not None:
            trajopt.AddPathPositionConstraint(
                PointToPointDistanceConstraint(plant, world, np.asarray(bound.p_W, dtype=float), frame_E,
                                               np.zeros(3), 0.0, bound.radius_m, context), bound.s)
        if bound.R_WE is not None:
            trajopt.AddPathPositionConstraint(
                OrientationConstraint(plant, world, bound.R_WE, frame_E, RotationMatrix(), bound.angle_rad, context),
                bound.s)
    samples = np.linspace(0.0, 1.0, max(clearance_samples, 2))
    if limits.shoulder_margin_m > 0.0:
        _add_shoulder_margin(trajopt, scene, (q_start, q_goal), samples[1:-1],  # the ends are fixed
                             limits.shoulder_margin_m)
    if scene.has_boxes and clearance_samples > 0:
        clearance = MinimumDistanceLowerBoundConstraint(plant, limits.clearance_m, context, None, 0.05)
        for s in samples:
            trajopt.AddPathPositionConstraint(clearance, float(s))
    prog = trajopt.get_mutable_prog()
    # The guess in time: its duration is the initial guess of T.
    knots = np.asarray(guess.basis().knots()) * guess_duration_s
    trajopt.SetInitialGuess(BsplineTrajectory(BsplineBasis(guess.basis().order(), knots),
                                              [c.reshape(-1, 1) for c in control.T]))
    options = SolverOptions()
    for name, value in _SNOPT_OPTIONS.items():
        options.SetOption(SnoptSolver.id(), name, value)
    options.SetOption(SnoptSolver.id(), "Major iterations limit", int(budget.major_iterations))
    options.SetOption(SnoptSolver.id(), "Minor iterations limit", int(budget.minor_iterations))
    options.SetOption(SnoptSolver.id(), "Iterations limit", int(budget.iterations))
    evaluations = [0]
    start = time.perf_counter()
    stop_at = None if budget.safety_stop_s is None else start + budget.safety_stop_s

    def count(_):
        evaluations[0] += 1
        if stop_at is not None and time.perf_counter() > stop_at:
            raise _SafetyStop(_SAFETY_STOP_MESSAGE)

    prog.AddVisualizationCallback(count, prog.decision_variables())
    try:
        result = SnoptSolver().Solve(prog, None, options)
    except RuntimeError as error:
        if _SAFETY_STOP_MESSAGE not in str(error):
            raise
        return OptimizedTrajectory(None, False, f"{_SAFETY_STOP_MESSAGE} after {budget.safety_stop_s:g} s",
                                   time.perf_counter() - start, evaluations[0], safety_stopped=True)
    elapsed = time.perf_counter() - start
    info = int(result.get_solver_details().info)
    if result.is_success():
        return OptimizedTrajectory(trajopt.ReconstructTrajectory(result), True, f"SNOPT info {info}", elapsed,
                                   evaluations[0])
    status = f"{result.get_solution_result()} (SNOPT info {info})"
    if info in _BUDGET_SPENT:
        return OptimizedTrajectory(trajopt.ReconstructTrajectory(result), False,
                                   f"{_BUDGET_SPENT[info]} reached (SNOPT info {info})", elapsed, evaluations[0],
                                   budget_spent=True)
    if info == _INFEASIBLE:
        violation = _max_violation(prog, result.GetSolution())
        if violation <= _NEARLY_FEASIBLE:
            return OptimizedTrajectory(trajopt.ReconstructTrajectory(result), False,
                                       f"{status}, violated by at most {violation:.1e}", elapsed, evaluations[0],
                                       nearly_feasible=True)
    return OptimizedTrajectory(None, False, status, elapsed, evaluations[0])


def _max_violation(prog, x: np.ndarray) -> float:
    """The largest amount by which ``x`` breaks a constraint of ``prog``."""
    worst = 0.0
    for binding in prog.GetAllConstraints():
        value = np.asarray(prog.EvalBinding(binding, x), dtype=float).reshape(-1)
        if value.size:
            c = binding.evaluator()
            worst = max(worst, float(np.max(np.maximum(c.lower_bound() - value, value - c.upper_bound()))))
    return worst


def _tool_speed_and_acceleration(scene: OptimizationScene, trajectory: BsplineTrajectory, tau: float,
                                 h: float = 1e-3) -> tuple[float, float]:
    """E's speed (m/s) and the magnitude of its acceleration (m/s^2) at time ``tau`` of
    ``trajectory`` (central differences over ``h``)."""
    times = [max(tau - h, trajectory.start_time()), tau, min(tau + h, trajectory.end_time())]
    p = [scene.X_WE(trajectory.value(x)[:, 0]).translation() for x in times]
    speed = float(np.linalg.norm(p[2] - p[0]) / max(times[2] - times[0], 1e-12))
    acceleration = float(np.linalg.norm(p[2] - 2.0 * p[1] + p[0]) / h ** 2)
    return speed, acceleration


def _slowed_clock(scene: OptimizationScene, trajectory: BsplineTrajectory, due: np.ndarray,
                  pass_speed_m_s: float | None, pass_acceleration_m_s2: float | None,
                  window_s: float) -> tuple[np.ndarray, np.ndarray]:
    """A retiming that passes each of the inner times ``due`` at most at
    ``pass_speed_m_s`` and ``pass_acceleration_m_s2``: the motion's rate is multiplied by
    ``1 - (1 - rho) cos^2`` bumps ``window_s`` wide on either side of each (``rho``: the
    slow-down needed; at a bump's centre the rate is flat, so speed scales by ``rho``
    and acceleration by ``rho^2``), so the path stays the same and speeds only drop.
    Returns the original times ``tau`` (a 1 ms grid) and the new clock at them."""
    T = float(trajectory.end_time())
    tau = np.linspace(0.0, T, max(int(np.ceil(T / 1e-3)), 2) + 1)
    rate = np.ones_like(tau)
    for t_i in due[1:-1] if pass_speed_m_s is not None else ():
        speed, acceleration = _tool_speed_and_acceleration(scene, trajectory, float(t_i))
        rho = min(1.0, pass_speed_m_s / speed if speed > 0 else 1.0)
        if pass_acceleration_m_s2 is not None and acceleration > 0:
            rho = min(rho, math.sqrt(pass_acceleration_m_s2 / acceleration))
        x = np.clip((tau - t_i) / window_s, -1.0, 1.0)
        rate *= 1.0 - (1.0 - rho) * np.cos(0.5 * np.pi * x) ** 2
    clock = np.concatenate([[0.0], np.cumsum(0.5 * (1.0 / rate[1:] + 1.0 / rate[:-1]) * np.diff(tau))])
    return tau, clock


def sample_trajectory(
    scene: OptimizationScene,
    trajectory: BsplineTrajectory,
    fractions: Sequence[float] | np.ndarray,
    *,
    time_step: float,
    tool_speed_m_s: float,
    tool_acceleration_m_s2: float | None = None,
    pass_speed_m_s: float | None = None,
    pass_acceleration_m_s2: float | None = None,
    slow_window_s: float = 0.15,
) -> tuple[np.ndarray, np.ndarray, list[RigidTransform], list[int], np.ndarray]:
    """Samples ``trajectory`` every ``time_step`` with each path fraction of
    ``fractions`` (the targets, in order, 0 and 1 included) on a sample.

    The motion is retimed along its path, never faster: around each inner fraction it
    slows to pass it at most at ``pass_speed_m_s`` and ``pass_acceleration_m_s2``
    (None: as optimized; see
    :func:`_slowed_clock`: a closed loop lags the command by a few milliseconds, so
    the speed at a critical configuration is what its error there grows with); each
    stretch between consecutive fractions is stretched to a whole number of steps; then
    the whole motion is slowed uniformly until E's speed (finite differences of the
    samples) is within ``tool_speed_m_s`` and, when given, the magnitude of its
    acceleration (second differences) within ``tool_acceleration_m_s2`` (uniform
    slowing keeps every path constraint and lowers every speed and acceleration).

    Returns
    -------
    t : array (m,)
    q : array (m, 6)
    X_WE : list of RigidTransform, one per sample
    indices : list of int
        The sample of each fraction.
    s : array (m,)
        Each sample's path fraction.
    """
    T = float(trajectory.end_time())
    fractions = np.asarray(fractions, dtype=float)
    tau, clock = _slowed_clock(scene, trajectory, fractions * T, pass_speed_m_s, pass_acceleration_m_s2,
                               slow_window_s)
    clock_due = np.interp(fractions * T, tau, clock)
    scale = 1.0
    for _ in range(5):
        steps = np.maximum(np.ceil(np.diff(clock_due) * scale / time_step - 1e-9), 1).astype(int)
        indices = np.concatenate([[0], np.cumsum(steps)]).astype(int)
        t = np.arange(indices[-1] + 1) * time_step
        # Each sample's clock: linear within each stretch; then its original time.
        sample_clock = np.interp(np.arange(indices[-1] + 1), indices, clock_due)
        sample_tau = np.interp(sample_clock, clock, tau)
        q = np.array([trajectory.value(float(x))[:, 0] for x in sample_tau])
        X = [scene.X_WE(x) for x in q]
        p = np.array([x.translation() for x in X])
        peak = float(np.max(np.linalg.norm(np.diff(p, axis=0), axis=1)) / time_step) if len(p) > 1 else 0.0
        slow = peak / tool_speed_m_s
        if tool_acceleration_m_s2 is not None and len(p) > 2:
            peak_acceleration = float(np.max(np.linalg.norm(np.diff(p, 2, axis=0), axis=1)) / time_step ** 2)
            slow = max(slow, math.sqrt(peak_acceleration / tool_acceleration_m_s2))
        if slow <= 1.0:
            break
        scale *= 1.02 * slow
    return t, q, X, [int(i) for i in indices], sample_tau / T
