"""Figures written on request (matplotlib, headless): training curves, SE(3) plans, joint
trajectories with their limits, distances to obstacles and shells, separation from people
with the speed override.

Each figure has a ``draw_*`` function that builds and returns the
:class:`matplotlib.figure.Figure` (to show it, test it or save it yourself) and a
``*_figure`` function that draws it, writes it as a PNG and returns the path. The figures
are plain ``Figure`` objects, not pyplot ones: importing this module selects no backend
and leaves pyplot's state alone, so it is safe in a notebook.

Not for: computing what is plotted.
"""

from __future__ import annotations

import itertools
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure
from matplotlib.legend_handler import HandlerTuple
from matplotlib.lines import Line2D

__all__ = [
    'JOINT_LABELS',
    'PLAN_COLOURS',
    'draw_training_curve',
    'training_curve_figure',
    'draw_plan',
    'plan_figure',
    'draw_joint_trajectories',
    'joint_trajectories_figure',
    'draw_shell_distance',
    'shell_distance_figure',
    'draw_separation',
    'separation_figure',
    'save_figure',
]

JOINT_LABELS = ("shoulder_pan", "shoulder_lift", "elbow", "wrist_1", "wrist_2", "wrist_3")

#: Colours of the plan figure, by what they show (the legend uses the same names).
PLAN_COLOURS = {
    "plan": "goldenrod",
    "critical configurations": "k",
    "obstacle": "red",
    "safety shell": "purple",
    "tool x": "r",
    "tool y": "g",
    "tool z": "b",
}

_DPI = 120


def save_figure(figure: Figure, path) -> Path:
    """Writes ``figure`` to ``path`` (the format from its suffix, PNG at 120 dpi) and
    returns the path."""
    path = Path(path)
    figure.savefig(path, dpi=_DPI)
    return path


# ----------------------------------------------------------------------- training curve
def draw_training_curve(curve, *, steady_episode=None, exploring=None, title="Training (Fig. 7)") -> Figure:
    """Accumulated reward per episode (averaged over the training tasks), like Fig. 7:
    ``curve`` in blue (the greedy policy after each episode), ``exploring`` in grey."""
    curve = np.asarray(curve, dtype=float)
    figure = Figure(figsize=(6, 3.5), layout="constrained")
    axes = figure.add_subplot()
    episodes = np.arange(1, len(curve) + 1)
    if exploring is not None:
        axes.plot(episodes, exploring, lw=0.8, color="0.7", label="exploring episodes")
    axes.plot(episodes, curve, lw=2, color="C0", label="greedy policy")
    if steady_episode is not None:
        axes.axvline(steady_episode, color="C3", ls="--", lw=1, label=f"steady from {steady_episode}")
    axes.set_xlabel("episode")
    axes.set_ylabel("accumulated reward")
    axes.set_title(title)
    axes.legend(loc="lower right", fontsize=8)
    return figure


def training_curve_figure(path, curve, *, steady_episode=None, exploring=None,
                          title="Training (Fig. 7)") -> Path:
    """:func:`draw_training_curve`, written to ``path``; returns the path."""
    return save_figure(draw_training_curve(curve, steady_episode=steady_episode, exploring=exploring,
                                           title=title), path)


# ----------------------------------------------------------------------- SE(3) plan
def _box_edges(box):
    """The 12 edges of a box (turned by its ``rotation``, if it has one), as (2, 3)
    segments."""
    signs = np.array(list(itertools.product((-1, 1), repeat=3)))
    half = np.asarray(box.size, dtype=float) / 2.0
    rotation = np.asarray(getattr(box, "rotation", np.eye(3)), dtype=float)
    corners = np.asarray(box.centre, dtype=float) + (signs * half) @ rotation.T
    edges = []
    for a, b in itertools.combinations(range(8), 2):
        if np.count_nonzero(signs[a] != signs[b]) == 1:  # corners differing in one axis
            edges.append(corners[[a, b]])
    return edges


