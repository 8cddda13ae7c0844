"""The guiding hand of a simulated kinesthetic demonstration: scripts and the hand's path.

A guidance script says where a person's hand takes the tool: waypoints ``X_WE`` at times
``t``, a hold at the end, and how unsteady the hand is. :class:`GuidanceScript` is the
checked form (the YAML is read by :mod:`drake_lfd.io.guidance_scripts`, documented in
docs/guidance_scripts.rst). :class:`GuidancePath` turns one into the hand's pose at every
time, ``X_WH(t)``: waypoints joined by screw motions (ScLERP) with a minimum-jerk time
profile, perturbed like a human hand (a seeded smooth wobble of about a millimetre and
half a degree, and a slightly uneven pace), then held still at the last waypoint so the
arm settles. :meth:`GuidancePath.sample` puts it on a regular time grid
(:class:`SampledGuidance`), which the :class:`~drake_lfd.systems.virtual_hand.VirtualHand`
system looks up. Everything here is numpy (and Drake's ``RigidTransform``) and can be
tested without a diagram.

Not for: reading script files (:mod:`drake_lfd.io.guidance_scripts`), the hand's wrench
on the arm (:mod:`drake_lfd.systems.virtual_hand`), simulating the recording
(:mod:`drake_lfd.diagrams.kinesthetic`).
"""

from __future__ import annotations

import dataclasses
import math
from typing import NamedTuple

import numpy as np
from pydrake.math import RigidTransform

from drake_lfd.core.demonstrations import RTDE_RATE_HZ
from drake_lfd.core.dual_quaternion import (
    dual_quaternion_from_translation_rotation,
    translation_rotation_from_dual_quaternion,
)
from drake_lfd.core.pose_conversions import dual_quaternion_from_rigid_transform, matrices_from_dual_quaternion
from drake_lfd.core.quaternion import (
    quaternion_conjugate,
    quaternion_from_rotation_vector,
    quaternion_multiply,
    rotation_vector_from_quaternion,
)
from drake_lfd.core.screw_motion import dual_quaternion_sclerp

__all__ = [
    "KINESTHETIC_TIME_STEP_S",
    "DEFAULT_HOLD_S",
    "Waypoint",
    "HandNoise",
    "STEADY_HAND",
    "GuidanceScript",
    "minimum_jerk",
    "GuidancePath",
    "SampledGuidance",
]

# The time step of a simulated kinesthetic recording: its plant steps at this rate and
# the guidance is sampled on it, so no log can be sampled faster.
KINESTHETIC_TIME_STEP_S = 1e-3
DEFAULT_HOLD_S = 0.5


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
    """A checked guidance script (:func:`~drake_lfd.io.guidance_scripts.load_guidance_script`).

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


# ------------------------------------------------------------------ guidance path


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
        p_nominal, r_nominal = translation_rotation_from_dual_quaternion(self.nominal_poses(self.script_time(t)))
        dp_W, dtheta_E = self.wobble(t)
        r = quaternion_multiply(r_nominal, quaternion_from_rotation_vector(dtheta_E))
        return dual_quaternion_from_translation_rotation(p_nominal + dp_W, r)

    def sample(self, time_step_s):
        """The hand's pose and velocity every ``time_step_s`` from 0 to past the end."""
        count = int(math.ceil(self.duration_s / time_step_s)) + 2
        t = np.arange(count) * time_step_s
        D = self.poses(t)
        p, q = translation_rotation_from_dual_quaternion(D)
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

    def index(self, t) -> int:  # type: ignore[override]  # (a sample's index by time, not tuple.index)
        """Index of the sample nearest time ``t`` (clamped to the grid)."""
        return min(max(int(round(t / self.time_step_s)), 0), self.p_WH.shape[0] - 1)
