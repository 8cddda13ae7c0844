"""The ``simulation:`` block's own keys and the range checks of its values, in plain Python.

A task file's ``simulation:`` block is loaded into :class:`~drake_lfd.io.simulation_config.PipelineConfig`,
whose fields are either drake-lfd's dataclasses (the station's drive and command period,
the controller, the monitor, the planner system, the joint check, the log period, the
settling time) or Drake's config structs (``station.plant``, ``station.visualization``,
``simulator``). The ``*Spec`` dataclasses here have the same keys, in the same order, with
the same kinds of values (``tests/test_task_checks.py`` compares them), so a block without
Drake's structs is checked before Drake is imported, with the loader's messages; every
value is None where the file is silent (the config's default, which passes).
:func:`check_simulation_values` is the one list of range checks: ``PipelineConfig.checked``
runs it on a loaded config (with Drake judging its structs), the early check on a
:class:`SimulationSpec`.

Not for: the config itself or its defaults (``simulation_config.py``), building anything.
"""

# No ``from __future__ import annotations``: check_schema reads the fields' types at run time.
import dataclasses
import math
from typing import Any, Optional

from drake_lfd.core.errors import InputError

__all__ = [
    "COMPILED_METHOD",
    "CONTROLLER_METHODS",
    "GRAVITY_COMPENSATIONS",
    "DRAKE_STRUCT_KEYS",
    "DriveSpec",
    "StationSpec",
    "ControllerSpec",
    "MonitorSpec",
    "PlannerSystemSpec",
    "JointCheckSpec",
    "SimulationSpec",
    "drake_struct_keys_in",
    "check_simulation_values",
]

# The controller methods: the compiled joint-space tracker (the default; Drake's C++
# systems, ``systems/joint_trajectory_controller.py``), and the Python task-space
# controller with Drake's differential-IK law or the paper's pseudo-inverse (Eq. 35-38).
COMPILED_METHOD = "compiled"
CONTROLLER_METHODS = (COMPILED_METHOD, "drake", "pseudo_inverse")
# How the drive carries the arm's weight (StationConfig.gravity_compensation).
GRAVITY_COMPENSATIONS = ("inverse_dynamics", "arm_weightless")

#: The keys whose values are Drake's config structs, by the block they are in: only
#: Drake knows their keys and judges their values.
DRAKE_STRUCT_KEYS = {"": ("simulator",), "station": ("plant", "visualization")}

# A None default below is "absent": the config's own default, which every check passes.
_ABSENT: Any = None


@dataclasses.dataclass
class DriveSpec:
    """``simulation.station.drive`` (``DriveConfig``)."""

    proportional_gains: list[float] = _ABSENT
    derivative_gains: list[float] = _ABSENT
    rotor_inertia_kg_m2: list[float] = _ABSENT
    gear_ratio: float = _ABSENT


@dataclasses.dataclass
class StationSpec:
    """``simulation.station`` (``StationConfig``); ``plant`` and ``visualization`` are
    Drake's structs."""

    plant: Optional[dict] = _ABSENT
    visualization: Optional[dict] = _ABSENT
    time_step: float = _ABSENT
    command_period: float = _ABSENT
    drive: DriveSpec = dataclasses.field(default_factory=DriveSpec)
    visualizer_publish_period: float = _ABSENT
    model_name: str = _ABSENT
    sampled_output_ports: bool = _ABSENT
    gravity_compensation: str = _ABSENT


@dataclasses.dataclass
class ControllerSpec:
    """``simulation.controller`` (``ControllerConfig``)."""

    method: str = _ABSENT
    time_step: float = _ABSENT
    position_gain: float = _ABSENT
    velocity_limit_fraction: float = _ABSENT


@dataclasses.dataclass
class MonitorSpec:
    """``simulation.monitor`` (``MonitorConfig``)."""

    period: float = _ABSENT
    stop_on_penetration: bool = _ABSENT
    from_log: bool = _ABSENT


@dataclasses.dataclass
class PlannerSystemSpec:
    """``simulation.planner`` (``PlannerSystemConfig``)."""

    check_period: float = _ABSENT


@dataclasses.dataclass
class JointCheckSpec:
    """``simulation.joint_check`` (``JointCheckConfig``)."""

    elbow_margin: float = _ABSENT
    wrist_margin: float = _ABSENT
    shoulder_margin_m: float = _ABSENT
    clearance_m: float = _ABSENT


