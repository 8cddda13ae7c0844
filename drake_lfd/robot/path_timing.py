"""Time-optimal timing of a plan's joint path under the UR5e's limits (Drake's ``Toppra``).

The plan-time joint check records the joint path the arm takes through a plan
(:class:`~drake_lfd.robot.joint_path_records.JointPath`, one sample per 10 ms
controller step of a slow geometric pass). :func:`time_joint_path` gives that path its
executed timing:

1. **Path.** Samples that do not move are dropped; the path parameter ``s`` is the
   joint-space arc length (rad). A C2 cubic spline through knots ``knot_step_rad``
   apart (and through every critical configuration's sample) smooths away the
   controller-step jitter of the recorded path, which would otherwise make the curvature
   and so the time-optimal speed oscillate. If the spline strays more than
   ``max_deviation_m`` from the recorded tool path, a finer knot step is tried, then a
   shape-preserving cubic through every sample (exact, no overshoot).
2. **Stops.** The path is split where the tool must come to rest: the critical
   configurations whose ``stop`` is set (by default the first and the last) and those
   where the joint path has a corner (its direction turns by more than
   ``corner_angle_deg`` over ``corner_window_rad`` on each side): a corner cannot be
   passed at speed without a velocity jump. Between stops the tool passes critical
   configurations without slowing more than the limits require.
3. **Timing.** Each piece is parametrized time-optimally by Drake's ``Toppra``
   (TOPP-RA) from rest to rest under the joint speed and acceleration limits, the tool
   speed limit and, where the task sets one, a tool acceleration limit, all scaled by
   ``TimingLimits.limit_fraction``; the grid holds every knot, so sharp turns along the
   path (a demonstration's own corners) slow the motion as the limits require.
   Velocity is continuous everywhere: it is zero where pieces join.

A piece's timing is remembered by its exact inputs (its recorded samples, its critical
ones, the options, the arm and its limits; :mod:`~drake_lfd.core.exact_memo`): trials of
a task that share a piece (every assembling trial, the first spans of filling and
pouring) time it once per process, with the result timing it again would give.

The result is sampled at the controller period, with the exact time each critical
configuration is reached added as a sample (the tool passes a non-stop configuration at
speed: the plan must say where it is due, not round it to a step).

A human's demonstrated speed profile is not used: the mapping scales each demonstration
by the task's span (:mod:`drake_lfd.core.mapping`), so demonstrated speeds do not carry
over, and where a person slows down (corners, a careful approach) the path has the
curvature that makes the acceleration limits slow the robot too.

Not for: checking the path (``joint_path.py``) or choosing it (``planning/``).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence

import numpy as np
from pydrake.multibody.optimization import CalcGridPointsOptions, Toppra
from pydrake.trajectories import PiecewisePolynomial

from drake_lfd.core.pose_conversions import dual_quaternion_from_matrices
from drake_lfd.core.exact_memo import ExactMemo, exact_key
from drake_lfd.core.timing import TimedPlan, TimingLimits
from drake_lfd.robot.joint_path_records import JointPath
from drake_lfd.robot.kinematics import UR5eKinematics
from drake_lfd.robot.toppra import path_constraints, solve_parametrization

__all__ = ["PathTimingOptions", "TimedJointPath", "TimingError", "time_joint_path", "retime_plan",
           "corner_samples", "forget_timed_pieces"]


# Longest time a piece between stops may take; Toppra's answer beyond it is refused.
_LONGEST_PIECE_S = 3600.0
# Timed pieces remembered by their exact inputs (a few plans' worth; process-local).
_PIECES = ExactMemo(maxsize=32)


def forget_timed_pieces() -> None:
    """Forgets the remembered timed pieces (a process that timed nothing yet; the
    results are the same either way, only slower)."""
    _PIECES.clear()


class TimingError(RuntimeError):
    """Toppra found no parametrization (the path cannot be followed within the limits)."""


@dataclasses.dataclass(frozen=True)
class PathTimingOptions:
    """How the recorded joint path becomes a smooth path to time (module docstring).

    Attributes
    ----------
    knot_step_rad : float
        Joint-space arc length between spline knots (0.04 rad; halved, then quartered
        where the spline strays more than ``max_deviation_m``). On the paper's tasks
        0.02 rad keeps within about 1 mm of the recorded path, 0.05 rad strays 2-3 mm;
        the smoother the spline, the faster its time-optimal traversal (0.04 rad
        traverses assembling markedly faster than 0.02 rad).
    max_deviation_m : float
        Largest tool-position distance of the spline from the recorded path (2 mm).
    corner_angle_deg, corner_window_rad : float
        A critical configuration is a corner (the tool stops there) when the joint path's
        direction over ``corner_window_rad`` before it and after it differs by more than
        ``corner_angle_deg`` (30 deg over 0.05 rad).
    period_s : float
        Sample period of the result (the controller's, 10 ms).
    """

    knot_step_rad: float = 0.04
    max_deviation_m: float = 0.002
    corner_angle_deg: float = 30.0
    corner_window_rad: float = 0.05
    period_s: float = 0.01


@dataclasses.dataclass(frozen=True)
class TimedJointPath:
    """A joint path with its executed timing.

    Attributes
    ----------
    t : array (m,)
        Sample times from 0, s: multiples of the period, plus each critical
        configuration's exact time.
    q, qdot : array (m, 6)
        Joint positions and velocities at ``t``.
    critical_indices : tuple of int
        Index into ``t`` of each critical configuration.
    stops : tuple of bool
        Per critical configuration, whether the tool is at rest there.
    corners : tuple of int
        1-based critical configurations that stop because the path has a corner there.
    max_deviation_m : float
        Largest tool distance of the timed path from the recorded one.
    """

    t: np.ndarray
    q: np.ndarray
    qdot: np.ndarray
    critical_indices: tuple[int, ...]
    stops: tuple[bool, ...]
    corners: tuple[int, ...]
    max_deviation_m: float

    @property
    def duration(self) -> float:
        return float(self.t[-1])

    def on_grid(self, period_s: float) -> np.ndarray:
        """Which samples are at multiples of ``period_s`` (the last one always): bool (m,)."""
        mask = np.abs(self.t / period_s - np.round(self.t / period_s)) < 1e-9
        mask[-1] = True
        return mask


def _arc_length(q: np.ndarray) -> np.ndarray:
    return np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(q, axis=0), axis=1))])


def corner_samples(q: np.ndarray, candidates: Sequence[int], *, angle_deg: float, window_rad: float) -> list[int]:
    """Which of the sample indices ``candidates`` of the joint path ``q`` (m, 6) are
    corners: the direction from ``window_rad`` of arc length before to the sample and
    from it to ``window_rad`` after differ by more than ``angle_deg``. The path's ends
    are never corners."""
    s = _arc_length(q)
    corners = []
    for index in candidates:
        if index <= 0 or index >= len(q) - 1:
            continue
        before = q[index] - q[int(np.searchsorted(s, s[index] - window_rad, side="right")) - 1]
        after_index = min(int(np.searchsorted(s, s[index] + window_rad, side="left")), len(q) - 1)
        after = q[after_index] - q[index]
        norms = np.linalg.norm(before) * np.linalg.norm(after)
        if norms <= 1e-12:
            continue
        cosine = float(np.clip(before @ after / norms, -1.0, 1.0))
        if math.degrees(math.acos(cosine)) > angle_deg:
            corners.append(int(index))
    return corners


def _spline(s: np.ndarray, q: np.ndarray, required: Sequence[int], step: float | None) -> PiecewisePolynomial:
    """A C2 spline through knots ``step`` apart in ``s`` and the samples ``required``
    (``step`` None: a shape-preserving cubic through every sample)."""
    if step is None:
        return PiecewisePolynomial.CubicShapePreserving(s, q.T, zero_end_point_derivatives=False)
    targets = np.arange(0.0, s[-1], step)
    knots = np.unique(np.concatenate([np.searchsorted(s, targets).clip(0, len(s) - 1), required, [0, len(s) - 1]]))
    if len(knots) < 3:
        return PiecewisePolynomial.FirstOrderHold(s[knots], q[knots].T)
    return PiecewisePolynomial.CubicWithContinuousSecondDerivatives(s[knots], q[knots].T, periodic_end_condition=False)


class _PieceTimer:
    """Toppra on one piece of path, with the plant's limits bound once per plant."""

    def __init__(self, kinematics: UR5eKinematics, limits: TimingLimits):
        self.kinematics = kinematics
        f = limits.limit_fraction
        self.v = f * limits.joint_speed_rad_s * np.ones(6)
        self.a = f * limits.joint_acceleration_rad_s2 * np.ones(6)
        self.tool_speed = f * limits.tool_speed_m_s
        self.tool_acceleration = None if limits.tool_acceleration_m_s2 is None else \
            f * limits.tool_acceleration_m_s2 / math.sqrt(3.0)

    @property
    def key(self) -> tuple:
        """What a piece's timing depends on besides the piece: the arm (its base and E)
        and the limits."""
        k = self.kinematics
        return exact_key(k.X_WB.GetAsMatrix34(), k.X_tool0_E.GetAsMatrix34(), self.v, self.a,
                         self.tool_speed, self.tool_acceleration)

    def solve(self, path: PiecewisePolynomial) -> PiecewisePolynomial | None:
        """s(t), or None when TOPP-RA finds none (the caller tries another fit or
        reports): Drake's ``Toppra`` on this grid and these limits, its programs solved
        in closed form (:mod:`~drake_lfd.robot.toppra`)."""
        grid = np.unique(np.concatenate([
            Toppra.CalcGridPoints(path, CalcGridPointsOptions()), np.asarray(path.get_segment_times())]))
        # Grid points closer than this make Toppra's s(t) break times collide.
        grid = grid[np.concatenate([[True], np.diff(grid) > 1e-6 * max(grid[-1], 1e-9)])]
        grid[-1] = path.end_time()
        constraints = path_constraints(
            path, grid, self.kinematics.plant, self.kinematics.end_effector_frame, joint_speed=self.v,
            joint_acceleration=self.a, tool_speed=self.tool_speed,
            tool_acceleration=None if self.tool_acceleration is None else
            np.array([np.inf] * 3 + [self.tool_acceleration] * 3))
        s_of_t = solve_parametrization(constraints)
        # A grid too coarse for the path can give a parametrization that barely moves.
        if s_of_t is None or not (math.isfinite(s_of_t.end_time()) and s_of_t.end_time() < _LONGEST_PIECE_S):
            return None
        return s_of_t


def _tool_deviation(kinematics: UR5eKinematics, path: PiecewisePolynomial, s: np.ndarray, q: np.ndarray,
                    stride: int = 3) -> float:
    idx = np.arange(0, len(s), stride)
    recorded = kinematics.X_WE_table_batch(q[idx])[:, :3, 3]
    fitted = kinematics.X_WE_table_batch(path.vector_values(s[idx]).T)[:, :3, 3]
    return float(np.linalg.norm(recorded - fitted, axis=1).max(initial=0.0))


def _fit_and_time(kinematics, timer, s, q, required, options) -> tuple[PiecewisePolynomial, PiecewisePolynomial, float]:
    """The smoothest candidate spline that keeps to the recorded tool path and that
    Toppra can time: ``(path, s_of_t, deviation)``; remembered by its exact inputs
    (:data:`_PIECES`: trials of a task share pieces; the result is the same either way)."""
    key = exact_key(s, q, tuple(int(i) for i in required), options, timer.key)
    return _PIECES.get(key, lambda: _fit_and_time_afresh(kinematics, timer, s, q, required, options))


def _fit_and_time_afresh(kinematics, timer, s, q, required, options):
    """:func:`_fit_and_time` without the memo."""
    step = options.knot_step_rad
    for candidate in (step, step / 2.0, step / 4.0, None):
        path = _spline(s, q, required, candidate)
        deviation = 0.0 if candidate is None else _tool_deviation(kinematics, path, s, q)
        if deviation > options.max_deviation_m:
            continue
        s_of_t = timer.solve(path)
        if s_of_t is not None:
            return path, s_of_t, deviation
    raise TimingError("Toppra found no time parametrization of the joint path within the limits")


def _time_at(s_of_t: PiecewisePolynomial, s_target: float) -> float:
    """The time at which the monotone ``s(t)`` reaches ``s_target`` (bisection)."""
    lo, hi = s_of_t.start_time(), s_of_t.end_time()
    if s_target <= s_of_t.value(lo)[0, 0]:
        return lo
    if s_target >= s_of_t.value(hi)[0, 0]:
        return hi
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        if s_of_t.value(mid)[0, 0] < s_target:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


def time_joint_path(
    q: np.ndarray,
    critical_samples: Sequence[int],
    stops: Sequence[bool],
    kinematics: UR5eKinematics,
    limits: TimingLimits = TimingLimits(),
    options: PathTimingOptions = PathTimingOptions(),
) -> TimedJointPath:
    """Times the recorded joint path ``q`` (m, 6) time-optimally (module docstring).

    Parameters
    ----------
    q : array (m, 6)
        The recorded joint path, first to last critical configuration.
    critical_samples : sequence of int
        Sample index of each critical configuration (increasing, first 0, last m - 1).
    stops : sequence of bool
        Per critical configuration, whether the task asks the tool to stop there.
    kinematics : UR5eKinematics
        The arm (with its base and E) whose limits apply.

    Raises
    ------
    ValueError
        Malformed inputs. TimingError: no parametrization exists.
    """
    q = np.asarray(q, dtype=float)
    critical = [int(i) for i in critical_samples]
    if q.ndim != 2 or q.shape[1] != 6 or len(q) < 2:
        raise ValueError(f"q must have shape (m >= 2, 6), got {q.shape}")
    if critical[0] != 0 or critical[-1] != len(q) - 1 or np.any(np.diff(critical) <= 0) or len(stops) != len(critical):
        raise ValueError("critical_samples must increase from 0 to m - 1, one stop flag each")
    # Drop samples that do not move (the geometric pass rests at each critical
    # configuration); a critical configuration is the last kept sample at or before it.
    keep, critical_kept = [0], []
    critical_set = set(critical)
    # Moves of more than twice the threshold from the sample before need no exact test.
    clearly_moving = (np.abs(np.diff(q, axis=0)).max(axis=1) > 2e-7).tolist()
    for k in range(len(q)):
        if k > 0 and ((keep[-1] == k - 1 and clearly_moving[k - 1]) or np.linalg.norm(q[k] - q[keep[-1]]) > 1e-7):
            keep.append(k)
        if k in critical_set:
            critical_kept.append(len(keep) - 1)
    q_kept = q[keep]
    s = _arc_length(q_kept)
    corners = corner_samples(q_kept, critical_kept[1:-1], angle_deg=options.corner_angle_deg,
                             window_rad=options.corner_window_rad)
    stop_flags = [bool(flag) or index in corners for flag, index in zip(stops, critical_kept)]
    stop_flags[0] = stop_flags[-1] = True
    boundaries = sorted({index for index, flag in zip(critical_kept, stop_flags) if flag})
    if len(boundaries) == 1:  # the path does not move at all
        boundaries = [0, 0]

    # Time each piece between stops from rest to rest.
    timer = _PieceTimer(kinematics, limits)
    pieces = []  # (t_start, duration, s_of_t or None, path or None, first sample)
    con_time = {}  # kept sample index -> time
    t_start, max_deviation = 0.0, 0.0
    for first, last in zip(boundaries[:-1], boundaries[1:]):
        s_piece, q_piece = s[first:last + 1] - s[first], q_kept[first:last + 1]
        inside = sorted({c - first for c in critical_kept if first <= c <= last})
        if s_piece[-1] <= 1e-9:  # does not move: hold for one period
            pieces.append((t_start, options.period_s, None, None, first))
            for c in inside:
                con_time.setdefault(first + c, t_start)
            t_start += options.period_s
            continue
        path, s_of_t, deviation = _fit_and_time(kinematics, timer, s_piece, q_piece, inside, options)
        max_deviation = max(max_deviation, deviation)
        duration = float(s_of_t.end_time())
        for c in inside:
            con_time.setdefault(first + c, t_start + (duration if first + c == last else _time_at(s_of_t, s_piece[c])))
        pieces.append((t_start, duration, s_of_t, path, first))
        t_start += duration
    total = t_start

    # Sample on the controller's grid, plus each critical configuration's exact time.
    period = options.period_s
    t_all = np.unique(np.concatenate([np.arange(0.0, total, period), list(con_time.values()), [total]]))
    t_all = t_all[np.concatenate([[True], np.diff(t_all) > 1e-9])]
    positions, velocities = np.empty((len(t_all), 6)), np.zeros((len(t_all), 6))
    starts = np.array([piece[0] for piece in pieces])
    exact = {round(t, 9): index for index, t in con_time.items()}
    which = np.maximum(np.searchsorted(starts, t_all + 1e-12, side="right") - 1, 0)
    exact_index = np.array([exact.get(round(float(t), 9), -1) for t in t_all])
    for number, (piece_start, duration, s_of_t, path, first) in enumerate(pieces):
        # The piece's samples: its path at s(t), the joints' velocity dq/ds * ds/dt inside it.
        mine = np.flatnonzero((which == number) & (exact_index < 0))
        if s_of_t is None:
            positions[mine] = q_kept[first]
            continue
        tau = np.minimum(np.maximum(t_all[mine] - piece_start, 0.0), duration)
        x = np.clip(s_of_t.vector_values(tau)[0], 0.0, path.end_time())
        positions[mine] = path.vector_values(x).T
        moving = (0.0 < tau) & (tau < duration)
        velocities[mine[moving]] = (path.derivative(1).vector_values(x[moving])
                                    * s_of_t.derivative(1).vector_values(tau[moving])[0]).T
    for k in np.flatnonzero(exact_index >= 0).tolist():
        # Exactly the recorded configuration, at the speed the timing passes it.
        index = int(exact_index[k])
        piece_start, duration, s_of_t, path, first = pieces[which[k]]
        positions[k] = q_kept[index]
        t = float(t_all[k])
        if s_of_t is not None and 0.0 < t - piece_start < duration:
            tau = t - piece_start
            velocities[k] = path.EvalDerivative(s[index] - s[first], 1)[:, 0] * s_of_t.EvalDerivative(tau, 1)[0, 0]
    indices = tuple(int(np.argmin(np.abs(t_all - con_time[c]))) for c in critical_kept)
    corner_cons = tuple(i + 1 for i, c in enumerate(critical_kept) if c in corners)
    return TimedJointPath(t_all, positions, velocities, indices, tuple(stop_flags), corner_cons, max_deviation)


def retime_plan(plan: TimedPlan, joint_path: JointPath, stops: Sequence[bool], kinematics: UR5eKinematics,
                limits: TimingLimits = TimingLimits(), options: PathTimingOptions = PathTimingOptions(),
                ) -> tuple[TimedPlan, JointPath, TimedJointPath]:
    """The executed timing of a checked plan: ``joint_path`` (the check's record of the
    geometric pass over ``plan``) timed by :func:`time_joint_path`.

    Returns
    -------
    timed : TimedPlan
        The poses of E along the timed joint path (forward kinematics), with the
        critical configurations at their exact times: what the controller tracks.
    path : JointPath
        ``joint_path`` with the timed samples at the controller period (its checks'
        figures kept: the geometry is the same); per-sample clearances are carried over
        by matching arc-length fractions within each span.
    timed_path : TimedJointPath
    """
    period = options.period_s
    due = plan.times[list(plan.critical_indices)]
    step = float(joint_path.t[1] - joint_path.t[0]) if len(joint_path.t) > 1 else period
    samples = np.minimum(np.round(due / step).astype(int), len(joint_path.q) - 1)
    q_recorded = joint_path.q[:samples[-1] + 1]
    timed_path = time_joint_path(q_recorded, samples, stops, kinematics, limits, options)
    poses = dual_quaternion_from_matrices(kinematics.X_WE_batch(timed_path.q))
    timed = TimedPlan(timed_path.t.copy(), poses, timed_path.critical_indices)
    on_grid = timed_path.on_grid(period)
    t_uniform, q_uniform = timed_path.t[on_grid], timed_path.q[on_grid]
    clearances = _carried_over(np.asarray(joint_path.clearances)[:samples[-1] + 1], q_recorded, samples,
                               q_uniform, timed_path, on_grid)
    path = dataclasses.replace(joint_path, t=t_uniform, q=q_uniform, clearances=clearances)
    return timed, path, timed_path


def _carried_over(values: np.ndarray, q_old: np.ndarray, old_critical: Sequence[int], q_new: np.ndarray,
                  timed_path: TimedJointPath, on_grid: np.ndarray) -> np.ndarray:
    """Per-sample ``values`` of the recorded path moved to the timed samples ``q_new``:
    within each span, the recorded sample at the same fraction of the span's arc length."""
    s_old = _arc_length(q_old)
    s_new = _arc_length(q_new)
    new_index = np.cumsum(on_grid) - 1  # timed sample -> uniform sample
    new_critical = [int(new_index[i]) for i in timed_path.critical_indices]
    out = np.empty(len(q_new))
    for (a_old, b_old), (a_new, b_new) in zip(zip(old_critical[:-1], old_critical[1:]),
                                              zip(new_critical[:-1], new_critical[1:])):
        length_old, length_new = s_old[b_old] - s_old[a_old], s_new[b_new] - s_new[a_new]
        k = np.arange(a_new, b_new + 1)
        fraction = np.zeros(len(k)) if length_new <= 0 else (s_new[k] - s_new[a_new]) / length_new
        target = s_old[a_old] + fraction * length_old
        out[k] = values[np.clip(np.searchsorted(s_old, target), a_old, b_old)]
    return out
