"""The simulated UR5e work cell: a position-controlled arm in its scene.

:class:`Station` is a Diagram in the style of the manipulation course's hardware
station (:func:`build_station` makes one): a discrete UR5e MultibodyPlant in its work cell
(:class:`~drake_lfd.robot.workcell.Workcell`: obstacles, safety shells, the optional
table, the tool on the flange; ``scene.py`` registers them), a realistic position-controlled drive, SceneGraph and
optional Meshcat visualisation, with ports named ``<model>.<quantity>``: the drive's,
and every output port of the plant (:func:`plant_output_port_names`), for whatever
monitors a user attaches. What feeds the
position command (the differential-IK controller) and what watches the scene (the shell
monitor) are wired outside, by ``closed_loop.py``.

The drive, as on a real UR5e (a joint-space position servo behind a 101:1 strain-wave
gear, commanded at a fixed rate):

- PD-controlled actuators on the plant (``PdControllerGains``). The discrete plant
  treats them implicitly (SAP), so stiff gains are stable at any step. The contact
  approximation is ``kSap``: with ``kTamsi`` PD-controlled actuators silently do
  nothing.
- Gravity compensation on the actuation input, as a UR5e's controller does it:
  ``InverseDynamics`` in gravity-compensation mode on a separate kinematics-only plant of
  the same arm (same ``X_WB``: gravity depends on how the base is mounted), so the links
  keep their weight and the actuators' effort limits see it. ``InverseDynamics`` only
  refers to that plant, so the Diagram owns it through a ``SharedPointerSystem`` (as the
  manipulation course's ``MakeHardwareStation`` does). The other way,
  ``StationConfig.gravity_compensation: arm_weightless``, switches gravity off on the arm
  (``plant.set_gravity_enabled(model, False)``, as the manipulation course's station does
  for its position-controlled arms): on ``bench_closed_loop.py`` both track identically
  (also at 1 ms and with the Python controller), and a weightless arm costs less
  simulation time (the gravity torques are not computed every step), but its actuators never carry the
  arm's weight, so an effort limit cannot bind as on the robot.
- ``StateInterpolatorWithDiscreteDerivative`` turning joint position commands, sampled
  every ``command_period`` s, into the desired state (position and finite-difference
  velocity) of the PD controllers.
- Reflected rotor inertia (rotor inertia times gear ratio squared) on every joint: on a
  geared arm it dominates the wrists' inertia. It is realism, not a stability fix: the
  implicit PD is stable without it, and tracking is the same with it.

The plant's output ports are not sampled (``SetUseSampledOutputPorts(False)``): its step
is then a discrete update, simultaneous with the other discrete updates of the same
instant, rather than an unrestricted update, for which Drake's Simulator copies the whole
Diagram's state every step (Python-valued states included, a cost at every step). The state output reports the state the step starts
from, as a periodic publisher sees it.

Gains, steps and periods come from a :class:`~drake_lfd.io.simulation_config.StationConfig`,
the plant's and the visualisation's settings as Drake's own ``MultibodyPlantConfig`` and
``VisualizationConfig``, applied with Drake's ``AddMultibodyPlant`` and
``ApplyVisualizationConfig`` (with a null LCM bus: Meshcat only, no LCM traffic).

Not for: choosing the command (``differential_ik.py``), measuring shell distances
(``shell_monitor.py``), running or judging a simulation (``closed_loop.py``).
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np
from pydrake.geometry import Meshcat, MeshcatVisualizer, SceneGraph
from pydrake.math import RigidTransform
from pydrake.multibody.plant import AddMultibodyPlant, MultibodyPlant
from pydrake.multibody.tree import JointActuatorIndex, ModelInstanceIndex, PdControllerGains
from pydrake.visualization import ApplyVisualizationConfig, VisualizationConfig
from pydrake.systems.controllers import InverseDynamics
from pydrake.systems.framework import Context, Diagram, DiagramBuilder
from pydrake.systems.lcm import ApplyLcmBusConfig
from pydrake.systems.primitives import Demultiplexer, SharedPointerSystem, StateInterpolatorWithDiscreteDerivative

from drake_lfd.core.tasks import Box
from drake_lfd.io.simulation_config import DriveConfig, StationConfig
from drake_lfd.robot.kinematics import NUM_JOINTS, UR5E_JOINT_NAMES, add_ur5e
from drake_lfd.robot.scene import SceneGeometry, add_scene
from drake_lfd.robot.workcell import Workcell

__all__ = ["Station", "build_station", "configure_ur5e_drive", "plant_output_port_names"]


def configure_ur5e_drive(plant: MultibodyPlant, model: ModelInstanceIndex, drive: DriveConfig | None = None) -> None:
    """Sets PD gains, rotor inertia and gear ratio on the UR5e's six actuators.

    Call before ``plant.Finalize()``. Actuators are matched to joints by name, so the
    gains follow UR joint order whatever order the parser created the actuators in.
    """
    drive = DriveConfig() if drive is None else drive
    actuators = {}
    for actuator_index in range(plant.num_actuators()):
        actuator = plant.get_joint_actuator(JointActuatorIndex(actuator_index))
        if actuator.model_instance() == model:
            actuators[actuator.joint().name()] = actuator
    for i, joint_name in enumerate(UR5E_JOINT_NAMES):
        actuator = actuators[joint_name]
        actuator.set_controller_gains(
            PdControllerGains(p=drive.proportional_gains[i], d=drive.derivative_gains[i]))
        actuator.set_default_rotor_inertia(drive.rotor_inertia_kg_m2[i])
        actuator.set_default_gear_ratio(drive.gear_ratio)


class Station(Diagram):
    """The UR5e work cell as one Diagram that owns everything it uses.

    .. pydrake_system::

        name: Station
        input_ports:
        - ur5e.position_command
        output_ports:
        - ur5e.position_measured
        - ur5e.velocity_measured
        - ur5e.state
        - ur5e.body_poses
        - ur5e.contact_results
        - ... (every plant output port)
        - query_object

    (``ur5e`` is ``config.model_name``.) ``position_command`` and the measured
    positions and speeds are (6,) in UR joint order; ``state`` is (12,); ``query_object``
    is SceneGraph's, for distance queries against the obstacles and shells. Every other
    output port of the plant is exported too, named by :func:`plant_output_port_names`
    (``ur5e.body_poses``, ``ur5e.contact_results``, ``ur5e.generalized_contact_forces``,
    ``ur5e.plant_state``, ...).

    Parameters
    ----------
    workcell : Workcell, optional
        The whole scene; when given, the next five parameters are not used.
    X_WB : RigidTransform, optional
        Robot base in W (identity by default).
    X_tool0_E : RigidTransform, optional
        End-effector frame E on ``tool0`` (identity by default).
    obstacles, safety_shells : iterable of :class:`drake_lfd.core.tasks.Box`
    table : Box, optional
        See :func:`drake_lfd.robot.workcell.table_under_robot`.
    tool : tuple of ToolShape, optional
        Shapes on ``tool0`` (None: the default of ``X_tool0_E``, ``()``: none).
    meshcat : Meshcat, optional
        Adds a MeshcatVisualizer (illustration role) when given.
    config : StationConfig, optional

    Attributes
    ----------
    plant : MultibodyPlant
        The simulated (discrete) plant.
    scene_graph : SceneGraph
    model : ModelInstanceIndex
        The UR5e.
    scene : SceneGeometry
        Robot, obstacle, shell and table geometry ids and their names.
    controller_plant : MultibodyPlant
        A continuous, kinematics-only plant of the same arm, for the controllers wired
        outside (differential IK, the pipeline's law). Owned by the Diagram.
    controller_model : ModelInstanceIndex
    interpolator : StateInterpolatorWithDiscreteDerivative
    visualizer : MeshcatVisualizer or None
        The illustration visualizer ``ApplyVisualizationConfig`` added (recordings).
    config : StationConfig
    workcell : Workcell
    X_WB, X_tool0_E : RigidTransform
    obstacles, safety_shells : tuple of Box
    table : Box or None
        The work cell's, for short.
    """

    def __init__(
        self,
        *,
        workcell: Workcell | None = None,
        X_WB: RigidTransform | None = None,
        X_tool0_E: RigidTransform | None = None,
        obstacles: Iterable[Box] = (),
        safety_shells: Iterable[Box] = (),
        table: Box | None = None,
        tool=None,
        meshcat: Meshcat | None = None,
        config: StationConfig | None = None,
    ):
        super().__init__()
        config = StationConfig() if config is None else config
        self.config = config
        if workcell is None:
            workcell = Workcell.make(X_WB=X_WB, X_tool0_E=X_tool0_E, obstacles=obstacles,
                                     safety_shells=safety_shells, table=table, tool=tool)
        self.workcell = workcell
        self.X_WB, self.X_tool0_E = workcell.X_WB, workcell.X_tool0_E
        self.obstacles, self.safety_shells = workcell.obstacles, workcell.safety_shells
        self.table = workcell.table
        name = config.model_name
        builder = DiagramBuilder()
        # Drake's MultibodyPlantConfig: the step, SAP, and the plant's step as a discrete
        # update with its output ports computed from the current state (see the module
        # docstring).
        plant, scene_graph = AddMultibodyPlant(config.plant, builder)
        model = add_ur5e(plant, X_WB=self.X_WB, X_tool0_E=self.X_tool0_E, model_name=name)
        configure_ur5e_drive(plant, model, config.drive)
        weightless = config.gravity_compensation == "arm_weightless"
        if weightless:  # the servo carries no weight (see the module docstring)
            plant.set_gravity_enabled(model, False)
        scene = add_scene(plant, scene_graph, model=model, obstacles=self.obstacles,
                          safety_shells=self.safety_shells, table=self.table, tool=workcell.tool)
        plant.Finalize()
        # The desired state and the gravity compensation are in joint order, the actuators
        # in actuator order. They coincide for the shipped URDF; make sure.
        if not np.array_equal(plant.MakeActuationMatrix(), np.eye(NUM_JOINTS)):
            raise RuntimeError("UR5e actuators are not in joint order; the drive wiring assumes they are")

        controller_plant = MultibodyPlant(time_step=0.0)
        controller_model = add_ur5e(controller_plant, X_WB=self.X_WB, X_tool0_E=self.X_tool0_E, model_name=name)
        controller_plant.Finalize()
        # The Diagram keeps the controller plant alive (InverseDynamics and the controllers
        # wired outside only refer to it).
        SharedPointerSystem.AddToBuilder(builder, controller_plant)

        # Drive: command -> desired state -> PD actuators; gravity compensation fed forward.
        interpolator = builder.AddNamedSystem(
            "position_command_interpolator",
            StateInterpolatorWithDiscreteDerivative(NUM_JOINTS, config.command_period,
                                                    suppress_initial_transient=True),
        )
        builder.Connect(interpolator.get_output_port(), plant.get_desired_state_input_port(model))
        if not weightless:
            gravity_compensation = builder.AddNamedSystem(
                "gravity_compensation",
                InverseDynamics(controller_plant, InverseDynamics.InverseDynamicsMode.kGravityCompensation))
            builder.Connect(plant.get_state_output_port(model), gravity_compensation.get_input_port_estimated_state())
            builder.Connect(gravity_compensation.get_output_port_generalized_force(),
                            plant.get_actuation_input_port(model))

        state_split = builder.AddNamedSystem("state_split", Demultiplexer([NUM_JOINTS, NUM_JOINTS]))
        builder.Connect(plant.get_state_output_port(model), state_split.get_input_port(0))

        builder.ExportInput(interpolator.get_input_port(), f"{name}.position_command")
        builder.ExportOutput(state_split.get_output_port(0), f"{name}.position_measured")
        builder.ExportOutput(state_split.get_output_port(1), f"{name}.velocity_measured")
        plant_ports = plant_output_port_names(plant, model)
        builder.ExportOutput(plant_ports.pop(f"{name}.state"), f"{name}.state")  # third, as it always was
        for port_name, port in plant_ports.items():
            builder.ExportOutput(port, port_name)
        builder.ExportOutput(scene_graph.get_query_output_port(), "query_object")

        self.visualizer = None
        if meshcat is not None:
            self.visualizer = _add_visualization(builder, config.visualization, plant, scene_graph, meshcat)
        builder.BuildInto(self)
        self.set_name("station")
        self.plant = plant
        self.scene_graph = scene_graph
        self.model = model
        self.scene: SceneGeometry = scene
        self.controller_plant = controller_plant
        self.controller_model = controller_model
        self.interpolator = interpolator

    @staticmethod
    def AddToBuilder(*, builder: DiagramBuilder, name: str = "station", **kwargs) -> "Station":
        """Adds a station named ``name`` (``kwargs``: the constructor's: ``workcell``,
        ``meshcat``, ``config``, ...); wire its ``ur5e.*`` ports as you need."""
        return builder.AddNamedSystem(name, Station(**kwargs))

    @property
    def model_name(self) -> str:
        return self.config.model_name

    @property
    def time_step(self) -> float:
        """The plant's discrete step, s."""
        return self.plant.time_step()

    def port_name(self, quantity: str) -> str:
        """``"ur5e.position_command"`` for ``"position_command"``."""
        return f"{self.config.model_name}.{quantity}"

    def set_initial_positions(self, root_context: Context, q: np.ndarray) -> None:
        """Puts the arm at rest at ``q`` (6,) with the drive holding ``q``.

        ``root_context`` is the context of the diagram holding the station (or of the
        station itself).
        """
        q = np.asarray(q, dtype=float)
        plant_context = self.plant.GetMyMutableContextFromRoot(root_context)
        self.plant.SetPositions(plant_context, self.model, q)
        self.plant.SetVelocities(plant_context, self.model, np.zeros(NUM_JOINTS))
        self.interpolator.set_initial_position(self.interpolator.GetMyMutableContextFromRoot(root_context), q)


def plant_output_port_names(plant: MultibodyPlant, model: ModelInstanceIndex) -> dict:
    """The Station's name for each of ``plant``'s output ports: ``{name: port}``.

    As the manipulation course's station exports its plant's ports, prefixed by model:

    - a port of one model instance, ``<instance>_<quantity>`` in the plant, is
      ``<instance>.<quantity>`` (``ur5e.state``, ``ur5e.generalized_contact_forces``,
      ``WorldModelInstance.net_actuation``, ...);
    - a plant-wide port ``<quantity>`` is ``<model>.<quantity>`` with ``model`` the
      arm's name (``ur5e.body_poses``, ``ur5e.contact_results``, ``ur5e.geometry_pose``,
      ...), or ``<model>.plant_<quantity>`` where the arm's own port has that name
      (``ur5e.plant_state``: the whole plant's state, next to the arm's ``ur5e.state``;
      likewise ``generalized_acceleration`` and ``net_actuation``).
    """
    per_instance = {}
    for i in range(plant.num_model_instances()):
        instance = ModelInstanceIndex(i)
        instance_name = plant.GetModelInstanceName(instance)
        for port in (plant.get_state_output_port(instance), plant.get_generalized_acceleration_output_port(instance),
                     plant.get_net_actuation_output_port(instance),
                     plant.get_generalized_contact_forces_output_port(instance)):
            quantity = port.get_name().removeprefix(f"{instance_name}_")
            per_instance[int(port.get_index())] = f"{instance_name}.{quantity}"
    prefix = plant.GetModelInstanceName(model)
    taken = set(per_instance.values())
    names = {}
    for i in range(plant.num_output_ports()):
        port = plant.get_output_port(i)
        name = per_instance.get(i)
        if name is None:
            name = f"{prefix}.{port.get_name()}"
            if name in taken:
                name = f"{prefix}.plant_{port.get_name()}"
        names[name] = port
    return names


def _add_visualization(builder: DiagramBuilder, config: VisualizationConfig, plant: MultibodyPlant,
                       scene_graph: SceneGraph, meshcat: Meshcat) -> MeshcatVisualizer | None:
    """Applies ``config`` with Drake's ``ApplyVisualizationConfig`` to ``meshcat`` alone.

    The LCM bus is Drake's "no LCM" (``ApplyLcmBusConfig`` with a null bus): no LCM
    publisher is added, nothing leaves the process. Returns the illustration
    MeshcatVisualizer (for recordings), or None when ``config`` publishes none.
    """
    lcm_buses = ApplyLcmBusConfig({config.lcm_bus: None}, builder)
    ApplyVisualizationConfig(config, builder, lcm_buses=lcm_buses, plant=plant, scene_graph=scene_graph,
                             meshcat=meshcat)
    if not config.publish_illustration:
        return None
    return builder.GetSubsystemByName("meshcat_visualizer(illustration)")


def build_station(**kwargs) -> Station:
    """Builds the UR5e station Diagram; the keyword arguments are :class:`Station`'s."""
    return Station(**kwargs)
