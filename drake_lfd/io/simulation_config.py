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

Not for: building anything (``station.py``, ``pipeline.py``) or the task itself.
"""

# No "from __future__ import annotations": yaml_load_typed needs the real field types.

import dataclasses
import math


from drake_lfd.core.errors import InputError

__all__ = [
    "DriveConfig",
    "StationConfig",
    "ControllerConfig",
    "MonitorConfig",
    "PlannerSystemConfig",
    "JointCheckConfig",
    "PipelineConfig",
    "STATION_TIME_STEP_S",
    "CLOSED_LOOP_TIME_STEP_S",
    "COMPILED_METHOD",
    "CONTROLLER_METHODS",
]

# The plant step of a bare station (fine enough for any use) and of a closed-loop run
# (5 ms: tracks as well as 1 ms, 0.086 mm against 0.032 mm at the critical
# configurations, at about 3x the speed; benchmarks/bench_closed_loop.py).
STATION_TIME_STEP_S = 1e-3
CLOSED_LOOP_TIME_STEP_S = 5e-3

# The controller methods: the compiled joint-space tracker (the default; Drake's C++
# systems, ``systems/joint_trajectory_controller.py``), and the Python task-space
# controller with Drake's differential-IK law or the paper's pseudo-inverse (Eq. 35-38).
COMPILED_METHOD = "compiled"
CONTROLLER_METHODS = (COMPILED_METHOD, "drake", "pseudo_inverse")


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


@dataclasses.dataclass
class StationConfig:
    """The station: plant step, drive, command sampling, visualisation.

    Attributes
    ----------
    time_step : float
        The discrete plant's step, s.
    command_period : float
        Period at which the drive samples the position command, s; match the rate of
        whatever produces it (the differential-IK period).
    drive : DriveConfig
    visualizer_publish_period : float
        Meshcat frame period, s (when a Meshcat is given).
    model_name : str
        Robot model instance name and prefix of the exported ports.
    sampled_output_ports : bool
        Drake's sampled output ports for the plant (its step an unrestricted update);
        off: the step is a discrete update and the outputs follow the current state
        (``station.py``).
    """

    time_step: float = STATION_TIME_STEP_S
    command_period: float = 0.01
    drive: DriveConfig = dataclasses.field(default_factory=DriveConfig)
    visualizer_publish_period: float = 1.0 / 32.0
    model_name: str = "ur5e"
    sampled_output_ports: bool = False


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
    time_step: float = 0.01
    position_gain: float = 20.0
    velocity_limit_fraction: float = 0.97


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

    period: float = 0.01
    stop_on_penetration: bool = False
    from_log: bool = True


@dataclasses.dataclass
class PlannerSystemConfig:
    """The planner system: how often it looks for a changed task or library (s)."""

    check_period: float = 0.05


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

    elbow_margin: float = 0.06
    wrist_margin: float = 0.06
    shoulder_margin_m: float = 0.05
    clearance_m: float = 0.01


@dataclasses.dataclass
class PipelineConfig:
    """Everything a closed-loop run is configured by.

    Attributes
    ----------
    station : StationConfig
        Its ``time_step`` defaults to the closed-loop step (5 ms) here.
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
    controller: ControllerConfig = dataclasses.field(default_factory=ControllerConfig)
    monitor: MonitorConfig = dataclasses.field(default_factory=MonitorConfig)
    planner: PlannerSystemConfig = dataclasses.field(default_factory=PlannerSystemConfig)
    joint_check: JointCheckConfig = dataclasses.field(default_factory=JointCheckConfig)
    log_period: float = 0.01
    settle_s: float = 0.5

    def checked(self, *, file: str | None = None) -> "PipelineConfig":
        """Itself after range checks (positive periods, six gains, known method), with
        the drive's command period tied to the controller's; raises InputError."""
        def positive(value, field):
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                raise InputError(f"must be a finite number > 0, got {value!r}", file=file,
                                 field=f"simulation.{field}")

        positive(self.station.time_step, "station.time_step")
        positive(self.controller.time_step, "controller.time_step")
        positive(self.monitor.period, "monitor.period")
        positive(self.planner.check_period, "planner.check_period")
        for name in ("elbow_margin", "wrist_margin"):
            value = getattr(self.joint_check, name)
            if not (isinstance(value, (int, float)) and 0.0 <= value < 1.0):
                raise InputError(f"must be a number in [0, 1), got {value!r}", file=file,
                                 field=f"simulation.joint_check.{name}")
        for name in ("shoulder_margin_m", "clearance_m"):
            value = getattr(self.joint_check, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value >= 0.0):
                raise InputError(f"must be a finite number >= 0, got {value!r}", file=file,
                                 field=f"simulation.joint_check.{name}")
        positive(self.log_period, "log_period")
        positive(self.station.visualizer_publish_period, "station.visualizer_publish_period")
        positive(self.station.drive.gear_ratio, "station.drive.gear_ratio")
        if not (math.isfinite(self.settle_s) and self.settle_s >= 0):
            raise InputError(f"must be a finite number >= 0, got {self.settle_s!r}", file=file,
                             field="simulation.settle_s")
        if self.controller.method not in CONTROLLER_METHODS:
            raise InputError(f"must be one of {', '.join(repr(m) for m in CONTROLLER_METHODS)}, "
                             f"got {self.controller.method!r}",
                             file=file, field="simulation.controller.method")
        if not 0 < self.controller.velocity_limit_fraction <= 1:
            raise InputError("must be in (0, 1]", file=file, field="simulation.controller.velocity_limit_fraction")
        drive = self.station.drive
        for name in ("proportional_gains", "derivative_gains", "rotor_inertia_kg_m2"):
            values = getattr(drive, name)
            if len(values) != 6 or not all(math.isfinite(v) and v >= 0 for v in values):
                raise InputError("must be six finite numbers >= 0", file=file,
                                 field=f"simulation.station.drive.{name}")
        return dataclasses.replace(
            self, station=dataclasses.replace(self.station, command_period=self.controller.time_step))
