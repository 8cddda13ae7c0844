"""Closed-loop UR5e runs on the pipeline Diagram, one Diagram for many trials.

:class:`ClosedLoopRunner` owns one :class:`~drake_lfd.diagrams.pipeline.Pipeline` and one
Simulator and runs trials on them: for each it resets the Context, sets the task input,
lets the planner system plan, puts the arm at rest at the initial configuration (inverse
kinematics of the plan's first pose, elbow up, unless given), holds it for the settling
time, then tracks the plan while the planner watches the task input. The
critical-configuration errors are measured when each configuration is due, from the
simulated joint positions by forward kinematics of E, independently of the controller.
Judging a run against the success criteria is :mod:`drake_lfd.experiments.judging`'s job.

The plant step of a run is 5 ms (a bare station's default is 1 ms). The plant's cost
per step barely depends on the step (SAP's fixed overhead with PD-controlled
actuators), so the step sets the speed, and with PD treated implicitly the accuracy
hardly suffers. Measured on a 10 s plan (``benchmarks/bench_closed_loop.py``):

    plant step            1 ms      2 ms      4 ms      5 ms
    real-time factor      3.0-3.8x  5-7x      9-10x     10-14x
    path error max / rms  1.15/0.16 1.20/0.17 1.27/0.23 1.34/0.20 mm
    at critical configs   0.03      0.07      0.04      0.09 mm (< 0.003 deg)

against the success tolerances of 5 mm and 2 deg. 5 ms divides the 10 ms periods of the
drive's command sampling, the monitor and the logger, so their events fall on plant steps.

Not for: building the Diagram (``pipeline.py``), planning (``planning/``), the drive
(``station.py``), the controller's maths (``systems/differential_ik.py``).
"""

from __future__ import annotations

import copy
import math
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Sequence

import numpy as np
from pydrake.geometry import Meshcat
from pydrake.math import RigidTransform
from pydrake.systems.analysis import Simulator

from drake_lfd.core.dual_quaternion import dual_quaternion_from_rigid_transform, dual_quaternion_sclerp
from drake_lfd.core.tasks import ConcreteTask
from drake_lfd.core.timing import TimedPlan, time_plan
from drake_lfd.io.simulation_config import PipelineConfig
from drake_lfd.diagrams.pipeline import Pipeline, build_pipeline
from drake_lfd.diagrams.recording_meshcat import recording_meshcat
from drake_lfd.io.atomic_files import atomic_write_bytes
from drake_lfd.planning.replanning import ScheduledPlan
from drake_lfd.diagrams.plan_markers import draw_plan
from drake_lfd.robot.initial_ik import InitialConfiguration, solve_initial_configuration
from drake_lfd.robot.kinematics import NUM_JOINTS, UR5eKinematics
from drake_lfd.robot.scene import KinematicScene
from drake_lfd.systems.joint_trajectory_controller import joint_path_of_plan
from drake_lfd.systems.shell_monitor import BoxClearance

# The controller of runs whose task changes while the arm moves (replanning).
TASK_SPACE_METHOD = "drake"

__all__ = [
    "CriticalError",
    "ClosedLoopResult",
    "ClosedLoopRunner",
    "plan_through_joint_configurations",
    "run_closed_loop",
]


def plan_through_joint_configurations(
    q_critical,
    *,
    X_WB: RigidTransform | None = None,
    X_tool0_E: RigidTransform | None = None,
    samples_per_span: int = 20,
    **timing_options,
) -> TimedPlan:
    """A timed plan whose critical configurations are the poses of E at ``q_critical``.

    Consecutive poses are joined by ScLERP (a straight screw motion of E) and timed by
    :func:`drake_lfd.core.timing.time_plan`. For tests, benchmarks and trying the closed loop
    without a planner: every critical configuration is reachable by construction
    (the path between them need not be).

    Parameters
    ----------
    q_critical : array-like, shape (n, 6)
        Joint configurations, n >= 2.
    samples_per_span : int
        Poses per span (excluding its start).
    **timing_options
        ``max_speed_m_s``, ``max_angular_speed_rad_s``.
    """
    kinematics = UR5eKinematics(
        X_WB=RigidTransform() if X_WB is None else X_WB,
        X_tool0_E=RigidTransform() if X_tool0_E is None else X_tool0_E,
    )
    D = [dual_quaternion_from_rigid_transform(kinematics.X_WE(q)) for q in np.atleast_2d(q_critical)]
    poses, critical = [D[0]], [0]
    s = np.linspace(0.0, 1.0, samples_per_span + 1)[1:]
    for D_from, D_to in zip(D[:-1], D[1:]):
        poses.extend(dual_quaternion_sclerp(D_from, D_to, s))
        critical.append(len(poses) - 1)
    return time_plan(np.array(poses), critical, **timing_options)


