"""The whole pipeline as one Diagram: library -> planner -> trajectory -> diff IK -> UR5e.

:class:`Pipeline` wires the stages in pipeline order, one ``Connect`` per arrow::

    FeatureLibrarySystem --library--> PlannerSystem <--task-- (exported input "task")
    PlannerSystem --plan--> PlanTrajectorySource
    PlanTrajectorySource --X_WE_desired, V_WE_desired--> DifferentialIKController
    DifferentialIKController --q_command--> Station (ur5e.position_command)
    Station --ur5e.position_measured--> DifferentialIKController
    Station --query_object, ur5e.position_measured--> ShellMonitor
    Station --ur5e.state--> joint logger

The scene (robot base, table under it, obstacles, safety shells) is fixed when the
Diagram is built; the task is an input, so one Diagram serves every trial of a task
(``closed_loop.py`` runs them). With ``plan=`` instead of a library, a constant plan
replaces the library and planner (for trying the closed loop on a given motion).

Not for: running a simulation (``closed_loop.py``) or judging one
(``experiments/judging.py``).
"""

from __future__ import annotations

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
from drake_lfd.io.simulation_config import PipelineConfig
from drake_lfd.diagrams.station import Station
from drake_lfd.planning.planner import PlanResult
from drake_lfd.planning.q_learning import QPolicy
from drake_lfd.planning.replanning import ScheduledPlan
from drake_lfd.robot.kinematics import END_EFFECTOR_FRAME_NAME
from drake_lfd.robot.scene import table_under_robot
from drake_lfd.systems.differential_ik import DifferentialIKController
from drake_lfd.systems.feature_library import FeatureLibrarySystem
from drake_lfd.systems.plan_trajectory_source import PlanTrajectorySource
from drake_lfd.systems.planner import PlannerSystem
from drake_lfd.systems.shell_monitor import ShellMonitor

__all__ = ["Pipeline", "build_pipeline", "scheduled_plan_from_timed"]


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
    X_WB, X_tool0_E : RigidTransform, optional
    obstacles, safety_shells : iterable of Box
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

    Attributes
    ----------
    station, library, planner, source, controller, monitor, logger
        The subsystems (``library`` and ``planner`` are None with a given ``plan``).
    config : PipelineConfig
    table : Box or None
    """

    def __init__(
        self,
        *,
        X_WB: RigidTransform | None = None,
        X_tool0_E: RigidTransform | None = None,
        obstacles=(),
        safety_shells=(),
        with_table: bool = True,
        features: Mapping[str, Feature] | None = None,
        planner: str = "exact",
        policy: QPolicy | None = None,
        plan: TimedPlan | None = None,
        config: PipelineConfig | None = None,
        meshcat: Meshcat | None = None,
        accept_demonstrations: bool = False,
    ):
        super().__init__()
        config = (PipelineConfig() if config is None else config).checked()
        self.config = config
        if plan is None and features is None:
            raise ValueError("a pipeline needs a library (features) or a given plan")
        X_WB = RigidTransform() if X_WB is None else RigidTransform(X_WB)
        X_tool0_E = RigidTransform() if X_tool0_E is None else RigidTransform(X_tool0_E)
        self.table: Box | None = table_under_robot(X_WB) if with_table else None
        floor_z = None if self.table is None else float(self.table.centre[2] + self.table.size[2] / 2)

        builder = DiagramBuilder()
        station = builder.AddNamedSystem("station", Station(
            X_WB=X_WB, X_tool0_E=X_tool0_E, obstacles=obstacles, safety_shells=safety_shells,
            table=self.table, meshcat=meshcat, config=config.station))
        self.library = self.planner = None
        if plan is None:
            self.library = builder.AddNamedSystem("feature_library", FeatureLibrarySystem(
                features=features, X_tool0_E=X_tool0_E, accept_demonstrations=accept_demonstrations,
                check_period=config.planner.check_period))
            self.planner = builder.AddNamedSystem("planner", PlannerSystem(
                planner=planner, policy=policy, start_time_s=config.settle_s, floor_z=floor_z,
                check_period=config.planner.check_period))
            plan_port = self.planner.plan_output_port
        else:
            constant = builder.AddNamedSystem("given_plan", ConstantValueSource(
                AbstractValue.Make(scheduled_plan_from_timed(plan, config.settle_s))))
            plan_port = constant.get_output_port()
        self.source = builder.AddNamedSystem("plan_trajectory_source", PlanTrajectorySource())
        controller_plant = station.controller_plant
        self.controller = builder.AddNamedSystem("differential_ik", DifferentialIKController(
            plant=controller_plant, model=station.controller_model,
            frame_E=controller_plant.GetFrameByName(END_EFFECTOR_FRAME_NAME),
            time_step=config.controller.time_step, method=config.controller.method,
            position_gain=config.controller.position_gain,
            velocity_limit_fraction=config.controller.velocity_limit_fraction))
        scene = station.scene
        self.monitor = builder.AddNamedSystem("shell_monitor", ShellMonitor(
            plant=station.plant, robot_geometry_ids=scene.robot_geometry_ids,
            shell_geometry_ids=scene.keep_out_geometry_ids, period=config.monitor.period,
            stop_on_penetration=config.monitor.stop_on_penetration, names=scene.names, kinds=scene.kinds))

        # Pipeline order, one Connect per arrow.
        if self.planner is not None:
            builder.Connect(self.library.library_output_port, self.planner.library_input_port)
            builder.ExportInput(self.planner.task_input_port, "task")
            if accept_demonstrations:
                builder.ExportInput(self.library.demonstration_input_port, "demonstration")
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

    @property
    def plan_output_port(self):
        return self.GetOutputPort("plan")

    @property
    def task_input_port(self):
        return self.GetInputPort("task")


def build_pipeline(task: ConcreteTask | None = None, features: Mapping[str, Feature] | None = None, *,
                   plan: TimedPlan | None = None, **kwargs) -> Pipeline:
    """A :class:`Pipeline` for the scene of ``task`` (base, tool frame, obstacles and
    shells; the critical configurations are set later through the ``task`` input)."""
    if task is not None:
        kwargs.setdefault("X_WB", task.X_WB)
        kwargs.setdefault("X_tool0_E", task.X_tool0_E)
        kwargs.setdefault("obstacles", tuple(task.obstacles))
        kwargs.setdefault("safety_shells", tuple(task.safety_shells))
    return Pipeline(features=features, plan=plan, **kwargs)
