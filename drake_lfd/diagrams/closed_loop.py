"""A closed-loop UR5e run of a timed plan, and the judgement of it (SPEC 9).

:func:`build_closed_loop` wires the stages in pipeline order, one ``Connect`` per arrow::

    PlanTrajectorySource --X_WE_desired, V_WE_desired--> DifferentialIKController
    DifferentialIKController --q_command--> station (ur5e.position_command)
    station (ur5e.position_measured) --q_measured--> DifferentialIKController
    station (query_object) --> ShellMonitor
    station (ur5e.state) --> logger (100 Hz)

:func:`run_closed_loop` simulates it: the arm starts at rest at the initial configuration
(inverse kinematics of the plan's first pose unless given), holds it for ``settle_s``,
then tracks the plan. The critical-configuration errors are measured at the time each
configuration is due, from the simulated joint positions by forward kinematics of E,
independently of the controller. :func:`judge_run` applies SPEC 9's criteria.

The plant step of a run is 5 ms (the station's own default is 1 ms). The plant's cost
per step barely depends on the step (about 170-230 us with PD-controlled actuators, SAP's
fixed overhead), so the step sets the speed, and with PD treated implicitly the accuracy
hardly suffers. Measured on a 10 s plan (``benchmarks/bench_closed_loop.py``):

    plant step            1 ms      2 ms      4 ms      5 ms
    real-time factor      3.0-3.8x  5-7x      9-10x     10-14x
    path error max / rms  1.15/0.16 1.20/0.17 1.27/0.23 1.34/0.20 mm
    at critical configs   0.03      0.07      0.04      0.09 mm (< 0.003 deg)

against SPEC 9's 5 mm / 2 deg tolerances. 5 ms divides the 10 ms periods of the drive's
command sampling, the monitor and the logger, so their events fall on plant steps.

Not for: planning (the planners), the drive (``station.py``), the controller's maths
(``differential_ik.py``).
"""

from __future__ import annotations

import math
import time
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from pydrake.geometry import Meshcat
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import Diagram, DiagramBuilder
from pydrake.systems.primitives import LogVectorOutput, VectorLogSink

from drake_lfd.systems.differential_ik import DifferentialIKController
from drake_lfd.core.dual_quaternion import (
    dual_quaternion_from_rigid_transform,
    dual_quaternion_sclerp,
    rigid_transform_from_dual_quaternion,
)
from drake_lfd.robot.initial_ik import InitialConfiguration, solve_initial_configuration
from drake_lfd.robot.kinematics import END_EFFECTOR_FRAME_NAME, NUM_JOINTS, UR5E_JOINT_NAMES, shared_kinematics
from drake_lfd.systems.plan_trajectory_source import PlanTrajectorySource
from drake_lfd.systems.shell_monitor import BoxClearance, ShellMonitor
from drake_lfd.diagrams.station import Station, build_station
from drake_lfd.io.task_files import Box, rigid_transform_from_euler_zyx
from drake_lfd.core.timing import TimedPlan, time_plan

DEFAULT_SETTLE_S = 0.5
# The plant step of a closed-loop run (see run_closed_loop: measured accuracy vs speed).
DEFAULT_CLOSED_LOOP_TIME_STEP_S = 0.005
DEFAULT_LOG_PERIOD_S = 0.01
DEFAULT_IK_TIME_STEP_S = 0.01
DEFAULT_MONITOR_PERIOD_S = 0.01
POSITION_TOLERANCE_M = 0.005
ROTATION_TOLERANCE_RAD = math.radians(2.0)


@dataclass
class ClosedLoop:
    """The closed-loop diagram and its parts."""

    diagram: Diagram
    station: Station
    source: PlanTrajectorySource
    controller: DifferentialIKController
    monitor: ShellMonitor
    logger: VectorLogSink


