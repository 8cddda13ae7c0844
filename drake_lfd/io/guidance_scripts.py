"""Guidance scripts: the YAML of a simulated kinesthetic demonstration, read and checked.

A guidance script is YAML, loaded with ``pydrake.common.yaml.yaml_load_typed`` into the
``*Spec`` dataclasses below (unknown keys are errors), then checked value by value into a
:class:`~drake_lfd.core.guidance.GuidanceScript`. The format is documented for users in
docs/guidance_scripts.rst; every problem is one :class:`~drake_lfd.core.errors.InputError`
naming the file and the field (``waypoints[1].p[0]``, list indices from 0).

Guidance script (every key except ``name`` and ``waypoints`` optional; unknown keys are
errors)::

    name: screw_cw
    description: twist a screwdriver 90 deg clockwise while pushing it in
    X_WB: {p: [0, 0, 0], euler_zyx: [0, 0, 0]}        # robot base in W (identity)
    X_tool0_E: {p: [0, 0, 0], euler_zyx: [0, 0, 0]}   # frame E on tool0 (identity)
    waypoints:            # poses of E in W; t in seconds, strictly increasing
      - {t: 0.0, p: [0.40, 0.20, 0.35], euler_zyx: [0, 0, pi]}
      - {t: 3.0, p: [0.40, 0.20, 0.27], euler_zyx: [pi/2, 0, pi]}
    hold_s: 0.5           # the hand holds the last waypoint this long (>= 0.2)
    hand_noise:           # set the sizes to 0 for a perfectly steady hand
      position_m: 0.001   # RMS size of the positional wobble
      rotation_deg: 0.5   # RMS angle of the rotational wobble
      speed_variation: 0.05   # peak relative deviation of the pace (0.05 = +-5 %)
      frequency_hz: [0.2, 0.8]  # band of the wobble's frequencies
    seed: 1               # the noise is a pure function of the seed
    sample_rate_hz: 500   # logging rate (the UR's RTDE rate)

Orientations are ``euler_zyx: [yaw, pitch, roll]``, ``R = Rz(yaw) Ry(pitch) Rx(roll)``
(docs/method.rst, Conventions); angles may be written as in task files (``pi/2``,
``-90deg``). Consecutive waypoints must differ by less than a half turn (ScLERP takes
the short way round): split larger turns with an intermediate waypoint.

Not for: the hand's path (:mod:`drake_lfd.core.guidance`), simulating the recording
(:mod:`drake_lfd.diagrams.kinesthetic`), reading joint logs
(:mod:`drake_lfd.io.demonstration_logs`).
"""

# No ``from __future__ import annotations``: yaml_load_typed reads the Spec fields'
# types from dataclasses.fields(), which would then be strings.
import dataclasses
import math
from pathlib import Path

from drake_lfd.core.demonstrations import RTDE_RATE_HZ
from drake_lfd.core.errors import InputError
from drake_lfd.core.guidance import (
    DEFAULT_HOLD_S,
    KINESTHETIC_TIME_STEP_S,
    GuidanceScript,
    HandNoise,
    Waypoint,
)
# The YAML checks (schema check naming the exact field, duplicate keys refused, angle
# spellings) are shared with task files, so scripts and tasks report problems alike.
from drake_lfd.io.yaml_checks import PoseSpec, Scalar, load_spec, read_text, required
from drake_lfd.io.yaml_values import finite, pose, vector

__all__ = [
    "request_guidance_yaml",
    "MIN_HOLD_S",
    "MAX_WAYPOINT_TURN_RAD",
    "WaypointSpec",
    "HandNoiseSpec",
    "GuidanceScriptSpec",
    "guidance_script_spec_from_text",
    "guidance_script_from_spec",
    "guidance_script_from_text",
    "load_guidance_script",
]

# The arm needs this long at the last waypoint to settle before the log ends.
MIN_HOLD_S = 0.2
# The largest turn between consecutive waypoints (ScLERP is ambiguous at a half turn).
MAX_WAYPOINT_TURN_RAD = math.radians(179.0)


# ------------------------------------------------------------------ schema (the YAML)


@dataclasses.dataclass
class WaypointSpec:
    """One guidance waypoint: time ``t`` (s), position ``p`` (m), ``euler_zyx`` (rad)."""

    t: float = required(float)
    p: list[float] = required(list)
    euler_zyx: list[Scalar] = required(list)


@dataclasses.dataclass
class HandNoiseSpec:
    """How unsteady the guiding hand is (see the module docstring)."""

    position_m: float = 0.001
    rotation_deg: float = 0.5
    speed_variation: float = 0.05
    frequency_hz: list[float] = dataclasses.field(default_factory=lambda: [0.2, 0.8])


