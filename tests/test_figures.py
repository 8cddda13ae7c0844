"""Figures (drake_lfd.experiments.figures): the legends name what the colours mean, and the
joint figure draws each joint's own position limits from the model."""

import numpy as np
import pytest
from matplotlib.colors import to_rgba
from matplotlib.figure import Figure

from drake_lfd.core.pose_conversions import dual_quaternion_from_euler_zyx
from drake_lfd.core.tasks import Box
from drake_lfd.experiments.figures import (
    JOINT_LABELS,
    PLAN_COLOURS,
    draw_joint_trajectories,
    draw_plan,
    draw_shell_distance,
    draw_training_curve,
    joint_trajectories_figure,
    plan_figure,
)
from drake_lfd.robot.kinematics import UR5eKinematics


def _poses(n=40):
    s = np.linspace(0.0, 1.0, n)[:, None]
    p = np.hstack([0.3 * s, 0.2 * s, 0.4 - 0.1 * s])
    euler = np.hstack([0.5 * s, np.full_like(s, -np.pi / 2), np.zeros_like(s)])
    return dual_quaternion_from_euler_zyx(p, euler)


def _legend(axes):
    legend = axes.get_legend()
    assert legend is not None
    return {text.get_text(): handle for text, handle in zip(legend.get_texts(), legend.legend_handles)}


def _boxes():
    obstacle = Box("obstacle", centre=[0.1, 0.1, 0.1], size=[0.2, 0.2, 0.2])
    shell = Box("shell", centre=[0.1, 0.1, 0.1], size=[0.4, 0.4, 0.4])
    return (obstacle,), (shell,)


def test_plan_legend_names_the_path_the_critical_configurations_the_obstacle_and_the_shell():
    obstacles, shells = _boxes()
    figure = draw_plan(_poses(), [0, 20, 39], obstacles=obstacles, safety_shells=shells)
    assert isinstance(figure, Figure)
    (axes,) = figure.axes
    entries = _legend(axes)
    expected = {"plan": "plan", "critical configurations (con_j)": "critical configurations",
                "obstacle": "obstacle", "safety shell (keep out)": "safety shell"}
    assert set(entries) == {*expected, "tool axes x, y, z"}
    for label, kind in expected.items():  # each entry has the colour that kind is drawn in
        assert to_rgba(entries[label].get_color()) == to_rgba(PLAN_COLOURS[kind]), label
    drawn = {to_rgba(line.get_color(), alpha=1) for line in axes.get_lines()}
    assert to_rgba(PLAN_COLOURS["obstacle"]) in drawn and to_rgba(PLAN_COLOURS["safety shell"]) in drawn
    # Obstacle and shell colours differ, or the legend could not tell them apart.
    assert to_rgba(PLAN_COLOURS["obstacle"]) != to_rgba(PLAN_COLOURS["safety shell"])


def test_plan_legend_lists_only_what_is_drawn():
    entries = _legend(draw_plan(_poses(), [0, 39]).axes[0])
    assert "plan" in entries and "critical configurations (con_j)" in entries
    assert "obstacle" not in entries and "safety shell (keep out)" not in entries


def _joint_axes(figure):
    return {axes.get_title(): axes for axes in figure.axes if axes.get_title() in JOINT_LABELS}


def test_joint_figure_draws_each_joints_limits_from_the_model():
    lower, upper = UR5eKinematics().position_limits()
    # The model's limits: the elbow +-pi, every other joint +-2 pi.
    np.testing.assert_allclose(upper, [2 * np.pi, 2 * np.pi, np.pi, 2 * np.pi, 2 * np.pi, 2 * np.pi])
    np.testing.assert_allclose(lower, -upper)
    t = np.linspace(0.0, 2.0, 50)
    q = 0.5 * np.sin(t[:, None] + np.arange(6))
    figure = draw_joint_trajectories(t, q, lower=lower, upper=upper, velocity_limit=np.full(6, np.pi))
    panels = _joint_axes(figure)
    assert list(panels) == list(JOINT_LABELS)
    for name, axes in panels.items():
        limit = np.pi if name == "elbow" else 2 * np.pi
        lines = [line for line in axes.get_lines() if line.get_gid() == "position_limit"]
        levels = sorted(float(line.get_ydata()[0]) for line in lines)
        assert levels == pytest.approx([-limit, limit]), name
        lo, hi = axes.get_ylim()
        assert lo < -limit and hi > limit, name  # both lines inside the view
        entries = _legend(axes)
        assert ("limits ±π" if name == "elbow" else "limits ±2π") in entries, (name, list(entries))
        assert "position" in entries
    # The speed panel names every joint and the speed limit.
    (speeds,) = [axes for axes in figure.axes if axes.get_title() not in JOINT_LABELS]
    assert set(_legend(speeds)) == {*JOINT_LABELS, "speed limit"}


