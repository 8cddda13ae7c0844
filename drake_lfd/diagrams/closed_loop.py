"""Closed-loop UR5e runs on the pipeline Diagram, one Diagram for many trials.

:class:`ClosedLoopRunner` owns one :class:`~drake_lfd.diagrams.pipeline.Pipeline` and one
Simulator and runs trials on them: for each it sets the trial up in the Context
(``Pipeline.prepare_trial``: the task input, the plan, the arm at rest at the plan's
start), holds it for the settling time, then tracks the plan until the Diagram ends the
run, applying task changes on the way (the planner system then replans), and reads the
result off the Context (``Pipeline.trial_result``). It adds what a Context does not hold:
Meshcat recordings and wall-clock timings. Judging a run against the success criteria is
:mod:`drake_lfd.diagrams.judging`'s job.

The plant step of a run is 5 ms (a bare station's default is 1 ms). The plant's cost
per step barely depends on the step (SAP's fixed overhead with PD-controlled
actuators), so the step sets the speed, and with PD treated implicitly the accuracy
hardly suffers: from 1 ms to 5 ms the run gets several times faster while the errors
along the path and at the critical configurations stay far inside the success
tolerances of 5 mm and 2 deg (``benchmarks/bench_closed_loop.py``; figures in
benchmarks/RESULTS.md). 5 ms divides the 10 ms periods of the
drive's command sampling, the monitor and the logger, so their events fall on plant steps.

Not for: building the Diagram (``pipeline.py``), planning (``planning/``), the drive
(``station.py``), the controller's maths (``systems/differential_ik.py``).
"""

from __future__ import annotations

import copy
import dataclasses
import time
from pathlib import Path
from typing import Sequence

import numpy as np
from pydrake.geometry import Meshcat
from pydrake.math import RigidTransform
from pydrake.systems.analysis import ApplySimulatorConfig, Simulator

from drake_lfd.core.pose_conversions import dual_quaternion_from_rigid_transform
from drake_lfd.core.screw_motion import dual_quaternion_sclerp
from drake_lfd.core.tasks import ConcreteTask
from drake_lfd.core.timing import TimedPlan, time_plan
from drake_lfd.io.simulation_config import PipelineConfig
from drake_lfd.diagrams.pipeline import Pipeline, TrialStart, build_pipeline
from drake_lfd.diagrams.trial_result import ClosedLoopResult
from drake_lfd.diagrams.recording_meshcat import recording_meshcat
from drake_lfd.io.atomic_files import atomic_write_bytes
from drake_lfd.planning.replanning import ScheduledPlan
from drake_lfd.diagrams.override_indicator import draw_override_indicator, draw_robot_skins, record_override
from drake_lfd.diagrams.plan_markers import draw_plan
from drake_lfd.robot.kinematics import UR5eKinematics
from drake_lfd.systems.trial_end import plan_end_time_s

# The controller of runs whose task changes while the arm moves (replanning).
TASK_SPACE_METHOD = "drake"

