"""What a closed-loop run did: its joint log, its errors at the critical configurations,
its clearances, as a plain record.

:class:`ClosedLoopResult` is read off a run's Context (``Pipeline.trial_result``) and is
what :mod:`drake_lfd.diagrams.judging` judges; :func:`critical_errors_from_log` measures
each critical configuration's error at its due time from the joint-state log (linear
between the log's samples), by forward kinematics of E, independently of the controller.

:func:`read_trial` reads a run off its Context (the plan, the joint log, the monitor's
records), for the pipeline and for Diagrams composed by hand.

Not for: running a simulation (``closed_loop.py``, ``pipeline.py``) or judging one
(``judging.py``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from pydrake.math import RigidTransform

from drake_lfd.diagrams.collaboration_result import CollaborationRecord
from drake_lfd.diagrams.station import Station
from drake_lfd.planning.replanning import ScheduledPlan
from drake_lfd.robot.initial_ik import InitialConfiguration
from drake_lfd.robot.kinematics import NUM_JOINTS, UR5eKinematics
from drake_lfd.systems.shell_monitor import BoxClearance, ShellMonitor
from drake_lfd.systems.trial_end import plan_end_time_s

__all__ = ["CriticalError", "ClosedLoopResult", "critical_errors_from_log", "pose_errors", "read_trial"]


@dataclass(frozen=True)
class CriticalError:
    """How far E was from con_i when it was due.

    Attributes
    ----------
    con : int
        1-based.
    time_s : float
        Simulation time at which con_i was due.
    position_m, rotation_rad : float
        ``|p_WE(q) - p_con|`` and the angle of ``R_con^T R_WE(q)``; nan if the run
        stopped before.
    q : array, shape (6,)
        Joint positions at that time (nan if not reached).
    reached : bool
        False when the run stopped before ``time_s``.
    """

    con: int
    time_s: float
    position_m: float
    rotation_rad: float
    q: np.ndarray
    reached: bool = True


@dataclass(frozen=True)
class ClosedLoopResult:
    """What a closed-loop run did.

    Attributes
    ----------
    t : array, shape (m,)
        Sample times (s) of the joint-state log (100 Hz by default).
    q, qdot : array, shape (m, 6)
        Measured joint positions (rad) and speeds (rad/s).
    critical_errors : tuple of CriticalError
    clearances : tuple of BoxClearance
        Closest approach to each obstacle and safety shell.
    plan_start_time_s : float
        When the plan started (after settling).
    sim_time_s, wall_time_s : float
        Simulated time and the wall-clock time simulating it.
    setup_wall_time_s : float
        Wall-clock time placing the arm and setting the run up.
    cpu_time_s : float
        The process's CPU time simulating (insensitive to other processes' load).
    stopped_early : bool
        The shell monitor ended the run at a penetration.
    stop_reason : str
    controller : str
    q_initial : array, shape (6,)
    initial_configuration : InitialConfiguration or None
        The inverse-kinematics result when ``q_initial`` was not given.
    X_WB, X_tool0_E : RigidTransform
    velocity_limits : array, shape (6,)
        The UR5e's joint speed limits, rad/s.
    path_constraints : tuple of PathConstraint
        The trial's path constraints (``ConcreteTask.path_constraints``), which
        :func:`~drake_lfd.diagrams.judging.judge_run` checks on the log.
    collaboration : CollaborationRecord or None
        With people in the cell: separation, ``S_p`` and the speed override over the
        run; None without people.
    """

    t: np.ndarray
    q: np.ndarray
    qdot: np.ndarray
    critical_errors: tuple
    clearances: tuple
    plan_start_time_s: float
    sim_time_s: float
    wall_time_s: float
    stopped_early: bool
    stop_reason: str
    controller: str
    q_initial: np.ndarray
    initial_configuration: InitialConfiguration | None
    X_WB: RigidTransform
    X_tool0_E: RigidTransform
    velocity_limits: np.ndarray
    setup_wall_time_s: float = 0.0
    cpu_time_s: float = 0.0
    path_constraints: tuple = ()
    collaboration: CollaborationRecord | None = None

    @property
    def closest_clearance(self) -> BoxClearance | None:
        if not self.clearances:
            return None
        return min(self.clearances, key=lambda c: c.distance_m)

    @property
    def min_shell_distance_m(self) -> float:
        """Minimum signed distance to any obstacle or shell (``inf`` without boxes)."""
        closest = self.closest_clearance
        return math.inf if closest is None else closest.distance_m

    @property
    def min_distance_pair(self) -> tuple[str, str] | None:
        """(robot geometry, box description) of the closest approach."""
        closest = self.closest_clearance
        return None if closest is None else (closest.robot_geometry, closest.describe())

    @property
    def max_joint_speed_fraction(self) -> float:
        """max over samples and joints of ``|qdot| / limit``."""
        if len(self.qdot) == 0:
            return 0.0
        return float(np.max(np.abs(self.qdot) / self.velocity_limits))

    @property
    def realtime_factor(self) -> float:
        return self.sim_time_s / self.wall_time_s if self.wall_time_s > 0 else math.inf

    def trial_fields(self) -> dict:
        """The run's part of a ``simulate --json`` trial (docs/cli.rst), plain Python.

        ``critical_errors``, ``min_shell_distance_m`` (None when the scene has no
        obstacle or shell, or the value is not finite), ``max_joint_speed_fraction``,
        ``t`` and ``q``; with people in the cell, ``collaboration``
        (:meth:`CollaborationRecord.to_json`). Unreached configurations have None errors.
        """

        def number(value):
            return float(value) if math.isfinite(value) else None

        return {
            "critical_errors": [
                {"con": e.con, "position_m": number(e.position_m), "rotation_rad": number(e.rotation_rad)}
                for e in self.critical_errors
            ],
            "min_shell_distance_m": number(self.min_shell_distance_m),
            "max_joint_speed_fraction": self.max_joint_speed_fraction,
            "t": self.t.tolist(),
            "q": self.q.tolist(),
        } | ({} if self.collaboration is None else {"collaboration": self.collaboration.to_json()})


def _pose_errors(X_WE: RigidTransform, X_WE_desired: RigidTransform) -> tuple[float, float]:
    position = float(np.linalg.norm(X_WE.translation() - X_WE_desired.translation()))
    rotation = float(X_WE_desired.rotation().inverse().multiply(X_WE.rotation()).ToAngleAxis().angle())
    return position, rotation


def pose_errors(X_WE: RigidTransform, X_WE_desired: RigidTransform) -> tuple[float, float]:
    """``|p - p_desired|`` (m) and the angle of ``R_desired^T R`` (rad)."""
    position = float(np.linalg.norm(X_WE.translation() - X_WE_desired.translation()))
    rotation = float(X_WE_desired.rotation().inverse().multiply(X_WE.rotation()).ToAngleAxis().angle())
    return position, rotation


def critical_errors_from_log(t: np.ndarray, q: np.ndarray, due_times_s, X_WE_critical, end_time_s: float,
                             kinematics: UR5eKinematics, plant_step_s: float) -> tuple[CriticalError, ...]:
    """Each critical configuration's error when it was due, from a joint-state log.

    ``t`` (m,) and ``q`` (m, 6) are the log; ``due_times_s`` and ``X_WE_critical`` the
    plan's due time and pose of each con; ``end_time_s`` the time the run reached;
    ``plant_step_s`` the discrete plant's step. The joint positions at a due time are the
    plant's state in the Context then (the result of its last step before it), which a
    periodic log reports at the next step's time: the log at that time, linear between
    its samples. A con due after ``end_time_s`` (or after the last sample) was not reached.
    """
    errors = []
    t = np.asarray(t, dtype=float)
    q = np.asarray(q, dtype=float).reshape(-1, NUM_JOINTS)
    for con, (t_due, X_desired) in enumerate(zip(due_times_s, X_WE_critical), start=1):
        t_due = float(t_due)
        if len(t) == 0 or t_due > end_time_s + 1e-9 or t_due > t[-1] + 1e-9:
            nan6 = np.full(NUM_JOINTS, np.nan)
            errors.append(CriticalError(con, t_due, math.nan, math.nan, nan6, reached=False))
            continue
        # The state at t_due is the result of the last step strictly before it, which the
        # log reports at the first step time at or after t_due.
        t_state = math.ceil(t_due / plant_step_s - 1e-9) * plant_step_s
        q_due = np.array([np.interp(t_state, t, q[:, j]) for j in range(NUM_JOINTS)])
        position, rotation = pose_errors(kinematics.X_WE(q_due), X_desired)
        errors.append(CriticalError(con, t_due, position, rotation, q_due))
    return tuple(errors)


def read_trial(context, *, plan: ScheduledPlan, logger, monitor: ShellMonitor, station: Station,
               kinematics: UR5eKinematics | None = None, controller: str = "", stop_reason: str = "",
               wall_time_s: float = 0.0, cpu_time_s: float = 0.0, setup_wall_time_s: float = 0.0,
               initial_configuration: InitialConfiguration | None = None, due_times_s=None,
               path_finished: bool | None = None,
               collaboration: CollaborationRecord | None = None) -> ClosedLoopResult | None:
    """What the run in ``context`` (a root Context) did so far, read off the Context; None
    when ``plan`` (the plan in force) is not a plan.

    ``logger`` is the ``VectorLogSink`` of the station's ``ur5e.state`` (Drake's
    ``LogVectorOutput``), ``monitor`` the ShellMonitor of the scene, ``station`` the
    station; the pipeline's :meth:`~drake_lfd.diagrams.pipeline.Pipeline.trial_result`
    passes its own, and a Diagram composed by hand passes its. The result holds the
    joint log, each critical configuration's error at its due time
    (:func:`critical_errors_from_log`), the closest approach to every obstacle and shell
    (the monitor's records, the logged samples measured too) and the trial's path
    constraints. The Context is not changed. ``controller``, ``stop_reason``, the timings
    and ``initial_configuration`` are what the caller knows of the run. A run whose
    speed was scaled (people in the cell) gives the times its path reached each critical
    configuration (``due_times_s``; by default the plan's), whether the path was
    finished (``path_finished``; by default whether the clock reached the plan's end) and
    its ``collaboration`` record.
    """
    end = plan_end_time_s(plan)
    if end is None:
        return None
    if kinematics is None:
        kinematics = UR5eKinematics(X_WB=station.X_WB, X_tool0_E=station.X_tool0_E)
    log = logger.FindLog(context)
    t = log.sample_times().copy()
    data = log.data()
    q, qdot = data[:NUM_JOINTS].T.copy(), data[NUM_JOINTS:].T.copy()
    now = context.get_time()
    if monitor.measures_log:
        clearances = monitor.clearances_with_log(context, t, q)
    else:
        clearances = monitor.clearances(monitor.GetMyContextFromRoot(context))
    stopped_early = now < end - 1e-9 if path_finished is None else not path_finished
    if stopped_early and not stop_reason:
        stop_reason = f"the run ended at t = {now:.3f} s, before the plan's end at {end:.3f} s"
    # The plant's state now, which the log would report at the next step, ends the
    # samples the errors are read from (a con due at the run's very end).
    h = station.time_step
    t_next = (math.floor(now / h + 1e-9) + 1) * h
    q_now = station.plant.GetPositions(station.plant.GetMyContextFromRoot(context), station.model)
    t_all, q_all = (np.append(t, t_next), np.vstack([q, q_now])) if not len(t) or t_next > t[-1] else (t, q)
    due = plan.due_times_s() if due_times_s is None else due_times_s
    critical_errors = critical_errors_from_log(t_all, q_all, due, plan.timed.X_WE_critical(), now, kinematics, h)
    return ClosedLoopResult(
        t=t, q=q, qdot=qdot, critical_errors=critical_errors, clearances=tuple(clearances),
        plan_start_time_s=plan.start_time_s, sim_time_s=now, wall_time_s=wall_time_s,
        stopped_early=stopped_early, stop_reason=stop_reason, controller=controller,
        q_initial=q[0].copy() if len(q) else np.full(NUM_JOINTS, math.nan),
        initial_configuration=initial_configuration, X_WB=station.X_WB, X_tool0_E=station.X_tool0_E,
        velocity_limits=kinematics.velocity_limits(), setup_wall_time_s=setup_wall_time_s,
        cpu_time_s=cpu_time_s, path_constraints=tuple(plan.result.task.path_constraints),
        collaboration=collaboration)

