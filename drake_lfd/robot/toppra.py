"""Time-optimal path parametrization (TOPP-RA) with each stage's linear program in closed form.

Drake's ``Toppra`` (``multibody/optimization/toppra.cc``) times a path ``q(s)`` on a
grid ``s_0 < ... < s_N``: with ``x = sdot^2`` and ``u = sddot`` every limit is linear in
``(x, u)`` at a grid point (joint speeds and the tool's translational speed bound ``x``
alone; joint and tool accelerations are rows ``lb <= a x + b u <= ub``, each also
imposed at the next grid point through ``x' = x + 2 delta u``, its "interpolation"
discretization). A backward pass computes the controllable sets ``[K0_k, K1_k]`` (the
least and largest ``x`` from which the rest can still be run, ending at rest), a forward
pass takes the largest ``u`` that keeps the next ``x`` inside them, and ``s(t)`` is the
piecewise quadratic through the grid (``s_k + sdot_k tau + u_k tau^2 / 2``).

Drake solves each stage's two-variable linear program with CLP, three solver calls per
grid point. This module builds the same constraints and solves the
same programs exactly, in closed form: eliminating ``u`` (Fourier-Motzkin) turns every
pair of a lower and an upper bound on ``u`` into a bound on ``x``; the pairs that do not
involve the next stage's set are computed for all stages at once, the few that do in
the sequential passes. The result equals Drake's to CLP's tolerance (1e-9 relative on
the paper's pieces; ``tests/test_toppra.py`` compares them), at about a tenth of its
cost.

Not for: fitting the path or splitting it at stops (``path_timing.py``).
"""

from __future__ import annotations

import math

import numpy as np
from pydrake.multibody.tree import JacobianWrtVariable
from pydrake.polynomial import Polynomial
from pydrake.trajectories import PiecewisePolynomial

__all__ = ["StageConstraints", "path_constraints", "solve_parametrization"]

# Drake's bound on x that keeps the backward pass's sets bounded.
_X_CEILING = 1e16
# Relative slack below which a stage's infeasibility is rounding (CLP's tolerance is 1e-7).
_FEASIBILITY_SLACK = 1e-9
# Drake's tolerance on the start's controllability and its shortest segment of s(t).
_START_SLACK = 1e-8
_EPSILON_TIME = np.finfo(float).eps


class StageConstraints:
    """The limits at grid points ``0 .. N-1`` of a grid ``gridpoints`` (N + 1,):
    ``x_lower``, ``x_upper`` (N,) bound ``x`` alone; rows ``lb <= a x + b u <= ub`` with
    ``a``, ``b``, ``lb``, ``ub`` (N, R)."""

    def __init__(self, gridpoints, x_lower, x_upper, a, b, lb, ub):
        self.gridpoints = np.asarray(gridpoints, dtype=float)
        self.x_lower, self.x_upper = np.asarray(x_lower, dtype=float), np.asarray(x_upper, dtype=float)
        self.a, self.b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
        self.lb, self.ub = np.asarray(lb, dtype=float), np.asarray(ub, dtype=float)


def _interpolated(gridpoints, a, b, lb, ub):
    """Drake's interpolation discretization: each row also at the next grid point,
    through ``x' = x + 2 delta u`` (the last stage repeats its own rows)."""
    delta = np.diff(gridpoints)[:, None]  # (N, 1)
    a2, b2 = np.empty_like(a), np.empty_like(b)
    a2[:-1], b2[:-1] = a[1:], b[1:] + 2.0 * delta[:-1] * a[1:]
    a2[-1], b2[-1] = a[-1], b[-1]
    lb2, ub2 = np.concatenate([lb[1:], lb[-1:]]), np.concatenate([ub[1:], ub[-1:]])
    return (np.concatenate([a, a2], axis=1), np.concatenate([b, b2], axis=1),
            np.concatenate([lb, lb2], axis=1), np.concatenate([ub, ub2], axis=1))