def build_closed_loop(
    plan: TimedPlan,
    *,
    X_WB: RigidTransform | None = None,
    X_tool0_E: RigidTransform | None = None,
    obstacles: Iterable[Box] = (),
    safety_shells: Iterable[Box] = (),
    table: Box | None = None,
    plan_start_time_s: float = 0.0,
    controller: str = "drake",
    time_step: float = DEFAULT_CLOSED_LOOP_TIME_STEP_S,
    ik_time_step: float = DEFAULT_IK_TIME_STEP_S,
    monitor_period: float = DEFAULT_MONITOR_PERIOD_S,
    log_period: float = DEFAULT_LOG_PERIOD_S,
    stop_on_penetration: bool = False,
    meshcat: Meshcat | None = None,
    controller_options: dict | None = None,
) -> ClosedLoop:
    """The station, the plan source, the controller, the monitor and a logger, wired.

    Parameters
    ----------
    plan : TimedPlan
    X_WB, X_tool0_E : RigidTransform, optional
    obstacles, safety_shells : iterable of Box
    table : Box, optional
    plan_start_time_s : float
        Simulation time at which the plan starts (the settling time).
    controller : {"drake", "pseudo_inverse"}
        The differential-IK method.
    time_step : float
        The plant's discrete step, s.
    ik_time_step : float
        The controller's period, s (also the drive's command period).
    monitor_period, log_period : float
        Shell monitor and joint-state logger periods, s.
    stop_on_penetration : bool
        End the run at the first penetration.
    meshcat : Meshcat, optional
    controller_options : dict, optional
        More keyword arguments for :class:`DifferentialIKController`.
    """
    station = build_station(
        X_WB=X_WB,
        X_tool0_E=X_tool0_E,
        obstacles=obstacles,
        safety_shells=safety_shells,
        table=table,
        meshcat=meshcat,
        time_step=time_step,
        command_period=ik_time_step,
    )
    builder = DiagramBuilder()
    builder.AddNamedSystem("station", station.diagram)
    source = builder.AddNamedSystem("plan", PlanTrajectorySource(plan=plan, start_time_s=plan_start_time_s))
    ik = builder.AddNamedSystem(
        "differential_ik",
        DifferentialIKController(
            plant=station.controller_plant,
            model=station.controller_model,
            frame_E=station.controller_plant.GetFrameByName(END_EFFECTOR_FRAME_NAME),
            time_step=ik_time_step,
            method=controller,
            **(controller_options or {}),
        ),
    )
    scene = station.scene
    monitor = builder.AddNamedSystem(
        "shell_monitor",
        ShellMonitor(
            plant=station.plant,
            robot_geometry_ids=scene.robot_geometry_ids,
            shell_geometry_ids=scene.keep_out_geometry_ids,
            period=monitor_period,
            stop_on_penetration=stop_on_penetration,
            names=scene.names,
            kinds=scene.kinds,
        ),
    )
    builder.Connect(source.X_WE_desired_output_port, ik.X_WE_desired_input_port)
    builder.Connect(source.V_WE_desired_output_port, ik.V_WE_desired_input_port)
    builder.Connect(ik.q_command_output_port, station.GetInputPort("position_command"))
    builder.Connect(station.GetOutputPort("position_measured"), ik.q_measured_input_port)
    builder.Connect(station.GetOutputPort("query_object"), monitor.query_object_input_port)
    logger = LogVectorOutput(station.GetOutputPort("state"), builder, log_period)
    logger.set_name("joint_state_logger")
    builder.ExportOutput(monitor.min_distance_output_port, "min_distance")
    diagram = builder.Build()
    diagram.set_name("closed_loop")
    return ClosedLoop(diagram=diagram, station=station, source=source, controller=ik, monitor=monitor, logger=logger)


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
    kinematics = shared_kinematics(
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
        """The run's part of a ``simulate --json`` trial (INTERFACES.md), plain Python.

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


def run_closed_loop(
    plan: TimedPlan,
    *,
    X_WB: RigidTransform | None = None,
    X_tool0_E: RigidTransform | None = None,
    obstacles: Iterable[Box] = (),
    safety_shells: Iterable[Box] = (),
    table: Box | None = None,
    q_initial: np.ndarray | None = None,
    settle_s: float = DEFAULT_SETTLE_S,
    meshcat: Meshcat | None = None,
    record_html: str | Path | None = None,
    controller: str = "drake",
    time_step: float = DEFAULT_CLOSED_LOOP_TIME_STEP_S,
    ik_time_step: float = DEFAULT_IK_TIME_STEP_S,
    stop_on_penetration: bool = False,
    controller_options: dict | None = None,
) -> ClosedLoopResult:
    """Simulates the UR5e tracking ``plan`` in the scene; see the module docstring.

    Parameters
    ----------
    plan : TimedPlan
    X_WB, X_tool0_E : RigidTransform, optional
    obstacles, safety_shells : iterable of Box
    table : Box, optional
    q_initial : array, shape (6,), optional
        Initial joint positions; inverse kinematics of the plan's first pose (elbow up)
        when absent (raises ``UnreachableConfigurationError`` if unreachable).
    settle_s : float
        Time at rest before the plan starts, s.
    meshcat : Meshcat, optional
        Visualise (and record, with ``record_html``) in this Meshcat.
    record_html : path, optional
        Write a self-contained Meshcat HTML replay of the run there (a Meshcat is
        created if none is given).
    controller : {"drake", "pseudo_inverse"}
    time_step, ik_time_step : float
        Plant step and controller period, s (see the module docstring for the choice).
    stop_on_penetration : bool
        End the run at the first penetration of an obstacle or shell.
    controller_options : dict, optional
        More keyword arguments for :class:`DifferentialIKController`.

    Returns
    -------
    ClosedLoopResult
    """
    setup_start = time.perf_counter()
    X_WB = RigidTransform() if X_WB is None else RigidTransform(X_WB)
    X_tool0_E = RigidTransform() if X_tool0_E is None else RigidTransform(X_tool0_E)
    obstacles, safety_shells = tuple(obstacles), tuple(safety_shells)
    X_WE_critical = [rigid_transform_from_dual_quaternion(plan.poses[i]) for i in plan.critical_indices]

    initial_configuration = None
    if q_initial is None:
        initial_configuration = solve_initial_configuration(
            X_WE_critical[0], X_WB=X_WB, X_tool0_E=X_tool0_E, obstacles=obstacles, safety_shells=safety_shells
        )
        q_initial = initial_configuration.q
    q_initial = np.asarray(q_initial, dtype=float)

    if record_html is not None and meshcat is None:
        meshcat = Meshcat()
    loop = build_closed_loop(
        plan,
        X_WB=X_WB,
        X_tool0_E=X_tool0_E,
        obstacles=obstacles,
        safety_shells=safety_shells,
        table=table,
        plan_start_time_s=settle_s,
        controller=controller,
        time_step=time_step,
        ik_time_step=ik_time_step,
        stop_on_penetration=stop_on_penetration,
        meshcat=meshcat,
        controller_options=controller_options,
    )
    station = loop.station
    simulator = Simulator(loop.diagram)
    context = simulator.get_mutable_context()
    station.set_initial_positions(context, q_initial)
    plant, model = station.plant, station.model
    plant_context = plant.GetMyContextFromRoot(context)
    visualizer = station.visualizer
    if meshcat is not None:
        # Look at the middle of the robot's base and the work, from the front right.
        target = 0.5 * (X_WB.translation() + np.mean([X.translation() for X in X_WE_critical], axis=0))
        meshcat.SetCameraPose(camera_in_world=target + [0.9, -1.0, 0.55], target_in_world=target)
    if visualizer is not None and record_html is not None:
        visualizer.StartRecording(set_transforms_while_recording=False)
    setup_wall_time_s = time.perf_counter() - setup_start

    kinematics = shared_kinematics(X_WB=X_WB, X_tool0_E=X_tool0_E)
    due_times = [settle_s + float(plan.times[i]) for i in plan.critical_indices]
    stopped_early, stop_reason = False, ""
    critical_errors = []
    wall_start = time.perf_counter()
    simulator.Initialize()
    for con, (t_due, X_WE_desired) in enumerate(zip(due_times, X_WE_critical), start=1):
        if not stopped_early:
            status = simulator.AdvanceTo(t_due)
            if status.reason() == status.ReturnReason.kReachedTerminationCondition:
                stopped_early, stop_reason = True, status.message()
        if stopped_early:
            nan6 = np.full(NUM_JOINTS, np.nan)
            critical_errors.append(CriticalError(con, t_due, math.nan, math.nan, nan6, reached=False))
            continue
        q = plant.GetPositions(plant_context, model).copy()
        position, rotation = _pose_errors(kinematics.X_WE(q), X_WE_desired)
        critical_errors.append(CriticalError(con, t_due, position, rotation, q))
    wall_time_s = time.perf_counter() - wall_start
    sim_time_s = context.get_time()

    if visualizer is not None and record_html is not None:
        visualizer.StopRecording()
        visualizer.PublishRecording()
        Path(record_html).write_text(meshcat.StaticHtml())

    log = loop.logger.FindLog(context)
    data = log.data()
    return ClosedLoopResult(
        t=log.sample_times().copy(),
        q=data[:NUM_JOINTS].T.copy(),
        qdot=data[NUM_JOINTS:].T.copy(),
        critical_errors=tuple(critical_errors),
        clearances=tuple(loop.monitor.clearances(loop.monitor.GetMyContextFromRoot(context))),
        plan_start_time_s=settle_s,
        sim_time_s=sim_time_s,
        wall_time_s=wall_time_s,
        stopped_early=stopped_early,
        stop_reason=stop_reason,
        controller=controller,
        q_initial=q_initial,
        initial_configuration=initial_configuration,
        X_WB=X_WB,
        X_tool0_E=X_tool0_E,
        velocity_limits=plant.GetVelocityUpperLimits()[: NUM_JOINTS].copy(),
        setup_wall_time_s=setup_wall_time_s,
    )


# ------------------------------------------------------------------------------ judging


@dataclass(frozen=True)
class RunJudgement:
    """SPEC 9's verdict: ``success`` and one line per failed criterion."""

    success: bool
    failures: list = field(default_factory=list)


def judge_run(
    result: ClosedLoopResult,
    plan: TimedPlan,
    *,
    joint_limits: tuple[np.ndarray, np.ndarray] | None = None,
    velocity_limits: np.ndarray | None = None,
    path_constraints: Sequence = (),
    position_tolerance_m: float = POSITION_TOLERANCE_M,
    rotation_tolerance_rad: float = ROTATION_TOLERANCE_RAD,
) -> RunJudgement:
    """Checks a run against SPEC 9.

    - each critical configuration reached within ``position_tolerance_m`` (5 mm) and
      ``rotation_tolerance_rad`` (2 deg) when due;
    - every path constraint (``tasks.PathConstraint``: tool orientation within
      ``tolerance_rad`` of ``euler_zyx`` from con_from to con_to) holds on the log;
    - no robot geometry penetrates an obstacle or a safety shell (min distance > 0);
    - joint positions inside ``joint_limits`` and speeds inside ``velocity_limits``
      (the UR5e's, by default) at every logged sample.

    Returns
    -------
    RunJudgement
    """
    kinematics = shared_kinematics(X_WB=result.X_WB, X_tool0_E=result.X_tool0_E)
    if joint_limits is None:
        joint_limits = kinematics.position_limits()
    if velocity_limits is None:
        velocity_limits = kinematics.velocity_limits()
    lower, upper = (np.asarray(v, dtype=float) for v in joint_limits)
    velocity_limits = np.asarray(velocity_limits, dtype=float)
    failures = []

    for error in result.critical_errors:
        if not error.reached:
            failures.append(
                f"con_{error.con}: not reached (the run stopped at t = {result.sim_time_s:.2f} s: "
                f"{result.stop_reason})"
            )
            continue
        if not error.position_m <= position_tolerance_m:
            failures.append(
                f"con_{error.con}: position error {1000 * error.position_m:.1f} mm > "
                f"{1000 * position_tolerance_m:g} mm (t = {error.time_s:.2f} s)"
            )
        if not error.rotation_rad <= rotation_tolerance_rad:
            failures.append(
                f"con_{error.con}: rotation error {math.degrees(error.rotation_rad):.2f} deg > "
                f"{math.degrees(rotation_tolerance_rad):g} deg (t = {error.time_s:.2f} s)"
            )

    due = [result.plan_start_time_s + float(plan.times[i]) for i in plan.critical_indices]
    for constraint in path_constraints:
        t_from, t_to = due[constraint.con_from - 1], due[constraint.con_to - 1]
        window = (result.t >= t_from - 1e-9) & (result.t <= t_to + 1e-9)
        if not np.any(window):
            continue
        R_target = rigid_transform_from_euler_zyx(np.zeros(3), constraint.euler_zyx).rotation()
        angles = np.array(
            [_rotation_from(kinematics.X_WE(q).rotation(), R_target) for q in result.q[window]]
        )
        worst = int(np.argmax(angles))
        if angles[worst] > constraint.tolerance_rad:
            failures.append(
                f"path constraint con_{constraint.con_from}..con_{constraint.con_to}: tool orientation "
                f"{math.degrees(angles[worst]):.1f} deg from euler_zyx "
                f"{np.round(constraint.euler_zyx, 4).tolist()} > {math.degrees(constraint.tolerance_rad):g} deg "
                f"(t = {result.t[window][worst]:.2f} s)"
            )

    for clearance in result.clearances:
        if not clearance.distance_m > 0.0:
            failures.append(
                f"{clearance.describe()} penetrated by {clearance.robot_geometry} "
                f"(signed distance {1000 * clearance.distance_m:.1f} mm at t = {clearance.time_s:.2f} s)"
            )

    for j, name in enumerate(UR5E_JOINT_NAMES):
        if len(result.q) == 0:
            break
        outside = (result.q[:, j] < lower[j]) | (result.q[:, j] > upper[j])
        if np.any(outside):
            k = int(np.argmax(outside))
            failures.append(
                f"{name}: position {result.q[k, j]:.3f} rad outside [{lower[j]:.3f}, {upper[j]:.3f}] "
                f"(t = {result.t[k]:.2f} s)"
            )
        speeds = np.abs(result.qdot[:, j])
        k = int(np.argmax(speeds))
        if speeds[k] > velocity_limits[j]:
            failures.append(
                f"{name}: speed {speeds[k]:.2f} rad/s > limit {velocity_limits[j]:.2f} rad/s "
                f"(t = {result.t[k]:.2f} s)"
            )
    return RunJudgement(success=not failures, failures=failures)


def _rotation_from(R_a: RotationMatrix, R_b: RotationMatrix) -> float:
    return float(R_a.inverse().multiply(R_b).ToAngleAxis().angle())