# ------------------------------------------------------------------------------ results


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
        ``t`` and ``q``. Unreached configurations have None errors.
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
        }


def _pose_errors(X_WE: RigidTransform, X_WE_desired: RigidTransform) -> tuple[float, float]:
    position = float(np.linalg.norm(X_WE.translation() - X_WE_desired.translation()))
    rotation = float(X_WE_desired.rotation().inverse().multiply(X_WE.rotation()).ToAngleAxis().angle())
    return position, rotation


class ClosedLoopRunner:
    """Runs closed-loop trials on one pipeline Diagram and one Simulator.

    Parameters
    ----------
    pipeline : Pipeline
    record_meshcat : Meshcat, optional
        The Meshcat the pipeline was built with, if any; a run asked to record writes
        its replay from it.
    """

    def __init__(self, pipeline: Pipeline, *, record_meshcat: Meshcat | None = None):
        self.pipeline = pipeline
        self.meshcat = record_meshcat
        self.simulator = Simulator(pipeline)
        station = pipeline.station
        self.kinematics = UR5eKinematics(X_WB=station.X_WB, X_tool0_E=station.X_tool0_E)
        # The collision scene of the initial inverse kinematics, built once for all trials.
        self._ik_scene = KinematicScene(station.workcell)
        self._velocity_limits = station.plant.GetVelocityUpperLimits()[:NUM_JOINTS].copy()
        self._task_space: ClosedLoopRunner | None = None

    def _task_space_runner(self) -> "ClosedLoopRunner":
        """A runner on a sibling pipeline with the Python task-space controller (made once)."""
        if self._task_space is None:
            self._task_space = ClosedLoopRunner(self.pipeline.with_controller(TASK_SPACE_METHOD),
                                                record_meshcat=self.meshcat)
        return self._task_space

    def plan(self, task: ConcreteTask | None = None) -> ScheduledPlan:
        """Resets the Context, sets the task and plans it (what :meth:`run` starts with)."""
        pipeline = self.pipeline
        context = self.simulator.get_mutable_context()
        pipeline.SetDefaultContext(context)
        context.SetTime(0.0)
        if pipeline.planner is None:
            return pipeline.plan_output_port.Eval(context)
        if task is None:
            raise ValueError("this pipeline plans: give it a task")
        pipeline.task_input_port.FixValue(context, task)
        return pipeline.planner.plan_now(context)

    def run(
        self,
        task: ConcreteTask | None = None,
        *,
        q_initial: np.ndarray | None = None,
        record_html: str | Path | None = None,
        scheduled: ScheduledPlan | None = None,
        task_changes: Sequence[tuple[float, ConcreteTask]] = (),
    ) -> tuple[ScheduledPlan, "ClosedLoopResult | None"]:
        """Plans ``task`` and, when it planned, simulates it.

        Parameters
        ----------
        task : ConcreteTask, optional
            Required unless the pipeline was built with a given plan.
        q_initial : array, shape (6,), optional
            Initial joint positions; when absent, the start of the plan's checked joint
            path, or (a plan made without the check) inverse kinematics of the plan's
            first pose, elbow up (raises ``UnreachableConfigurationError``, an
            InputError, if unreachable).
        record_html : path, optional
            Write a self-contained Meshcat replay there (needs ``record_meshcat``).
        scheduled : ScheduledPlan, optional
            The result of :meth:`plan` just called (skips planning again).
        task_changes : sequence of (time_s, ConcreteTask)
            The task input changes to each task at its simulation time (for example the
            cup to pour into was moved); the planner system replans from where the arm
            is, and the run follows the plan in force.

        Returns
        -------
        scheduled : ScheduledPlan
            The plan at the end of the run (after any replanning).
        result : ClosedLoopResult or None
            None when nothing was planned.
        """
        if task_changes and self.pipeline.compiled:
            # Replanning during a run: the plan in force changes inside the Diagram, which
            # the Python controller follows from the plan port (the compiled one tracks a
            # joint path set before the run).
            return self._task_space_runner().run(task, q_initial=q_initial, record_html=record_html,
                                                 task_changes=task_changes)
        setup_start = time.perf_counter()
        pipeline, station, simulator = self.pipeline, self.pipeline.station, self.simulator
        if scheduled is None:
            scheduled = self.plan(task)
        if scheduled is None or not scheduled.planned:
            return scheduled, None
        context = simulator.get_mutable_context()
        initial_configuration = None
        joint_path = scheduled.result.joint_path
        if q_initial is None and joint_path is not None:
            # The plan-time check chose the start (IK branch and windings) for the whole
            # plan: start where its joint path starts.
            q_initial = joint_path.q[0]
        if q_initial is None:
            initial_configuration = solve_initial_configuration(
                scheduled.X_WE_desired(0.0), X_WB=station.X_WB, X_tool0_E=station.X_tool0_E,
                obstacles=station.obstacles, safety_shells=station.safety_shells, scene=self._ik_scene)
            q_initial = initial_configuration.q
        q_initial = np.asarray(q_initial, dtype=float)
        station.set_initial_positions(context, q_initial)
        if pipeline.compiled:
            pipeline.controller.set_path(context, *joint_path_of_plan(scheduled, q_initial, pipeline.law))
            pipeline.controller.set_initial_command(context, q_initial)
        pipeline.logger.FindMutableLog(context).Clear()
        visualizer = station.visualizer
        recording = record_html is not None and visualizer is not None
        if self.meshcat is not None:
            draw_plan(self.meshcat, scheduled.timed)  # the planned path and the critical configurations
        if recording:
            X_critical = [scheduled.timed.X_WE_list()[i] for i in scheduled.timed.critical_indices]
            target = 0.5 * (station.X_WB.translation() + np.mean([X.translation() for X in X_critical], axis=0))
            self.meshcat.SetCameraPose(camera_in_world=target + [0.9, -1.0, 0.55], target_in_world=target)
            visualizer.DeleteRecording()
            visualizer.StartRecording(set_transforms_while_recording=False)
        simulator.Initialize()  # setup, as the bare station's in bench_pipeline.py
        setup_wall_time_s = time.perf_counter() - setup_start

        wall_start, cpu_start = time.perf_counter(), time.process_time()
        plant, model = station.plant, station.model
        plant_context = plant.GetMyContextFromRoot(context)
        stopped_early, stop_reason = False, ""
        critical_errors = []
        num_cons = len(scheduled.timed.critical_indices)
        changes = sorted(task_changes, key=lambda change: change[0])
        for con in range(1, num_cons + 1):
            # The planner may replan while the arm moves: advance until the due time
            # of this configuration in the plan in force no longer moves.
            t_due = float(scheduled.due_times_s()[con - 1])
            while not stopped_early:
                scheduled = pipeline.plan_output_port.Eval(context)
                t_due = float(scheduled.due_times_s()[con - 1])
                if changes and changes[0][0] <= min(t_due, context.get_time()) + 1e-12:
                    pipeline.task_input_port.FixValue(context, changes.pop(0)[1])
                    continue
                if context.get_time() >= t_due - 1e-12:
                    break
                target = min(t_due, changes[0][0]) if changes else t_due
                status = simulator.AdvanceTo(target)
                if status.reason() == status.ReturnReason.kReachedTerminationCondition:
                    stopped_early, stop_reason = True, status.message()
            if stopped_early:
                nan6 = np.full(NUM_JOINTS, np.nan)
                critical_errors.append(CriticalError(con, t_due, math.nan, math.nan, nan6, reached=False))
                continue
            X_WE_desired = scheduled.timed.X_WE_critical()[con - 1]  # the plan's pose of con_i
            q = plant.GetPositions(plant_context, model).copy()
            position, rotation = _pose_errors(self.kinematics.X_WE(q), X_WE_desired)
            critical_errors.append(CriticalError(con, t_due, position, rotation, q))
        if pipeline.monitor.measures_log:
            # The shell monitor measures the run's joint-state log, in one batch.
            log = pipeline.logger.GetLog(pipeline.logger.GetMyContextFromRoot(context))
            pipeline.monitor.measure_log(context, log.sample_times(), log.data()[:NUM_JOINTS].T)
        wall_time_s, cpu_time_s = time.perf_counter() - wall_start, time.process_time() - cpu_start
        scheduled = pipeline.plan_output_port.Eval(context)

        if recording:
            visualizer.StopRecording()
            visualizer.PublishRecording()
            atomic_write_bytes(Path(record_html), self.meshcat.StaticHtml().encode())

        log = pipeline.logger.FindLog(context)
        data = log.data()
        monitor = pipeline.monitor
        return scheduled, ClosedLoopResult(
            t=log.sample_times().copy(),
            q=data[:NUM_JOINTS].T.copy(),
            qdot=data[NUM_JOINTS:].T.copy(),
            critical_errors=tuple(critical_errors),
            clearances=tuple(monitor.clearances(monitor.GetMyContextFromRoot(context))),
            plan_start_time_s=scheduled.start_time_s,
            sim_time_s=context.get_time(),
            wall_time_s=wall_time_s,
            stopped_early=stopped_early,
            stop_reason=stop_reason,
            controller=pipeline.config.controller.method,
            q_initial=q_initial,
            initial_configuration=initial_configuration,
            X_WB=station.X_WB,
            X_tool0_E=station.X_tool0_E,
            velocity_limits=self._velocity_limits,
            setup_wall_time_s=setup_wall_time_s,
            cpu_time_s=cpu_time_s,
        )


