"""Closed-loop UR5e runs of short hand-built plans, and their judgement (docs/method.rst, Closed loop and success)."""

import base64
import math
import re

import numpy as np
import pytest

import drake_lfd.diagrams.closed_loop as mut
import drake_lfd.diagrams.judging as judging
from drake_lfd.robot.kinematics import UR5eKinematics
from drake_lfd.robot.scene import KinematicScene
from drake_lfd.core.tasks import Box, PathConstraint
from browser import CHROMIUM, fraction_of_hue, fraction_of_purple, screenshot

pytestmark = pytest.mark.slow

Q_HOME = np.array([0.0, -1.2, 1.6, -1.97, -math.pi / 2, 0.0])
Q_A = Q_HOME + np.array([0.25, 0.1, -0.15, 0.05, 0.1, 0.2])
Q_B = Q_HOME + np.array([-0.05, 0.05, 0.1, 0.1, -0.1, -0.2])
# A shell under the path, about 5 cm from the flange at its closest, around an obstacle.
SHELL_BELOW = Box(name="shell_below", centre=[-0.60, -0.25, 0.12], size=[0.3, 0.3, 0.1])
OBSTACLE = Box(name="block", centre=[-0.60, -0.25, 0.12], size=[0.1, 0.1, 0.05])


@pytest.fixture(scope="module")
def plan():
    """Three critical configurations (con_1 .. con_3) in about 3 s."""
    plan = mut.plan_through_joint_configurations([Q_HOME, Q_A, Q_B])
    assert 2.0 < plan.duration < 3.5
    return plan


@pytest.fixture(scope="module")
def html_path(tmp_path_factory):
    return tmp_path_factory.mktemp("recording") / "run.html"


@pytest.fixture(scope="module")
def tracked(plan, html_path):
    """The default run (IK start, Drake's differential IK, 5 ms plant), recorded."""
    return mut.run_closed_loop(plan, obstacles=[OBSTACLE], safety_shells=[SHELL_BELOW], record_html=html_path)


def _assert_tracked(result, plan):
    assert [e.con for e in result.critical_errors] == [1, 2, 3]
    for error, index in zip(result.critical_errors, plan.critical_indices):
        assert error.reached
        assert error.time_s == pytest.approx(result.plan_start_time_s + plan.times[index])
        assert error.position_m < 0.005 and error.rotation_rad < math.radians(2.0)
        # Independent of the controller: FK of the logged q at that time.
        expected = plan.X_WE_list()[index]
        X = UR5eKinematics().X_WE(error.q)
        assert np.linalg.norm(X.translation() - expected.translation()) == pytest.approx(error.position_m)
    judgement = judging.judge_run(result)
    assert judgement.success, judgement.failures


def test_tracks_the_critical_configurations_beside_a_shell(tracked, plan):
    result = tracked
    _assert_tracked(result, plan)
    # Much better than the 5 mm / 2 deg tolerances: the arm is at rest at each con.
    assert max(e.position_m for e in result.critical_errors) < 0.5e-3
    assert result.initial_configuration is not None and result.initial_configuration.collision_free
    # The log: 100 Hz over settle + plan, joint speeds well inside the limits.
    assert np.all(np.diff(result.t) <= 0.01 + 1e-9)
    assert result.t[-1] == pytest.approx(result.plan_start_time_s + plan.duration, abs=0.011)
    assert result.q.shape == result.qdot.shape == (len(result.t), 6)
    assert 0.0 < result.max_joint_speed_fraction < 0.9
    assert result.sim_time_s == pytest.approx(result.plan_start_time_s + plan.duration)


def test_shell_clearance_matches_a_recomputation_from_logged_q(tracked):
    result = tracked
    assert 0.0 < result.min_shell_distance_m < 0.1
    assert result.min_distance_pair == ("wrist_3_link/flange", "safety shell 'shell_below'")
    block, shell = result.clearances
    assert (block.box, block.kind, shell.box, shell.kind) == ("block", "obstacle", "shell_below", "safety shell")
    assert block.distance_m > shell.distance_m
    scene = KinematicScene(obstacles=[OBSTACLE], safety_shells=[SHELL_BELOW])
    recomputed = np.array([scene.signed_distances(q).min(axis=0) for q in result.q]).min(axis=0)
    # The monitor samples the same instants and states as the 100 Hz logger: exact.
    np.testing.assert_allclose([block.distance_m, shell.distance_m], recomputed, atol=1e-9)


def test_html_recording_is_written_and_self_contained(tracked, html_path):
    html = html_path.read_text()
    assert "<html" in html.lower()
    assert not re.search(r"<script[^>]+src=\"https?://", html)
    assert not re.search(r"<link[^>]+href=\"https?://", html)
    assert len(html) > 1_000_000  # three.js and the animation are inlined
    # Meshcat's commands are inlined as base64 msgpack: the scene and an animation.
    commands = [base64.b64decode(b) for b in re.findall(r"data:application/octet-binary;base64,([A-Za-z0-9+/=]+)", html)]
    for name in (b"shell_below", b"block", b"wrist_3_link", b"animation", b"plan/tool_path", b"plan/con_1",
                 b"plan/con_3"):
        assert any(name in command for command in commands), name


