"""Kinesthetic demonstrations in simulation: a virtual hand guides a free-driven UR5e.

On the real robot a person switches the UR5e to free drive (the controller cancels
gravity and adds a little damping) and pulls the tool along the motion while the
controller logs the joints over RTDE. This module does the same in Drake:

- the UR5e is a discrete MultibodyPlant (1 ms, SAP) whose actuation is gravity
  compensation only (``InverseDynamics`` in gravity-compensation mode on a kinematics
  plant); the free-drive damping is viscous joint damping, which the discrete solver
  integrates implicitly (an explicit damping torque on wrist 3, whose inertia about its
  axis is 4e-4 kg m^2, would go unstable at 1 ms);
- a :class:`VirtualHand` pulls the end-effector frame E towards the guidance pose with a
  spring-damper wrench (``ExternallyAppliedSpatialForce``), capped at what a hand exerts;
- the guidance pose comes from a *guidance script* (YAML, below): waypoints joined by
  screw motions (ScLERP) with a minimum-jerk time profile, perturbed like a human hand
  (seeded smooth wobble of about a millimetre and half a degree, and a slightly uneven
  pace), then held still at the last waypoint so the arm settles;
- a :class:`~drake_lfd.systems.demo_recorder.DemoRecorder` samples the measured joints at the
  RTDE rate (500 Hz) into an RTDE-style CSV.

The arm starts at rest at the inverse-kinematics solution of the first waypoint with an
elbow-up preference (:func:`initial_joint_positions`, from ``initial_ik.py``). Nothing
here commands joint positions: the recorded joints are whatever the arm's dynamics made
of the hand's pull.

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
(SPEC 2); angles may be written as in task files (``pi/2``, ``-90deg``). Consecutive
waypoints must differ by less than a half turn (ScLERP takes the short way round): split
larger turns with an intermediate waypoint.

Not for: reading or storing logs (``demonstrations.py``, ``library.py``), executing
plans (the closed-loop modules).
"""

# No ``from __future__ import annotations``: yaml_load_typed reads the Spec fields'
# types from dataclasses.fields(), which would then be strings.
import dataclasses
import math
import time
from pathlib import Path
from typing import Callable, NamedTuple

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.multibody.math import SpatialForce, SpatialVelocity
from pydrake.multibody.plant import (
    DiscreteContactApproximation,
    ExternallyAppliedSpatialForce_,
    MultibodyPlant,
)
from pydrake.systems.analysis import Simulator
from pydrake.systems.controllers import InverseDynamics
from pydrake.systems.framework import DiagramBuilder, LeafSystem
from pydrake.systems.primitives import Demultiplexer

from drake_lfd.systems.demo_recorder import RTDE_RATE_HZ, DemoRecorder
from drake_lfd.io.demonstration_logs import Demonstration
from drake_lfd.core.dual_quaternion import (
    axis_angle_from_quaternion,
    dual_quaternion_from_matrices,
    dual_quaternion_from_pose,
    dual_quaternion_from_rigid_transform,
    dual_quaternion_relative,
    dual_quaternion_sclerp,
    matrices_from_dual_quaternion,
    pose_from_dual_quaternion,
    quaternion_conjugate,
    quaternion_from_rotation_vector,
    quaternion_multiply,
    rotation_vector_from_quaternion,
)
from drake_lfd.core.errors import InputError
from drake_lfd.robot.initial_ik import UnreachableConfigurationError, solve_initial_configuration
from drake_lfd.robot.kinematics import (
    END_EFFECTOR_FRAME_NAME,
    NUM_JOINTS,
    UR5E_JOINT_NAMES,
    UR5eKinematics,
    add_ur5e,
)
from drake_lfd.io.task_files import PoseSpec

# The YAML checks (schema check naming the exact field, duplicate keys refused, angle
# spellings) are shared with task files, so scripts and tasks report problems alike.
from drake_lfd.io.yaml_checks import Scalar, finite, load_spec, pose, read_text, required, vector

