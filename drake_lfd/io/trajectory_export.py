"""A planned joint trajectory made ready for a real UR5e: read, resampled, checked, written.

``drake-lfd export`` (docs/cli.rst) reads a ``plan --json`` document and turns its
``joint_trajectory`` (the plan-time check's joint path, 100 Hz) into what a UR5e runs:

- :func:`load_plan_trajectory` reads the document; one without a joint trajectory, or
  with a status other than ``planned``, is refused (one line naming the file and field);
- :func:`resample` stretches the plan's time by ``slow_down`` (1: the plan's own timing)
  and resamples it at the e-Series controller period (2 ms, 500 Hz) with a cubic spline
  through the plan's samples, at rest at both ends (zero velocity: the arm starts from
  the ``movej`` to the start and ends with ``stopj``). The spline passes through every
  sample of the plan, so where the two grids meet the exported targets are the plan's;
- :func:`check_limits` checks the start configuration and every exported target against
  the UR5e's limits: joint positions (the model's, models/ur5e/ur5e.urdf: +-2 pi, the
  elbow +-pi), joint speed 180 deg/s (pi rad/s) and joint acceleration
  :data:`UR5E_JOINT_ACCELERATION_LIMIT_RAD_S2`, speeds and accelerations by finite
  differences of the 2 ms targets (what the controller is asked to do). A violation is an
  :class:`~drake_lfd.core.errors.InputError` naming the joint, the value, the limit and
  the time, with the least ``--slow-down`` that would keep speeds and accelerations
  within their limits (:func:`least_slow_down`);
- :func:`rtde_csv_text` and :func:`ros2_trajectory_yaml` write the other two formats;
  the URScript program is :mod:`drake_lfd.io.urscript`.

Not for: planning (``planning/``), running anything on a robot.
"""

from __future__ import annotations

import dataclasses
import json
import math
import re
from pathlib import Path

import numpy as np

from drake_lfd.core.errors import InputError
from drake_lfd.robot.kinematics import UR5E_JOINT_NAMES

__all__ = [
    "CONTROLLER_PERIOD_S",
    "UR5E_POSITION_LIMITS_RAD",
    "UR5E_JOINT_SPEED_LIMIT_RAD_S",
    "UR5E_JOINT_ACCELERATION_LIMIT_RAD_S2",
    "PlanTrajectory",
    "ExportTrajectory",
    "load_plan_trajectory",
    "resample",
    "least_slow_down",
    "check_limits",
    "rtde_csv_text",
    "ros2_joint_names",
    "ros2_trajectory_yaml",
]

#: The UR e-Series controller period (500 Hz): servoj's ``t`` and the export's time step.
CONTROLLER_PERIOD_S = 0.002
#: Joint position limits, rad, shoulder_pan .. wrist_3 (symmetric; as models/ur5e/ur5e.urdf:
#: every joint +-360 deg, the elbow +-180 deg as in Universal Robots' ROS description).
UR5E_POSITION_LIMITS_RAD = np.array([2 * math.pi, 2 * math.pi, math.pi, 2 * math.pi, 2 * math.pi, 2 * math.pi])
#: Joint speed limit, rad/s, every joint (180 deg/s, the UR5e data sheet).
UR5E_JOINT_SPEED_LIMIT_RAD_S = math.pi
#: Joint acceleration limit, rad/s^2, every joint. Universal Robots publish none for the
#: UR5e; 40 rad/s^2 is the largest joint acceleration PolyScope's move commands accept
#: and the bound ``ur_rtde`` checks (``UR_JOINT_ACCELERATION_MAX``).
UR5E_JOINT_ACCELERATION_LIMIT_RAD_S2 = 40.0

_PREFIX_PATTERN = re.compile(r"^[A-Za-z0-9_/]*$")


@dataclasses.dataclass(frozen=True)
class PlanTrajectory:
    """The joint trajectory of a plan document: times (m,) s and positions (m, 6) rad."""

    task: str
    t: np.ndarray
    q: np.ndarray


