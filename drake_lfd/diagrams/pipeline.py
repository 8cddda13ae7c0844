"""The whole pipeline as one Diagram: library -> planner -> trajectory -> controller -> UR5e.

:class:`Pipeline` wires the stages in pipeline order, one ``Connect`` per arrow. With the
default, compiled controller (``controller.method: compiled``)::

    FeatureLibrarySystem --library--> PlannerSystem <--task-- (exported input "task")
    PlannerSystem --plan--> JointPathSource        (systems/joint_path_source.py)
    JointPathSource --chunk--> JointTrajectoryController   (systems/joint_trajectory_controller.py)
    JointTrajectoryController --q_command--> Station (ur5e.position_command)
    Station --ur5e.position_measured--> JointTrajectoryController, JointPathSource
    PlannerSystem --plan--> TrialEnd              (ends the run once the plan is executed)
    Station --ur5e.state--> joint logger; ShellMonitor measures the logged samples

With people in the cell (``people=``, a task's ``people:``; compiled controller only),
the source and controller are replaced, nothing else changes (without people the Diagram
is exactly the one above)::

    Station (people's capsules, a SceneGraph source inside it) --query_object, ur5e.state--> SeparationMonitor
    TimeScaledJointPathSource --path_rate--> SeparationMonitor --separation--> TimeScaledJointPathSource
    PlannerSystem --plan--> TimeScaledJointPathSource --q_command--> Station (ur5e.position_command)
    TimeScaledJointPathSource --path_time--> TrialEnd (ends the run when the path is done)
    TimeScaledJointPathSource --status--> collaboration logger (separation, S_p, override)

With the Python task-space controller (``drake`` or ``pseudo_inverse``, the paper's
baseline)::

    PlannerSystem --plan--> PlanTrajectorySource
    PlanTrajectorySource --X_WE_desired, V_WE_desired--> DifferentialIKController
    DifferentialIKController --q_command--> Station (ur5e.position_command)
    Station --ur5e.position_measured--> DifferentialIKController
    Station --query_object, ur5e.position_measured--> ShellMonitor

Everything a trial needs lives in its Context: the task on the ``task`` input, the plan
in the planner's state, the run's joint path in the source's, the arm's positions, the
log and the monitor's records. So one Diagram runs many trials, in turn or in several
Contexts at once, and Drake's ``MonteCarloSimulation`` runs it:
:meth:`Pipeline.make_simulator` draws a trial from a ``RandomGenerator``,
:meth:`Pipeline.trial_succeeded` judges a finished run from its Context alone, and the
``TrialEnd`` system stops the simulation once the plan has been executed, so any
``final_time`` at or beyond a trial's end works. :meth:`Pipeline.prepare_trial` sets a
trial up in a Context (plan, arm at the plan's start); :meth:`Pipeline.trial_result`
reads the run off it.

The scene (a :class:`~drake_lfd.robot.workcell.Workcell`: robot base, table under it,
obstacles, safety shells, the tool) is fixed when the Diagram is built, and the planner
system keeps the tool above the same table top (``Workcell.planner_floor``) that
``drake-lfd plan`` uses. With ``plan=`` instead of a library, a constant plan replaces the
library and planner (for trying the closed loop on a given motion).

Not for: the loop that runs trials with Meshcat recordings and task changes
(``closed_loop.py``) or the success criteria (``judging.py``).
"""

from __future__ import annotations

import dataclasses
import math
from typing import Mapping, NamedTuple

import numpy as np
from pydrake.common import RandomGenerator
from pydrake.geometry import Meshcat
from pydrake.math import RigidTransform, RollPitchYaw
from pydrake.systems.analysis import ApplySimulatorConfig, Simulator
from pydrake.systems.framework import Context, Diagram, DiagramBuilder, System
from pydrake.systems.primitives import LogVectorOutput