def run_closed_loop(
    plan: TimedPlan,
    *,
    X_WB: RigidTransform | None = None,
    X_tool0_E: RigidTransform | None = None,
    obstacles=(),
    safety_shells=(),
    table: bool = False,
    tool=None,
    q_initial: np.ndarray | None = None,
    record_html: str | Path | None = None,
    config: PipelineConfig | None = None,
    controller: str | None = None,
    time_step: float | None = None,
    stop_on_penetration: bool | None = None,
) -> ClosedLoopResult:
    """Simulates the UR5e tracking a given ``plan`` (no planner) in its scene.

    Builds a pipeline with the plan as a constant source (``table``: put the table under
    the robot; ``tool``: the shapes on ``tool0``, None for the default of ``X_tool0_E``)
    and runs it once; see :meth:`ClosedLoopRunner.run`. ``controller``
    (method), ``time_step`` (plant step) and ``stop_on_penetration`` override ``config``.
    """
    config = PipelineConfig() if config is None else copy.deepcopy(config)
    if controller is not None:
        config.controller.method = controller
    if time_step is not None:
        config.station.time_step = float(time_step)
    if stop_on_penetration is not None:
        config.monitor.stop_on_penetration = bool(stop_on_penetration)
    meshcat = recording_meshcat() if record_html is not None else None
    pipeline = build_pipeline(plan=plan, X_WB=X_WB, X_tool0_E=X_tool0_E, obstacles=obstacles,
                              safety_shells=safety_shells, tool=tool, with_table=table, config=config,
                              meshcat=meshcat)
    _, result = ClosedLoopRunner(pipeline, record_meshcat=meshcat).run(q_initial=q_initial, record_html=record_html)
    return result
