"""Typed configuration of the simulated work cell and the closed loop.

Every gain, step and period of the station, the controller, the shell monitor, the
joint logger and the planner system lives in one of these dataclasses, with the measured
defaults, so a scenario can change them without code. A task file may carry them in an
optional ``simulation:`` block, which :mod:`drake_lfd.io.task_files` loads (Drake's
``yaml_load_typed``; unknown keys are errors) and checks with :meth:`PipelineConfig.checked`::

    simulation:
      station: {time_step: 0.002}
      controller: {method: pseudo_inverse, position_gain: 10.0}
      settle_s: 0.3

The plant, the simulator and the visualisation are configured by Drake's own structs,
loaded the same way and applied with Drake's functions (as the manipulation course's
scenarios do): ``station.plant`` is a ``MultibodyPlantConfig`` (``ApplyMultibodyPlantConfig``),
``station.visualization`` a ``VisualizationConfig`` (``ApplyVisualizationConfig``) and
``simulator`` a ``SimulatorConfig`` (``ApplySimulatorConfig``)::

    simulation:
      station:
        plant: {time_step: 0.002, penetration_allowance: 0.002}
        visualization: {publish_period: 0.05, publish_proximity: true}
      simulator: {target_realtime_rate: 1.0}

``station.time_step``, ``station.sampled_output_ports`` and
``station.visualizer_publish_period`` are the older, shorter spellings of
``station.plant.time_step``, ``station.plant.use_sampled_output_ports`` and
``station.visualization.publish_period``: the same values, stored once, in the structs.

Not for: building anything (``station.py``, ``pipeline.py``) or the task itself.
"""

# No "from __future__ import annotations": yaml_load_typed needs the real field types.

import copy
import dataclasses
import math

from pydrake.multibody.plant import ApplyMultibodyPlantConfig, MultibodyPlant, MultibodyPlantConfig
from pydrake.systems.analysis import ApplySimulatorConfig, Simulator, SimulatorConfig
from pydrake.systems.primitives import ConstantVectorSource
from pydrake.common.yaml import yaml_dump_typed, yaml_load_typed
from pydrake.visualization import VisualizationConfig

from drake_lfd.core.errors import InputError
# The closed sets of the block's words and its range checks are plain Python (the command
# line checks a block before Drake loads), stated there once.
from drake_lfd.io.simulation_schema import (
    COMPILED_METHOD,
    CONTROLLER_METHODS,
    GRAVITY_COMPENSATIONS,
    check_simulation_values,
)
from drake_lfd.robot.differential_ik_law import (
    DEFAULT_POSITION_GAIN,
    DEFAULT_TIME_STEP_S,
    DEFAULT_VELOCITY_LIMIT_FRACTION,
)
from drake_lfd.robot.joint_path_records import JointPathLimits

__all__ = [
    "DriveConfig",
    "StationConfig",
    "ControllerConfig",
    "MonitorConfig",
    "PlannerSystemConfig",
    "JointCheckConfig",
    "PipelineConfig",
    "plant_config",
    "visualization_config",
    "STATION_TIME_STEP_S",
    "CLOSED_LOOP_TIME_STEP_S",
    "COMPILED_METHOD",
    "CONTROLLER_METHODS",
    "GRAVITY_COMPENSATIONS",
    "DEFAULT_MONITOR_PERIOD_S",
    "DEFAULT_CHECK_PERIOD_S",
]

# The defaults of the closed loop's systems, each stated once: the controller's are the
# differential-IK law's (robot/differential_ik_law.py), the joint check's margins
# JointPathLimits' (robot/joint_path_records.py); these two are the systems' own, which
# systems/shell_monitor.py and systems/planner.py take from here.
#: The shell monitor's sampling period, s.
DEFAULT_MONITOR_PERIOD_S = 0.01
#: How often the planner system (and the feature library system) look for a changed
#: task or library, s.
DEFAULT_CHECK_PERIOD_S = 0.05

# The plant step of a bare station (fine enough for any use) and of a closed-loop run
# (5 ms: tracks the critical configurations as well as 1 ms, far inside the success
# tolerances, at several times the speed; benchmarks/bench_closed_loop.py).
STATION_TIME_STEP_S = 1e-3
CLOSED_LOOP_TIME_STEP_S = 5e-3

