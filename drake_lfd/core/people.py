"""People in the work cell and ISO/TS 15066 speed and separation monitoring, as plain data and maths.

A :class:`Person` is a body of four capsules (torso, head, two arms; :class:`BodySize`,
default sizes of a large adult) moved by a :class:`ScriptedPath` (timed floor waypoints,
linear between them, still after the last, an optional :class:`Reach` of both arms toward
a point) or by a :class:`RecordedTrack` (keypoint positions over time, as a skeleton
tracker writes them). :meth:`Person.capsules` gives the four capsules' poses at a time,
a function of time alone.

:class:`CollaborationParameters` holds the terms of ISO/TS 15066's protective separation
distance (clause 5.5.4)::

    S_p = v_h (T_r + T_s) + v_r T_r + S_s + C + Z_d + Z_r

and :func:`protective_separation_distance`, :func:`separation_override` and
:func:`stop_only_override` are the monitor's and the speed override's maths, testable
without a Diagram. Every default is documented on the record with its source.

Not for: reading people files (``io/people_files.py``), SceneGraph geometry
(``systems/people.py``), measuring distances in a run (``systems/separation.py``).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from pydrake.math import RigidTransform, RotationMatrix

from drake_lfd.core.read_only_arrays import read_only_array
# The override policies (plain Python, so a people file is checked before Drake loads).
from drake_lfd.core.task_terms import POLICIES, SSM_POLICY, STOP_ONLY_POLICY

__all__ = [
    "BodySize", "Waypoint", "Reach", "ScriptedPath", "RecordedTrack", "Person", "CapsulePose",
    "CollaborationParameters", "CAPSULE_NAMES", "TRACK_KEYPOINTS", "SSM_POLICY", "STOP_ONLY_POLICY", "POLICIES",
    "protective_separation_distance", "separation_override", "stop_only_override", "rate_limited",
    "stop_only_radius_m", "WORKBENCH_HEIGHT_M",
]

#: How far the floor is below the robot's base by default, m: a workbench's height (work
#: tables for standing work are 0.9-1.0 m, for seated 0.72-0.75 m; the arm's base plate
#: adds a little).
WORKBENCH_HEIGHT_M = 0.75

#: The capsules of every person, in this order.
CAPSULE_NAMES = ("torso", "head", "left_arm", "right_arm")

#: The keypoints of a recorded track, in the CSV's column order (each as x, y, z in W, m).
TRACK_KEYPOINTS = ("pelvis", "neck", "head", "left_shoulder", "left_hand", "right_shoulder", "right_hand")



@dataclasses.dataclass(frozen=True)
class BodySize:
    """A person's capsules, metres. The defaults are a large adult, rounded from the
    95th-percentile man of the anthropometric tables of DIN 33402-2 / ISO 7250-1
    (stature about 1.85 m, shoulder breadth about 0.48 m), so a smaller person is covered.

    Attributes
    ----------
    torso_radius_m : float
        0.2: half the shoulder (bideltoid) breadth, rounded down to the chest. The torso
        capsule runs from the floor to the shoulders: it holds the legs too.
    shoulder_height_m : float
        1.5: the shoulders' height above the floor (95th percentile about 1.52 m).
    shoulder_half_width_m : float
        0.2: each shoulder joint's distance from the body's vertical axis.
    head_radius_m : float
        0.12: half the head's breadth and depth (about 0.16 and 0.21 m), rounded up.
    head_top_m : float
        1.85: the top of the head above the floor (the stature).
    arm_radius_m : float
        0.06: the upper arm's girth (about 0.35 m) over 2 pi, rounded up.
    arm_length_m : float
        0.8: shoulder joint to fingertip (about 0.78 m), the reach of a straight arm.
    """

    torso_radius_m: float = 0.2
    shoulder_height_m: float = 1.5
    shoulder_half_width_m: float = 0.2
    head_radius_m: float = 0.12
    head_top_m: float = 1.85
    arm_radius_m: float = 0.06
    arm_length_m: float = 0.8

    def capsule_lengths(self) -> tuple[float, float, float]:
        """The cylinder lengths of the torso (floor to shoulders), the head (shoulders to
        the top of the head) and an arm (shoulder to fingertip), caps excluded, m."""
        return (self.shoulder_height_m - 2.0 * self.torso_radius_m,
                self.head_top_m - self.shoulder_height_m - 2.0 * self.head_radius_m,
                self.arm_length_m - self.arm_radius_m)

    def __post_init__(self):
        for field in dataclasses.fields(self):
            value = getattr(self, field.name)
            if not (math.isfinite(value) and value > 0.0):
                raise ValueError(f"{field.name} must be > 0, got {value!r}")
        if self.shoulder_height_m < 2.0 * self.torso_radius_m:
            raise ValueError("shoulder_height_m must be at least the torso's diameter")
        if self.head_top_m < self.shoulder_height_m + 2.0 * self.head_radius_m:
            raise ValueError("head_top_m must leave room for the head above the shoulders")
        if self.arm_length_m < 2.0 * self.arm_radius_m:
            raise ValueError("arm_length_m must be at least the arm's diameter")


@dataclasses.dataclass(frozen=True)
class CapsulePose:
    """One capsule at one time: ``radius`` and cylinder ``length`` (m, along its z axis,
    the caps beyond it), and its pose ``X_WC`` (centre and axis)."""

    name: str
    radius: float
    length: float
    X_WC: RigidTransform


@dataclasses.dataclass(frozen=True)
class Waypoint:
    """The body's vertical axis at ``xy`` (W, m) on the floor at ``t`` s from the start
    of the trial (t = 0 of its joint log)."""

    t: float
    xy: np.ndarray

    def __post_init__(self):
        object.__setattr__(self, "xy", read_only_array(self.xy, (2,)))


@dataclasses.dataclass(frozen=True)
class Reach:
    """Both arms stretched toward ``point`` (W, m) from ``t_from`` to ``t_to`` s (hanging
    down otherwise; raised and lowered over :attr:`RAISE_S`)."""

    point: np.ndarray
    t_from: float
    t_to: float

    #: How long raising (or lowering) the arms takes, s.
    RAISE_S = 0.5

    def __post_init__(self):
        object.__setattr__(self, "point", read_only_array(self.point, (3,)))
        if not self.t_from <= self.t_to:
            raise ValueError("a reach's t_from must be <= its t_to")

    def amount(self, t: float) -> float:
        """0 (arms down) .. 1 (stretched toward the point) at time ``t``."""
        rise = (t - self.t_from + self.RAISE_S) / self.RAISE_S
        fall = (self.t_to + self.RAISE_S - t) / self.RAISE_S
        return float(np.clip(min(rise, fall), 0.0, 1.0))


@dataclasses.dataclass(frozen=True)
class ScriptedPath:
    """Timed floor waypoints (increasing ``t``), linear between, standing still before
    the first and after the last; an optional :class:`Reach`."""

    waypoints: tuple
    reach: Reach | None = None

    def __post_init__(self):
        if not self.waypoints:
            raise ValueError("a path needs at least one waypoint")
        times = [w.t for w in self.waypoints]
        if any(b <= a for a, b in zip(times, times[1:])):
            raise ValueError("waypoint times must increase")

    def xy(self, t: float) -> np.ndarray:
        """Where the body's axis is at ``t``, (2,)."""
        times = np.array([w.t for w in self.waypoints])
        points = np.array([w.xy for w in self.waypoints])
        return np.array([np.interp(t, times, points[:, 0]), np.interp(t, times, points[:, 1])])

    @property
    def end_time_s(self) -> float:
        return float(self.waypoints[-1].t)


