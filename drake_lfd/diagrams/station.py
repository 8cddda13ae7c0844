"""The simulated UR5e work cell: a position-controlled arm in its scene (SPEC 9).

:func:`build_station` returns a Diagram in the style of the manipulation course's
hardware station: a discrete UR5e MultibodyPlant with the task's obstacles, safety shells
and optional table (``scene.py``), a realistic position-controlled drive, SceneGraph and
an optional MeshcatVisualizer, with ports named ``<model>.<quantity>``. What feeds the
position command (the differential-IK controller) and what watches the scene (the shell
monitor) are wired outside, by ``closed_loop.py``.

The drive, as on a real UR5e (a joint-space position servo behind a 101:1 strain-wave
gear, commanded at a fixed rate):

- PD-controlled actuators on the plant (``PdControllerGains``). The discrete plant
  treats them implicitly (SAP), so stiff gains are stable at any step. The contact
  approximation is ``kSap``: with ``kTamsi`` PD-controlled actuators silently do
  nothing (DRAKE_NOTES).
- Gravity compensation on the actuation input: ``InverseDynamics`` in gravity
  compensation mode on a separate kinematics-only plant of the same arm (same ``X_WB``:
  gravity depends on how the base is mounted).
- ``StateInterpolatorWithDiscreteDerivative`` turning joint position commands, sampled
  every ``command_period`` s, into the desired state (position and finite-difference
  velocity) of the PD controllers.
- Reflected rotor inertia (rotor inertia times gear ratio squared) on every joint: on a
  geared arm it dominates the wrists' inertia. It is realism, not a stability fix: the
  implicit PD is stable without it, and tracking measured the same within 0.02 mm.

Not for: choosing the command (``differential_ik.py``), measuring shell distances
(``shell_monitor.py``), running or judging a simulation (``closed_loop.py``).
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np
from pydrake.geometry import Meshcat, MeshcatVisualizer, MeshcatVisualizerParams, Role, SceneGraph
from pydrake.math import RigidTransform
from pydrake.multibody.plant import (
    AddMultibodyPlantSceneGraph,
    DiscreteContactApproximation,
    MultibodyPlant,
)
from pydrake.multibody.tree import JointActuatorIndex, ModelInstanceIndex, PdControllerGains
from pydrake.systems.controllers import InverseDynamics
from pydrake.systems.framework import Context, Diagram, DiagramBuilder
from pydrake.systems.primitives import Demultiplexer, StateInterpolatorWithDiscreteDerivative

from drake_lfd.robot.kinematics import NUM_JOINTS, UR5E_JOINT_NAMES, add_ur5e
from drake_lfd.robot.scene import SceneGeometry, add_scene
from drake_lfd.io.task_files import Box

DEFAULT_TIME_STEP_S = 1e-3
DEFAULT_COMMAND_PERIOD_S = 0.01

# Strain-wave gear ratio of every UR5e joint.
UR5E_GEAR_RATIO = 101.0
# Rotor inertias (kg m^2). UR does not publish them; these are the order of magnitude of
# frameless servo motors of the joint sizes (size 3 for base, shoulder, elbow; size 1 for
# the wrists). Reflected through the gear (x 101^2) they add about 0.36 kg m^2 to the
# large joints and 0.10 kg m^2 to the wrists.
UR5E_ROTOR_INERTIA_KG_M2 = np.array([3.5e-5, 3.5e-5, 3.5e-5, 1.0e-5, 1.0e-5, 1.0e-5])
# PD gains of the joint servos, chosen as omega^2 I and 2 zeta omega I (zeta = 1) for a
# position bandwidth of about omega = 40 rad/s (shoulder, with the arm outstretched:
# I = 3 kg m^2), 50 rad/s (elbow, I = 1.2) and 55 rad/s (wrists, I = 0.1 with the
# reflected rotor inertia). With velocity feed-forward from the interpolator, the
# tracking error of such a servo is about I * qddot / Kp: under 1 mrad for the
# accelerations of a 0.25 m/s tool motion, and the 150 / 28 N m torque limits leave
# room for 30 mrad (large joints) and 90 mrad (wrists) of error before saturating.
UR5E_PD_PROPORTIONAL_GAINS = np.array([4800.0, 4800.0, 3000.0, 300.0, 300.0, 300.0])
UR5E_PD_DERIVATIVE_GAINS = np.array([240.0, 240.0, 120.0, 11.0, 11.0, 11.0])


@dataclass
class Station:
    """The station diagram and handles into it.

    Attributes
    ----------
    diagram : Diagram
        Input ``<model>.position_command`` (6); outputs ``<model>.position_measured`` (6),
        ``<model>.velocity_measured`` (6), ``<model>.state`` (12) and ``query_object``.
    plant : MultibodyPlant
        The simulated (discrete) plant.
    scene_graph : SceneGraph
    model : ModelInstanceIndex
        The UR5e.
    scene : SceneGeometry
        Robot, obstacle, shell and table geometry ids and their names.
    controller_plant : MultibodyPlant
        The kinematics-only plant used for gravity compensation; usable for differential
        IK too. Kept here because ``InverseDynamics`` only references it (letting it be
        garbage collected crashes the process).
    controller_model : ModelInstanceIndex
        The UR5e in ``controller_plant``.
    interpolator : StateInterpolatorWithDiscreteDerivative
    visualizer : MeshcatVisualizer or None
    model_name : str
    X_WB, X_tool0_E : RigidTransform
    time_step : float
        The plant's discrete step, s.
    command_period : float
        Sampling period of the position command, s.
    """

    diagram: Diagram
    plant: MultibodyPlant
    scene_graph: SceneGraph
    model: ModelInstanceIndex
    scene: SceneGeometry
    controller_plant: MultibodyPlant
    controller_model: ModelInstanceIndex
    interpolator: StateInterpolatorWithDiscreteDerivative
    visualizer: MeshcatVisualizer | None
    model_name: str
    X_WB: RigidTransform
    X_tool0_E: RigidTransform
    time_step: float
    command_period: float

    def port_name(self, quantity: str) -> str:
        """``"ur5e.position_command"`` for ``"position_command"``."""
        return f"{self.model_name}.{quantity}"

    def GetInputPort(self, quantity: str):
        return self.diagram.GetInputPort(self.port_name(quantity))

    def GetOutputPort(self, quantity: str):
        if quantity == "query_object":
            return self.diagram.GetOutputPort("query_object")
        return self.diagram.GetOutputPort(self.port_name(quantity))

    def set_initial_positions(self, root_context: Context, q: np.ndarray) -> None:
        """Puts the arm at rest at ``q`` (6,) with the drive holding ``q``.

        ``root_context`` is the context of the diagram holding the station (or of the
        station itself).
        """
        q = np.asarray(q, dtype=float)
        plant_context = self.plant.GetMyMutableContextFromRoot(root_context)
        self.plant.SetPositions(plant_context, self.model, q)
        self.plant.SetVelocities(plant_context, self.model, np.zeros(NUM_JOINTS))
        self.interpolator.set_initial_position(
            self.interpolator.GetMyMutableContextFromRoot(root_context), q
        )


def configure_ur5e_drive(plant: MultibodyPlant, model: ModelInstanceIndex) -> None:
    """Sets PD gains, rotor inertia and gear ratio on the UR5e's six actuators.

    Call before ``plant.Finalize()``. Actuators are matched to joints by name, so the
    gains follow UR joint order whatever order the parser created the actuators in.
    """
    actuators = {}
    for actuator_index in range(plant.num_actuators()):
        actuator = plant.get_joint_actuator(JointActuatorIndex(actuator_index))
        if actuator.model_instance() == model:
            actuators[actuator.joint().name()] = actuator
    for i, joint_name in enumerate(UR5E_JOINT_NAMES):
        actuator = actuators[joint_name]
        actuator.set_controller_gains(
            PdControllerGains(p=UR5E_PD_PROPORTIONAL_GAINS[i], d=UR5E_PD_DERIVATIVE_GAINS[i])
        )
        actuator.set_default_rotor_inertia(UR5E_ROTOR_INERTIA_KG_M2[i])
        actuator.set_default_gear_ratio(UR5E_GEAR_RATIO)


def build_station(
    *,
    X_WB: RigidTransform | None = None,
    X_tool0_E: RigidTransform | None = None,
    obstacles: Iterable[Box] = (),
    safety_shells: Iterable[Box] = (),
    table: Box | None = None,
    meshcat: Meshcat | None = None,
    time_step: float = DEFAULT_TIME_STEP_S,
    command_period: float = DEFAULT_COMMAND_PERIOD_S,
    visualizer_publish_period: float = 1.0 / 32.0,
    model_name: str = "ur5e",
) -> Station:
    """Builds the UR5e station diagram.

    Parameters
    ----------
    X_WB : RigidTransform, optional
        Robot base in W (identity by default).
    X_tool0_E : RigidTransform, optional
        End-effector frame E on ``tool0`` (identity by default).
    obstacles, safety_shells : iterable of :class:`drake_lfd.io.task_files.Box`
    table : Box, optional
        See :func:`drake_lfd.robot.scene.table_under_robot`.
    meshcat : Meshcat, optional
        Adds a MeshcatVisualizer (illustration role) when given.
    time_step : float
        The plant's discrete step, s (1 ms by default).
    command_period : float
        Period at which the position command is sampled and differentiated, s; match
        the rate of whatever produces the command (the differential-IK step).
    visualizer_publish_period : float
        Meshcat frame period, s.
    model_name : str
        Name of the robot model instance and the prefix of the exported ports.

    Returns
    -------
    Station
    """
    X_WB = RigidTransform() if X_WB is None else RigidTransform(X_WB)
    X_tool0_E = RigidTransform() if X_tool0_E is None else RigidTransform(X_tool0_E)
    builder = DiagramBuilder()
    plant, scene_graph = AddMultibodyPlantSceneGraph(builder, time_step=time_step)
    plant.set_discrete_contact_approximation(DiscreteContactApproximation.kSap)
    model = add_ur5e(plant, X_WB=X_WB, X_tool0_E=X_tool0_E, model_name=model_name)
    configure_ur5e_drive(plant, model)
    scene = add_scene(
        plant, scene_graph, model=model, obstacles=obstacles, safety_shells=safety_shells, table=table
    )
    plant.Finalize()
    # The gravity-compensation output is in joint (velocity) order; the actuation input
    # is in actuator order. They coincide for the shipped URDF; make sure.
    if not np.array_equal(plant.MakeActuationMatrix(), np.eye(NUM_JOINTS)):
        raise RuntimeError("UR5e actuators are not in joint order; the drive wiring assumes they are")

    controller_plant = MultibodyPlant(time_step=0.0)
    controller_model = add_ur5e(controller_plant, X_WB=X_WB, X_tool0_E=X_tool0_E, model_name=model_name)
    controller_plant.Finalize()

    # Drive: command -> desired state -> PD actuators; gravity compensation feed-forward.
    interpolator = builder.AddNamedSystem(
        "position_command_interpolator",
        StateInterpolatorWithDiscreteDerivative(NUM_JOINTS, command_period, suppress_initial_transient=True),
    )
    builder.Connect(interpolator.get_output_port(), plant.get_desired_state_input_port(model))
    gravity_compensation = builder.AddNamedSystem(
        "gravity_compensation",
        InverseDynamics(controller_plant, InverseDynamics.InverseDynamicsMode.kGravityCompensation),
    )
    builder.Connect(plant.get_state_output_port(model), gravity_compensation.get_input_port_estimated_state())
    builder.Connect(gravity_compensation.get_output_port_generalized_force(), plant.get_actuation_input_port(model))

    state_split = builder.AddNamedSystem("state_split", Demultiplexer([NUM_JOINTS, NUM_JOINTS]))
    builder.Connect(plant.get_state_output_port(model), state_split.get_input_port(0))

    builder.ExportInput(interpolator.get_input_port(), f"{model_name}.position_command")
    builder.ExportOutput(state_split.get_output_port(0), f"{model_name}.position_measured")
    builder.ExportOutput(state_split.get_output_port(1), f"{model_name}.velocity_measured")
    builder.ExportOutput(plant.get_state_output_port(model), f"{model_name}.state")
    builder.ExportOutput(scene_graph.get_query_output_port(), "query_object")

    visualizer = None
    if meshcat is not None:
        params = MeshcatVisualizerParams(role=Role.kIllustration, publish_period=visualizer_publish_period)
        visualizer = MeshcatVisualizer.AddToBuilder(builder, scene_graph, meshcat, params)

    diagram = builder.Build()
    diagram.set_name("station")
    return Station(
        diagram=diagram,
        plant=plant,
        scene_graph=scene_graph,
        model=model,
        scene=scene,
        controller_plant=controller_plant,
        controller_model=controller_model,
        interpolator=interpolator,
        visualizer=visualizer,
        model_name=model_name,
        X_WB=X_WB,
        X_tool0_E=X_tool0_E,
        time_step=time_step,
        command_period=command_period,
    )