# The discrete contact approximations that support the drive's PD-controlled actuators
# (with "tamsi", Drake's continuous-era solver, they would silently do nothing).
PD_CONTACT_APPROXIMATIONS = ("sap", "similar", "lagged")

# The Meshcat frame period of a station (s): 32 frames a second.
VISUALIZER_PUBLISH_PERIOD_S = 1.0 / 32.0


def plant_config(time_step: float = STATION_TIME_STEP_S) -> MultibodyPlantConfig:
    """The station plant's ``MultibodyPlantConfig``: Drake's defaults but for three.

    - ``time_step``: ``time_step`` (s).
    - ``discrete_contact_approximation="sap"``: with ``"lagged"`` (Drake's default) or
      ``"tamsi"`` the PD-controlled actuators of the drive are not supported.
    - ``use_sampled_output_ports=False``: the plant's step a discrete update, its outputs
      computed from the current state (``diagrams/station.py``).

    Every other field (contact model, penetration allowance, stiction tolerance, ...)
    is Drake's default, which is also what a plant made with
    ``AddMultibodyPlantSceneGraph(builder, time_step)`` has.
    """
    return MultibodyPlantConfig(time_step=time_step, discrete_contact_approximation="sap",
                                use_sampled_output_ports=False)


def visualization_config() -> VisualizationConfig:
    """The station's ``VisualizationConfig``: the illustration geometry only, 32 frames a
    second.

    Drake's default also publishes the proximity geometry, the contact forces and the
    inertias; each is one field away (``publish_proximity: true``, ...). Used only when
    the station is given a Meshcat.
    """
    return VisualizationConfig(publish_period=VISUALIZER_PUBLISH_PERIOD_S, publish_proximity=False,
                               publish_contacts=False, publish_inertia=False)


class _OwnedStruct:
    """A dataclass field holding a Drake config struct that the instance owns.

    Every value set (by the constructor, an assignment or the YAML loader) is stored as a
    deep copy, so no two configs share a struct and writing through one of the short
    spellings (:class:`_StructField`) never changes another config. The default is
    ``factory()``.
    """

    def __init__(self, factory):
        self._factory = factory

    def __set_name__(self, owner, name):
        self._slot = f"_{name}"

    def __get__(self, instance, owner=None):
        if instance is None:
            return self._factory()  # the dataclass default; copied when set
        return instance.__dict__[self._slot]

    def __set__(self, instance, value):
        instance.__dict__[self._slot] = copy.deepcopy(value)


class _StructField:
    """A dataclass field that is another name for an attribute of a Drake config struct.

    ``StationConfig.time_step`` reads and writes ``StationConfig.plant.time_step``: a
    value set through either spelling (constructor keyword, attribute, YAML key) is the
    one value the station uses. The field's default (None) leaves the struct's value.
    """

    def __init__(self, struct: str, attribute: str):
        self._struct = struct
        self._attribute = attribute

    def __set_name__(self, owner, name):
        self._name = name

    def __get__(self, instance, owner=None):
        if instance is None:
            return None  # the dataclass default: keep the struct's value
        return getattr(getattr(instance, self._struct), self._attribute)

    def __set__(self, instance, value):
        if value is not None:
            setattr(getattr(instance, self._struct), self._attribute, value)


class _PicklableStructs:
    """Pickling for a config holding Drake's structs (which do not pickle): each struct
    travels as its type and its YAML (``yaml_dump_typed``), and is loaded back with
    ``yaml_load_typed``, so configs reach worker processes (``--workers``)."""

    def __getstate__(self):
        state = dict(self.__dict__)
        for key, value in state.items():
            if hasattr(type(value), "__fields__"):
                state[key] = _DrakeStruct(type(value), yaml_dump_typed(value))
        return state

    def __setstate__(self, state):
        for key, value in state.items():
            if isinstance(value, _DrakeStruct):
                state[key] = yaml_load_typed(schema=value.schema, data=value.yaml)
        self.__dict__.update(state)

    def __deepcopy__(self, memo):
        # Drake's structs deep-copy directly (no YAML round trip: a task's config is
        # copied whenever a Context clones the task it travels with).
        new = object.__new__(type(self))
        memo[id(self)] = new
        new.__dict__.update({key: copy.deepcopy(value, memo) for key, value in self.__dict__.items()})
        return new