def path_constraints(path: PiecewisePolynomial, gridpoints: np.ndarray, plant, frame, *, joint_speed: np.ndarray,
                     joint_acceleration: np.ndarray, tool_speed: float,
                     tool_acceleration: np.ndarray | None = None) -> StageConstraints:
    """The constraints Drake's ``Toppra`` builds for ``AddJointVelocityLimit(-v, v)``,
    ``AddJointAccelerationLimit(-a, a)``, ``AddFrameTranslationalSpeedLimit(frame,
    tool_speed)`` and, with ``tool_acceleration`` (6,) (spatial: rotation then
    translation), ``AddFrameAccelerationLimit(frame, -bound, bound)``, on ``plant``'s
    positions along ``path`` at ``gridpoints``."""
    g = np.asarray(gridpoints, dtype=float)
    s = g[:-1]
    q = path.vector_values(s).T  # (N, n)
    qs = path.derivative(1).vector_values(s).T
    qss = path.derivative(2).vector_values(s).T
    v = np.asarray(joint_speed, dtype=float)
    with np.errstate(divide="ignore"):
        sd_max = np.min(np.where(qs != 0.0, v / np.abs(qs), np.inf), axis=1)
    x_upper = np.minimum(sd_max**2, _X_CEILING)
    context = plant.CreateDefaultContext()
    world = plant.world_frame()
    speed_squared = np.empty(len(s))
    rows_tool = []
    origin = np.zeros(3)
    for k in range(len(s)):
        plant.SetPositions(context, q[k])
        if tool_acceleration is None:
            J = plant.CalcJacobianTranslationalVelocity(context, JacobianWrtVariable.kV, frame, origin, world, world)
            velocity = J @ qs[k]
            speed_squared[k] = velocity @ velocity
            continue
        J = plant.CalcJacobianSpatialVelocity(context, JacobianWrtVariable.kQDot, frame, origin, world, world)
        plant.SetVelocities(context, qs[k])
        bias = plant.CalcBiasSpatialAcceleration(context, JacobianWrtVariable.kV, frame, origin, world,
                                                 world).get_coeffs()
        velocity = J[3:] @ qs[k]
        speed_squared[k] = velocity @ velocity
        rows_tool.append((J @ qss[k] + bias, J @ qs[k]))
    with np.errstate(divide="ignore"):
        x_tool = np.where(speed_squared > 0.0, tool_speed**2 / speed_squared, np.inf)
    x_upper = np.minimum(x_upper, x_tool)
    acceleration = np.broadcast_to(np.asarray(joint_acceleration, dtype=float), qs.shape)
    a, b, lb, ub = qss, qs, -acceleration, acceleration
    if tool_acceleration is not None:
        bound = np.broadcast_to(np.asarray(tool_acceleration, dtype=float), (len(s), 6))
        a = np.concatenate([a, np.array([r[0] for r in rows_tool])], axis=1)
        b = np.concatenate([b, np.array([r[1] for r in rows_tool])], axis=1)
        lb, ub = np.concatenate([lb, -bound], axis=1), np.concatenate([ub, bound], axis=1)
    a, b, lb, ub = _interpolated(g, a, b, lb, ub)
    return StageConstraints(g, np.zeros(len(s)), x_upper, a, b, lb, ub)


def _lines(c: StageConstraints):
    """Each row as bounds on u: ``u >= p + m x`` and ``u <= P + M x`` ((N, R) each;
    p = -inf, P = inf where a row gives none), and the x-interval of the rows without u."""
    a, b, lb, ub = c.a, c.b, c.lb, c.ub
    moving = b != 0.0
    safe_b = np.where(moving, b, 1.0)
    m = np.where(moving, -a / safe_b, 0.0)
    positive = b > 0.0
    with np.errstate(invalid="ignore"):
        p = np.where(moving, np.where(positive, lb, ub) / safe_b, -np.inf)
        P = np.where(moving, np.where(positive, ub, lb) / safe_b, np.inf)
    # Rows without u bound x (a x in [lb, ub]).
    x_lo, x_hi = np.maximum(c.x_lower, 0.0), np.minimum(c.x_upper, _X_CEILING)
    feasible = np.ones(len(a), dtype=bool)
    still = ~moving
    if still.any():
        with np.errstate(divide="ignore", invalid="ignore"):
            low = np.where(a > 0, lb / a, np.where(a < 0, ub / a, -np.inf))
            high = np.where(a > 0, ub / a, np.where(a < 0, lb / a, np.inf))
        x_lo = np.maximum(x_lo, np.max(np.where(still, low, -np.inf), axis=1))
        x_hi = np.minimum(x_hi, np.min(np.where(still, high, np.inf), axis=1))
        feasible &= ~np.any(still & (a == 0.0) & ((lb > 0.0) | (ub < 0.0)), axis=1)
    return p, m, P, m, x_lo, x_hi, feasible


def _pair_bounds(p, m, P, M):
    """The x-interval where every lower bound on u stays below every upper one, for all
    stages at once ((N,) each), and whether some pair is contradictory whatever x."""
    c = m[:, :, None] - M[:, None, :]  # (N, lower, upper)
    r = P[:, None, :] - p[:, :, None]
    active = np.isfinite(p)[:, :, None] & np.isfinite(P)[:, None, :]
    with np.errstate(divide="ignore", invalid="ignore"):
        bound = r / c
    hi = np.min(np.where(active & (c > 0.0), bound, np.inf), axis=(1, 2))
    lo = np.max(np.where(active & (c < 0.0), bound, -np.inf), axis=(1, 2))
    contradictory = np.any(active & (c == 0.0) & (r < 0.0), axis=(1, 2))
    return lo, hi, contradictory


def _slack(value: float) -> float:
    return _FEASIBILITY_SLACK * max(1.0, abs(value))