@dataclasses.dataclass(frozen=True, eq=False)
class RecordedTrack:
    """Keypoints over time, as a skeleton tracker records them: ``t`` (m,) increasing,
    ``keypoints`` (m, 7, 3) in W (m), in :data:`TRACK_KEYPOINTS` order; linear between
    rows, held before the first and after the last. ``file`` says where it came from."""

    t: np.ndarray
    keypoints: np.ndarray
    file: str = ""

    def __post_init__(self):
        t = read_only_array(self.t, (len(self.t),))
        keypoints = read_only_array(self.keypoints, (len(t), len(TRACK_KEYPOINTS), 3))
        if len(t) == 0 or np.any(np.diff(t) <= 0.0):
            raise ValueError("a track needs at least one row, times increasing")
        object.__setattr__(self, "t", t)
        object.__setattr__(self, "keypoints", keypoints)

    def at(self, t: float) -> np.ndarray:
        """The keypoints at ``t``, (7, 3)."""
        flat = self.keypoints.reshape(len(self.t), -1)
        return np.array([np.interp(t, self.t, flat[:, i]) for i in range(flat.shape[1])]).reshape(-1, 3)

    @property
    def end_time_s(self) -> float:
        return float(self.t[-1])


def _capsule_along(name: str, radius: float, length: float, p_start: np.ndarray, p_toward: np.ndarray) -> CapsulePose:
    """The capsule of ``radius`` whose axis segment of ``length`` starts at ``p_start``
    and points toward ``p_toward`` (straight up when they coincide)."""
    axis = np.asarray(p_toward, dtype=float) - np.asarray(p_start, dtype=float)
    norm = float(np.linalg.norm(axis))
    z = axis / norm if norm > 1e-9 else np.array([0.0, 0.0, 1.0])
    R_WC = RotationMatrix.MakeFromOneVector(z, 2)
    return CapsulePose(name, radius, length, RigidTransform(R_WC, np.asarray(p_start, dtype=float) + 0.5 * length * z))