from drake_lfd.core.failures import Failure
from drake_lfd.core.features import Feature
from drake_lfd.core.tasks import Box, ConcreteTask, Task, draw_trial
from drake_lfd.core.people import CollaborationParameters
from drake_lfd.core.timing import TimedPlan, TimingLimits
from drake_lfd.io.library_source import resolve_features
from drake_lfd.io.plan_json import describe_uncovered
from drake_lfd.io.simulation_config import COMPILED_METHOD, PipelineConfig
from drake_lfd.diagrams.collaboration_result import (
    CollaborationRecord, collaboration_record_from_log, scaled_due_times,
)
from drake_lfd.diagrams.judging import RunJudgement, judge_run
from drake_lfd.diagrams.station import Station
from drake_lfd.diagrams.trial_result import ClosedLoopResult, read_trial
from drake_lfd.planning.options import PlanningOptions
from drake_lfd.planning.planner import PlanResult
from drake_lfd.planning.q_learning import QPolicy
from drake_lfd.planning.replanning import ScheduledPlan
from drake_lfd.planning.span_index import prepared_library
from drake_lfd.robot.initial_ik import InitialConfiguration, solve_initial_configuration
from drake_lfd.robot.joint_path import JointPathChecker
from drake_lfd.robot.joint_path_records import JointPathLimits
from drake_lfd.robot.kinematics import END_EFFECTOR_FRAME_NAME, UR5eKinematics
from drake_lfd.robot.scene import KinematicScene
from drake_lfd.robot.workcell import Workcell, table_under_robot
from drake_lfd.systems.differential_ik import DifferentialIKController
from drake_lfd.systems.feature_library import FeatureLibrarySystem
from drake_lfd.systems.joint_path_source import JointPathSource
from drake_lfd.systems.joint_trajectory_controller import JointTrajectoryController, law_for_plant
from drake_lfd.systems.plan_trajectory_source import PlanTrajectorySource
from drake_lfd.systems.planner import NO_PLAN, GivenPlan, PlannerSystem
from drake_lfd.systems.separation import SeparationMonitor
from drake_lfd.systems.shell_monitor import ShellMonitor
from drake_lfd.systems.speed_override import TimeScaledJointPathSource
from drake_lfd.systems.trial_end import TrialEnd, plan_end_time_s

__all__ = ["Pipeline", "TrialStart", "build_pipeline", "joint_path_checker", "scheduled_plan_from_timed"]


class TrialStart(NamedTuple):
    """How a trial was set up in a Context (:meth:`Pipeline.prepare_trial`).

    ``plan``: the plan in the Context; ``q_initial``: where the arm starts (None when
    nothing was planned); ``initial_configuration``: the inverse-kinematics result when
    the start came from it (a plan without a checked joint path), else None.
    """

    plan: ScheduledPlan | None
    q_initial: np.ndarray | None
    initial_configuration: InitialConfiguration | None


def joint_path_checker(workcell: Workcell, config: PipelineConfig | None = None) -> JointPathChecker:
    """The plan-time joint-space check of ``workcell`` with the closed loop's controller
    (period, gain, speed fraction of ``config``), so a checked plan's joint path is the
    one the controller will command, and ``config.joint_check``'s margins."""
    config = (PipelineConfig() if config is None else config).checked()
    controller, margins = config.controller, config.joint_check
    limits = JointPathLimits(elbow_margin=margins.elbow_margin, wrist_margin=margins.wrist_margin,
                             shoulder_margin_m=margins.shoulder_margin_m, clearance_m=margins.clearance_m)
    return JointPathChecker.for_workcell(workcell, limits=limits, time_step=controller.time_step,
                                         position_gain=controller.position_gain,
                                         velocity_limit_fraction=controller.velocity_limit_fraction)


def scheduled_plan_from_timed(plan: TimedPlan, start_time_s: float = 0.0) -> ScheduledPlan:
    """A ScheduledPlan for a motion made without the planner (its critical
    configurations are the plan's poses at its critical indices)."""
    X = plan.X_WE_list()
    positions = np.array([X[i].translation() for i in plan.critical_indices])
    euler = []
    for i in plan.critical_indices:
        rpy = RollPitchYaw(X[i].rotation())
        euler.append([rpy.yaw_angle(), rpy.pitch_angle(), rpy.roll_angle()])
    task = ConcreteTask.from_fixed("given plan", positions, np.array(euler))
    result = PlanResult("planned", "given", task, np.array(euler), timed=plan)
    return ScheduledPlan(result, float(start_time_s))