def test_joint_figure_labels_asymmetric_and_missing_limits():
    t = np.linspace(0.0, 1.0, 10)
    q = np.zeros((10, 6))
    lower = np.array([-np.pi, -np.inf, -1.0, -np.pi / 2, 0.0, -3 * np.pi])
    upper = np.array([np.pi / 2, np.inf, 2.0, np.pi / 2, np.pi, 3 * np.pi])
    panels = _joint_axes(draw_joint_trajectories(t, q, lower=lower, upper=upper))
    assert "limits -π, π/2" in _legend(panels["shoulder_pan"])
    assert not [line for line in panels["shoulder_lift"].get_lines() if line.get_gid() == "position_limit"]
    assert "limits -1.000, 2.000" in _legend(panels["elbow"])
    assert "limits ±π/2" in _legend(panels["wrist_1"])
    assert "limits 0, π" in _legend(panels["wrist_2"])
    assert "limits ±3π" in _legend(panels["wrist_3"])
    # Without limits, no limit lines at all.
    bare = _joint_axes(draw_joint_trajectories(t, q))
    assert not [line for axes in bare.values() for line in axes.get_lines() if line.get_gid() == "position_limit"]


def test_other_figures_have_legends():
    curve = draw_training_curve(np.linspace(-10, -1, 30), steady_episode=12, exploring=np.linspace(-10, -2, 30))
    assert set(_legend(curve.axes[0])) == {"exploring episodes", "greedy policy", "steady from 12"}
    distance = draw_shell_distance(np.linspace(0, 1, 5), np.linspace(0.1, 0.02, 5))
    assert "contact" in _legend(distance.axes[0])


def test_figure_files_are_written(tmp_path):
    obstacles, shells = _boxes()
    lower, upper = UR5eKinematics().position_limits()
    plan = plan_figure(tmp_path / "plan.png", _poses(), [0, 39], obstacles=obstacles, safety_shells=shells)
    t = np.linspace(0.0, 1.0, 20)
    joints = joint_trajectories_figure(tmp_path / "joints.png", t, np.zeros((20, 6)), lower=lower, upper=upper)
    for path in (plan, joints):
        assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_trial_figures_use_the_models_limits_per_joint(tmp_path, monkeypatch):
    """``simulate --figures`` and ``paper`` draw a trial's joints through write_trial_figures,
    which passes each joint's limits from the model (the elbow's +-pi included)."""
    from types import SimpleNamespace

    from pydrake.math import RigidTransform

    import drake_lfd.experiments.figures as figures
    from drake_lfd.experiments.simulation import write_trial_figures

    drawn = {}

    def capture(path, t, q, **kwargs):
        drawn["figure"] = draw_joint_trajectories(t, q, **kwargs)
        return path

    monkeypatch.setattr(figures, "joint_trajectories_figure", capture)
    task = SimpleNamespace(X_WB=RigidTransform(), X_tool0_E=RigidTransform(), obstacles=(), safety_shells=())
    t = np.linspace(0.0, 1.0, 20)
    outcome = SimpleNamespace(trial=1, plan=SimpleNamespace(task=task, timed=SimpleNamespace(
        poses=_poses(20), critical_indices=[0, 19])), run=SimpleNamespace(t=t, q=np.zeros((20, 6))))
    written = write_trial_figures(task, outcome, tmp_path, "demo")
    assert (tmp_path / written["plan"]).is_file()
    panels = _joint_axes(drawn["figure"])
    for name, axes in panels.items():
        limit = np.pi if name == "elbow" else 2 * np.pi
        levels = sorted(float(line.get_ydata()[0]) for line in axes.get_lines() if line.get_gid() == "position_limit")
        assert levels == pytest.approx([-limit, limit]), name