@pytest.mark.skipif(CHROMIUM is None, reason="needs Debian's chromium (installed by .ci/run)")
def test_html_recording_shows_the_arm_and_the_obstacle(tracked, html_path, tmp_path):
    def shows_everything(image):
        return (fraction_of_hue(image, channel=0) > 0.001 and fraction_of_hue(image, channel=2) > 0.001
                and fraction_of_purple(image) > 0.005 and fraction_of_hue(image, channel=1) > 0.00025)

    image = screenshot(html_path, tmp_path / "run.png")
    if not shows_everything(image):  # a loaded machine can starve the renderer: once more, longer
        image = screenshot(html_path, tmp_path / "run_again.png", budget_ms=9000)
    assert fraction_of_hue(image, channel=0) > 0.001  # the red obstacle
    assert fraction_of_hue(image, channel=2) > 0.001  # the UR's blue joint caps
    assert fraction_of_purple(image) > 0.005  # the translucent purple safety shell
    assert fraction_of_hue(image, channel=1) > 0.00025  # the green planned path and the triads' y axes


@pytest.mark.parametrize(
    "options",
    [
        {"time_step": 1e-3},  # the 1 ms plant
        {"controller": "pseudo_inverse"},  # the paper's Eq. 35-38 baseline
    ],
    ids=["plant_1ms", "pseudo_inverse"],
)
def test_other_settings_track_too(plan, options):
    result = mut.run_closed_loop(plan, q_initial=Q_HOME, safety_shells=[SHELL_BELOW], **options)
    _assert_tracked(result, plan)
    assert result.initial_configuration is None
    np.testing.assert_array_equal(result.q[0], Q_HOME)


def test_a_plan_through_a_shell_fails_naming_the_shell(plan):
    X = plan.X_WE_list()
    midway = 0.5 * (X[0].translation() + X[plan.critical_indices[1]].translation())
    in_the_way = Box(name="in_the_way", centre=midway, size=[0.04, 0.04, 0.04])
    result = mut.run_closed_loop(plan, q_initial=Q_HOME, safety_shells=[SHELL_BELOW, in_the_way])
    assert result.min_shell_distance_m < -0.01
    judgement = judging.judge_run(result)
    assert not judgement.success
    assert len(judgement.failures) == 1
    assert judgement.failures[0].startswith("safety shell 'in_the_way' penetrated by wrist_3_link/")
    # The shell never pushed the arm: the run still reaches its configurations.
    assert all(e.position_m < 0.005 for e in result.critical_errors)

    stopped = mut.run_closed_loop(
        plan, q_initial=Q_HOME, safety_shells=[in_the_way], stop_on_penetration=True
    )
    assert stopped.stopped_early and stopped.sim_time_s < result.sim_time_s
    assert "in_the_way" in stopped.stop_reason
    failures = judging.judge_run(stopped).failures
    assert any(f.startswith("con_3: not reached") for f in failures)
    assert any(f.startswith("safety shell 'in_the_way' penetrated") for f in failures)


def test_judge_names_each_broken_criterion(tracked, plan):
    result = tracked
    R_con_1 = UR5eKinematics().X_WE(Q_HOME).rotation()
    euler_zyx = R_con_1.ToRollPitchYaw().vector()[::-1]
    keep_level = PathConstraint(
        kind="orientation", con_from=1, con_to=3, euler_zyx=euler_zyx, tolerance_rad=math.radians(5.0)
    )
    loose = PathConstraint(
        kind="orientation", con_from=1, con_to=3, euler_zyx=euler_zyx, tolerance_rad=math.radians(30.0)
    )
    assert judging.judge_run(result, path_constraints=[loose]).success
    failures = judging.judge_run(
        result,
        path_constraints=[keep_level],
        velocity_limits=np.full(6, 0.05),
        joint_limits=(np.full(6, -2 * math.pi), np.array([7.0, 7.0, 7.0, 7.0, -1.6, 7.0])),
        position_tolerance_m=1e-6,
        rotation_tolerance_rad=1e-7,
    ).failures
    text = "\n".join(failures)
    assert "path constraint con_1..con_3: tool orientation" in text
    assert re.search(r"shoulder_pan_joint: speed [0-9.]+ rad/s > limit 0.05 rad/s", text)
    assert re.search(r"wrist_2_joint: position -1.[0-9]+ rad outside", text)
    assert re.search(r"con_2: position error [0-9.]+ mm > 0.001 mm", text)
    assert "con_2: rotation error" in text