@dataclasses.dataclass(frozen=True)
class _DrakeStruct:
    schema: type
    yaml: str


def _struct_fields(struct) -> tuple:
    """The values of a Drake config struct's serialized fields, for comparisons."""
    return tuple((field.name, repr(getattr(struct, field.name))) for field in type(struct).__fields__)


@dataclasses.dataclass
class DriveConfig:
    """The UR5e's joint servos: PD gains, rotor inertia and gear ratio, per joint.

    The gains are omega^2 I and 2 zeta omega I (zeta = 1) for a position bandwidth of
    about 40 rad/s (shoulder with the arm outstretched, I = 3 kg m^2), 50 rad/s (elbow,
    I = 1.2) and 55 rad/s (wrists, I = 0.1 with the reflected rotor inertia). With
    velocity feed-forward, a servo's tracking error is about I qddot / Kp: under 1 mrad
    for a 0.25 m/s tool motion. UR does not publish rotor inertias; these are the order
    of magnitude of frameless servo motors of the joint sizes, reflected through the
    101:1 strain-wave gear (x 101^2).
    """

    proportional_gains: list[float] = dataclasses.field(
        default_factory=lambda: [4800.0, 4800.0, 3000.0, 300.0, 300.0, 300.0])
    derivative_gains: list[float] = dataclasses.field(
        default_factory=lambda: [240.0, 240.0, 120.0, 11.0, 11.0, 11.0])
    rotor_inertia_kg_m2: list[float] = dataclasses.field(
        default_factory=lambda: [3.5e-5, 3.5e-5, 3.5e-5, 1.0e-5, 1.0e-5, 1.0e-5])
    gear_ratio: float = 101.0


@dataclasses.dataclass(eq=False)
class StationConfig(_PicklableStructs):
    """The station: plant, drive, command sampling, visualisation.

    Attributes
    ----------
    plant : pydrake.multibody.plant.MultibodyPlantConfig
        The plant (Drake's struct, applied with ``ApplyMultibodyPlantConfig``); see
        :func:`plant_config` for the defaults.
    visualization : pydrake.visualization.VisualizationConfig
        What a Meshcat given to the station shows (Drake's struct, applied with
        ``ApplyVisualizationConfig``); see :func:`visualization_config`.
    time_step : float
        The discrete plant's step, s: ``plant.time_step``.
    command_period : float
        Period at which the drive samples the position command, s; match the rate of
        whatever produces it (the differential-IK period).
    drive : DriveConfig
    visualizer_publish_period : float
        Meshcat frame period, s: ``visualization.publish_period``.
    model_name : str
        Robot model instance name and prefix of the exported ports.
    sampled_output_ports : bool
        Drake's sampled output ports for the plant (its step an unrestricted update);
        off: the step is a discrete update and the outputs follow the current state
        (``station.py``). ``plant.use_sampled_output_ports``.
    gravity_compensation : {"inverse_dynamics", "arm_weightless"}
        How the drive carries the arm's weight: ``inverse_dynamics`` (the default), the
        gravity torques of a second, kinematics-only plant fed forward to the actuation,
        as a UR5e's controller does, so the links keep their weight and the actuators'
        effort limits see it; ``arm_weightless``, gravity switched off on the arm
        (``MultibodyPlant.set_gravity_enabled``, as the manipulation course's station
        does), one call and about 15 % less simulation time. Both track identically.

    ``time_step``, ``visualizer_publish_period`` and ``sampled_output_ports`` are stored
    in the structs; given with the struct to the constructor, they win.
    """

    # The structs come first: the constructor sets them before their short spellings.
    plant: MultibodyPlantConfig = _OwnedStruct(plant_config)
    visualization: VisualizationConfig = _OwnedStruct(visualization_config)
    time_step: float = _StructField("plant", "time_step")
    command_period: float = 0.01
    drive: DriveConfig = dataclasses.field(default_factory=DriveConfig)
    visualizer_publish_period: float = _StructField("visualization", "publish_period")
    model_name: str = "ur5e"
    sampled_output_ports: bool = _StructField("plant", "use_sampled_output_ports")
    gravity_compensation: str = "inverse_dynamics"

    def __eq__(self, other):
        if not isinstance(other, StationConfig):
            return NotImplemented
        return (_struct_fields(self.plant) == _struct_fields(other.plant)
                and _struct_fields(self.visualization) == _struct_fields(other.visualization)
                and (self.command_period, self.drive, self.model_name, self.gravity_compensation)
                == (other.command_period, other.drive, other.model_name, other.gravity_compensation))