class Pipeline(Diagram):
    """The closed-loop pipeline Diagram (see the module docstring for the wiring).

    .. pydrake_system::

        name: Pipeline
        input_ports:
        - task
        output_ports:
        - plan
        - min_distance
        - ur5e.state

    ``task`` is an abstract :class:`~drake_lfd.core.tasks.ConcreteTask` (absent with a
    given ``plan``); ``plan`` the planner's
    :class:`~drake_lfd.planning.replanning.ScheduledPlan`; ``min_distance`` the closest
    approach to any obstacle or shell so far (m).

    Parameters
    ----------
    workcell : Workcell, optional
        The whole scene; when given, ``X_WB``, ``X_tool0_E``, ``obstacles``,
        ``safety_shells``, ``tool`` and ``with_table`` are not used.
    X_WB, X_tool0_E : RigidTransform, optional
    obstacles, safety_shells : iterable of Box
    tool : tuple of ToolShape, optional
        None: the default tool of ``X_tool0_E``.
    with_table : bool
        Put the table under the robot (it is also the floor the planner keeps the tool
        above).
    task : Task, optional
        The task whose trials the pipeline runs (:meth:`make_simulator` draws them).
    features : Mapping[str, Feature], optional
        The library; required unless ``plan`` is given.
    planning : PlanningOptions
        How the planner system plans
        (:class:`~drake_lfd.planning.options.PlanningOptions`; by default as
        ``drake-lfd plan`` does: exact planner, fidelity cost, the plan-time joint-space
        check, no refinement; ``PlanningOptions.paper_baseline()`` for the paper's).
    policy : QPolicy, optional
        The Q-policy of ``planning.planner == "q"``.
    plan : TimedPlan, optional
        A fixed motion instead of library and planner.
    config : PipelineConfig, optional
    meshcat : Meshcat, optional
    accept_demonstrations : bool
        Give the library system its ``demonstration`` input (exported as
        ``demonstration``).
    people : sequence of Person
        People in the cell (:mod:`drake_lfd.core.people`); none: nothing is added.
    collaboration : CollaborationParameters, optional
        Speed and separation monitoring with people (None: the defaults).

    Attributes
    ----------
    station, library, planner, source, controller, monitor, logger, trial_end
        The subsystems (``library`` and ``planner`` are None with a given ``plan``;
        ``source`` is the JointPathSource with the compiled controller, the
        PlanTrajectorySource with the task-space one).
    law : DifferentialIKLaw
        The controller's law on the controller plant (the compiled controller's limits;
        following a plan that has no joint path).
    compiled : bool
        Whether the controller is the compiled one.
    config : PipelineConfig
    planning : PlanningOptions
    task : Task or None
    workcell : Workcell
    table : Box or None
    kinematics : UR5eKinematics
        The arm's forward kinematics in this work cell (judging the runs).
    people : tuple of Person
    collaboration : CollaborationParameters or None
        None without people.
    separation, collaboration_logger
        With people: the SeparationMonitor and the log of the source's ``status``
        (None without people).
    """

    def __init__(
        self,
        *,
        task: Task | None = None,
        workcell: Workcell | None = None,
        X_WB: RigidTransform | None = None,
        X_tool0_E: RigidTransform | None = None,
        obstacles=(),
        safety_shells=(),
        tool=None,
        with_table: bool = True,
        features: Mapping[str, Feature] | None = None,
        planning: PlanningOptions = PlanningOptions(),
        policy: QPolicy | None = None,
        plan: TimedPlan | None = None,
        config: PipelineConfig | None = None,
        meshcat: Meshcat | None = None,
        accept_demonstrations: bool = False,
        people=(),
        collaboration: CollaborationParameters | None = None,
    ):
        super().__init__()
        # What it was built from, for a sibling with another controller (``with_controller``).
        self._options = dict(task=task, workcell=workcell, X_WB=X_WB, X_tool0_E=X_tool0_E, obstacles=obstacles,
                             safety_shells=safety_shells, tool=tool, with_table=with_table, features=features,
                             planning=planning, policy=policy, plan=plan, config=config, meshcat=meshcat,
                             accept_demonstrations=accept_demonstrations, people=people,
                             collaboration=collaboration)
        if not isinstance(planning, PlanningOptions):
            raise TypeError(f"planning must be PlanningOptions, got {type(planning).__name__}")
        self.planning = planning
        config = (PipelineConfig() if config is None else config).checked()
        self.config = config
        self.task = task
        if plan is None and features is None:
            raise ValueError("a pipeline needs a library (features) or a given plan")
        if workcell is None:
            workcell = Workcell.make(X_WB=X_WB, X_tool0_E=X_tool0_E, obstacles=obstacles,
                                     safety_shells=safety_shells, tool=tool,
                                     table=table_under_robot(X_WB) if with_table else None)
        self.workcell = workcell
        X_tool0_E = workcell.X_tool0_E
        self.table: Box | None = workcell.table
        floor_z = workcell.planner_floor

        # Pipeline order: each stage added with its AddToBuilder, which connects its inputs.
        self.people = tuple(people)
        self.collaboration = (CollaborationParameters() if collaboration is None else collaboration) \
            if self.people else None
        self.compiled = config.controller.method == COMPILED_METHOD
        if self.people and not self.compiled:
            raise ValueError("people in the cell need the compiled controller (controller.method: compiled)")
        builder = DiagramBuilder()
        # Without people the station is built as it always was (nothing added).
        people_options = dict(people=self.people, floor_z=self.collaboration.floor_z(workcell.X_WB.translation()[2])) \
            if self.people else {}
        station = Station.AddToBuilder(builder=builder, workcell=workcell, meshcat=meshcat, config=config.station,
                                       **people_options)
        q_measured_port = station.GetOutputPort(station.port_name("position_measured"))
        q_command_port = station.GetInputPort(station.port_name("position_command"))
        self.library = self.planner = None
        if plan is None:
            self.library = FeatureLibrarySystem.AddToBuilder(
                builder=builder, features=features, X_tool0_E=X_tool0_E,
                accept_demonstrations=accept_demonstrations, check_period=config.planner.check_period)
            self.planner = PlannerSystem.AddToBuilder(
                builder=builder, library_output_port=self.library.library_output_port,
                options=planning, policy=policy, start_time_s=config.settle_s, floor_z=floor_z,
                checker=joint_path_checker(workcell, config) if planning.joint_check else None,
                # The compiled controller follows the joint path of the plan its run started
                # with (a run with task changes goes to a task-space sibling,
                # ``with_controller``): nothing to check for during it.
                check_period=None if self.compiled else config.planner.check_period)
            builder.ExportInput(self.planner.task_input_port, "task")
            if accept_demonstrations:
                builder.ExportInput(self.library.demonstration_input_port, "demonstration")
            plan_port = self.planner.plan_output_port
            # The library prepared for the legal-action table (its stacks, its span index
            # and the index's one-time scipy.spatial import) is built with the Diagram,
            # not in the first trial's plan; every plan of these features reuses it.
            prepared_library(list(features.values()), planning.tolerances)
        else:
            given = GivenPlan.AddToBuilder(builder=builder, plan=scheduled_plan_from_timed(plan, config.settle_s))
            plan_port = given.plan_output_port
        controller_plant = station.controller_plant
        frame_E = controller_plant.GetFrameByName(END_EFFECTOR_FRAME_NAME)
        #: The controller's law on the controller plant (the compiled controller's limits,
        #: and following a plan that has no joint path).
        self.law = law_for_plant(controller_plant, station.controller_model, frame_E, config.controller)
        #: With people: the separation monitor and the log of the override's status
        #: (None without people).
        self.separation = self.collaboration_logger = None
        lead_s = config.station.time_step if station.plant.has_sampled_output_ports() else 0.0
        if self.people:
            # People in the cell: the joint path followed in scaled time, at the override
            # their separation allows (a Python system at the control rate).
            timing = getattr(task, "timing", None) or TimingLimits()
            stopping_time_s = self.collaboration.stopping_time(timing.joint_speed_rad_s,
                                                               timing.joint_acceleration_rad_s2)
            self.source = self.controller = TimeScaledJointPathSource.AddToBuilder(
                builder=builder, plan_output_port=plan_port, q_measured_output_port=q_measured_port,
                q_command_input_port=q_command_port, law=self.law, parameters=self.collaboration,
                stopping_time_s=stopping_time_s, num_people=len(self.people), lead_s=lead_s)
            self.separation = SeparationMonitor.AddToBuilder(
                builder=builder, query_object_output_port=station.GetOutputPort("query_object"),
                state_output_port=station.GetOutputPort(station.port_name("state")),
                path_rate_output_port=self.source.path_rate_output_port, plant=station.plant, model=station.model,
                scene_graph=station.scene_graph, robot_geometry_ids=station.scene.robot_geometry_ids,
                people_geometry_ids=station.people.geometry_ids, parameters=self.collaboration,
                stopping_time_s=stopping_time_s)
            builder.Connect(self.separation.separation_output_port, self.source.separation_input_port)
            self.collaboration_logger = LogVectorOutput(self.source.status_output_port, builder, self.law.time_step)
            self.collaboration_logger.set_name("collaboration_logger")
        elif self.compiled:
            # The plan reaches the compiled controller as its joint path, in chunks from the
            # source; no Python system is evaluated in the 100 Hz loop.
            self.source = JointPathSource.AddToBuilder(
                builder=builder, plan_output_port=plan_port, q_measured_output_port=q_measured_port, law=self.law,
                lead_s=lead_s)
            self.controller = JointTrajectoryController.AddToBuilder(
                builder=builder, law=self.law, chunk_output_port=self.source.chunk_output_port,
                q_measured_output_port=q_measured_port, q_command_input_port=q_command_port, lead_s=lead_s)
        else:
            self.source = PlanTrajectorySource.AddToBuilder(builder=builder, plan_output_port=plan_port)
            self.controller = DifferentialIKController.AddToBuilder(
                builder=builder, plant=controller_plant, model=station.controller_model, frame_E=frame_E,
                X_WE_desired_output_port=self.source.X_WE_desired_output_port,
                V_WE_desired_output_port=self.source.V_WE_desired_output_port,
                q_measured_output_port=q_measured_port, q_command_input_port=q_command_port,
                time_step=config.controller.time_step, method=config.controller.method,
                position_gain=config.controller.position_gain,
                velocity_limit_fraction=config.controller.velocity_limit_fraction)
        scene = station.scene
        # The monitor measures the joint-state log (same samples) when both have one period.
        # The station's plant holds only the arm: its positions are the plant's.
        from_log = config.monitor.from_log and config.monitor.period == config.log_period
        self.monitor = ShellMonitor.AddToBuilder(
            builder=builder, plant=station.plant, query_object_output_port=station.GetOutputPort("query_object"),
            robot_geometry_ids=scene.robot_geometry_ids, shell_geometry_ids=scene.keep_out_geometry_ids,
            robot_positions_output_port=q_measured_port, period=config.monitor.period,
            stop_on_penetration=config.monitor.stop_on_penetration, names=scene.names, kinds=scene.kinds,
            scene=KinematicScene(workcell) if from_log else None)
        state_port = station.GetOutputPort(station.port_name("state"))
        self.logger = LogVectorOutput(state_port, builder, config.log_period)
        self.logger.set_name("joint_state_logger")
        # Ends the run once the plan is executed (with people: once the path is).
        if self.people:
            self.trial_end = TrialEnd.AddToBuilder(builder=builder, plan_output_port=plan_port,
                                                   path_time_output_port=self.source.path_time_output_port,
                                                   time_limit_s=self.collaboration.max_time_lost_s)
        else:
            self.trial_end = TrialEnd.AddToBuilder(builder=builder, plan_output_port=plan_port)
        builder.ExportOutput(plan_port, "plan")
        builder.ExportOutput(self.monitor.min_distance_output_port, "min_distance")
        builder.ExportOutput(state_port, station.port_name("state"))
        builder.BuildInto(self)
        self.set_name("pipeline")
        self.station = station
        self.kinematics = UR5eKinematics(X_WB=station.X_WB, X_tool0_E=station.X_tool0_E)
        self._ik_scene: KinematicScene | None = None  # the initial IK's collision scene, made on first use

    def with_controller(self, method: str) -> "Pipeline":
        """A new pipeline like this one (same scene, library, planner, Meshcat) with the
        controller ``method`` (``"compiled"``, ``"drake"``, ``"pseudo_inverse"``)."""
        options = dict(self._options, workcell=self.workcell)
        options["config"] = dataclasses.replace(
            self.config, controller=dataclasses.replace(self.config.controller, method=method))
        return Pipeline(**options)

    @property
    def plan_output_port(self):
        return self.GetOutputPort("plan")

    @property
    def task_input_port(self):
        return self.GetInputPort("task")

    # -- trials in a Context ---------------------------------------------------------------
    def prepare_trial(self, context: Context, trial: ConcreteTask | None = None, *,
                      q_initial: np.ndarray | None = None) -> TrialStart:
        """Sets a trial up in ``context`` (the root Context of this Diagram), ready for a
        Simulator to initialize and advance it.

        Resets the Context to its defaults at time 0, sets ``trial`` on the ``task``
        input and plans it into the planner's state (a pipeline with a given plan keeps
        its plan); when it planned, puts the arm at rest at ``q_initial``, by default the
        start of the plan's checked joint path or (a plan made without the check) inverse
        kinematics of its first pose, elbow up (raises ``UnreachableConfigurationError``,
        an InputError, when unreachable). The Simulator's initialization then hands the
        plan to the trajectory source and the controller.
        """
        self.SetDefaultContext(context)
        context.SetTime(0.0)
        self.logger.FindMutableLog(context).Clear()  # the log is the Context's, but no state
        if self.collaboration_logger is not None:
            self.collaboration_logger.FindMutableLog(context).Clear()
        if self.planner is None:
            scheduled = self.plan_output_port.Eval(context)
        else:
            if trial is None:
                raise ValueError("this pipeline plans: give it a trial (a ConcreteTask)")
            self.task_input_port.FixValue(context, trial)
            scheduled = self.planner.plan_now(context)
        if scheduled is None or not scheduled.planned:
            return TrialStart(scheduled, None, None)
        initial_configuration = None
        joint_path = scheduled.result.joint_path
        if q_initial is None and joint_path is not None:
            # The plan-time check chose the start (IK branch and windings) for the whole
            # plan: start where its joint path starts.
            q_initial = joint_path.q[0]
        if q_initial is None:
            if self._ik_scene is None:
                self._ik_scene = KinematicScene(self.workcell)
            station = self.station
            initial_configuration = solve_initial_configuration(
                scheduled.X_WE_desired(0.0), X_WB=station.X_WB, X_tool0_E=station.X_tool0_E,
                obstacles=station.obstacles, safety_shells=station.safety_shells, scene=self._ik_scene)
            q_initial = initial_configuration.q
        q_initial = np.array(q_initial, dtype=float)
        self.station.set_initial_positions(context, q_initial)
        return TrialStart(scheduled, q_initial, initial_configuration)

    def make_simulator(self, generator: RandomGenerator) -> Simulator:
        """A Simulator of this Diagram with one trial of the pipeline's task drawn from
        ``generator`` (the same generator state gives the same trial), planned in its
        Context, the arm at the plan's start: Drake's ``SimulatorFactory``.

        Drake's ``RandomSimulation`` resets the Context with ``SetRandomContext`` after
        this returns; the trial survives it: the task is a fixed input value (kept), the
        planner plans it again at initialization (the same plan: planning is
        deterministic, and the planner system remembers its last plan), and the arm's
        start is also made the plant's default positions. That default is a property of
        the System shared by every Context, so run the trials of one pipeline in one
        thread (``MonteCarloSimulation``'s default); Contexts set up with
        :meth:`prepare_trial` set their positions themselves and do not depend on it.
        """
        if self.task is None:
            raise ValueError("make_simulator needs the pipeline's task (build_pipeline(task, ...))")
        seed = int(generator()) % (2 ** 31)
        simulator = Simulator(self)
        ApplySimulatorConfig(self.config.simulator, simulator)
        start = self.prepare_trial(simulator.get_mutable_context(), draw_trial(self.task, seed))
        if start.q_initial is not None:
            self.station.plant.SetDefaultPositions(self.station.model, start.q_initial)
        return simulator

    def trial_result(self, context: Context, *, stop_reason: str = "", wall_time_s: float = 0.0,
                     cpu_time_s: float = 0.0, setup_wall_time_s: float = 0.0,
                     initial_configuration: InitialConfiguration | None = None) -> ClosedLoopResult | None:
        """What the run in ``context`` did so far (None when nothing was planned).

        The joint log, each critical configuration's error at its due time (from the
        log), the closest approach to every obstacle and shell (the monitor's records, the
        logged samples measured too), the trial's path constraints. The Context is not
        changed. ``stop_reason``, the timings and ``initial_configuration`` are what the
        caller knows of the run (a Simulator's status message, clocks).
        """
        plan = self.plan_output_port.Eval(context)
        people = {}
        if self.people and plan_end_time_s(plan) is not None:
            # The path ran in scaled time: each critical configuration is judged when the
            # path reached it, and the run is over when the path is.
            record = self.collaboration_record(context)
            now, s_now = context.get_time(), self.path_time_s(context)
            # The log ends a period before the state it leads to: the path position now too.
            t, s = (np.append(record.t, now), np.append(record.path_time_s, s_now)) \
                if not len(record.t) or now > record.t[-1] else (record.t, record.path_time_s)
            people = dict(collaboration=record, path_finished=s_now >= plan_end_time_s(plan) - 1e-9,
                          due_times_s=scaled_due_times(plan.due_times_s(), t, s, now))
        return read_trial(context, plan=plan, logger=self.logger,
                          monitor=self.monitor, station=self.station, kinematics=self.kinematics,
                          controller=self.config.controller.method, stop_reason=stop_reason,
                          wall_time_s=wall_time_s, cpu_time_s=cpu_time_s, setup_wall_time_s=setup_wall_time_s,
                          initial_configuration=initial_configuration, **people)

    def path_time_s(self, context: Context) -> float:
        """Where the run in ``context`` is along its path now, s: with people in the cell
        the path position (the source's state holds it for its next update, ``s + o dt``
        ahead of the last one: taken back to the clock's time), the clock without."""
        now = context.get_time()
        if not self.people:
            return now
        status = self.source.status_output_port.Eval(self.source.GetMyContextFromRoot(context))
        dt = self.law.time_step
        next_update = math.ceil(now / dt - 1e-9) * dt
        return float(status[0] - status[1] * (next_update - now))

    def collaboration_record(self, context: Context) -> CollaborationRecord | None:
        """The people's effect on the run in ``context`` so far (None without people)."""
        if not self.people:
            return None
        log = self.collaboration_logger.FindLog(context)
        return collaboration_record_from_log(log.sample_times(), log.data(), people=self.people,
                                             parameters=self.collaboration, time_step=self.law.time_step)

    def trial_judgement(self, context: Context) -> RunJudgement:
        """The verdict on the run in ``context`` (the success criteria of
        :func:`~drake_lfd.diagrams.judging.judge_run`, the trial's path constraints
        included); a trial with nothing planned fails with the planner's reasons."""
        scheduled = self.plan_output_port.Eval(context)
        if scheduled is None or scheduled is NO_PLAN or scheduled.result.status == NO_PLAN.result.status:
            return RunJudgement(False, [Failure("nothing_planned", "nothing planned")])
        plan = scheduled.result
        if plan.status == "no_executable_plan":
            return RunJudgement(False, [
                Failure("no_executable_plan", "no executable plan: " + segment.describe(),
                        configuration=segment.con_from, cause=segment.reason)
                for segment in plan.infeasible])
        if not plan.planned:
            return RunJudgement(False, [
                Failure("demonstration_requested", "demonstration requested: " + line, configuration=segment.con_from)
                for segment, line in zip(plan.uncovered, describe_uncovered(plan))])
        return judge_run(self.trial_result(context), kinematics=self.kinematics)

    def trial_succeeded(self, system: System, context: Context) -> float:
        """1.0 when the run in ``context`` succeeded, else 0.0: Drake's
        ``ScalarSystemFunction`` for ``MonteCarloSimulation`` (``system`` is this
        pipeline)."""
        return 1.0 if self.trial_judgement(context).success else 0.0


