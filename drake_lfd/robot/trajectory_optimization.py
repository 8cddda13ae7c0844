"""Drake's kinematic trajectory optimization of a UR5e joint path in a work cell.

:func:`optimize_joint_trajectory` sets up and solves one
``KinematicTrajectoryOptimization`` (a clamped B-spline ``q(s)``, ``s`` in [0, 1], with a
free duration ``T``; docs/method.rst, Refinement by trajectory optimization). Its inputs
and its answer are the records of ``optimization_records.py`` (``TrajectoryLimits``,
``SolverBudget``, ``PoseTarget``, ``PoseBound``, ``OptimizedTrajectory``); it runs on an
``OptimizationScene`` (``optimization_scene.py``). The program:

- minimum duration (``AddDurationCost``), duration within bounds; optionally plus a small
  path-energy cost (``AddPathEnergyCost``, ``energy_weight``), which makes the minimum unique
  where the duration leaves the shape free;
- joint position bounds: the UR5e's limits, narrowed for the elbow (q3) and the wrist
  (q5) to the singularity-free interval (``|sin q| >= margin``) the initial guess lies
  in; bounds on the control points hold on the whole path (convex hull);
- joint speed and acceleration bounds (on the whole path, by the same property):
  ``TrajectoryLimits``, by default a task's ``timing:`` limits at its ``limit_fraction``
  (:meth:`TrajectoryLimits.of_timing
  <drake_lfd.robot.optimization_records.TrajectoryLimits.of_timing>`);
- zero path velocity and acceleration at both ends (the arm starts and ends at rest);
- pose targets (``PoseTarget``: a position box of E and, for its rotation, position
  boxes of two points 1 m out on its axes (well scaled, unlike a trace bound) at a
  fixed path fraction, and optionally a bound on E's speed there, linear in the control
  points and the duration), pose bounds along the path (``PoseBound``: E's distance
  to a point and its angle to a rotation, at a fixed path fraction: the task's
  orientation constraints and the demonstration tube);
- the shoulder singularity: the wrist centre at least ``shoulder_margin_m`` from the
  shoulder axis, on the side both ends are on, at the clearance's path fractions (a
  one-sided ``PositionConstraint`` of the wrist centre in the shoulder link's frame);
- clearance: ``MinimumDistanceLowerBoundConstraint`` at evenly spread path fractions on
  the ``OptimizationScene``, the work cell's geometry with every robot and tool
  geometry checked against every obstacle, shell and the table (the base and shoulder
  links, which stand on the table, excepted).

The constraints Drake has no ready-made form for (the rotation targets, the speed at a
target, the shoulder margin, the singularity-free intervals) are written in
``trajectory_constraints.py``.

SNOPT's work is bounded by iteration counts (``SolverBudget``), never by a clock; at an
iteration limit its last iterate is returned for the caller to check.

A scene remembers its last solutions by the program's exact inputs (the guess, its
duration, the targets, bounds, limits and budget, every number by its bits;
:mod:`~drake_lfd.core.exact_memo`): SNOPT keeps nothing between solves, so solving the
same program again gives the same bits, and a remembered answer is that answer (but
for its wall time, a measurement: 0). Every assembling trial (a task
without variables) asks the same programs; each worker solves them once.

Constraints at path fractions hold at those samples only: callers sample densely and
keep margins, and check the result (``planning/refinement_check.py`` runs the joint-path
check on it). ``trajectory_sampling.py`` fits the guess to a path's samples and turns
the solution into 10 ms samples, with every target on a sample and the tool speed
bounded.

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
from pydrake.math import BsplineBasis, RigidTransform, RotationMatrix
from pydrake.multibody.inverse_kinematics import (
    MinimumDistanceLowerBoundConstraint,
    OrientationConstraint,
    PointToPointDistanceConstraint,
    PositionConstraint,
)
from pydrake.planning import KinematicTrajectoryOptimization
from pydrake.solvers import SnoptSolver, SolverOptions
from pydrake.trajectories import BsplineTrajectory

from drake_lfd.core.exact_memo import exact_key
from drake_lfd.robot.optimization_records import (
    OptimizedTrajectory,
    PoseBound,
    PoseTarget,
    SolverBudget,
    TrajectoryLimits,
)
from drake_lfd.robot.optimization_scene import OptimizationScene
from drake_lfd.robot.trajectory_constraints import (
    add_pass_speed_bound,
    add_rotation_target,
    add_shoulder_margin,
    singularity_free_interval,
)

__all__ = ["optimize_joint_trajectory"]

# A loose optimality tolerance: a feasible, nearly minimum-time motion is the goal, and
# SNOPT's default (1e-6) spends most of the solve shaving the last hundredths of a second.
# No option here reads a clock ("Time limit" is left unset; the SNOPT in Drake's wheel
# ignores it anyway): the solve is bounded by SolverBudget's iteration counts.
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
    scene : optimization_scene.OptimizationScene
    guess : BsplineTrajectory
        Initial guess ``q(s)``; its number of control points and order are the program's.
    guess_duration_s : float
    targets, bounds : sequences of PoseTarget, PoseBound
    clearance_samples : int
        Path fractions (evenly spread, ends included) the clearance is constrained at.
    limits : optimization_records.TrajectoryLimits
    budget : optimization_records.SolverBudget
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
        interval = singularity_free_interval(control[j, [0, -1]], limits.singularity_margin)
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
        add_rotation_target(trajopt, scene, target)
        if target.pass_speed_m_s is not None and target.q_nominal is not None:
            add_pass_speed_bound(trajopt, scene.translational_jacobian(target.q_nominal), target.s,
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
        add_shoulder_margin(trajopt, scene, (q_start, q_goal), samples[1:-1],  # the ends are fixed
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
