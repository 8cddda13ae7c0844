"""Simulated kinesthetic demonstrations: guidance scripts, the guidance path, the virtual
hand, the RTDE-rate recorder, ``drake-lfd record`` and the bundled paper libraries (Table 5)."""

import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from pydrake.math import RigidTransform, RollPitchYaw, RotationMatrix
from pydrake.multibody.math import SpatialVelocity

import drake_lfd.experiments.table5 as table5
from drake_lfd.io.task_files import load_task
from pydrake.systems.analysis import Simulator

import drake_lfd.core.guidance as guidance
import drake_lfd.diagrams.kinesthetic as mut
import drake_lfd.io.guidance_scripts as scripts
from drake_lfd.systems.virtual_hand import VirtualHand, VirtualHandGains
from drake_lfd.systems.demo_recorder import DemoRecorder
from drake_lfd.robot.kinematics import dual_quaternions_from_demonstration
from drake_lfd.io.demonstration_logs import read_rtde_csv
from drake_lfd.core.dual_quaternion import dual_quaternion_relative
from drake_lfd.core.pose_conversions import dual_quaternion_from_rigid_transform
from drake_lfd.core.quaternion import axis_angle_from_quaternion
from drake_lfd.core.errors import InputError
from drake_lfd.core.features import Feature
from drake_lfd.robot.kinematics import UR5eKinematics
from drake_lfd.io.library import Library

REPOSITORY = Path(__file__).resolve().parent.parent
SIMS = REPOSITORY / "sims"

# A short screwing motion: -90 deg about the tool's z axis (clockwise seen from the
# tool's face) while pushing 5 cm along it, then the default hold.
SCREW_SCRIPT = """\
name: short_screw
description: a short clockwise screwing motion
waypoints:
  - {t: 0.0, p: [0.45, 0.15, 0.32], euler_zyx: [0, 0, pi]}
  - {t: 2.0, p: [0.45, 0.15, 0.27], euler_zyx: [90deg, 0, pi]}
seed: 7
"""


# ----------------------------------------------------------------------- scripts


def test_script_loads_with_defaults():
    script = scripts.guidance_script_from_text(SCREW_SCRIPT, file="screw.yaml")
    assert script.name == "short_screw"
    assert len(script.waypoints) == 2
    assert script.sample_rate_hz == 500.0
    assert script.hold_s == guidance.DEFAULT_HOLD_S
    assert script.duration_s == pytest.approx(2.0 + guidance.DEFAULT_HOLD_S)
    assert script.hand_noise == guidance.HandNoise()
    assert script.seed == 7
    # euler_zyx [90deg, 0, pi] is Rz(90 deg) Rx(180 deg).
    expected = RotationMatrix(RollPitchYaw(math.pi, 0.0, math.pi / 2))
    np.testing.assert_allclose(script.waypoints[1].X_WE.rotation().matrix(), expected.matrix(), atol=1e-12)
    np.testing.assert_allclose(script.waypoints[1].X_WE.translation(), [0.45, 0.15, 0.27])
    assert script.X_WB.IsExactlyIdentity() and script.X_tool0_E.IsExactlyIdentity()


@pytest.mark.parametrize(
    "edit, field, words",
    [
        (lambda s: s + "wobble: 3\n", "wobble", "unknown key"),
        (lambda s: s.replace("[0.45, 0.15, 0.27]", "[0.45, .nan, 0.27]"), "waypoints[1].p[1]", "not a finite"),
        (lambda s: s.replace("t: 2.0", "t: 0.0"), "waypoints[1].t", "strictly increase"),
        (lambda s: s.replace("[90deg, 0, pi]", "[0, 0, 0]"), "waypoints[1].euler_zyx", "intermediate waypoint"),
        (lambda s: s + "hand_noise: {speed_variation: 0.7}\n", "hand_noise.speed_variation", "< 0.5"),
        (lambda s: s + "hand_noise: {jitter: 1}\n", "hand_noise.jitter", "unknown key"),
        (lambda s: s + "sample_rate_hz: 5000\n", "sample_rate_hz", "between"),
        (lambda s: s.replace("seed: 7", "seed: 1.5"), "seed", "integer"),
        (lambda s: s.replace("name: short_screw\n", ""), "name", "missing"),
        (lambda s: s.split("  - {t: 2.0")[0] + "seed: 1\n", "waypoints", "at least 2"),
    ],
)
def test_bad_scripts_name_the_field(edit, field, words):
    text = edit(SCREW_SCRIPT)
    with pytest.raises(InputError) as info:
        scripts.guidance_script_from_text(text, file="bad.yaml")
    message = str(info.value)
    assert "\n" not in message
    assert message.startswith("bad.yaml: ")
    assert info.value.field == field
    assert words in message