__all__ = [
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


class ClosedLoopRunner:
    """Runs closed-loop trials on one pipeline Diagram and one Simulator, with Meshcat
    recordings and task changes during a run.

    Each run sets its trial up in the Simulator's Context
    (:meth:`Pipeline.prepare_trial <drake_lfd.diagrams.pipeline.Pipeline.prepare_trial>`),
    initializes and advances until the Diagram ends the run (the pipeline's ``TrialEnd``),
    and reads the result off the Context (:meth:`Pipeline.trial_result
    <drake_lfd.diagrams.pipeline.Pipeline.trial_result>`): the same path
    ``MonteCarloSimulation`` takes, with nothing written into a System.

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
        ApplySimulatorConfig(pipeline.config.simulator, self.simulator)
        self.kinematics = pipeline.kinematics
        self._task_space: ClosedLoopRunner | None = None
        self._start: TrialStart | None = None

    def _task_space_runner(self) -> "ClosedLoopRunner":
        """A runner on a sibling pipeline with the Python task-space controller (made once)."""
        if self._task_space is None:
            self._task_space = ClosedLoopRunner(self.pipeline.with_controller(TASK_SPACE_METHOD),
                                                record_meshcat=self.meshcat)
        return self._task_space

    def plan(self, task: ConcreteTask | None = None, *, q_initial: np.ndarray | None = None) -> ScheduledPlan:
        """Sets the trial ``task`` up in the Simulator's Context and returns its plan (what
        :meth:`run` starts with; raises ``UnreachableConfigurationError``, an InputError,
        when the plan's first pose is unreachable)."""
        self._start = self.pipeline.prepare_trial(self.simulator.get_mutable_context(), task, q_initial=q_initial)
        return self._start.plan

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
            The result of :meth:`plan` just called (the trial is set up: not again).
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
            # the Python controller follows from the plan port (the compiled one follows the
            # joint path of the plan it started with).
            return self._task_space_runner().run(task, q_initial=q_initial, record_html=record_html,
                                                 task_changes=task_changes)
        setup_start = time.perf_counter()
        pipeline, station, simulator = self.pipeline, self.pipeline.station, self.simulator
        if scheduled is None or self._start is None or self._start.plan is not scheduled:
            scheduled = self.plan(task, q_initial=q_initial)
        start = self._start
        if scheduled is None or not scheduled.planned:
            return scheduled, None
        context = simulator.get_mutable_context()
        visualizer = station.visualizer
        recording = record_html is not None and visualizer is not None
        if self.meshcat is not None:
            draw_plan(self.meshcat, scheduled.timed)
            if recording:
                target = scheduled.timed.X_WE_list()[0].translation()
                if pipeline.people:  # farther out, to the side: the people come from around the cell
                    self.meshcat.SetCameraPose(camera_in_world=target + [2.8, -1.4, 1.5],
                                               target_in_world=target + [0.0, -0.7, -0.2])
                else:
                    self.meshcat.SetCameraPose(camera_in_world=target + [0.9, -1.0, 0.55], target_in_world=target)
            if pipeline.people:
                draw_override_indicator(self.meshcat, station.X_WB)
            visualizer.DeleteRecording()
            visualizer.StartRecording(set_transforms_while_recording=False)
        simulator.Initialize()  # setup, as the bare station's in bench_pipeline.py
        skins = draw_robot_skins(self.meshcat, station.plant, station.scene_graph) \
            if recording and pipeline.people else []
        setup_wall_time_s = time.perf_counter() - setup_start

        wall_start, cpu_start = time.perf_counter(), time.process_time()
        stop_reason = ""
        changes = sorted(task_changes, key=lambda change: change[0])
        while True:
            if changes and changes[0][0] <= context.get_time() + 1e-12:
                pipeline.task_input_port.FixValue(context, changes.pop(0)[1])
                continue
            # To the end of the plan in force (the Diagram would end the run at its first
            # check after it; stopping at the end keeps the log to the plan's own span).
            end = plan_end_time_s(pipeline.plan_output_port.Eval(context))
            if pipeline.people:
                # The path runs in scaled time: the end is where the path position reaches
                # it, at least the remaining path time later (never sooner).
                if end is None or pipeline.path_time_s(context) >= end - 1e-9:
                    break
                end = context.get_time() + max(end - pipeline.path_time_s(context), pipeline.law.time_step)
            elif end is None or context.get_time() >= end - 1e-12:
                break
            status = simulator.AdvanceTo(min(end, changes[0][0]) if changes else end)
            if status.reason() == status.ReturnReason.kReachedTerminationCondition:
                stop_reason = status.message()
                break
        scheduled = pipeline.plan_output_port.Eval(context)
        end = plan_end_time_s(scheduled)
        early = end is not None and pipeline.path_time_s(context) < end - 1e-9
        # Reading the run off the Context (the monitor measures the logged samples there)
        # is part of the closed loop's time.
        result = pipeline.trial_result(context, stop_reason=stop_reason if early else "",
                                       setup_wall_time_s=setup_wall_time_s,
                                       initial_configuration=start.initial_configuration)
        if result is not None:  # (None only if a replan left nothing in force)
            result = dataclasses.replace(result, wall_time_s=time.perf_counter() - wall_start,
                                         cpu_time_s=time.process_time() - cpu_start)
        if recording:
            visualizer.StopRecording()
            record = pipeline.collaboration_record(context)
            if record is not None:
                record_override(visualizer.get_mutable_recording(), record.t, record.override, skins)
            visualizer.PublishRecording()
            atomic_write_bytes(Path(record_html), self.meshcat.StaticHtml().encode())
        return scheduled, result


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