@dataclasses.dataclass(frozen=True)
class ExportTrajectory:
    """The exported motion: ``t`` (n,) s from 0 at :data:`CONTROLLER_PERIOD_S`, ``q`` (n, 6)
    rad, ``qd`` (n, 6) rad/s (the spline's derivative); ``slow_down`` the time stretch;
    ``plan_t`` and ``plan_q`` the plan's samples at stretched times (for ROS 2)."""

    task: str
    t: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    slow_down: float
    plan_t: np.ndarray
    plan_q: np.ndarray
    plan_qd: np.ndarray

    @property
    def duration_s(self) -> float:
        return float(self.t[-1])


def load_plan_trajectory(path: str | Path) -> PlanTrajectory:
    """The joint trajectory of a ``plan --json`` document, checked (one-line errors)."""
    path = Path(path)
    text = path.read_text(encoding="utf-8")  # OSError: a path the user named (exit 2)
    try:
        document = json.loads(text)
    except (ValueError, RecursionError) as error:
        raise InputError(f"not a JSON document ({error})"[:200], file=path) from None
    if not isinstance(document, dict):
        raise InputError("not a plan --json document (expected an object)", file=path)
    status = document.get("status")
    if status != "planned":
        raise InputError(f"is {status!r}, not 'planned': only a planned motion can be exported",
                         file=path, field="status")
    trajectory = document.get("joint_trajectory")
    if not isinstance(trajectory, dict) or not trajectory.get("t"):
        raise InputError("missing or empty: re-plan with this drake-lfd (plan --json) to get the joint path",
                         file=path, field="joint_trajectory")
    try:
        t = np.asarray(trajectory["t"], dtype=float)
        q = np.asarray(trajectory.get("q"), dtype=float)
    except (TypeError, ValueError):
        raise InputError("t must be a list of numbers and q a list of six-number lists",
                         file=path, field="joint_trajectory") from None
    if t.ndim != 1 or q.shape != (len(t), 6):
        raise InputError(f"t has {t.size} values but q has shape {q.shape}; expected ({t.size}, 6)",
                         file=path, field="joint_trajectory.q")
    if len(t) < 2:
        raise InputError("needs at least two samples", file=path, field="joint_trajectory.t")
    if not (np.isfinite(t).all() and np.isfinite(q).all()):
        raise InputError("holds a number that is not finite", file=path, field="joint_trajectory")
    steps = np.diff(t)
    if (steps <= 0).any():
        index = int(np.argmax(steps <= 0)) + 1
        raise InputError(f"times must increase (sample {index}: {t[index]:.4f} s after {t[index - 1]:.4f} s)",
                         file=path, field="joint_trajectory.t")
    task = document.get("task") if isinstance(document.get("task"), str) else path.stem
    return PlanTrajectory(task, t - t[0], q)


class _Spline:
    """A clamped cubic spline through every sample (at rest at both ends, after
    ``movej`` and before ``stopj``), Drake's
    ``PiecewisePolynomial.CubicWithContinuousSecondDerivatives``; called as
    ``spline(t)`` for positions (len(t), 6) and ``spline(t, 1)`` for velocities."""

    def __init__(self, t: np.ndarray, q: np.ndarray):
        from pydrake.trajectories import PiecewisePolynomial

        zero = np.zeros((q.shape[1], 1))
        self._q = PiecewisePolynomial.CubicWithContinuousSecondDerivatives(t, q.T, zero, zero)
        self._qd = self._q.derivative(1)

    def __call__(self, t, derivative: int = 0) -> np.ndarray:
        trajectory = self._q if derivative == 0 else self._qd
        return np.asarray(trajectory.vector_values(np.atleast_1d(np.asarray(t, dtype=float)))).T


def _spline(t: np.ndarray, q: np.ndarray) -> _Spline:
    return _Spline(t, q)