@dataclasses.dataclass
class SimulationSpec:
    """The ``simulation:`` block (``PipelineConfig``); ``simulator`` is Drake's struct."""

    station: StationSpec = dataclasses.field(default_factory=StationSpec)
    simulator: Optional[dict] = _ABSENT
    controller: ControllerSpec = dataclasses.field(default_factory=ControllerSpec)
    monitor: MonitorSpec = dataclasses.field(default_factory=MonitorSpec)
    planner: PlannerSystemSpec = dataclasses.field(default_factory=PlannerSystemSpec)
    joint_check: JointCheckSpec = dataclasses.field(default_factory=JointCheckSpec)
    log_period: float = _ABSENT
    settle_s: float = _ABSENT

    def checked(self, *, file=None) -> "SimulationSpec":
        """Itself after :func:`check_simulation_values` (as ``PipelineConfig.checked``)."""
        check_simulation_values(self, file=file)
        return self


def drake_struct_keys_in(block) -> list[str]:
    """The keys of Drake's structs a raw ``simulation:`` mapping sets (``station.plant``, ...)."""
    found = []
    if not isinstance(block, dict):
        return found
    for path, keys in DRAKE_STRUCT_KEYS.items():
        inner = block.get(path) if path else block
        if isinstance(inner, dict):
            found += [f"{path}.{key}" if path else key for key in keys if key in inner]
    return found


def check_simulation_values(config, *, file=None, judge_plant=None, judge_simulator=None) -> None:
    """The range checks of a ``simulation:`` block, in order: positive periods and gear
    ratio, margins in [0, 1), distances >= 0, a known controller method and gravity
    compensation, six gains. ``config`` is a ``PipelineConfig`` or a :class:`SimulationSpec`
    (a None value is absent and passes); ``judge_plant`` and ``judge_simulator``, when
    given, judge Drake's structs at their place in the order.

    Raises
    ------
    InputError
        Naming ``simulation.<field>``.
    """
    def positive(value, field):
        if value is not None and not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
            raise InputError(f"must be a finite number > 0, got {value!r}", file=file, field=f"simulation.{field}")

    station, controller, joint_check = config.station, config.controller, config.joint_check
    positive(station.time_step, "station.time_step")
    if judge_plant is not None:
        judge_plant()
    gravity = station.gravity_compensation
    if gravity is not None and gravity not in GRAVITY_COMPENSATIONS:
        raise InputError(f"must be one of {', '.join(GRAVITY_COMPENSATIONS)}, got {gravity!r}", file=file,
                         field="simulation.station.gravity_compensation")
    if judge_simulator is not None:
        judge_simulator()
    positive(controller.time_step, "controller.time_step")
    positive(config.monitor.period, "monitor.period")
    positive(config.planner.check_period, "planner.check_period")
    for name in ("elbow_margin", "wrist_margin"):
        value = getattr(joint_check, name)
        if value is not None and not (isinstance(value, (int, float)) and 0.0 <= value < 1.0):
            raise InputError(f"must be a number in [0, 1), got {value!r}", file=file,
                             field=f"simulation.joint_check.{name}")
    for name in ("shoulder_margin_m", "clearance_m"):
        value = getattr(joint_check, name)
        if value is not None and not (isinstance(value, (int, float)) and math.isfinite(value) and value >= 0.0):
            raise InputError(f"must be a finite number >= 0, got {value!r}", file=file,
                             field=f"simulation.joint_check.{name}")
    positive(config.log_period, "log_period")
    positive(station.visualizer_publish_period, "station.visualization.publish_period")
    positive(station.drive.gear_ratio, "station.drive.gear_ratio")
    settle = config.settle_s
    if settle is not None and not (math.isfinite(settle) and settle >= 0):
        raise InputError(f"must be a finite number >= 0, got {settle!r}", file=file, field="simulation.settle_s")
    method = controller.method
    if method is not None and method not in CONTROLLER_METHODS:
        raise InputError(f"must be one of {', '.join(repr(m) for m in CONTROLLER_METHODS)}, got {method!r}",
                         file=file, field="simulation.controller.method")
    fraction = controller.velocity_limit_fraction
    if fraction is not None and not 0 < fraction <= 1:
        raise InputError("must be in (0, 1]", file=file, field="simulation.controller.velocity_limit_fraction")
    for name in ("proportional_gains", "derivative_gains", "rotor_inertia_kg_m2"):
        values = getattr(station.drive, name)
        if values is not None and (len(values) != 6 or not all(math.isfinite(v) and v >= 0 for v in values)):
            raise InputError("must be six finite numbers >= 0", file=file, field=f"simulation.station.drive.{name}")
