"""The whole pipeline as one Diagram: library -> planner -> trajectory -> diff IK -> UR5e.

:class:`Pipeline` wires the stages in pipeline order, one ``Connect`` per arrow. With the
default, compiled controller (``controller.method: compiled``)::

    FeatureLibrarySystem --library--> PlannerSystem <--task-- (exported input "task")
    PlannerSystem --plan--> (exported output "plan"; the runner sets the plan's joint path
                             on the controller's TrajectorySource)
    JointTrajectoryController --q_command--> Station (ur5e.position_command)
    Station --ur5e.position_measured--> JointTrajectoryController
    Station --ur5e.state--> joint logger; ShellMonitor measures the logged samples

The planner system then plans at initialization only (no periodic check: the compiled
controller tracks the joint path set before the run, and a run whose task changes is
run on a sibling pipeline with the task-space controller, ``with_controller``).

With the Python task-space controller (``drake`` or ``pseudo_inverse``, the paper's
baseline)::

    PlannerSystem --plan--> PlanTrajectorySource
    PlanTrajectorySource --X_WE_desired, V_WE_desired--> DifferentialIKController
    DifferentialIKController --q_command--> Station (ur5e.position_command)
    Station --ur5e.position_measured--> DifferentialIKController
    Station --query_object, ur5e.position_measured--> ShellMonitor
    Station --ur5e.state--> joint logger

The scene (a :class:`~drake_lfd.robot.workcell.Workcell`: robot base, table under it,
obstacles, safety shells, the tool) is fixed when the Diagram is built, and the planner
system keeps the tool above the same table top (``Workcell.planner_floor``) that
``drake-lfd plan`` uses; the task is an input, so one Diagram serves every trial of a task
(``closed_loop.py`` runs them). With ``plan=`` instead of a library, a constant plan
replaces the library and planner (for trying the closed loop on a given motion).

Not for: running a simulation (``closed_loop.py``) or judging one
(``experiments/judging.py``).
"""

from __future__ import annotations

import dataclasses
from typing import Mapping

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.geometry import Meshcat
from pydrake.math import RigidTransform, RollPitchYaw
from pydrake.systems.framework import Diagram, DiagramBuilder
from pydrake.systems.primitives import ConstantValueSource, LogVectorOutput

from drake_lfd.core.features import Feature
from drake_lfd.core.tasks import Box, ConcreteTask
from drake_lfd.core.timing import TimedPlan
from drake_lfd.io.simulation_config import COMPILED_METHOD, PipelineConfig
from drake_lfd.diagrams.station import Station
from drake_lfd.planning.options import PlanningOptions
from drake_lfd.planning.planner import PlanResult
from drake_lfd.planning.q_learning import QPolicy
from drake_lfd.planning.replanning import ScheduledPlan
from drake_lfd.planning.span_index import prepared_library
from drake_lfd.robot.joint_path import JointPathChecker, JointPathLimits
from drake_lfd.robot.kinematics import END_EFFECTOR_FRAME_NAME
from drake_lfd.robot.scene import KinematicScene
from drake_lfd.robot.workcell import Workcell, table_under_robot
from drake_lfd.systems.differential_ik import DifferentialIKController
from drake_lfd.systems.feature_library import FeatureLibrarySystem
from drake_lfd.systems.joint_trajectory_controller import JointTrajectoryController, law_for_plant
from drake_lfd.systems.plan_trajectory_source import PlanTrajectorySource
from drake_lfd.systems.planner import PlannerSystem
from drake_lfd.systems.shell_monitor import ShellMonitor