def resample(plan: PlanTrajectory, slow_down: float = 1.0, period_s: float = CONTROLLER_PERIOD_S) -> ExportTrajectory:
    """The plan at ``period_s`` with its time stretched by ``slow_down`` (module docstring)."""
    if not (math.isfinite(slow_down) and slow_down >= 1.0):
        raise InputError(f"must be a number >= 1, not {slow_down}", field="--slow-down")
    plan_t = plan.t * slow_down
    spline = _spline(plan_t, plan.q)
    count = int(math.floor(plan_t[-1] / period_s + 1e-9))
    t = np.arange(count + 1) * period_s
    if plan_t[-1] - t[-1] > 1e-9:  # end exactly on the plan's last sample
        t = np.append(t, t[-1] + period_s)
    q = spline(np.minimum(t, plan_t[-1]))
    qd = spline(np.minimum(t, plan_t[-1]), 1)
    return ExportTrajectory(plan.task, t, q, qd, float(slow_down), plan_t, plan.q, spline(plan_t, 1))


def _speeds_accelerations(q: np.ndarray, dt: float):
    speed = np.diff(q, axis=0) / dt
    acceleration = np.diff(q, n=2, axis=0) / dt**2
    return speed, acceleration


def least_slow_down(plan: PlanTrajectory, *, speed_limit: float = UR5E_JOINT_SPEED_LIMIT_RAD_S,
                    acceleration_limit: float = UR5E_JOINT_ACCELERATION_LIMIT_RAD_S2) -> float:
    """The least ``slow_down`` (rounded up to 0.1) whose export keeps speeds and
    accelerations within the limits; speeds scale as 1/s and accelerations as 1/s^2."""
    trajectory = resample(plan, 1.0)
    speed, acceleration = _speeds_accelerations(trajectory.q, CONTROLLER_PERIOD_S)
    factor = max(1.0, float(np.abs(speed).max(initial=0.0)) / speed_limit,
                 math.sqrt(float(np.abs(acceleration).max(initial=0.0)) / acceleration_limit))
    # The spline's shape changes a little with the grid: step up until it holds.
    factor = math.ceil(factor * 10 - 1e-9) / 10
    for _ in range(50):
        stretched = resample(plan, factor)
        speed, acceleration = _speeds_accelerations(stretched.q, CONTROLLER_PERIOD_S)
        if (np.abs(speed).max(initial=0.0) <= speed_limit
                and np.abs(acceleration).max(initial=0.0) <= acceleration_limit):
            return factor
        factor = round(factor + 0.1, 1)
    return factor


def check_limits(trajectory: ExportTrajectory, *, file=None, plan: PlanTrajectory | None = None,
                 position_limits: np.ndarray = UR5E_POSITION_LIMITS_RAD,
                 speed_limit: float = UR5E_JOINT_SPEED_LIMIT_RAD_S,
                 acceleration_limit: float = UR5E_JOINT_ACCELERATION_LIMIT_RAD_S2) -> dict:
    """Raises :class:`InputError` at the first limit the export breaks (the start
    configuration's position first, then positions, speeds, accelerations in time
    order); returns the largest fractions of each limit used, for the summary."""
    dt = CONTROLLER_PERIOD_S
    q = trajectory.q
    speed, acceleration = _speeds_accelerations(q, dt)
    hint = ""
    if plan is not None:
        hint = f"; --slow-down {least_slow_down(plan, speed_limit=speed_limit, acceleration_limit=acceleration_limit):.1f} would keep speeds and accelerations within"

    def refuse(what, joint, value, limit, time_s, unit, extra=""):
        raise InputError(f"{UR5E_JOINT_NAMES[joint]} {what} {value:.3f} {unit} exceeds the limit "
                         f"{limit:.3f} {unit} at t = {time_s:.3f} s{extra}", file=file, field="joint_trajectory")

    start_outside = np.abs(q[0]) > position_limits
    if start_outside.any():
        joint = int(np.argmax(start_outside))
        refuse("start position", joint, abs(q[0, joint]), position_limits[joint], 0.0, "rad")
    candidates = []  # (time, kind, joint, value, limit, unit)
    outside = np.abs(q) > position_limits
    if outside.any():
        k, joint = np.argwhere(outside)[0]
        candidates.append((trajectory.t[k], "position", joint, abs(q[k, joint]), position_limits[joint], "rad"))
    fast = np.abs(speed) > speed_limit
    if fast.any():
        k, joint = np.argwhere(fast)[0]
        candidates.append((trajectory.t[k], "speed", joint, abs(speed[k, joint]), speed_limit, "rad/s"))
    sharp = np.abs(acceleration) > acceleration_limit
    if sharp.any():
        k, joint = np.argwhere(sharp)[0]
        candidates.append((trajectory.t[k + 1], "acceleration", joint, abs(acceleration[k, joint]),
                           acceleration_limit, "rad/s^2"))
    if candidates:
        time_s, kind, joint, value, limit, unit = min(candidates, key=lambda c: c[0])
        refuse(kind, int(joint), float(value), float(limit), float(time_s), unit,
               hint if kind != "position" else "")
    return {
        "position_fraction": float((np.abs(q) / position_limits).max()),
        "speed_fraction": float(np.abs(speed).max(initial=0.0) / speed_limit),
        "acceleration_fraction": float(np.abs(acceleration).max(initial=0.0) / acceleration_limit),
    }