@dataclasses.dataclass
class GuidanceScriptSpec:
    """A guidance script file as written (structure checked, values not yet)."""

    name: str = required(str)
    description: str = ""
    X_WB: PoseSpec = dataclasses.field(default_factory=PoseSpec)
    X_tool0_E: PoseSpec = dataclasses.field(default_factory=PoseSpec)
    waypoints: list[WaypointSpec] = required(list)
    hold_s: float = DEFAULT_HOLD_S
    hand_noise: HandNoiseSpec = dataclasses.field(default_factory=HandNoiseSpec)
    seed: int = 0
    sample_rate_hz: float = RTDE_RATE_HZ


# ------------------------------------------------------------------ checking


def guidance_script_spec_from_text(text, *, file=None) -> GuidanceScriptSpec:
    """Parses a guidance script's YAML into a :class:`GuidanceScriptSpec`.

    Raises
    ------
    InputError
        Invalid YAML, a duplicated or unknown key, a missing or mistyped value.
    """
    return load_spec(text, GuidanceScriptSpec, file=file, document="the guidance script", keys="script keys")


def guidance_script_from_spec(spec: GuidanceScriptSpec, *, file=None) -> GuidanceScript:
    """Checks the values of a :class:`GuidanceScriptSpec`.

    Raises
    ------
    InputError
        Naming the field: non-finite numbers, fewer than 2 waypoints, times not
        increasing, a half turn or more between waypoints, bad noise sizes or rates.
    """
    if not spec.name.strip():
        raise InputError("a guidance script needs a non-empty name", file=file, field="name")
    X_WB = pose(spec.X_WB, file=file, field="X_WB")
    X_tool0_E = pose(spec.X_tool0_E, file=file, field="X_tool0_E")
    if len(spec.waypoints) < 2:
        raise InputError(
            f"has {len(spec.waypoints)} waypoint(s); a guidance needs at least 2", file=file, field="waypoints"
        )
    waypoints = []
    for index, item in enumerate(spec.waypoints):
        field = f"waypoints[{index}]"
        t = finite(item.t, file=file, field=f"{field}.t")
        if t < 0.0:
            raise InputError(f"times start at 0, got {t:g}", file=file, field=f"{field}.t")
        if waypoints and not t > waypoints[-1].t:
            raise InputError(
                f"t = {t:g} s is not after the previous waypoint's {waypoints[-1].t:g} s; "
                "times must strictly increase",
                file=file,
                field=f"{field}.t",
            )
        X_WE = pose(item, file=file, field=field)
        if waypoints:
            turn = waypoints[-1].X_WE.rotation().InvertAndCompose(X_WE.rotation()).ToAngleAxis().angle()
            if turn > MAX_WAYPOINT_TURN_RAD:
                raise InputError(
                    f"turns {math.degrees(turn):.1f} deg from the previous waypoint; screw "
                    f"interpolation needs less than {math.degrees(MAX_WAYPOINT_TURN_RAD):.0f} deg "
                    "(add an intermediate waypoint)",
                    file=file,
                    field=f"{field}.euler_zyx",
                )
        waypoints.append(Waypoint(t=t, X_WE=X_WE))
    hold_s = finite(spec.hold_s, file=file, field="hold_s")
    if hold_s < MIN_HOLD_S:
        raise InputError(
            f"{hold_s:g} s is too short for the arm to settle; use >= {MIN_HOLD_S:g} s", file=file, field="hold_s"
        )
    noise = spec.hand_noise
    sizes = {}
    for key in ("position_m", "rotation_deg", "speed_variation"):
        value = finite(getattr(noise, key), file=file, field=f"hand_noise.{key}")
        if value < 0.0:
            raise InputError(f"must be >= 0, got {value:g}", file=file, field=f"hand_noise.{key}")
        sizes[key] = value
    if sizes["speed_variation"] >= 0.5:
        raise InputError(
            f"must be < 0.5 (the pace may not stop or reverse), got {sizes['speed_variation']:g}",
            file=file,
            field="hand_noise.speed_variation",
        )
    band = vector(noise.frequency_hz, 2, file=file, field="hand_noise.frequency_hz", convert=finite)
    if not 0.0 < band[0] <= band[1]:
        raise InputError(
            f"expected [low, high] with 0 < low <= high, got [{band[0]:g}, {band[1]:g}]",
            file=file,
            field="hand_noise.frequency_hz",
        )
    rate = finite(spec.sample_rate_hz, file=file, field="sample_rate_hz")
    if not 1.0 <= rate <= 1.0 / KINESTHETIC_TIME_STEP_S:
        raise InputError(
            f"must be between 1 and {1.0 / KINESTHETIC_TIME_STEP_S:g} Hz (the simulation's rate), got {rate:g}",
            file=file,
            field="sample_rate_hz",
        )
    return GuidanceScript(
        name=spec.name,
        description=spec.description,
        waypoints=tuple(waypoints),
        X_WB=X_WB,
        X_tool0_E=X_tool0_E,
        hold_s=hold_s,
        hand_noise=HandNoise(
            position_m=sizes["position_m"],
            rotation_rad=math.radians(sizes["rotation_deg"]),
            speed_variation=sizes["speed_variation"],
            frequency_hz=(float(band[0]), float(band[1])),
        ),
        seed=int(spec.seed),
        sample_rate_hz=rate,
        source=None if file is None else str(file),
    )