def solve_parametrization(c: StageConstraints, s_dot_start: float = 0.0,
                          s_dot_end: float = 0.0) -> PiecewisePolynomial | None:
    """``s(t)`` from ``s_dot_start`` to ``s_dot_end`` (Drake's
    ``SolvePathParameterization``), or None when the path cannot be run within the
    constraints (the cases where Drake's returns none)."""
    g = c.gridpoints
    N = len(g) - 1
    p, m, P, M, x_lo, x_hi, feasible = _lines(c)
    static_lo, static_hi, contradictory = _pair_bounds(p, m, P, M)
    if np.any(contradictory) or not np.all(feasible):
        return None
    static_lo, static_hi = np.maximum(static_lo, x_lo), np.minimum(static_hi, x_hi)
    h = 0.5 / np.diff(g)  # 1 / (2 delta): the continuity row x + 2 delta u in [K0', K1']
    # Pairs with the continuity row: its lower bound on u, (K0' - x) h, against each
    # upper bound (P + M x), and each lower bound (p + m x) against its upper, (K1' - x) h.
    # x <= or >= (P - K0' h) / (-h - M) and (K1' h - p) / (m + h).
    c1 = -h[:, None] - M
    c2 = m + h[:, None]
    fp, fP = np.isfinite(p), np.isfinite(P)
    up1, lo1, up2, lo2 = fP & (c1 > 0.0), fP & (c1 < 0.0), fp & (c2 > 0.0), fp & (c2 < 0.0)
    zeros = np.zeros_like(P)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        inv1, inv2 = 1.0 / c1, 1.0 / c2
        # Each bound is alpha + beta K0' + gamma K1', as (N, 2R) arrays for the upper and
        # the lower bounds on x.
        alpha_up = np.concatenate([np.where(up1, P * inv1, np.inf), np.where(up2, -p * inv2, np.inf)], axis=1)
        beta_up = np.concatenate([np.where(up1, -h[:, None] * inv1, 0.0), zeros], axis=1)
        gamma_up = np.concatenate([zeros, np.where(up2, h[:, None] * inv2, 0.0)], axis=1)
        alpha_lo = np.concatenate([np.where(lo1, P * inv1, -np.inf), np.where(lo2, -p * inv2, -np.inf)], axis=1)
        beta_lo = np.concatenate([np.where(lo1, -h[:, None] * inv1, 0.0), zeros], axis=1)
        gamma_lo = np.concatenate([zeros, np.where(lo2, h[:, None] * inv2, 0.0)], axis=1)

    # The sequential passes run on Python floats (a few dozen numbers a stage: cheaper
    # than numpy calls; the same operations, so the same numbers).
    au, bu, cu = alpha_up.tolist(), beta_up.tolist(), gamma_up.tolist()
    al, bl, cl = alpha_lo.tolist(), beta_lo.tolist(), gamma_lo.tolist()
    static_lo_list, static_hi_list = static_lo.tolist(), static_hi.tolist()
    K0, K1 = [0.0] * (N + 1), [0.0] * (N + 1)
    K0[N] = K1[N] = s_dot_end**2
    for k in range(N - 1, -1, -1):
        next_lo, next_hi = K0[k + 1], K1[k + 1]
        hi = min(static_hi_list[k], min([a + b * next_lo + c * next_hi for a, b, c in zip(au[k], bu[k], cu[k])]))
        lo = max(static_lo_list[k], max([a + b * next_lo + c * next_hi for a, b, c in zip(al[k], bl[k], cl[k])]))
        if math.isnan(lo) or math.isnan(hi) or lo > hi + _slack(hi):
            return None
        lo = min(lo, hi)
        K0[k], K1[k] = max(lo, 0.0), hi
    x_start = s_dot_start**2
    if x_start < K0[0] - _START_SLACK or x_start > K1[0] + _START_SLACK:
        return None

    # Forward pass: the largest u keeping every row and the next set.
    x = [0.0] * (N + 1)
    u = [0.0] * N
    x[0] = x_start
    delta = np.diff(g)
    P_rows, M_rows, p_rows, m_rows = P.tolist(), M.tolist(), p.tolist(), m.tolist()
    h_list, delta_list = h.tolist(), delta.tolist()
    for k in range(N):
        xk = x[k]
        u_up = min(min([a + b * xk for a, b in zip(P_rows[k], M_rows[k])]), (K1[k + 1] - xk) * h_list[k])
        u_lo = max(max([a + b * xk for a, b in zip(p_rows[k], m_rows[k])]), (K0[k + 1] - xk) * h_list[k])
        if math.isnan(u_up) or u_lo > u_up + _slack(u_up):
            return None
        u[k] = u_up
        x[k + 1] = max(K0[k + 1], min(K1[k + 1], xk + 2.0 * delta_list[k] * u_up))
    x, u = np.array(x), np.array(u)
    sd = np.sqrt(x)
    if np.any(np.isnan(sd)):
        return None
    dt = delta / ((sd[1:] + sd[:-1]) / 2.0)
    if not np.all(np.isfinite(dt)) or np.any(dt < _EPSILON_TIME):
        return None
    t_knots = np.concatenate([[g[0]], g[0] + np.cumsum(dt)])
    polynomials = [Polynomial(np.array([g[k], sd[k], 0.5 * u[k]])) for k in range(N)]
    return PiecewisePolynomial(polynomials, t_knots.tolist())