# ----------------------------------------------------------------------- guidance


def _poses_close(D_a, D_b, position_tol, angle_tol):
    relative = dual_quaternion_relative(np.atleast_2d(D_a), np.atleast_2d(D_b))
    _, angle = axis_angle_from_quaternion(relative[:, :4])
    from drake_lfd.core.dual_quaternion import translation_from_dual_quaternion

    return (
        np.all(np.linalg.norm(translation_from_dual_quaternion(relative), axis=-1) <= position_tol)
        and np.all(angle <= angle_tol)
    )


def test_steady_hand_passes_through_the_waypoints_and_stops():
    script = scripts.guidance_script_from_text(SCREW_SCRIPT)
    steady = guidance.GuidanceScript(**{**script.__dict__, "hand_noise": guidance.STEADY_HAND})
    path = guidance.GuidancePath(steady)
    D = steady.waypoint_dual_quaternions()
    assert _poses_close(path.poses([0.0]), D[0], 1e-12, 1e-9)
    assert _poses_close(path.poses([2.0, 2.3, 2.5]), D[1], 1e-12, 1e-9)
    # Minimum jerk: half way in time is half way along the screw.
    middle = path.poses([1.0])
    _, angle = axis_angle_from_quaternion(dual_quaternion_relative(D[:1], middle)[:, :4])
    assert math.degrees(angle[0]) == pytest.approx(45.0, abs=1e-6)
    sampled = path.sample(1e-3)
    assert np.abs(sampled.v_WH[0]).max() < 1e-6 and np.abs(sampled.v_WH[-1]).max() < 1e-6


def test_hand_noise_is_small_smooth_seeded_and_fades_out():
    script = scripts.guidance_script_from_text(SCREW_SCRIPT)
    path = guidance.GuidancePath(script)
    t = np.linspace(0.0, script.duration_s, 2001)
    dp, dtheta = path.wobble(t)
    assert np.abs(dp[0]).max() == 0.0 and np.abs(dtheta[0]).max() == 0.0
    assert np.abs(dp[-1]).max() < 1e-12  # faded out before the end of the hold
    moving = (t > 0.3) & (t < 2.0)
    rms_position = np.sqrt(np.mean(np.sum(dp[moving] ** 2, axis=1)))
    assert 0.0003 < rms_position < 0.003  # about a millimetre
    assert np.degrees(np.linalg.norm(dtheta, axis=1)).max() < 2.0
    # Slightly uneven pace that keeps the first and last waypoint times.
    tau = path.script_time(t)
    assert np.all(np.diff(tau) > 0.0)
    assert tau[0] == 0.0 and path.script_time([2.0])[0] == pytest.approx(2.0, abs=1e-12)
    assert 0.0 < np.abs(tau - t).max() < 0.05
    # Seeded.
    again = guidance.GuidancePath(script).poses(t)
    np.testing.assert_array_equal(path.poses(t), again)
    other = guidance.GuidancePath(guidance.GuidanceScript(**{**script.__dict__, "seed": 8})).poses(t)
    assert np.abs(other - again).max() > 1e-5


def test_virtual_hand_pulls_towards_the_guidance():
    gains = VirtualHandGains()
    count = 10
    R_WH = np.tile(np.eye(3), (count, 1, 1))
    sampled = guidance.SampledGuidance(
        time_step_s=1e-3,
        p_WH=np.tile([0.5, 0.0, 0.3], (count, 1)),
        R_WH=R_WH,
        v_WH=np.zeros((count, 3)),
        w_WH=np.zeros((count, 3)),
    )
    X_BE = RigidTransform([0.0, 0.0, 0.1])
    from pydrake.multibody.tree import BodyIndex

    dut = VirtualHand(guidance=sampled, body_index=BodyIndex(1), X_BE=X_BE, gains=gains)
    context = dut.CreateDefaultContext()
    # Body 1 such that E sits 1 cm short in x and turned 0.01 rad about z; at rest.
    X_WE = RigidTransform(RotationMatrix.MakeZRotation(0.01), [0.49, 0.0, 0.3])
    X_WB = X_WE.multiply(X_BE.inverse())
    dut.GetInputPort("body_poses").FixValue(context, [RigidTransform(), X_WB])
    dut.GetInputPort("body_spatial_velocities").FixValue(context, [SpatialVelocity.Zero(), SpatialVelocity.Zero()])
    (wrench,) = dut.GetOutputPort("spatial_force").Eval(context)
    assert int(wrench.body_index) == 1
    np.testing.assert_allclose(wrench.p_BoBq_B, [0.0, 0.0, 0.1])
    np.testing.assert_allclose(wrench.F_Bq_W.translational(), [gains.translational_stiffness * 0.01, 0, 0], atol=1e-9)
    np.testing.assert_allclose(wrench.F_Bq_W.rotational(), [0, 0, -gains.rotational_stiffness * 0.01], atol=1e-9)
    # A far target: the pull is capped at what a hand exerts.
    far = X_WB.multiply(RigidTransform([0.0, 0.0, -1.0]))
    dut.GetInputPort("body_poses").FixValue(context, [RigidTransform(), far])
    (wrench,) = dut.GetOutputPort("spatial_force").Eval(context)
    assert np.linalg.norm(wrench.F_Bq_W.translational()) == pytest.approx(gains.max_force)