def build_pipeline(task: Task | ConcreteTask | None = None, features: Mapping[str, Feature] | None = None, *,
                   library=None, plan: TimedPlan | None = None, **kwargs) -> Pipeline:
    """A :class:`Pipeline` for the work cell of ``task`` (:meth:`Workcell.of
    <drake_lfd.robot.workcell.Workcell.of>`: base, tool frame and tool, obstacles, shells,
    the table unless ``with_table=False``; the trials' critical configurations are set
    later, on the ``task`` input or by :meth:`Pipeline.make_simulator`).

    The library is ``features`` (name -> Feature) or ``library``: an opened
    :class:`~drake_lfd.io.library.Library`, a library folder or a bundled library's name
    (``"paper5"``); its end-effector frame must be the task's. ``kwargs`` are
    :class:`Pipeline`'s (``planning``, ``config``, ``meshcat``, ...): by default the
    planner plans as ``drake-lfd plan`` does.
    """
    if library is not None:
        if features is not None:
            raise ValueError("give the library once: features or library")
        features = resolve_features(library, task)
    if task is not None and "workcell" not in kwargs:
        kwargs["workcell"] = Workcell.of(task, with_table=kwargs.get("with_table", True))
    if isinstance(task, Task):
        kwargs.setdefault("task", task)
    if task is not None and "config" not in kwargs and getattr(task, "simulation", None) is not None:
        kwargs["config"] = task.simulation
    if isinstance(task, Task) and task.people and "people" not in kwargs:
        kwargs["people"] = task.people
        kwargs.setdefault("collaboration", task.collaboration)
    return Pipeline(features=features, plan=plan, **kwargs)