def rtde_csv_text(trajectory: ExportTrajectory) -> str:
    """The exported 2 ms targets as an RTDE-layout CSV (comma separated, as ``ur_rtde``
    writes): ``timestamp,target_q_0..5,actual_q_0..5``, the ``actual_q`` columns a copy
    of the targets (what a perfectly tracking robot would log), so ``library add`` and
    any RTDE tool reading ``actual_q_*`` read the motion; floats with ``repr``."""
    header = ["timestamp"] + [f"target_q_{j}" for j in range(6)] + [f"actual_q_{j}" for j in range(6)]
    lines = [",".join(header)]
    for time_s, q in zip(trajectory.t, trajectory.q):
        values = [repr(float(time_s))] + [repr(float(v)) for v in q]
        lines.append(",".join(values + values[1:]))
    return "\n".join(lines) + "\n"


def ros2_joint_names(prefix: str = "") -> list[str]:
    """``shoulder_pan_joint`` .. ``wrist_3_joint`` with ``prefix`` (``ur_``) in front."""
    if not _PREFIX_PATTERN.match(prefix):
        raise InputError(f"{prefix!r}: only letters, digits, '_' and '/' may form a ROS name prefix",
                         field="--joint-prefix")
    return [prefix + name for name in UR5E_JOINT_NAMES]


def _duration(seconds: float) -> dict:
    nanoseconds = int(round(seconds * 1e9))
    return {"sec": nanoseconds // 1_000_000_000, "nanosec": nanoseconds % 1_000_000_000}


def ros2_trajectory_yaml(trajectory: ExportTrajectory, *, joint_prefix: str = "") -> str:
    """A ``trajectory_msgs/msg/JointTrajectory`` as YAML (``ros2 topic pub`` / an action
    goal's ``trajectory`` field): the plan's own samples (10 ms, stretched by
    ``slow_down``) with positions and velocities (the spline's), the last at rest;
    ``header.stamp`` zero (start now)."""
    import yaml

    points = []
    last = len(trajectory.plan_t) - 1
    for index, (time_s, q, qd) in enumerate(zip(trajectory.plan_t, trajectory.plan_q, trajectory.plan_qd)):
        points.append({
            "positions": [float(v) for v in q],
            "velocities": [0.0] * 6 if index in (0, last) else [float(v) for v in qd],
            "time_from_start": _duration(float(time_s)),
        })
    message = {
        "header": {"stamp": {"sec": 0, "nanosec": 0}, "frame_id": ""},
        "joint_names": ros2_joint_names(joint_prefix),
        "points": points,
    }
    return (f"# trajectory_msgs/msg/JointTrajectory: plan {trajectory.task}, {len(points)} points over "
            f"{float(trajectory.plan_t[-1]):.3f} s (drake-lfd export)\n"
            + yaml.safe_dump(message, sort_keys=False, default_flow_style=None, width=1000))