@dataclasses.dataclass
class ControllerConfig:
    """The differential-IK controller (see :mod:`drake_lfd.systems.differential_ik`).

    Attributes
    ----------
    method : str
        ``"compiled"`` (the plan's joint path tracked by compiled Drake systems, the same
        feedback in joint space, :mod:`drake_lfd.systems.joint_trajectory_controller`),
        ``"drake"`` (the Python task-space controller with Drake's differential IK and
        joint limits) or ``"pseudo_inverse"`` (the Python controller with the paper's
        Eq. 35-38).
    time_step : float
        Update period, s; also the drive's command period in a closed loop.
    position_gain : float
        Feedback gain on the pose error, 1/s.
    velocity_limit_fraction : float
        Fraction of the UR5e's joint speed limits the controller may command.
    """

    method: str = COMPILED_METHOD
    time_step: float = DEFAULT_TIME_STEP_S
    position_gain: float = DEFAULT_POSITION_GAIN
    velocity_limit_fraction: float = DEFAULT_VELOCITY_LIMIT_FRACTION


@dataclasses.dataclass
class MonitorConfig:
    """The shell monitor (:mod:`drake_lfd.systems.shell_monitor`).

    Attributes
    ----------
    period : float
        Sampling period, s.
    stop_on_penetration : bool
        A penetration ends the run (at its sample: the monitor then samples itself).
    from_log : bool
        Measure the joint-state log's samples in batches (at each critical configuration
        and at the end of a run), not with a Python event every period; the records are
        the same. Needs the logger's period; a stop at a penetration samples with events.
    """

    period: float = DEFAULT_MONITOR_PERIOD_S
    stop_on_penetration: bool = False
    from_log: bool = True


@dataclasses.dataclass
class PlannerSystemConfig:
    """The planner system: how often it looks for a changed task or library (s)."""

    check_period: float = DEFAULT_CHECK_PERIOD_S


@dataclasses.dataclass
class JointCheckConfig:
    """The plan-time joint-space check (:mod:`drake_lfd.robot.joint_path`): the margins a
    planned joint path must keep (docs/method.rst, Executable plans).

    Attributes
    ----------
    elbow_margin, wrist_margin : float
        Least ``|sin q3|`` (elbow straight) and ``|sin q5|`` (wrist aligned), in (0, 1).
    shoulder_margin_m : float
        Least distance of the wrist point from the shoulder axis, m.
    clearance_m : float
        Least distance of every link and tool shape to obstacles, shells and the table, m.
    """

    elbow_margin: float = JointPathLimits.elbow_margin
    wrist_margin: float = JointPathLimits.wrist_margin
    shoulder_margin_m: float = JointPathLimits.shoulder_margin_m
    clearance_m: float = JointPathLimits.clearance_m


