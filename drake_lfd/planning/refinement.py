"""Demonstration-guided trajectory optimization of a composed plan (``--refine``), and
the plain optimizer it is compared with: the run (the program's rounds and starts, the
check of each motion, the choice) and its report.

:func:`refine_plan` takes an executable composed plan (a :class:`PlanResult` with its
joint path) and optimizes a joint trajectory around it (docs/method.rst, Refinement
by trajectory optimization): each critical configuration is pinned at the path
fraction where the composed plan reaches it (its configuration there, on the composed
joint path, fixes the IK branch), and the motion must stay in a tube around the mapped
demonstrations (E within the task's bounds of the composed SE(3) path: by default
``tube_position_m`` and ``tube_rotation_rad`` at the matching path fraction, within each
span matched by arc length; the task file's ``refinement:`` block and its path
constraints bound it span by span,
:func:`~drake_lfd.planning.refinement_bounds.allowed_deviations`), keep the task's path
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
(``refinement_starts.start_guesses``) and the plan takes a fixed choice among the motions
that pass (``refinement_starts.best_start``), with a small path-energy cost that makes the
minimum of each start unique where the duration alone leaves the shape free. The solve
is bounded by SNOPT's iteration counts
(:class:`~drake_lfd.robot.trajectory_optimization.SolverBudget`) per solve and a fixed
number of solves, never by time, and the bounds are the task's ``timing:`` limits at its ``limit_fraction``:
the same inputs give the same plan on any machine under any load.

:func:`~drake_lfd.planning.plain_optimizer.plain_plan` is the peer without demonstrations:
the same program and checks, from straight joint-space lines between the composed path's
configurations at the critical configurations, with no tube and a duration cost alone.

This module runs it and reports (:class:`RefinementReport`); its parts:

* ``refinement_options``: the settings
  (:class:`~drake_lfd.planning.refinement_options.RefinementOptions`).
* ``refinement_bounds``: the task file's bounds on the deviation, span by span.
* ``refinement_tube``: the composed path at path fractions, deviations from it, and the
  tube in the program.
* ``refinement_starts``: the program's starts and the choice among the motions that pass.
* ``refinement_check``: the check of a solved motion.

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

from drake_lfd.core.timing import TimingLimits
from drake_lfd.planning.planner import PlanResult
from drake_lfd.planning.refinement_bounds import allowed_at_fractions, path_constraint_bounds
from drake_lfd.planning.refinement_check import check_motion, CheckedMotion, with_iterate
from drake_lfd.planning.refinement_options import RefinementOptions
from drake_lfd.planning.refinement_starts import (
    START_NAMES,
    best_start,
    duration_guess,
    fractions_by_joint_arc_length,
    in_path_fraction,
    start_guesses,
    through_critical_configurations,
)
from drake_lfd.planning.refinement_tube import ComposedPathReference, tube_bounds
from drake_lfd.robot.joint_path import JointPathChecker
from drake_lfd.robot.optimization_records import OptimizedTrajectory, PoseTarget, TrajectoryLimits
from drake_lfd.robot.optimization_scene import OptimizationScene
from drake_lfd.robot.trajectory_optimization import optimize_joint_trajectory
from drake_lfd.robot.trajectory_sampling import fit_bspline

__all__ = ["RefinementReport", "refine_plan", "optimize_plan"]


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
        (:func:`~drake_lfd.planning.refinement_tube.tube_deviation`). Not in the JSON.
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

        document: dict[str, object] = {"method": self.method, "status": self.status, "reason": self.reason}
        if wall_times:
            document.update(solve_time_s=float(self.solve_time_s), total_time_s=float(self.total_time_s))
        document.update(duration_s=number(self.duration_s), unrefined_duration_s=number(self.unrefined_duration_s),
                        tube_max_position_m=number(self.tube_max_position_m),
                        tube_max_rotation_rad=number(self.tube_max_rotation_rad),
                        evaluations=int(self.evaluations), attempts=int(self.attempts),
                        budget_spent=bool(self.budget_spent))
        return document


def optimize_plan(result: PlanResult, checker: JointPathChecker, scene: OptimizationScene | None,
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
    assert timed is not None  # a planned result has its timed plan
    scene = OptimizationScene(checker.scene.workcell) if scene is None else scene
    reference = ComposedPathReference(timed)
    fractions = reference.fractions
    dt = checker.time_step
    # The composed joint path at path fractions (its samples after the plan's end are the settling).
    within = path.t <= timed.duration + 1e-9
    q_path = path.q[within]
    q_goal = path.q[min(int(round(timed.duration / dt)), len(path.q) - 1)]
    q_path[-1] = q_goal
    s_path = fractions_by_joint_arc_length(path.t[within], q_path, [timed.times[i] for i in timed.critical_indices],
                                            fractions)
    path_bounds = path_constraint_bounds(result, fractions, options)
    allowed = allowed_at_fractions(result.task, fractions, options)
    bounds = path_bounds + (tube_bounds(reference, options, allowed) if method == "refine" else [])
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
    lines = through_critical_configurations(fractions, q_path[0], q_due, q_goal)
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
    # every start of ``start_guesses`` (a motion through the clearance once more, with more
    # clearance), then the choice among the motions that pass every check (``best_start``).
    # A fixed number of solves at most, each within the iteration budget, so the work
    # stays bounded and the answer deterministic.
    rounds = (count,) if options.num_control_points else (count, count + count // 2)
    repair_limits = dataclasses.replace(limits, clearance_m=limits.clearance_m + options.repair_clearance_m)
    for attempt in rounds:
        failures: list[tuple[str, str, CheckedMotion | None]] = []
        passed: list[tuple[OptimizedTrajectory, CheckedMotion]] = []
        line_guess = fit_bspline(*lines, attempt, rest_ends=True, pins=pins)
        composed = functools.partial(fit_bspline, s_path, q_path, attempt, rest_ends=True, pins=pins)
        for label, guess, duration, first in start_guesses(method, line_guess, composed, limits, solve, path_bounds,
                                                     options.starts, options.fallback_starts, passed):
            solved = first if guess is None else solve(guess, duration, bounds)
            checked = None
            if solved.trajectory is not None and not solved.safety_stopped:
                work["budget_spent"] = solved.budget_spent
                checked = check_motion(result, checker, scene, solved, allowed, limits, options, method)
                if method == "refine" and options.repair_clearance_m > 0 and \
                        (checked.reason or "").startswith("check: collision"):
                    # Through the clearance where the program does not look (between its
                    # samples, or where the followed path lags the motion).
                    repaired = solve(*in_path_fraction(solved.trajectory), bounds, repair_limits)
                    if repaired.trajectory is not None and not repaired.safety_stopped:
                        again = check_motion(result, checker, scene, repaired, allowed, limits, options, method)
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
                failures.append((label, with_iterate(checked.reason, solved), checked))
        if passed:
            solved, checked = best_start(passed, options)
            work["budget_spent"] = solved.budget_spent
            return dataclasses.replace(result, timed=checked.plan, joint_path=checked.followed,
                                       refinement=report("refined", "", solve_time, checked.plan.duration,
                                                         checked.position, checked.rotation, checked.fractions))
    # The last round's failures, in the starts' order: the first as it is, each other one
    # with the start it comes from.
    reason = "; ".join([failures[0][1]] + [f"{START_NAMES[label]}: {text}" for label, text, _ in failures[1:]])
    checked = failures[0][2]
    if checked is None:
        return dataclasses.replace(result, refinement=report("failed", reason, solve_time))
    return dataclasses.replace(result, refinement=report("failed", reason, solve_time, checked.plan.duration,
                                                         checked.position, checked.rotation, checked.fractions))


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
    return optimize_plan(result, checker, scene, options, "refine")