def guidance_script_from_text(text, *, file=None) -> GuidanceScript:
    """Parses and checks a guidance script given as YAML text; ``file`` names it in errors."""
    return guidance_script_from_spec(guidance_script_spec_from_text(text, file=file), file=file)


def request_guidance_yaml(task, segment, *, duration_s: float = 3.0, path=None) -> str:
    """A guidance script (YAML text, ready to edit) of the motion a demonstration request
    asks for: E from ``segment``'s con_from pose to its con_to pose in the task's frames,
    split into steps under :data:`MAX_WAYPOINT_TURN_RAD`, for ``drake-lfd record``.

    ``segment`` is a :class:`~drake_lfd.planning.planner.UncoveredSegment` carrying its
    poses; ``task`` the concrete task (name, base and tool frames); ``path`` where the
    script is written, as the user named it (the comment's commands record that file
    and add the log beside it; without it, a file named after the segment).
    """
    import shlex

    import numpy as np
    from pydrake.math import RigidTransform, RollPitchYaw

    from drake_lfd.core.pose_conversions import matrices_from_dual_quaternion
    from drake_lfd.core.screw_motion import dual_quaternion_sclerp

    def euler(X):
        rpy = RollPitchYaw(X.rotation())
        return [rpy.yaw_angle(), rpy.pitch_angle(), rpy.roll_angle()]

    def pose_text(X):
        p = ", ".join(f"{v:.6g}" for v in X.translation())
        e = ", ".join(f"{v:.8g}" for v in euler(X))
        return f"p: [{p}], euler_zyx: [{e}]"

    D_from, D_to = np.asarray(segment.pose_from, dtype=float), np.asarray(segment.pose_to, dtype=float)
    steps = max(1, int(math.ceil(abs(segment.angle_rad) / (0.9 * MAX_WAYPOINT_TURN_RAD))))
    waypoints = []
    for i in range(steps + 1):
        D = dual_quaternion_sclerp(D_from, D_to, i / steps) if 0 < i < steps else (D_from if i == 0 else D_to)
        X = RigidTransform(matrices_from_dual_quaternion(np.asarray(D)[None])[0])
        waypoints.append(f"  - {{t: {duration_s * i / steps:.3g}, {pose_text(X)}}}")
    name = f"{task.name}_con_{segment.con_from}_con_{segment.con_to}"
    script = Path(f"{name}.yaml") if path is None else Path(path)
    log = script.with_suffix(".csv")
    axis = ", ".join(f"{a:.2f}" for a in segment.axis)
    move = ", ".join(f"{t:.3f}" for t in segment.translation_m)
    lines = [
        f"# The demonstration {task.name} asks for: E from con_{segment.con_from} to con_{segment.con_to},",
        f"# turning {math.degrees(segment.angle_rad):.0f} deg about body axis [{axis}] while moving [{move}] m",
        f"# (in con_{segment.con_from}'s frame). Edit the waypoints to show how a person does it",
        "# (the path between the ends is what the library learns), then:",
        f"#   drake-lfd record {shlex.quote(str(script))} --out {shlex.quote(str(log))}",
        f"#   drake-lfd library add LIB {shlex.quote(str(log))} --name NAME",
        f"name: {name}",
        f"description: the motion {task.name} needs from con_{segment.con_from} to con_{segment.con_to}",
        f"X_WB: {{{pose_text(task.X_WB)}}}",
        f"X_tool0_E: {{{pose_text(task.X_tool0_E)}}}",
        "waypoints:",
        *waypoints,
        "hold_s: 0.5",
        "hand_noise: {position_m: 0.001, rotation_deg: 0.5, speed_variation: 0.05, frequency_hz: [0.2, 0.8]}",
        "seed: 1",
        "sample_rate_hz: 500",
    ]
    return "\n".join(lines) + "\n"


def load_guidance_script(path) -> GuidanceScript:
    """Reads and checks a guidance script file.

    Raises
    ------
    InputError
        One line naming the file and the field (see :func:`guidance_script_from_spec`).
    """
    path = Path(path)
    text = read_text(path, directory_problem="is a directory, not a guidance script")
    return guidance_script_from_text(text, file=path)