__all__ = ["Pipeline", "build_pipeline", "joint_path_checker", "scheduled_plan_from_timed"]


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
    features : Mapping[str, Feature], optional
        The library; required unless ``plan`` is given.
    planner : {"exact", "q"}
    policy : QPolicy, optional
    plan : TimedPlan, optional
        A fixed motion instead of library and planner.
    config : PipelineConfig, optional
    meshcat : Meshcat, optional
    accept_demonstrations : bool
        Give the library system its ``demonstration`` input (exported as
        ``demonstration``).
    joint_check : bool
        Plan only executable compositions (the plan-time joint-space check,
        :func:`joint_path_checker`); False plans in SE(3) alone, as the paper does (for
        comparisons).
    cost : {"paper", "fidelity"}
        The planner's action cost (:class:`~drake_lfd.systems.planner.PlannerSystem`):
        Eq. 31, or with the shape-fidelity terms (docs/method.rst, Shape fidelity).
    refine : bool
        Refine each executable plan by trajectory optimization (the planner system's
        ``refine``; needs ``joint_check``).
    planning : PlanningOptions, optional
        All of the planner's options at once
        (:class:`~drake_lfd.planning.options.PlanningOptions`); when given, ``planner``,
        ``joint_check``, ``cost`` and ``refine`` are not used.

    Attributes
    ----------
    station, library, planner, source, controller, monitor, logger
        The subsystems (``library`` and ``planner`` are None with a given ``plan``,
        ``source`` with the compiled controller).
    law : DifferentialIKLaw
        The controller's law on the controller plant (the compiled controller's limits;
        following a plan that has no joint path).
    compiled : bool
        Whether the controller is the compiled one.
    config : PipelineConfig
    workcell : Workcell
    table : Box or None
    """

    def __init__(
        self,
        *,
        workcell: Workcell | None = None,
        X_WB: RigidTransform | None = None,
        X_tool0_E: RigidTransform | None = None,
        obstacles=(),
        safety_shells=(),
        tool=None,
        with_table: bool = True,
        features: Mapping[str, Feature] | None = None,
        planner: str = "exact",
        policy: QPolicy | None = None,
        plan: TimedPlan | None = None,
        config: PipelineConfig | None = None,
        meshcat: Meshcat | None = None,
        accept_demonstrations: bool = False,
        joint_check: bool = True,
        cost: str = "paper",
        refine: bool = False,
        planning: PlanningOptions | None = None,
    ):
        super().__init__()
        # What it was built from, for a sibling with another controller (``with_controller``).
        self._options = dict(workcell=workcell, X_WB=X_WB, X_tool0_E=X_tool0_E, obstacles=obstacles,
                             safety_shells=safety_shells, tool=tool, with_table=with_table, features=features,
                             planner=planner, policy=policy, plan=plan, config=config, meshcat=meshcat,
                             accept_demonstrations=accept_demonstrations, joint_check=joint_check, cost=cost,
                             refine=refine, planning=planning)
        if planning is None:
            planning = PlanningOptions(planner=planner, cost=cost, refine=refine, joint_check=joint_check)
        config = (PipelineConfig() if config is None else config).checked()
        self.config = config
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

        builder = DiagramBuilder()
        station = builder.AddNamedSystem("station", Station(
            workcell=workcell, meshcat=meshcat, config=config.station))
        self.library = self.planner = None
        self.compiled = config.controller.method == COMPILED_METHOD
        if plan is None:
            self.library = builder.AddNamedSystem("feature_library", FeatureLibrarySystem(
                features=features, X_tool0_E=X_tool0_E, accept_demonstrations=accept_demonstrations,
                check_period=config.planner.check_period))
            self.planner = builder.AddNamedSystem("planner", PlannerSystem(
                options=planning, policy=policy, start_time_s=config.settle_s, floor_z=floor_z,
                checker=joint_path_checker(workcell, config) if planning.joint_check else None,
                # The compiled controller tracks the joint path set before a run (a run
                # with task changes goes to a task-space sibling, ``with_controller``):
                # nothing to check for during it.
                check_period=None if self.compiled else config.planner.check_period))
            plan_port = self.planner.plan_output_port
            # The library prepared for the legal-action table (its stacks, its span index
            # and the index's one-time scipy.spatial import) is built with the Diagram,
            # not in the first trial's plan; every plan of these features reuses it.
            prepared_library(list(features.values()), planning.tolerances)
        else:
            constant = builder.AddNamedSystem("given_plan", ConstantValueSource(
                AbstractValue.Make(scheduled_plan_from_timed(plan, config.settle_s))))
            plan_port = constant.get_output_port()
        controller_plant = station.controller_plant
        frame_E = controller_plant.GetFrameByName(END_EFFECTOR_FRAME_NAME)
        #: The controller's law on the controller plant (the compiled controller's limits,
        #: and following a plan that has no joint path).
        self.law = law_for_plant(controller_plant, station.controller_model, frame_E, config.controller)
        if self.compiled:
            # The plan reaches the compiled controller's own TrajectorySource as a joint
            # path, set by the runner; no Python source is evaluated (or stepped) at run time.
            self.source = None
            self.controller = builder.AddNamedSystem(
                "differential_ik", JointTrajectoryController.for_law(
                    self.law, lead_s=config.station.time_step if station.plant.has_sampled_output_ports() else 0.0))
        else:
            self.source = builder.AddNamedSystem("plan_trajectory_source", PlanTrajectorySource())
            self.controller = builder.AddNamedSystem("differential_ik", DifferentialIKController(
                plant=controller_plant, model=station.controller_model, frame_E=frame_E,
                time_step=config.controller.time_step, method=config.controller.method,
                position_gain=config.controller.position_gain,
                velocity_limit_fraction=config.controller.velocity_limit_fraction))
        scene = station.scene
        # The monitor measures the joint-state log (same samples) when both have one period.
        from_log = config.monitor.from_log and config.monitor.period == config.log_period
        self.monitor = builder.AddNamedSystem("shell_monitor", ShellMonitor(
            plant=station.plant, robot_geometry_ids=scene.robot_geometry_ids,
            shell_geometry_ids=scene.keep_out_geometry_ids, period=config.monitor.period,
            stop_on_penetration=config.monitor.stop_on_penetration, names=scene.names, kinds=scene.kinds,
            scene=KinematicScene(workcell) if from_log else None))

        # Pipeline order, one Connect per arrow.
        if self.planner is not None:
            builder.Connect(self.library.library_output_port, self.planner.library_input_port)
            builder.ExportInput(self.planner.task_input_port, "task")
            if accept_demonstrations:
                builder.ExportInput(self.library.demonstration_input_port, "demonstration")
        if not self.compiled:
            builder.Connect(plan_port, self.source.plan_input_port)
            builder.Connect(self.source.X_WE_desired_output_port, self.controller.X_WE_desired_input_port)
            builder.Connect(self.source.V_WE_desired_output_port, self.controller.V_WE_desired_input_port)
        builder.Connect(self.controller.q_command_output_port, station.GetInputPort(station.port_name("position_command")))
        builder.Connect(station.GetOutputPort(station.port_name("position_measured")), self.controller.q_measured_input_port)
        builder.Connect(station.GetOutputPort("query_object"), self.monitor.query_object_input_port)
        # The station's plant holds only the arm: its positions are the plant's.
        builder.Connect(station.GetOutputPort(station.port_name("position_measured")),
                        self.monitor.robot_positions_input_port)
        state_port = station.GetOutputPort(station.port_name("state"))
        self.logger = LogVectorOutput(state_port, builder, config.log_period)
        self.logger.set_name("joint_state_logger")
        builder.ExportOutput(plan_port, "plan")
        builder.ExportOutput(self.monitor.min_distance_output_port, "min_distance")
        builder.ExportOutput(state_port, station.port_name("state"))
        builder.BuildInto(self)
        self.set_name("pipeline")
        self.station = station

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


def build_pipeline(task: ConcreteTask | None = None, features: Mapping[str, Feature] | None = None, *,
                   plan: TimedPlan | None = None, **kwargs) -> Pipeline:
    """A :class:`Pipeline` for the work cell of ``task`` (:meth:`Workcell.of
    <drake_lfd.robot.workcell.Workcell.of>`: base, tool frame and tool, obstacles, shells,
    the table unless ``with_table=False``; the critical configurations are set later
    through the ``task`` input)."""
    if task is not None and "workcell" not in kwargs:
        kwargs["workcell"] = Workcell.of(task, with_table=kwargs.get("with_table", True))
    return Pipeline(features=features, plan=plan, **kwargs)