@dataclasses.dataclass(frozen=True, eq=False)
class Person:
    """A person in the cell: ``name``, ``motion`` (a :class:`ScriptedPath` or a
    :class:`RecordedTrack`) and ``body`` (:class:`BodySize`)."""

    name: str
    motion: ScriptedPath | RecordedTrack
    body: BodySize = BodySize()

    @property
    def end_time_s(self) -> float:
        """When the person's script or track ends (still after)."""
        return self.motion.end_time_s

    def keypoints(self, t: float, *, floor_z: float, face_xy) -> np.ndarray:
        """The :data:`TRACK_KEYPOINTS` at ``t``, (7, 3) in W. A scripted person stands on
        the floor at ``floor_z`` and faces the point ``face_xy`` (the robot's base)."""
        if isinstance(self.motion, RecordedTrack):
            return self.motion.at(t)
        body = self.body
        xy = self.motion.xy(t)
        forward = np.asarray(face_xy, dtype=float)[:2] - xy
        norm = np.linalg.norm(forward)
        forward = forward / norm if norm > 1e-9 else np.array([1.0, 0.0])
        left = np.array([-forward[1], forward[0]])
        ground = np.array([xy[0], xy[1], floor_z])
        up = np.array([0.0, 0.0, 1.0])
        shoulder_z = body.shoulder_height_m - body.arm_radius_m
        neck = ground + up * body.shoulder_height_m
        shoulders = [ground + up * shoulder_z + side * body.shoulder_half_width_m * np.append(left, 0.0)
                     for side in (1.0, -1.0)]
        hands = []
        reach = self.motion.reach
        amount = 0.0 if reach is None else reach.amount(t)
        for shoulder in shoulders:
            down = -up
            direction = down
            if reach is not None and amount > 0.0:
                toward = np.asarray(reach.point) - shoulder
                toward = toward / max(float(np.linalg.norm(toward)), 1e-9)
                blend = (1.0 - amount) * down + amount * toward
                direction = blend / max(float(np.linalg.norm(blend)), 1e-9)
            hands.append(shoulder + direction * (body.arm_length_m - body.arm_radius_m))
        head = ground + up * (body.head_top_m - body.head_radius_m)
        pelvis = ground + up * (0.5 * body.shoulder_height_m)
        return np.array([pelvis, neck, head, shoulders[0], hands[0], shoulders[1], hands[1]])

    def capsules(self, t: float, *, floor_z: float, face_xy) -> tuple[CapsulePose, ...]:
        """The four capsules at ``t`` (:data:`CAPSULE_NAMES` order), each of the body's
        fixed size (:meth:`BodySize.capsule_lengths`): the torso from the floor under
        the pelvis up toward the neck, the head from the neck up toward the head
        keypoint, each arm from its shoulder toward its hand."""
        body = self.body
        pelvis, neck, head, l_shoulder, l_hand, r_shoulder, r_hand = self.keypoints(t, floor_z=floor_z,
                                                                                      face_xy=face_xy)
        torso, head_length, arm = body.capsule_lengths()
        floor_point = np.array([pelvis[0], pelvis[1], floor_z + body.torso_radius_m])
        head_bottom = neck + np.array([0.0, 0.0, body.head_radius_m])
        return (
            _capsule_along("torso", body.torso_radius_m, torso, floor_point, neck),
            _capsule_along("head", body.head_radius_m, head_length, head_bottom, head),
            _capsule_along("left_arm", body.arm_radius_m, arm, l_shoulder, l_hand),
            _capsule_along("right_arm", body.arm_radius_m, arm, r_shoulder, r_hand),
        )