PLANT_TIME_STEP_S = 1e-3
DEFAULT_HOLD_S = 0.5
MIN_HOLD_S = 0.2
# Free-drive damping per joint (N m s/rad), shoulder_pan .. wrist_3: enough that the arm
# stops within a few tenths of a second when the hand stops, small against the hand's
# pull (a 1 rad/s shoulder motion costs 2 N m, about 4 N at the tool).
FREE_DRIVE_DAMPING = (2.0, 2.0, 1.5, 0.3, 0.3, 0.2)
# A guided arm that ends farther than this from the last waypoint did not follow the
# hand (out of reach, a joint limit, a singularity): the script is at fault.
MAX_FINAL_POSITION_ERROR_M = 0.005
MAX_FINAL_ROTATION_ERROR_RAD = math.radians(2.0)
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


# ------------------------------------------------------------------ checked script


@dataclasses.dataclass(frozen=True)
class Waypoint:
    """A guidance pose ``X_WE`` to be reached at time ``t`` (s)."""

    t: float
    X_WE: RigidTransform


@dataclasses.dataclass(frozen=True)
class HandNoise:
    """Human-hand irregularities added to the guidance (all sizes >= 0).

    Attributes
    ----------
    position_m : float
        RMS length of the positional wobble vector.
    rotation_rad : float
        RMS angle of the rotational wobble.
    speed_variation : float
        Peak relative deviation of the pace from the script's timing, in [0, 0.5).
    frequency_hz : tuple of 2 floats
        Band ``(low, high)`` the wobble's frequencies are drawn from.
    """

    position_m: float = 0.001
    rotation_rad: float = math.radians(0.5)
    speed_variation: float = 0.05
    frequency_hz: tuple[float, float] = (0.2, 0.8)


STEADY_HAND = HandNoise(position_m=0.0, rotation_rad=0.0, speed_variation=0.0)


