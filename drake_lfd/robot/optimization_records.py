"""The trajectory program's inputs and its answer: limits, work budget, pose targets and bounds, result.

:func:`~drake_lfd.robot.trajectory_optimization.optimize_joint_trajectory` takes
:class:`TrajectoryLimits` (what the motion keeps to), :class:`SolverBudget` (how much
work SNOPT may spend, in iteration counts), :class:`PoseTarget` and :class:`PoseBound`
(where E must be at given path fractions) and answers an :class:`OptimizedTrajectory`.
Every number of the inputs is part of the program's exact key: a scene's remembered
solution answers only a program with the same bits.

Not for: building or solving the program (``trajectory_optimization.py``).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.trajectories import BsplineTrajectory

from drake_lfd.core.timing import TimingLimits

__all__ = ["TrajectoryLimits", "SolverBudget", "PoseTarget", "PoseBound", "OptimizedTrajectory"]


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
    :func:`~drake_lfd.robot.trajectory_constraints.add_rotation_target`); with
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