@dataclasses.dataclass(frozen=True)
class CollaborationParameters:
    """The ``collaboration:`` block: ISO/TS 15066 speed and separation monitoring.

    Attributes
    ----------
    policy : str
        ``speed_and_separation`` (the default: the largest speed override that keeps
        ``d >= S_p``) or ``stop_only`` (a safety scanner's fixed radius: stop while anyone
        is within ``stop_radius_m``, resume when clear).
    human_speed_m_s : float
        v_h = 1.6 m/s: ISO 13855's walking speed for approach toward a protective device,
        which ISO/TS 15066 uses when the person's speed is not measured.
    reaction_time_s : float
        T_r = 0.1 s: detecting the person and issuing the override. A safety laser
        scanner's response time is 60-120 ms and UR's safety system reacts within one of
        its 2 ms cycles plus the RTDE cycle (2 ms at 500 Hz); 0.1 s covers a tracker at
        10 Hz or more. The simulated monitor itself reacts within one 10 ms period.
    stopping_time_s : float or None
        T_s: None (the default) takes it from the UR5e's joint limits: the time the
        fastest allowed joint needs to stop at the joint acceleration limit, joint speed
        limit / joint acceleration limit (the task's ``timing:`` block: pi / 8 =
        0.39 s). For a real cell use the stopping times and distances UR's manual lists
        for the robot and payload, or measure them. The override is ramped down at
        1 / T_s per second, so an override of 1 falls to 0 within T_s.
    intrusion_distance_m : float
        C = 0.208 m: ISO 13855's intrusion distance ``8 (d - 14)`` mm for a detection
        capability of d = 40 mm (a hand): how far a body part can reach past what the
        sensor sees. The simulation measures to the modelled arms, so this covers the
        hand and fingers beyond them and a limb the tracker misses.
    human_position_uncertainty_m : float
        Z_d = 0.1 m: the person-detection uncertainty (a safety laser scanner's
        measurement tolerance, ISO 13855's supplement for one, is of this order; a
        skeleton tracker's error on a limb likewise).
    robot_position_uncertainty_m : float
        Z_r = 0.01 m: the robot's (UR5e repeatability 0.03 mm, ISO 9283; this covers the
        simulated drive's tracking error, about 1.3 mm, and small unmodelled tool parts).
    stop_radius_m : float or None
        The ``stop_only`` policy's radius; None: :func:`stop_only_radius_m`, the radius
        that is as safe as speed and separation monitoring at the robot's top speed.
    floor_z_m : float or None
        Where the floor is in W; None (the default): :data:`WORKBENCH_HEIGHT_M` below the
        robot's base, which stands on a workbench (the shipped scenarios' table top).
    moving_toward_speed_m_s : float
        0.001 m/s: a robot point approaching a person more slowly than this counts as
        standing (a drive holding still measures speeds of this order, not zero).
    max_speed_m_s : float
        1.5 m/s: the fastest any robot point moves (UR's default safety tool speed limit;
        the plans keep to 0.9 of it); used for the stop-only radius.
    max_time_lost_s : float
        60 s: a run whose path is still unfinished this long after the plan's nominal end
        is ended there (someone stood in the way), and its remaining critical
        configurations count as not reached.
    """

    policy: str = SSM_POLICY
    human_speed_m_s: float = 1.6
    reaction_time_s: float = 0.1
    stopping_time_s: float | None = None
    intrusion_distance_m: float = 0.208
    human_position_uncertainty_m: float = 0.1
    robot_position_uncertainty_m: float = 0.01
    stop_radius_m: float | None = None
    floor_z_m: float | None = None
    moving_toward_speed_m_s: float = 0.001
    max_speed_m_s: float = 1.5
    max_time_lost_s: float = 60.0

    def __post_init__(self):
        if self.policy not in POLICIES:
            raise ValueError(f"policy must be one of {POLICIES}, got {self.policy!r}")

    def floor_z(self, base_z_m: float) -> float:
        """The floor's height in W for a robot base at height ``base_z_m``."""
        return float(base_z_m) - WORKBENCH_HEIGHT_M if self.floor_z_m is None else float(self.floor_z_m)

    def stopping_time(self, joint_speed_rad_s: float, joint_acceleration_rad_s2: float) -> float:
        """T_s: the given one, or joint speed limit / joint acceleration limit."""
        if self.stopping_time_s is not None:
            return float(self.stopping_time_s)
        return float(joint_speed_rad_s) / float(joint_acceleration_rad_s2)

    def standstill_distance_m(self, stopping_time_s: float) -> float:
        """``S_p`` of a robot that does not move toward the person:
        ``v_h (T_r + T_s) + C + Z_d + Z_r``."""
        return (self.human_speed_m_s * (self.reaction_time_s + stopping_time_s) + self.intrusion_distance_m
                + self.human_position_uncertainty_m + self.robot_position_uncertainty_m)