def test_initial_joint_positions_reach_the_pose_elbow_up():
    X_WE = RigidTransform(RollPitchYaw(math.pi, 0.0, 0.0), [0.4, 0.2, 0.3])
    q = mut.initial_joint_positions(X_WE)
    kinematics = UR5eKinematics()
    assert kinematics.X_WE(q).IsNearlyEqualTo(X_WE, 1e-5)
    # Elbow up: the elbow (origin of the forearm link) is above the shoulder-wrist line.
    plant, context = kinematics.plant, kinematics.context
    plant.SetPositions(context, q)

    def origin(name):
        return plant.CalcRelativeTransform(context, plant.world_frame(), plant.GetFrameByName(name)).translation()

    shoulder, elbow, wrist = origin("upper_arm_link"), origin("forearm_link"), origin("wrist_1_link")
    fraction = np.dot(elbow - shoulder, wrist - shoulder) / np.dot(wrist - shoulder, wrist - shoulder)
    assert elbow[2] > shoulder[2] + fraction * (wrist[2] - shoulder[2])
    np.testing.assert_array_equal(q, mut.initial_joint_positions(X_WE))  # deterministic
    with pytest.raises(InputError, match="out of reach"):
        mut.initial_joint_positions(RigidTransform([1.5, 0.0, 0.3]), file="s.yaml", field="waypoints[0]")


# ----------------------------------------------------------------------- recorder


def test_demo_recorder_alone_samples_at_the_rtde_rate(tmp_path):
    dut = DemoRecorder(num_joints=6, rate_hz=500.0)
    simulator = Simulator(dut)
    context = simulator.get_mutable_context()
    q = np.array([0.1, -1.2, 1.3, -1.4, -1.5, 0.6])
    dut.get_input_port().FixValue(context, q)
    simulator.AdvanceTo(0.1)
    assert dut.num_samples(context) == 50  # the update at t = 0.1 starts the next step
    simulator.AdvancePendingEvents()
    simulator.AdvancePendingEvents()  # a repeated time adds nothing
    assert dut.num_samples(context) == 51
    recorded = dut.demonstration(context, "still")
    np.testing.assert_allclose(recorded.timestamps, np.arange(51) * 0.002, atol=1e-12)
    np.testing.assert_array_equal(recorded.joint_positions, np.tile(q, (51, 1)))
    path = tmp_path / "log.csv"
    dut.write_csv(context, path, name="still")
    lines = path.read_text().splitlines()
    assert lines[0] == "timestamp,actual_q_0,actual_q_1,actual_q_2,actual_q_3,actual_q_4,actual_q_5"
    assert len(lines) == 52
    demonstration, warnings = read_rtde_csv(path)
    assert warnings == ()
    np.testing.assert_array_equal(demonstration.joint_positions, recorded.joint_positions)
    np.testing.assert_array_equal(demonstration.timestamps, recorded.timestamps)
    assert not list(tmp_path.glob(".*.tmp"))  # the temporary file was renamed away
    dut.SetDefaultContext(context)  # a reset Context holds no samples
    assert dut.num_samples(context) == 0


# ----------------------------------------------------------------------- drake-lfd record


def _record(args, env, cwd):
    return subprocess.run(
        [sys.executable, "-m", "drake_lfd", "record", *args],
        capture_output=True,
        text=True,
        env=env,
        cwd=cwd,
        timeout=120,
    )