@dataclasses.dataclass(eq=False)
class PipelineConfig(_PicklableStructs):
    """Everything a closed-loop run is configured by.

    Attributes
    ----------
    station : StationConfig
        Its ``time_step`` defaults to the closed-loop step (5 ms) here.
    simulator : pydrake.systems.analysis.SimulatorConfig
        The run's Simulator (Drake's struct, applied with ``ApplySimulatorConfig``). The
        default is a fresh Simulator's own settings (RK3 integrator, 0.1 s largest step,
        accuracy 1e-4 with error control, no real-time pacing, no publish at every step),
        so applying it changes nothing.
    controller : ControllerConfig
    monitor : MonitorConfig
    planner : PlannerSystemConfig
    log_period : float
        Joint-state logger period, s.
    settle_s : float
        Time at rest before the plan starts, s.
    """

    station: StationConfig = dataclasses.field(
        default_factory=lambda: StationConfig(time_step=CLOSED_LOOP_TIME_STEP_S))
    simulator: SimulatorConfig = _OwnedStruct(SimulatorConfig)
    controller: ControllerConfig = dataclasses.field(default_factory=ControllerConfig)
    monitor: MonitorConfig = dataclasses.field(default_factory=MonitorConfig)
    planner: PlannerSystemConfig = dataclasses.field(default_factory=PlannerSystemConfig)
    joint_check: JointCheckConfig = dataclasses.field(default_factory=JointCheckConfig)
    log_period: float = 0.01
    settle_s: float = 0.5

    def __eq__(self, other):
        if not isinstance(other, PipelineConfig):
            return NotImplemented
        return all(
            (_struct_fields(getattr(self, f.name)) == _struct_fields(getattr(other, f.name)))
            if f.name == "simulator" else getattr(self, f.name) == getattr(other, f.name)
            for f in dataclasses.fields(self))

    def checked(self, *, file: str | None = None) -> "PipelineConfig":
        """Itself after the range checks of
        :func:`~drake_lfd.io.simulation_schema.check_simulation_values` (positive periods,
        six gains, known method; Drake judges its structs), with the drive's command period
        tied to the controller's; raises InputError."""
        check_simulation_values(self, file=file, judge_plant=lambda: _check_plant_config(self.station.plant, file),
                                judge_simulator=lambda: _check_simulator_config(self.simulator, file))
        return dataclasses.replace(
            self, station=dataclasses.replace(self.station, command_period=self.controller.time_step))



def _first_line(error: Exception) -> str:
    return str(error).strip().splitlines()[0] if str(error).strip() else type(error).__name__


def _check_plant_config(config: MultibodyPlantConfig, file) -> None:
    """Raises InputError unless Drake accepts ``config`` for the station's plant.

    The strings Drake knows (contact model, surface representation) are judged by Drake:
    applied, one at a time, to a throwaway plant.
    """
    if config.discrete_contact_approximation not in PD_CONTACT_APPROXIMATIONS:
        raise InputError(
            f"must be one of {', '.join(repr(a) for a in PD_CONTACT_APPROXIMATIONS)} (the drive's PD-controlled "
            f"actuators need SAP), got {config.discrete_contact_approximation!r}",
            file=file, field="simulation.station.plant.discrete_contact_approximation")
    for name in ("penetration_allowance", "stiction_tolerance", "sap_near_rigid_threshold"):
        value = getattr(config, name)
        if not (math.isfinite(value) and value >= 0):
            raise InputError(f"must be a finite number >= 0, got {value!r}", file=file,
                             field=f"simulation.station.plant.{name}")
    for name in ("contact_model", "contact_surface_representation"):
        trial = plant_config()
        setattr(trial, name, getattr(config, name))
        try:
            ApplyMultibodyPlantConfig(trial, MultibodyPlant(trial.time_step))
        except Exception as error:  # Drake's own message names the accepted values
            raise InputError(_first_line(error), file=file, field=f"simulation.station.plant.{name}") from None


def _check_simulator_config(config: SimulatorConfig, file) -> None:
    """Raises InputError unless Drake accepts ``config`` for a Simulator (the integration
    scheme judged by Drake, on a throwaway one)."""
    for name in ("max_step_size", "accuracy"):
        value = getattr(config, name)
        if not (math.isfinite(value) and value > 0):
            raise InputError(f"must be a finite number > 0, got {value!r}", file=file,
                             field=f"simulation.simulator.{name}")
    for name in ("start_time", "target_realtime_rate"):
        value = getattr(config, name)
        if not (math.isfinite(value) and value >= 0):
            raise InputError(f"must be a finite number >= 0, got {value!r}", file=file,
                             field=f"simulation.simulator.{name}")
    trial = SimulatorConfig(integration_scheme=config.integration_scheme)
    try:
        ApplySimulatorConfig(trial, Simulator(ConstantVectorSource([0.0])))
    except Exception as error:
        raise InputError(_first_line(error), file=file, field="simulation.simulator.integration_scheme") from None