@dataclasses.dataclass(frozen=True)
class GuidanceScript:
    """A checked guidance script (:func:`load_guidance_script`).

    Attributes
    ----------
    name, description : str
    waypoints : tuple of Waypoint
        At least 2, times strictly increasing and >= 0.
    X_WB, X_tool0_E : RigidTransform
    hold_s : float
        How long the hand holds the last waypoint.
    hand_noise : HandNoise
    seed : int
    sample_rate_hz : float
    source : str or None
        The file it came from, named in error messages.
    """

    name: str
    waypoints: tuple[Waypoint, ...]
    description: str = ""
    X_WB: RigidTransform = dataclasses.field(default_factory=RigidTransform)
    X_tool0_E: RigidTransform = dataclasses.field(default_factory=RigidTransform)
    hold_s: float = DEFAULT_HOLD_S
    hand_noise: HandNoise = HandNoise()
    seed: int = 0
    sample_rate_hz: float = RTDE_RATE_HZ
    source: str | None = None

    @property
    def duration_s(self) -> float:
        """Length of the recording: the last waypoint's time plus the hold."""
        return float(self.waypoints[-1].t + self.hold_s)

    @property
    def times(self) -> np.ndarray:
        """Waypoint times, array shape (n,)."""
        return np.array([w.t for w in self.waypoints], dtype=float)

    def waypoint_dual_quaternions(self) -> np.ndarray:
        """Waypoint poses ``X_WE`` as dual quaternions, array shape (n, 8)."""
        return np.stack([dual_quaternion_from_rigid_transform(w.X_WE) for w in self.waypoints])


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
    if not 1.0 <= rate <= 1.0 / PLANT_TIME_STEP_S:
        raise InputError(
            f"must be between 1 and {1.0 / PLANT_TIME_STEP_S:g} Hz (the simulation's rate), got {rate:g}",
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


# ------------------------------------------------------------------ guidance path (numpy)


def minimum_jerk(tau):
    """Minimum-jerk profile ``10 u^3 - 15 u^4 + 6 u^5`` of ``u = clip(tau, 0, 1)``."""
    u = np.clip(np.asarray(tau, dtype=float), 0.0, 1.0)
    return u * u * u * (10.0 + u * (-15.0 + 6.0 * u))


def _smoothstep(u):
    u = np.clip(u, 0.0, 1.0)
    return u * u * (3.0 - 2.0 * u)


class _Sinusoids(NamedTuple):
    amplitude: np.ndarray  # (..., k)
    omega: np.ndarray  # (..., k) rad/s
    phase: np.ndarray  # (..., k)

    def value(self, t):
        """Sum over the last axis, at times t (N,): shape (N, ...)."""
        t = np.asarray(t, dtype=float).reshape((-1,) + (1,) * self.amplitude.ndim)
        return np.sum(self.amplitude * np.sin(self.omega * t + self.phase), axis=-1)


# Sinusoids per wobble component: few enough to stay smooth, enough not to look periodic.
_WOBBLE_TERMS = 3
# The wobble fades in over this long at the start (the hand takes hold of the tool).
_WOBBLE_RAMP_IN_S = 0.3
# It fades out over this fraction of the hold, so the arm settles at the last waypoint.
_WOBBLE_FADE_OUT_FRACTION = 0.6


class GuidancePath:
    """The pose the guiding hand wants for frame E at every time, ``X_WH(t)``.

    Waypoints are joined by ScLERP with a minimum-jerk profile in each interval, so the
    hand starts and stops at every waypoint, as a person placing a tool does. The hand's
    irregularities, all drawn from ``numpy.random.default_rng(script.seed)``:

    - pace: script time ``tau(t) = t + n(t) - t n(T)/T`` with ``n`` a sum of sinusoids
      whose rate ``n'`` peaks at ``speed_variation``, so the waypoints keep their order,
      the first and last waypoint keep their times and the pace varies by a few percent;
    - wobble: a smooth offset (sums of sinusoids in the ``frequency_hz`` band) of the
      position, in W, and of the orientation, about E's own axes, with the RMS sizes of
      :class:`HandNoise`; it fades in over the first 0.3 s and out during the hold.

    Parameters
    ----------
    script : GuidanceScript
    """

    def __init__(self, script: GuidanceScript):
        self.script = script
        self.waypoint_times = script.times
        self.waypoint_poses = script.waypoint_dual_quaternions()
        self.duration_s = script.duration_s
        noise = script.hand_noise
        rng = np.random.default_rng(script.seed)
        low, high = noise.frequency_hz
        # Pace. Splitting speed_variation over the terms bounds |n'| by it.
        weights = rng.uniform(0.5, 1.0, _WOBBLE_TERMS)
        self._pace = _Sinusoids(
            amplitude=noise.speed_variation * weights / weights.sum(),
            omega=2.0 * np.pi * rng.uniform(low, high, _WOBBLE_TERMS),
            phase=rng.uniform(0.0, 2.0 * np.pi, _WOBBLE_TERMS),
        )
        self._position = self._wobble(rng, noise.position_m, noise.frequency_hz)
        self._rotation = self._wobble(rng, noise.rotation_rad, noise.frequency_hz)

    @staticmethod
    def _wobble(rng, rms, frequency_hz):
        """Three components, each a sum of sinusoids, scaled to RMS vector length ``rms``."""
        amplitude = rng.normal(size=(3, _WOBBLE_TERMS))
        omega = 2.0 * np.pi * rng.uniform(*frequency_hz, size=(3, _WOBBLE_TERMS))
        phase = rng.uniform(0.0, 2.0 * np.pi, size=(3, _WOBBLE_TERMS))
        # Over a long time the mean square of a sum of sinusoids is sum(a^2) / 2.
        amplitude *= rms / math.sqrt(0.5 * float(np.sum(amplitude * amplitude)))
        return _Sinusoids(amplitude=amplitude, omega=omega, phase=phase)

    def _pace_integral(self, t):
        # n(t) = sum a/w (sin(w t + phi) - sin(phi)), n'(t) = sum a cos(w t + phi).
        pace = self._pace
        t = np.asarray(t, dtype=float)[:, None]
        return np.sum(pace.amplitude / pace.omega * (np.sin(pace.omega * t + pace.phase) - np.sin(pace.phase)), axis=-1)

    def script_time(self, t):
        """Script time ``tau(t)`` reached at wall time ``t`` (the uneven pace), shape (N,)."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        T = self.waypoint_times[-1]
        if T <= 0.0:
            return t.copy()
        inside = (t > 0.0) & (t < T)
        tau = t.copy()
        n_T = self._pace_integral(np.array([T]))[0]
        tau[inside] = t[inside] + self._pace_integral(t[inside]) - t[inside] * n_T / T
        return tau

    def nominal_poses(self, tau):
        """Poses of the scripted motion (no hand noise) at script times ``tau``, (N, 8)."""
        tau = np.atleast_1d(np.asarray(tau, dtype=float))
        times = self.waypoint_times
        segment = np.clip(np.searchsorted(times, tau, side="right") - 1, 0, len(times) - 2)
        start, end = times[segment], times[segment + 1]
        s = minimum_jerk((tau - start) / (end - start))
        return dual_quaternion_sclerp(self.waypoint_poses[segment], self.waypoint_poses[segment + 1], s)

    def wobble_envelope(self, t):
        """0..1 weight of the wobble at times ``t``, shape (N,)."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        fade = max(_WOBBLE_FADE_OUT_FRACTION * self.script.hold_s, 1e-9)
        return _smoothstep(t / _WOBBLE_RAMP_IN_S) * (1.0 - _smoothstep((t - self.waypoint_times[-1]) / fade))

    def wobble(self, t):
        """Position offset in W (N, 3) and rotation vector in E (N, 3) at times ``t``."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        envelope = self.wobble_envelope(t)[:, None]
        return envelope * self._position.value(t), envelope * self._rotation.value(t)

    def poses(self, t):
        """The hand's poses ``X_WH`` at times ``t`` (pace and wobble applied), (N, 8)."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        p_nominal, r_nominal = pose_from_dual_quaternion(self.nominal_poses(self.script_time(t)))
        dp_W, dtheta_E = self.wobble(t)
        r = quaternion_multiply(r_nominal, quaternion_from_rotation_vector(dtheta_E))
        return dual_quaternion_from_pose(p_nominal + dp_W, r)

    def sample(self, time_step_s):
        """The hand's pose and velocity every ``time_step_s`` from 0 to past the end."""
        count = int(math.ceil(self.duration_s / time_step_s)) + 2
        t = np.arange(count) * time_step_s
        D = self.poses(t)
        p, q = pose_from_dual_quaternion(D)
        R = matrices_from_dual_quaternion(D)[:, :3, :3]
        v = np.gradient(p, time_step_s, axis=0)
        # Angular velocity in W from neighbouring orientations: log(r_next r_prev*) / dt.
        after = np.concatenate([q[1:], q[-1:]])
        before = np.concatenate([q[:1], q[:-1]])
        spans = np.concatenate([[1.0], np.full(count - 2, 2.0), [1.0]]) * time_step_s
        w = rotation_vector_from_quaternion(quaternion_multiply(after, quaternion_conjugate(before))) / spans[:, None]
        return SampledGuidance(time_step_s=time_step_s, p_WH=p, R_WH=R, v_WH=v, w_WH=w)


class SampledGuidance(NamedTuple):
    """The guidance on a regular time grid: what :class:`VirtualHand` looks up.

    Attributes
    ----------
    time_step_s : float
    p_WH : array, shape (N, 3)
    R_WH : array, shape (N, 3, 3)
    v_WH : array, shape (N, 3)
        Translational velocity, m/s.
    w_WH : array, shape (N, 3)
        Angular velocity in W, rad/s.
    """

    time_step_s: float
    p_WH: np.ndarray
    R_WH: np.ndarray
    v_WH: np.ndarray
    w_WH: np.ndarray

    def index(self, t) -> int:
        """Index of the sample nearest time ``t`` (clamped to the grid)."""
        return min(max(int(round(t / self.time_step_s)), 0), self.p_WH.shape[0] - 1)


# ------------------------------------------------------------------ the virtual hand


@dataclasses.dataclass(frozen=True)
class VirtualHandGains:
    """Spring-damper of the guiding hand on frame E, and the most a hand exerts.

    The rotational damping is applied explicitly (it is an external wrench), so it must
    stay below ``2 I / dt`` for the smallest inertia it acts on: wrist 3 about its axis,
    about 4e-4 kg m^2, allows 0.8 N m s/rad at 1 ms.
    """

    translational_stiffness: float = 2000.0  # N/m
    translational_damping: float = 60.0  # N s/m
    rotational_stiffness: float = 20.0  # N m/rad
    rotational_damping: float = 0.2  # N m s/rad
    max_force: float = 80.0  # N
    max_torque: float = 8.0  # N m


class VirtualHand(LeafSystem):
    """A hand pulling frame E towards the guidance pose with a spring-damper wrench.

    .. pydrake_system::

        name: VirtualHand
        input_ports:
        - body_poses
        - body_spatial_velocities
        output_ports:
        - spatial_force

    ``body_poses`` and ``body_spatial_velocities`` are the plant's outputs of those
    names; ``spatial_force`` (a list with one ``ExternallyAppliedSpatialForce``) goes to
    the plant's ``applied_spatial_force`` input. The wrench, applied at E's origin, is

        f = K_t (p_WH - p_WE) + D_t (v_WH - v_WE)
        tau = K_r log(R_WH R_WE^T) + D_r (w_WH - w_WE)

    with the guidance pose ``X_WH`` and velocity looked up in a :class:`SampledGuidance`
    at the nearest grid time; force and torque are capped at the gains' maxima.

    Parameters
    ----------
    guidance : SampledGuidance
    body_index : BodyIndex
        The body frame E is fixed to.
    X_BE : RigidTransform
        Pose of E in that body.
    gains : VirtualHandGains
    """

    def __init__(self, *, guidance: SampledGuidance, body_index, X_BE: RigidTransform, gains=VirtualHandGains()):
        super().__init__()
        self._guidance = guidance
        self._body = int(body_index)
        self._body_index = body_index
        self._p_BE = np.array(X_BE.translation())
        self._R_BE = np.array(X_BE.rotation().matrix())
        self._gains = gains
        self._body_poses_port = self.DeclareAbstractInputPort("body_poses", AbstractValue.Make([RigidTransform()]))
        self._body_velocities_port = self.DeclareAbstractInputPort(
            "body_spatial_velocities", AbstractValue.Make([SpatialVelocity()])
        )
        self.DeclareAbstractOutputPort(
            "spatial_force",
            lambda: AbstractValue.Make([ExternallyAppliedSpatialForce_[float]()]),
            self._calc_spatial_force,
        )

    def _calc_spatial_force(self, context, output):
        gains = self._gains
        guidance = self._guidance
        k = guidance.index(context.get_time())
        X_WB = self._body_poses_port.Eval(context)[self._body]
        V_WB = self._body_velocities_port.Eval(context)[self._body]
        R_WB = X_WB.rotation().matrix()
        p_BE_W = R_WB @ self._p_BE
        p_WE = X_WB.translation() + p_BE_W
        R_WE = R_WB @ self._R_BE
        w_WE = V_WB.rotational()
        v_WE = V_WB.translational() + np.cross(w_WE, p_BE_W)
        force = gains.translational_stiffness * (guidance.p_WH[k] - p_WE) + gains.translational_damping * (
            guidance.v_WH[k] - v_WE
        )
        rotation_error = RotationMatrix(guidance.R_WH[k] @ R_WE.T).ToAngleAxis()
        torque = gains.rotational_stiffness * rotation_error.angle() * rotation_error.axis() + (
            gains.rotational_damping * (guidance.w_WH[k] - w_WE)
        )
        force = _capped(force, gains.max_force)
        torque = _capped(torque, gains.max_torque)
        wrench = ExternallyAppliedSpatialForce_[float]()
        wrench.body_index = self._body_index
        wrench.p_BoBq_B = self._p_BE
        wrench.F_Bq_W = SpatialForce(tau=torque, f=force)
        output.set_value([wrench])


def _capped(vector, limit):
    norm = float(np.linalg.norm(vector))
    return vector if norm <= limit else vector * (limit / norm)


# ------------------------------------------------------------------ initial configuration


def initial_joint_positions(X_WE, *, X_WB=None, X_tool0_E=None, file=None, field=None):
    """Joint angles that put frame E at ``X_WE`` in an elbow-up posture.

    The project's initial inverse kinematics (``initial_ik.solve_initial_configuration``:
    Drake's ``InverseKinematics`` from a fixed list of guesses, cost towards an elbow-up
    posture facing the target; deterministic), with its error re-addressed to the script.

    Raises
    ------
    InputError
        The pose is out of reach, naming ``file`` and ``field``.
    """
    try:
        solution = solve_initial_configuration(RigidTransform(X_WE), X_WB=X_WB, X_tool0_E=X_tool0_E)
    except UnreachableConfigurationError:
        raise InputError(
            "no joint configuration of the UR5e reaches this pose (out of reach?)", file=file, field=field
        ) from None
    return np.array(solution.q, dtype=float)


# ------------------------------------------------------------------ the diagram


class KinestheticSetup(NamedTuple):
    """What :func:`make_kinesthetic_diagram` builds."""

    diagram: object
    plant: MultibodyPlant
    model: object
    hand: VirtualHand
    recorder: DemoRecorder
    guidance: GuidancePath
    q_initial: np.ndarray
    # InverseDynamics refers to this plant without owning it: keep it alive with the diagram.
    kinematics_plant: MultibodyPlant


def make_kinesthetic_diagram(
    script: GuidanceScript, *, gains=VirtualHandGains(), damping=FREE_DRIVE_DAMPING, time_step_s=PLANT_TIME_STEP_S
) -> KinestheticSetup:
    """The free-driven UR5e, the virtual hand and the RTDE-rate recorder, wired.

    Pipeline: ``plant.state -> InverseDynamics (gravity) -> plant.actuation``;
    ``plant.body_poses, body_spatial_velocities -> VirtualHand -> plant.applied_spatial_force``;
    ``plant.state -> positions -> DemoRecorder``. The plant's default positions are the
    initial configuration (:func:`initial_joint_positions` of the first waypoint).
    """
    first = script.waypoints[0]
    q_initial = initial_joint_positions(
        first.X_WE, X_WB=script.X_WB, X_tool0_E=script.X_tool0_E, file=script.source, field="waypoints[0]"
    )
    builder = DiagramBuilder()
    plant = builder.AddSystem(MultibodyPlant(time_step=time_step_s))
    plant.set_name("plant")
    # SAP (not TAMSI): it integrates joint damping implicitly and keeps the actuation input live.
    plant.set_discrete_contact_approximation(DiscreteContactApproximation.kSap)
    model = add_ur5e(plant, X_WB=script.X_WB, X_tool0_E=script.X_tool0_E)
    joints = [plant.GetJointByName(name, model) for name in UR5E_JOINT_NAMES]
    for joint, b in zip(joints, damping):
        joint.set_default_damping(float(b))
    plant.Finalize()
    for joint, q in zip(joints, q_initial):
        joint.set_default_angle(float(q))

    # Free drive: gravity compensation computed on a kinematics-only copy of the arm.
    kinematics_plant = MultibodyPlant(time_step=0.0)
    add_ur5e(kinematics_plant, X_WB=script.X_WB, X_tool0_E=script.X_tool0_E)
    kinematics_plant.Finalize()
    gravity = builder.AddSystem(
        InverseDynamics(kinematics_plant, InverseDynamics.InverseDynamicsMode.kGravityCompensation)
    )
    gravity.set_name("gravity_compensation")
    builder.Connect(plant.get_state_output_port(model), gravity.get_input_port_estimated_state())
    builder.Connect(gravity.get_output_port_generalized_force(), plant.get_actuation_input_port(model))

    frame_E = plant.GetFrameByName(END_EFFECTOR_FRAME_NAME)
    body = frame_E.body()
    X_BE = frame_E.GetFixedPoseInBodyFrame()
    guidance = GuidancePath(script)
    hand = builder.AddSystem(
        VirtualHand(guidance=guidance.sample(time_step_s), body_index=body.index(), X_BE=X_BE, gains=gains)
    )
    hand.set_name("virtual_hand")
    builder.Connect(plant.get_body_poses_output_port(), hand.GetInputPort("body_poses"))
    builder.Connect(plant.get_body_spatial_velocities_output_port(), hand.GetInputPort("body_spatial_velocities"))
    builder.Connect(hand.GetOutputPort("spatial_force"), plant.get_applied_spatial_force_input_port())

    positions = builder.AddSystem(Demultiplexer([NUM_JOINTS, NUM_JOINTS]))
    positions.set_name("measured_position")
    builder.Connect(plant.get_state_output_port(model), positions.get_input_port())
    recorder = DemoRecorder.AddToBuilder(
        builder, positions.get_output_port(0), num_joints=NUM_JOINTS, rate_hz=script.sample_rate_hz
    )
    diagram = builder.Build()
    diagram.set_name(f"kinesthetic_{script.name}")
    return KinestheticSetup(diagram, plant, model, hand, recorder, guidance, q_initial, kinematics_plant)


# ------------------------------------------------------------------ recording


@dataclasses.dataclass(frozen=True)
class RecordedDemonstration:
    """A simulated kinesthetic demonstration and how well the arm followed the hand.

    Attributes
    ----------
    demonstration : Demonstration
        The joint log at ``script.sample_rate_hz``.
    q_initial : array, shape (6,)
    max_position_error_m, max_rotation_error_rad : float
        Largest distance between frame E and the hand's pose over the log.
    final_position_error_m, final_rotation_error_rad : float
        Distance of the last sample from the last waypoint.
    sim_time_s, wall_time_s : float
    """

    demonstration: Demonstration
    q_initial: np.ndarray
    max_position_error_m: float
    max_rotation_error_rad: float
    final_position_error_m: float
    final_rotation_error_rad: float
    sim_time_s: float
    wall_time_s: float


def _pose_errors(D_a, D_b):
    """Position distance (m) and rotation angle (rad) between poses, each shape (N,)."""
    p_a = matrices_from_dual_quaternion(D_a)[:, :3, 3]
    p_b = matrices_from_dual_quaternion(D_b)[:, :3, 3]
    _, angle = axis_angle_from_quaternion(dual_quaternion_relative(D_a, D_b)[:, :4])
    return np.linalg.norm(p_b - p_a, axis=-1), angle


def record_demonstration(
    script: GuidanceScript,
    *,
    progress: Callable[[float, float], None] | None = None,
    progress_interval_s: float = 1.0,
    gains=VirtualHandGains(),
    damping=FREE_DRIVE_DAMPING,
) -> RecordedDemonstration:
    """Simulates the guided demonstration of ``script`` and returns its joint log.

    Parameters
    ----------
    script : GuidanceScript
    progress : callable(sim_time_s, duration_s), optional
        Called every ``progress_interval_s`` of simulated time and at the end.

    Raises
    ------
    InputError
        The first waypoint is out of reach, or the arm ended farther than 5 mm / 2 deg
        from the last waypoint (it could not follow: out of reach, a joint limit or a
        singularity on the way).
    """
    wall_start = time.perf_counter()
    setup = make_kinesthetic_diagram(script, gains=gains, damping=damping)
    simulator = Simulator(setup.diagram)
    simulator.Initialize()
    duration = script.duration_s
    t = 0.0
    while t < duration:
        t = min(duration, t + progress_interval_s)
        simulator.AdvanceTo(t)
        if progress is not None:
            progress(t, duration)
    demonstration = setup.recorder.demonstration(script.name, script.description)

    kinematics = UR5eKinematics(X_WB=script.X_WB, X_tool0_E=script.X_tool0_E)
    D_measured = dual_quaternion_from_matrices(kinematics.X_WE_batch(demonstration.joint_positions))
    D_hand = setup.guidance.poses(demonstration.timestamps)
    p_error, r_error = _pose_errors(D_measured, D_hand)
    final_p, final_r = _pose_errors(D_measured[-1:], setup.guidance.waypoint_poses[-1:])
    if final_p[0] > MAX_FINAL_POSITION_ERROR_M or final_r[0] > MAX_FINAL_ROTATION_ERROR_RAD:
        worst = int(np.argmax(p_error / MAX_FINAL_POSITION_ERROR_M + r_error / MAX_FINAL_ROTATION_ERROR_RAD))
        raise InputError(
            f"the arm did not follow the hand: it ended {1000 * final_p[0]:.1f} mm / "
            f"{math.degrees(final_r[0]):.1f} deg from the last waypoint (worst at t = "
            f"{demonstration.timestamps[worst]:.2f} s: {1000 * p_error[worst]:.0f} mm, "
            f"{math.degrees(r_error[worst]):.0f} deg); a pose is out of reach or the path "
            "crosses a joint limit or a singularity",
            file=script.source,
            field=f"waypoints[{len(script.waypoints) - 1}]",
        )
    return RecordedDemonstration(
        demonstration=demonstration,
        q_initial=setup.q_initial,
        max_position_error_m=float(p_error.max()),
        max_rotation_error_rad=float(r_error.max()),
        final_position_error_m=float(final_p[0]),
        final_rotation_error_rad=float(final_r[0]),
        sim_time_s=duration,
        wall_time_s=time.perf_counter() - wall_start,
    )
