"""Figures written on request (matplotlib, headless): training curves and more.

Not for: computing what is plotted.
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

__all__ = [
    'training_curve_figure',
    'plan_figure',
    'JOINT_LABELS',
    'joint_trajectories_figure',
    'shell_distance_figure',
]


def training_curve_figure(path, curve, *, steady_episode=None, exploring=None,
                          title="Training (Fig. 7)") -> Path:
    """Accumulated reward per episode (averaged over the training tasks), like Fig. 7:
    ``curve`` in blue (the greedy policy after each episode), ``exploring`` in grey."""
    curve = np.asarray(curve, dtype=float)
    figure, axes = plt.subplots(figsize=(6, 3.5))
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
    figure.tight_layout()
    path = Path(path)
    figure.savefig(path, dpi=120)
    plt.close(figure)
    return path


def _box_edges(centre, size):
    """The 12 edges of an axis-aligned box, as (2, 3) segments."""
    import itertools

    half = np.asarray(size, dtype=float) / 2.0
    corners = np.array([np.asarray(centre) + half * s for s in itertools.product((-1, 1), repeat=3)])
    edges = []
    for a, b in itertools.combinations(range(8), 2):
        if np.count_nonzero(corners[a] != corners[b]) == 1:
            edges.append(corners[[a, b]])
    return edges


def plan_figure(path, poses, critical_indices, *, obstacles=(), safety_shells=(), triad_every=None,
                triad_length=0.04, title="SE(3) motion plan") -> Path:
    """The plan as a 3D path with tool triads (x red, y green, z blue), like Fig. 8-10.

    ``poses`` are unit dual quaternions (n, 8) of X_WE; critical configurations are
    labelled con_1 .. con_n; obstacles are drawn red, safety shells purple.
    """
    from drake_lfd.core.dual_quaternion import matrices_from_dual_quaternion

    T = matrices_from_dual_quaternion(np.asarray(poses))
    p = T[:, :3, 3]
    figure = plt.figure(figsize=(6.5, 5.5))
    axes = figure.add_subplot(projection="3d")
    axes.plot(*p.T, color="goldenrod", lw=2, label="plan")
    step = triad_every or max(len(p) // 25, 1)
    for index in list(range(0, len(p), step)) + list(critical_indices):
        for column, colour in zip(range(3), ("r", "g", "b")):
            end = p[index] + triad_length * T[index, :3, column]
            axes.plot(*np.stack([p[index], end]).T, color=colour, lw=1)
    for number, index in enumerate(critical_indices, start=1):
        axes.scatter(*p[index], color="k", s=15)
        axes.text(*p[index], f" con_{number}", fontsize=8)
    for boxes, colour in ((obstacles, "red"), (safety_shells, "purple")):
        for box in boxes:
            for edge in _box_edges(box.centre, box.size):
                axes.plot(*edge.T, color=colour, lw=0.8, alpha=0.7)
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
    figure.tight_layout()
    path = Path(path)
    figure.savefig(path, dpi=120)
    plt.close(figure)
    return path


JOINT_LABELS = ("shoulder_pan", "shoulder_lift", "elbow", "wrist_1", "wrist_2", "wrist_3")


def joint_trajectories_figure(path, t, q, *, lower=None, upper=None, velocity_limit=None,
                              title="Joint trajectories") -> Path:
    """Joint positions (and speeds as a fraction of the limit) over time, with limits."""
    t, q = np.asarray(t, dtype=float), np.asarray(q, dtype=float)
    figure, (top, bottom) = plt.subplots(2, 1, figsize=(7, 5.5), sharex=True)
    for j in range(q.shape[1]):
        top.plot(t, q[:, j], lw=1.2, label=JOINT_LABELS[j])
    if lower is not None and upper is not None:
        for bound in (np.min(lower), np.max(upper)):
            top.axhline(bound, color="k", ls=":", lw=0.8)
    top.set_ylabel("q (rad)")
    top.legend(fontsize=7, ncol=3)
    top.set_title(title)
    if len(t) > 1:
        qdot = np.gradient(q, t, axis=0)
        limit = np.full(q.shape[1], np.pi) if velocity_limit is None else np.asarray(velocity_limit)
        for j in range(q.shape[1]):
            bottom.plot(t, np.abs(qdot[:, j]) / limit[j], lw=1)
    bottom.axhline(1.0, color="r", ls="--", lw=0.8, label="speed limit")
    bottom.set_ylabel("|qdot| / limit")
    bottom.set_xlabel("t (s)")
    bottom.legend(fontsize=7)
    figure.tight_layout()
    path = Path(path)
    figure.savefig(path, dpi=120)
    plt.close(figure)
    return path


def shell_distance_figure(path, t, distance, *, title="Distance to obstacles and safety shells") -> Path:
    """Signed distance between the robot and the nearest obstacle or shell over time."""
    figure, axes = plt.subplots(figsize=(6.5, 3))
    axes.plot(t, np.asarray(distance) * 100.0, lw=1.5)
    axes.axhline(0.0, color="r", ls="--", lw=0.8, label="contact")
    axes.set_xlabel("t (s)")
    axes.set_ylabel("min distance (cm)")
    axes.set_title(title)
    axes.legend(fontsize=8)
    figure.tight_layout()
    path = Path(path)
    figure.savefig(path, dpi=120)
    plt.close(figure)
    return path
