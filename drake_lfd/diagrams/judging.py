"""Whether a closed-loop run succeeded, and if not, why (the success criteria).

A run succeeds when every critical configuration is reached within 5 mm and 2 deg when
it is due, the task's path constraints hold along the logged motion, no robot geometry
penetrates an obstacle or a safety shell, and the joints stay inside their position and
speed limits (docs/method.rst, Closed loop and success). :func:`judge_run` returns the
verdict with one record per failed criterion (``core/failures.py``: its kind and its line).

Not for: running the simulation (``pipeline.py``, ``closed_loop.py``) or the run's record
(``trial_result.py``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

from drake_lfd.core.failures import Failure
from drake_lfd.diagrams.trial_result import ClosedLoopResult
from drake_lfd.robot.path_constraints import constraint_rotation, describe_constraint, orientation_deviations
from drake_lfd.robot.kinematics import UR5E_JOINT_NAMES, UR5eKinematics

__all__ = ["RunJudgement", "judge_run", "SUCCESS_POSITION_TOLERANCE_M", "SUCCESS_ROTATION_TOLERANCE_RAD",
           "SUCCESS_SINGULARITY_MARGIN"]

SUCCESS_POSITION_TOLERANCE_M = 0.005
SUCCESS_ROTATION_TOLERANCE_RAD = math.radians(2.0)
SUCCESS_SINGULARITY_MARGIN = 0.05


@dataclass(frozen=True)
class RunJudgement:
    """The verdict: ``success`` and one :class:`~drake_lfd.core.failures.Failure` per failed
    criterion (its line, with its kind)."""

    success: bool
    failures: list = field(default_factory=list)


def judge_run(
    result: ClosedLoopResult,
    *,
    joint_limits: tuple[np.ndarray, np.ndarray] | None = None,
    velocity_limits: np.ndarray | None = None,
    path_constraints: Sequence | None = None,
    position_tolerance_m: float = SUCCESS_POSITION_TOLERANCE_M,
    rotation_tolerance_rad: float = SUCCESS_ROTATION_TOLERANCE_RAD,
    singularity_margin: float = SUCCESS_SINGULARITY_MARGIN,
    kinematics: UR5eKinematics | None = None,
) -> RunJudgement:
    """Checks a run against the success criteria.

    - each critical configuration reached within ``position_tolerance_m`` (5 mm) and
      ``rotation_tolerance_rad`` (2 deg) when due;
    - every path constraint (``tasks.PathConstraint``: tool orientation within
      ``tolerance_rad`` of ``euler_zyx`` from con_from to con_to) holds on the log;
    - no robot geometry penetrates an obstacle or a safety shell (min distance > 0);
    - joint positions inside ``joint_limits`` and speeds inside ``velocity_limits``
      (the UR5e's, by default) at every logged sample;
    - with people in the cell (``result.collaboration``), the robot never moved toward
      a person (``v_r`` above the record's threshold) closer than ISO/TS 15066's
      protective separation distance ``S_p``;
    - the elbow and the wrist keep ``singularity_margin`` (0.05) from their
      singularities at every logged sample: ``|sin q3|`` (elbow straight) and
      ``|sin q5|`` (wrist aligned) stay at or above it; a run through a singularity is
      not a success even when it ends at the right pose.

    ``path_constraints``: by default the run's own (``result.path_constraints``, the
    trial's), as ``simulate`` judges them; pass others to judge against those instead.
    ``kinematics``: the run's (its ``X_WB`` and ``X_tool0_E``), to save building one per
    run; by default made from the result's frames.

    Returns
    -------
    RunJudgement
    """
    if path_constraints is None:
        path_constraints = result.path_constraints
    if kinematics is None:
        kinematics = UR5eKinematics(X_WB=result.X_WB, X_tool0_E=result.X_tool0_E)
    if joint_limits is None:
        joint_limits = kinematics.position_limits()
    if velocity_limits is None:
        velocity_limits = kinematics.velocity_limits()
    lower, upper = (np.asarray(v, dtype=float) for v in joint_limits)
    velocity_limits = np.asarray(velocity_limits, dtype=float)
    failures = []

    for error in result.critical_errors:
        if not error.reached:
            failures.append(Failure(
                "not_reached", f"con_{error.con}: not reached (the run stopped at t = {result.sim_time_s:.2f} s: "
                f"{result.stop_reason})", configuration=error.con))
            continue
        if not error.position_m <= position_tolerance_m:
            failures.append(Failure(
                "position_error", f"con_{error.con}: position error {1000 * error.position_m:.1f} mm > "
                f"{1000 * position_tolerance_m:g} mm (t = {error.time_s:.2f} s)", configuration=error.con))
        if not error.rotation_rad <= rotation_tolerance_rad:
            failures.append(Failure(
                "rotation_error", f"con_{error.con}: rotation error {math.degrees(error.rotation_rad):.2f} deg > "
                f"{math.degrees(rotation_tolerance_rad):g} deg (t = {error.time_s:.2f} s)", configuration=error.con))

    due = [error.time_s for error in result.critical_errors]
    for constraint in path_constraints:
        t_from, t_to = due[constraint.con_from - 1], due[constraint.con_to - 1]
        window = (result.t >= t_from - 1e-9) & (result.t <= t_to + 1e-9)
        if not np.any(window):
            continue
        R_WE = np.array([kinematics.X_WE(q).rotation().matrix() for q in result.q[window]])
        angles = orientation_deviations(R_WE, constraint_rotation(constraint))
        worst = int(np.argmax(angles))
        if angles[worst] > constraint.tolerance_rad:
            failures.append(Failure(
                "path_constraint",
                f"{describe_constraint(constraint)}: tool orientation "
                f"{math.degrees(angles[worst]):.1f} deg from euler_zyx "
                f"{np.round(constraint.euler_zyx, 4).tolist()} > {math.degrees(constraint.tolerance_rad):g} deg "
                f"(t = {result.t[window][worst]:.2f} s)", configuration=constraint.con_from))

    for clearance in result.clearances:
        if not clearance.distance_m > 0.0:
            failures.append(Failure(
                "penetration", f"{clearance.describe()} penetrated by {clearance.robot_geometry} "
                f"(signed distance {1000 * clearance.distance_m:.1f} mm at t = {clearance.time_s:.2f} s)"))

    for j, name in enumerate(UR5E_JOINT_NAMES):
        if len(result.q) == 0:
            break
        outside = (result.q[:, j] < lower[j]) | (result.q[:, j] > upper[j])
        if np.any(outside):
            k = int(np.argmax(outside))
            failures.append(Failure(
                "joint_position_limit", f"{name}: position {result.q[k, j]:.3f} rad outside "
                f"[{lower[j]:.3f}, {upper[j]:.3f}] (t = {result.t[k]:.2f} s)"))
        speeds = np.abs(result.qdot[:, j])
        k = int(np.argmax(speeds))
        if speeds[k] > velocity_limits[j]:
            failures.append(Failure(
                "joint_speed_limit", f"{name}: speed {speeds[k]:.2f} rad/s > limit {velocity_limits[j]:.2f} rad/s "
                f"(t = {result.t[k]:.2f} s)"))
    record = result.collaboration
    if record is not None and record.violation_count:
        failures.append(Failure(
            "separation",
            f"separation: the robot moved toward a person closer than the protective separation distance S_p "
            f"in {record.violation_count} sample(s) (first at t = {record.first_violation_s():.2f} s; "
            f"least margin {1000 * record.min_margin_m:.0f} mm)"))
    if len(result.q):
        for j, what in ((2, "elbow straight (|sin q3|"), (4, "wrist aligned (|sin q5|")):
            margin = np.abs(np.sin(result.q[:, j]))
            k = int(np.argmin(margin))
            if margin[k] < singularity_margin:
                failures.append(Failure("singularity", f"singularity: {what} = {margin[k]:.3f} < "
                                        f"{singularity_margin:g} at t = {result.t[k]:.2f} s)"))
    return RunJudgement(success=not failures, failures=failures)