def draw_plan(poses, critical_indices, *, obstacles=(), safety_shells=(), triad_every=None,
              triad_length=0.04, title="SE(3) motion plan") -> Figure:
    """The plan as a 3D path with tool triads, like Fig. 8-10.

    ``poses`` are unit dual quaternions (n, 8) of X_WE; ``critical_indices`` the samples
    of con_1 .. con_n, marked and labelled. Colours (:data:`PLAN_COLOURS`): the path
    goldenrod, critical configurations black, triads x red, y green, z blue, obstacles
    red, safety shells purple (each box turned by its ``rotation``). The legend names
    each one drawn.
    """
    from drake_lfd.core.pose_conversions import matrices_from_dual_quaternion

    colours = PLAN_COLOURS
    T = matrices_from_dual_quaternion(np.asarray(poses))
    p = T[:, :3, 3]
    figure = Figure(figsize=(6.5, 5.5), layout="constrained")
    axes = figure.add_subplot(projection="3d")
    axes.plot(*p.T, color=colours["plan"], lw=2)
    step = triad_every or max(len(p) // 25, 1)
    for index in list(range(0, len(p), step)) + list(critical_indices):
        for column, name in enumerate(("tool x", "tool y", "tool z")):
            end = p[index] + triad_length * T[index, :3, column]
            axes.plot(*np.stack([p[index], end]).T, color=colours[name], lw=1)
    for number, index in enumerate(critical_indices, start=1):
        axes.scatter(*p[index], color=colours["critical configurations"], s=15)
        axes.text(*p[index], f" con_{number}", fontsize=8)
    for boxes, name in ((obstacles, "obstacle"), (safety_shells, "safety shell")):
        for box in boxes:
            for edge in _box_edges(box):
                axes.plot(*edge.T, color=colours[name], lw=0.8, alpha=0.7)
    # One legend entry per kind of thing drawn (proxy artists: a box is 12 edges).
    entries = [("plan", Line2D([], [], color=colours["plan"], lw=2))]
    if len(critical_indices):
        entries.append(("critical configurations (con_j)",
                        Line2D([], [], color=colours["critical configurations"], ls="", marker="o", ms=4)))
    if len(obstacles):
        entries.append(("obstacle", Line2D([], [], color=colours["obstacle"], lw=0.8)))
    if len(safety_shells):
        entries.append(("safety shell (keep out)", Line2D([], [], color=colours["safety shell"], lw=0.8)))
    entries.append(("tool axes x, y, z", tuple(Line2D([], [], color=colours[f"tool {axis}"], lw=1.5)
                                               for axis in "xyz")))
    labels, handles = zip(*entries)
    axes.legend(handles, labels, loc="upper left", fontsize=7, handler_map={tuple: HandlerTuple(ndivide=None)})
    everything = np.concatenate([p] + [np.asarray(b.centre)[None] for b in (*obstacles, *safety_shells)])
    centre = everything.mean(axis=0)
    radius = max(np.ptp(everything, axis=0).max() / 2.0, 0.1) + 0.05
    axes.set_xlim(centre[0] - radius, centre[0] + radius)
    axes.set_ylim(centre[1] - radius, centre[1] + radius)
    axes.set_zlim(centre[2] - radius, centre[2] + radius)
    axes.set_xlabel("x (m)")
    axes.set_ylabel("y (m)")
    axes.set_zlabel("z (m)")
    axes.set_title(title)
    return figure


def plan_figure(path, poses, critical_indices, *, obstacles=(), safety_shells=(), triad_every=None,
                triad_length=0.04, title="SE(3) motion plan") -> Path:
    """:func:`draw_plan`, written to ``path``; returns the path."""
    return save_figure(draw_plan(poses, critical_indices, obstacles=obstacles, safety_shells=safety_shells,
                                 triad_every=triad_every, triad_length=triad_length, title=title), path)


# ----------------------------------------------------------------------- joints
def _radians_text(value: float) -> str:
    """``value`` as a multiple of pi when it is one of half a pi (``2π``, ``-π/2``), else
    in radians with 3 decimals."""
    halves = value / (np.pi / 2)
    if abs(halves - round(halves)) > 1e-6:
        return f"{value:.3f}"
    halves = int(round(halves))
    if halves == 0:
        return "0"
    sign = "-" if halves < 0 else ""
    halves = abs(halves)
    if halves % 2:
        return f"{sign}{'' if halves == 1 else halves}π/2"
    return f"{sign}{'' if halves == 2 else halves // 2}π"


def _limits_label(lower: float, upper: float) -> str:
    if np.isclose(lower, -upper, rtol=0.0, atol=1e-9):
        return f"limits ±{_radians_text(upper)}"
    return f"limits {_radians_text(lower)}, {_radians_text(upper)}"


def draw_joint_trajectories(t, q, *, lower=None, upper=None, velocity_limit=None,
                            title="Joint trajectories") -> Figure:
    """Each joint's position over time in its own panel, with that joint's position
    limits, and below every joint's speed as a fraction of its limit.

    Parameters
    ----------
    t : array, shape (n,)
        Times, seconds.
    q : array, shape (n, 6)
        Joint positions, radians, in the order of :data:`JOINT_LABELS`.
    lower, upper : array, shape (6,), optional
        Position limits per joint (``UR5eKinematics.position_limits()``: +-2 pi, the
        elbow +-pi), drawn as dotted lines labelled in each panel's legend (lines with
        ``gid`` ``"position_limit"``); infinite bounds are not drawn.
    velocity_limit : array, shape (6,), optional
        Speed limits, rad/s; pi (180 deg/s) for every joint if not given.
    """
    t, q = np.asarray(t, dtype=float), np.asarray(q, dtype=float)
    num_joints = q.shape[1]
    rows = (num_joints + 1) // 2
    figure = Figure(figsize=(8, 2.0 * rows + 2.8), layout="constrained")
    grid = figure.add_gridspec(rows + 1, 2, height_ratios=[1.0] * rows + [1.3])
    speeds = figure.add_subplot(grid[rows, :])
    limits = lower is not None and upper is not None
    for j in range(num_joints):
        axes = figure.add_subplot(grid[j // 2, j % 2], sharex=speeds)
        label = JOINT_LABELS[j] if j < len(JOINT_LABELS) else f"joint {j + 1}"
        axes.plot(t, q[:, j], lw=1.2, color=f"C{j}", label="position")
        bounds = [b for b in (float(lower[j]), float(upper[j])) if np.isfinite(b)] if limits else []
        for k, bound in enumerate(bounds):
            axes.axhline(bound, color="k", ls=":", lw=0.9, gid="position_limit",
                         label=_limits_label(float(lower[j]), float(upper[j])) if k == 0 else "_nolegend_")
        shown = np.concatenate([q[:, j], bounds])
        if shown.size:  # room above the upper limit for the legend
            low, high = float(np.min(shown)), float(np.max(shown))
            span = max(high - low, 0.1)
            axes.set_ylim(low - 0.08 * span, high + 0.28 * span)
        axes.set_title(label, fontsize=9)
        axes.set_ylabel("q (rad)", fontsize=8)
        axes.tick_params(labelsize=7, labelbottom=False)
        axes.legend(fontsize=6, loc="upper right")
    if len(t) > 1:
        qdot = np.gradient(q, t, axis=0)
        limit = np.full(num_joints, np.pi) if velocity_limit is None else np.asarray(velocity_limit, dtype=float)
        for j in range(num_joints):
            label = JOINT_LABELS[j] if j < len(JOINT_LABELS) else f"joint {j + 1}"
            speeds.plot(t, np.abs(qdot[:, j]) / limit[j], lw=1, color=f"C{j}", label=label)
        speeds.set_ylim(0.0, max(1.4, 1.05 * float(np.max(np.abs(qdot) / limit))))
    speeds.axhline(1.0, color="r", ls="--", lw=0.8, label="speed limit")
    speeds.set_ylabel("|qdot| / limit")
    speeds.set_xlabel("t (s)")
    speeds.legend(fontsize=7, ncol=4, loc="upper right")
    figure.suptitle(title)
    return figure


def joint_trajectories_figure(path, t, q, *, lower=None, upper=None, velocity_limit=None,
                              title="Joint trajectories") -> Path:
    """:func:`draw_joint_trajectories`, written to ``path``; returns the path."""
    return save_figure(draw_joint_trajectories(t, q, lower=lower, upper=upper, velocity_limit=velocity_limit,
                                               title=title), path)


# ----------------------------------------------------------------------- clearance
def draw_shell_distance(t, distance, *, title="Distance to obstacles and safety shells") -> Figure:
    """Signed distance between the robot and the nearest obstacle or shell over time."""
    figure = Figure(figsize=(6.5, 3), layout="constrained")
    axes = figure.add_subplot()
    axes.plot(t, np.asarray(distance) * 100.0, lw=1.5, label="least signed distance")
    axes.axhline(0.0, color="r", ls="--", lw=0.8, label="contact")
    axes.set_xlabel("t (s)")
    axes.set_ylabel("min distance (cm)")
    axes.set_title(title)
    axes.legend(fontsize=8)
    return figure


def shell_distance_figure(path, t, distance, *, title="Distance to obstacles and safety shells") -> Path:
    """:func:`draw_shell_distance`, written to ``path``; returns the path."""
    return save_figure(draw_shell_distance(t, distance, title=title), path)


def draw_separation(separation_t, distance, protective_distance, t, override, *, people=(),
                    title="Separation from people and the speed override") -> Figure:
    """Each person's distance to the robot ``d`` and ISO/TS 15066's protective separation
    distance ``S_p`` over time (``separation_t`` (k,), ``distance`` and
    ``protective_distance`` (k, P), m), above the speed override (``t`` (m,),
    ``override`` (m,)), protective stops shaded."""
    figure = Figure(figsize=(6.5, 4.5), layout="constrained")
    top, bottom = figure.subplots(2, 1, sharex=True, height_ratios=(2, 1))
    distance = np.atleast_2d(np.asarray(distance, dtype=float).T).T
    protective_distance = np.atleast_2d(np.asarray(protective_distance, dtype=float).T).T
    names = list(people) or [f"person {i + 1}" for i in range(distance.shape[1])]
    for index, name in enumerate(names):
        line, = top.plot(separation_t, distance[:, index], lw=1.5, label=f"d, {name}")
        top.plot(separation_t, protective_distance[:, index], lw=1.0, ls="--", color=line.get_color(),
                 label=f"S_p, {name}")
    top.set_ylabel("distance (m)")
    top.set_title(title)
    top.legend(fontsize=8)
    override = np.asarray(override, dtype=float)
    bottom.plot(t, override, color="k", lw=1.5, label="speed override ds/dt")
    stopped = override <= 1e-9
    if np.any(stopped):
        bottom.fill_between(t, 0.0, 1.0, where=stopped, color="red", alpha=0.2, lw=0, label="protective stop")
    bottom.set_ylim(-0.05, 1.05)
    bottom.set_xlabel("t (s)")
    bottom.set_ylabel("override")
    bottom.legend(fontsize=8, loc="lower right")
    return figure


def separation_figure(path, separation_t, distance, protective_distance, t, override, *, people=(),
                      title="Separation from people and the speed override") -> Path:
    """:func:`draw_separation`, written to ``path``; returns the path."""
    return save_figure(draw_separation(separation_t, distance, protective_distance, t, override, people=people,
                                       title=title), path)
