"""Between joint samples and the program's B-splines: a guess fitted to samples, a solution sampled.

:func:`fit_bspline` fits the clamped B-spline guess ``q(s)`` of the trajectory program
to a path's joint samples (least squares; with its ends at rest and through pinned
configurations when asked). :func:`sample_trajectory` turns a solved trajectory into
samples at the controller's period, every target on a sample, the motion slowed along
its path where E would pass a target or move too fast.

Not for: building or solving the program (``trajectory_optimization.py``).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from pydrake.math import BsplineBasis, RigidTransform
from pydrake.trajectories import BsplineTrajectory

from drake_lfd.robot.optimization_scene import OptimizationScene

__all__ = ["fit_bspline", "sample_trajectory"]


def fit_bspline(s: np.ndarray, q: np.ndarray, num_control_points: int, order: int = 4, *,
                rest_ends: bool = False, pins: Sequence[tuple[float, np.ndarray]] = ()) -> BsplineTrajectory:
    """The clamped uniform B-spline in ``s`` (on [0, 1]) with ``num_control_points``
    control points closest (least squares) to the samples ``q`` (m, 6) at ``s`` (m,),
    its ends on the first and last sample.

    With ``rest_ends`` the first and last ``order - 1`` control points are the ends
    themselves (zero velocity and acceleration there, as the program demands); each pin
    ``(s_k, q_k)`` is met exactly (least squares under equality constraints), so the
    guess starts on every critical configuration. A guess that breaks those constraints
    starts SNOPT far from feasibility: fitted freely, a filling-and-pouring guess had a
    path acceleration of 423 rad at its ends where the program demands 0, and missed
    its critical configurations by up to 16 mm."""
    basis = BsplineBasis(order, num_control_points)

    def rows(x):
        return np.array([[basis.EvaluateBasisFunctionI(i, float(v)) for i in range(num_control_points)] for v in x])

    q = np.asarray(q, dtype=float)
    fixed = order - 1 if rest_ends else 1
    free = slice(fixed, num_control_points - fixed)
    A = rows(s)
    ends = np.zeros((num_control_points, q.shape[1]))
    ends[:fixed], ends[num_control_points - fixed:] = q[0], q[-1]
    target = q - A @ ends
    A_free = A[:, free]
    if pins:
        B = rows([p for p, _ in pins])
        d = np.array([x for _, x in pins]) - B @ ends
        B_free = B[:, free]
        k, m = A_free.shape[1], B_free.shape[0]
        kkt = np.block([[A_free.T @ A_free, B_free.T], [B_free, np.zeros((m, m))]])
        solution = np.linalg.lstsq(kkt, np.vstack([A_free.T @ target, d]), rcond=None)[0]
        inner = solution[:k]
    else:
        inner = np.linalg.lstsq(A_free, target, rcond=None)[0]
    control = ends.copy()
    control[free] = inner
    return BsplineTrajectory(basis, [c.reshape(-1, 1) for c in control])


def _tool_speed_and_acceleration(scene: OptimizationScene, trajectory: BsplineTrajectory, tau: float,
                                 h: float = 1e-3) -> tuple[float, float]:
    """E's speed (m/s) and the magnitude of its acceleration (m/s^2) at time ``tau`` of
    ``trajectory`` (central differences over ``h``)."""
    times = [max(tau - h, trajectory.start_time()), tau, min(tau + h, trajectory.end_time())]
    p = [scene.X_WE(trajectory.value(x)[:, 0]).translation() for x in times]
    speed = float(np.linalg.norm(p[2] - p[0]) / max(times[2] - times[0], 1e-12))
    acceleration = float(np.linalg.norm(p[2] - 2.0 * p[1] + p[0]) / h ** 2)
    return speed, acceleration


def _slowed_clock(scene: OptimizationScene, trajectory: BsplineTrajectory, due: np.ndarray,
                  pass_speed_m_s: float | None, pass_acceleration_m_s2: float | None,
                  window_s: float) -> tuple[np.ndarray, np.ndarray]:
    """A retiming that passes each of the inner times ``due`` at most at
    ``pass_speed_m_s`` and ``pass_acceleration_m_s2``: the motion's rate is multiplied by
    ``1 - (1 - rho) cos^2`` bumps ``window_s`` wide on either side of each (``rho``: the
    slow-down needed; at a bump's centre the rate is flat, so speed scales by ``rho``
    and acceleration by ``rho^2``), so the path stays the same and speeds only drop.
    Returns the original times ``tau`` (a 1 ms grid) and the new clock at them."""
    T = float(trajectory.end_time())
    tau = np.linspace(0.0, T, max(int(np.ceil(T / 1e-3)), 2) + 1)
    rate = np.ones_like(tau)
    for t_i in due[1:-1] if pass_speed_m_s is not None else ():
        speed, acceleration = _tool_speed_and_acceleration(scene, trajectory, float(t_i))
        rho = min(1.0, pass_speed_m_s / speed if speed > 0 else 1.0)
        if pass_acceleration_m_s2 is not None and acceleration > 0:
            rho = min(rho, math.sqrt(pass_acceleration_m_s2 / acceleration))
        x = np.clip((tau - t_i) / window_s, -1.0, 1.0)
        rate *= 1.0 - (1.0 - rho) * np.cos(0.5 * np.pi * x) ** 2
    clock = np.concatenate([[0.0], np.cumsum(0.5 * (1.0 / rate[1:] + 1.0 / rate[:-1]) * np.diff(tau))])
    return tau, clock


def sample_trajectory(
    scene: OptimizationScene,
    trajectory: BsplineTrajectory,
    fractions: Sequence[float] | np.ndarray,
    *,
    time_step: float,
    tool_speed_m_s: float,
    tool_acceleration_m_s2: float | None = None,
    pass_speed_m_s: float | None = None,
    pass_acceleration_m_s2: float | None = None,
    slow_window_s: float = 0.15,
) -> tuple[np.ndarray, np.ndarray, list[RigidTransform], list[int], np.ndarray]:
    """Samples ``trajectory`` every ``time_step`` with each path fraction of
    ``fractions`` (the targets, in order, 0 and 1 included) on a sample.

    The motion is retimed along its path, never faster: around each inner fraction it
    slows to pass it at most at ``pass_speed_m_s`` and ``pass_acceleration_m_s2``
    (None: as optimized; see
    :func:`_slowed_clock`: a closed loop lags the command by a few milliseconds, so
    the speed at a critical configuration is what its error there grows with); each
    stretch between consecutive fractions is stretched to a whole number of steps; then
    the whole motion is slowed uniformly until E's speed (finite differences of the
    samples) is within ``tool_speed_m_s`` and, when given, the magnitude of its
    acceleration (second differences) within ``tool_acceleration_m_s2`` (uniform
    slowing keeps every path constraint and lowers every speed and acceleration).

    Returns
    -------
    t : array (m,)
    q : array (m, 6)
    X_WE : list of RigidTransform, one per sample
    indices : list of int
        The sample of each fraction.
    s : array (m,)
        Each sample's path fraction.
    """
    T = float(trajectory.end_time())
    fractions = np.asarray(fractions, dtype=float)
    tau, clock = _slowed_clock(scene, trajectory, fractions * T, pass_speed_m_s, pass_acceleration_m_s2,
                               slow_window_s)
    clock_due = np.interp(fractions * T, tau, clock)
    scale = 1.0
    for _ in range(5):
        steps = np.maximum(np.ceil(np.diff(clock_due) * scale / time_step - 1e-9), 1).astype(int)
        indices = np.concatenate([[0], np.cumsum(steps)]).astype(int)
        t = np.arange(indices[-1] + 1) * time_step
        # Each sample's clock: linear within each stretch; then its original time.
        sample_clock = np.interp(np.arange(indices[-1] + 1), indices, clock_due)
        sample_tau = np.interp(sample_clock, clock, tau)
        q = np.array([trajectory.value(float(x))[:, 0] for x in sample_tau])
        X = [scene.X_WE(x) for x in q]
        p = np.array([x.translation() for x in X])
        peak = float(np.max(np.linalg.norm(np.diff(p, axis=0), axis=1)) / time_step) if len(p) > 1 else 0.0
        slow = peak / tool_speed_m_s
        if tool_acceleration_m_s2 is not None and len(p) > 2:
            peak_acceleration = float(np.max(np.linalg.norm(np.diff(p, 2, axis=0), axis=1)) / time_step ** 2)
            slow = max(slow, math.sqrt(peak_acceleration / tool_acceleration_m_s2))
        if slow <= 1.0:
            break
        scale *= 1.02 * slow
    return t, q, X, [int(i) for i in indices], sample_tau / T