def protective_separation_distance(speed_toward_m_s, parameters: CollaborationParameters,
                                   stopping_time_s: float):
    """ISO/TS 15066's ``S_p`` for a robot moving toward the person at ``v_r`` m/s (array or
    float; a robot moving away counts as standing):
    ``v_h (T_r + T_s) + v_r T_r + S_s + C + Z_d + Z_r`` with the stopping distance
    ``S_s = v_r T_s / 2`` (a uniform deceleration from ``v_r`` over ``T_s``)."""
    v_r = np.maximum(np.asarray(speed_toward_m_s, dtype=float), 0.0)
    value = (parameters.standstill_distance_m(stopping_time_s)
             + v_r * (parameters.reaction_time_s + 0.5 * stopping_time_s))
    return float(value) if value.ndim == 0 else value


def rate_limited(target: float, current: float, max_step: float) -> float:
    """``target`` in [0, 1], moved from ``current`` by at most ``max_step``."""
    target = min(max(target, 0.0), 1.0)
    return float(min(max(target, current - max_step), current + max_step))


def separation_override(distance_m: float, full_speed_m_s: float, parameters: CollaborationParameters,
                        stopping_time_s: float, time_step: float) -> float:
    """The largest speed override ``o`` in [0, 1] that keeps ``d >= S_p`` for one person
    (before the rate limit).

    ``distance_m``: d, the least distance between the person and the robot;
    ``full_speed_m_s``: ``u``, how fast the robot's closest point moves at override 1
    (its speed, not only its part toward the person, so a turn of the path toward the
    person is covered). The person may close in at ``v_h`` while the robot reacts (``T_r``:
    the simulated drive follows its command with a lag, and settles after a stop) and
    the override ramps from ``o`` down to 0 (within ``o T_s``), so ``o`` must satisfy::

        d - v_h (T_r + o T_s) >= S_p(o u) = S_p(0) + o u (T_r + T_s / 2)

    that is ``o <= (d - v_h T_r - S_p(0)) / (u (T_r + T_s / 2) + v_h T_s)``. As ``d``
    falls at ``v_h`` this bound falls at most ``1 / T_s`` per second, the ramp's own rate,
    so the ramped override keeps up with it. 0 (a protective stop) when even a standing
    robot would be too close.
    """
    room = (distance_m - parameters.human_speed_m_s * max(parameters.reaction_time_s, time_step)
            - parameters.standstill_distance_m(stopping_time_s))
    if room <= 0.0:
        return 0.0
    per_unit = (max(full_speed_m_s, 0.0) * (parameters.reaction_time_s + 0.5 * stopping_time_s)
                + parameters.human_speed_m_s * stopping_time_s)
    return float(min(room / per_unit, 1.0))


def stop_only_radius_m(parameters: CollaborationParameters, stopping_time_s: float, time_step: float) -> float:
    """The stop-only policy's radius: the given ``stop_radius_m``, else the distance at
    which speed and separation monitoring starts slowing a robot point moving at
    ``max_speed_m_s`` (S_p at that speed plus the person's approach while the robot
    stops): as safe, by the same terms, as that policy is."""
    if parameters.stop_radius_m is not None:
        return float(parameters.stop_radius_m)
    return (protective_separation_distance(parameters.max_speed_m_s, parameters, stopping_time_s)
            + parameters.human_speed_m_s * (stopping_time_s + max(parameters.reaction_time_s, time_step)))


def stop_only_override(distance_m: float, radius_m: float) -> float:
    """The stop-only policy: 0 while the person is within ``radius_m``, else 1."""
    return 0.0 if distance_m < radius_m else 1.0