@pytest.mark.slow
def test_record_cli_shows_the_scripted_twist(tmp_path, offline_env):
    script_path = tmp_path / "screw.yaml"
    script_path.write_text(SCREW_SCRIPT)
    out = tmp_path / "screw.csv"
    result = _record([str(script_path), "--out", str(out)], offline_env, tmp_path)
    assert result.returncode == 0, result.stderr
    assert "wrote" in result.stdout and "simulated 2.5 / 2.5 s" in result.stderr

    demonstration, warnings = read_rtde_csv(out)
    assert warnings == ()
    assert demonstration.num_samples == 2.5 * 500 + 1
    np.testing.assert_allclose(np.diff(demonstration.timestamps), 0.002, atol=1e-9)
    D = dual_quaternions_from_demonstration(demonstration, UR5eKinematics())
    feature = Feature.from_poses(D)
    axis, angle = axis_angle_from_quaternion(feature.rotations[0])
    assert math.degrees(angle) == pytest.approx(90.0, abs=3.0)
    assert np.dot(axis, [0.0, 0.0, -1.0]) > math.cos(math.radians(3.0))  # clockwise: -z_E
    direction = feature.translations[0] / np.linalg.norm(feature.translations[0])
    assert direction[2] > 0.99  # pushed along the tool axis
    # The arm settled where the script ended.
    script = scripts.guidance_script_from_text(SCREW_SCRIPT)
    end = dual_quaternion_from_rigid_transform(script.waypoints[-1].X_WE)
    assert _poses_close(D[-1], end, 0.002, math.radians(1.0))


@pytest.mark.parametrize(
    "text, words",
    [
        (SCREW_SCRIPT + "wobble: 3\n", "unknown key 'wobble'"),
        (SCREW_SCRIPT.replace("[0.45, 0.15, 0.27]", "[.nan, 0.15, 0.27]"), "waypoints[1].p[0]"),
    ],
)
def test_record_cli_bad_script_exits_2_with_one_line(tmp_path, offline_env, text, words):
    script_path = tmp_path / "bad.yaml"
    script_path.write_text(text)
    out = tmp_path / "out.csv"
    result = _record([str(script_path), "--out", str(out)], offline_env, tmp_path)
    assert result.returncode == 2
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1, result.stderr
    assert str(script_path) in lines[0] and words in lines[0]
    assert not out.exists()


@pytest.mark.slow
def test_unreachable_waypoint_is_reported_as_bad_input():
    text = SCREW_SCRIPT.replace("[0.45, 0.15, 0.27]", "[1.25, 0.15, 0.27]").replace("2.0,", "1.0,")
    script = scripts.guidance_script_from_text(text, file="far.yaml")
    with pytest.raises(InputError, match="did not follow the hand") as info:
        mut.record_demonstration(script)
    assert info.value.field == "waypoints[1]"


# ----------------------------------------------------------------------- the bundled demos


def test_bundled_paper5_features_match_table5():
    rows = table5.compare(Library.open("paper5"))
    assert len(rows) == 15
    matched = [row for row in rows if row.alpha <= 0.15]
    assert len(matched) >= 13, [(row.demo, row.sample, round(row.alpha, 3)) for row in rows]


def test_bundled_paper6_adds_the_span_demo():
    library = Library.open("paper6")
    assert library.names == ("screw_cw", "screw_ccw", "filling", "pouring", "stacking", "span")
    # The paper scenarios' tool frame, shared by both libraries and every scenario.
    for scenario in ("transferring", "filling_pouring", "assembling"):
        task = load_task(Path(__file__).resolve().parent.parent / "sims" / f"{scenario}.yaml")
        assert library.X_tool0_E.IsNearlyEqualTo(task.X_tool0_E, 1e-12)
    axis, angle = axis_angle_from_quaternion(library.feature("span").rotations[0])
    assert math.degrees(angle) == pytest.approx(90.0, abs=3.0)
    assert axis[0] > math.cos(math.radians(3.0))  # +90 deg about the tool's body x axis
    paper5 = Library.open("paper5")
    for name in paper5.names:
        assert library.log_path(name).read_bytes() == paper5.log_path(name).read_bytes()
        assert (SIMS / "demos" / f"{name}.csv").read_bytes() == paper5.log_path(name).read_bytes()


@pytest.mark.slow
def test_bundled_span_log_is_reproduced_by_its_script():
    """The bundled logs are what the current code records from the scripts (seeded);
    if this fails, re-run sims/make_paper_libraries.py."""
    script = scripts.load_guidance_script(SIMS / "demos" / "span.yaml")
    recorded = mut.record_demonstration(script).demonstration
    bundled, _ = read_rtde_csv(SIMS / "demos" / "span.csv")
    np.testing.assert_array_equal(recorded.timestamps, bundled.timestamps)
    np.testing.assert_allclose(recorded.joint_positions, bundled.joint_positions, atol=1e-6)
