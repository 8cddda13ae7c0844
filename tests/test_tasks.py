"""Task files: the paper's Tables 7-9 load, bad files are refused naming the field,
trials are drawn reproducibly within their ranges, bounded angles become grids."""

import math
from pathlib import Path

import numpy as np
import pytest
from pydrake.math import RigidTransform, RollPitchYaw, RotationMatrix

import drake_lfd.core.tasks as tasks
import drake_lfd.io.task_files as mut
from drake_lfd.io.yaml_values import angle_from_text
from drake_lfd.core.errors import InputError

DATA = Path(__file__).parent / "data"
PI = math.pi


def write(tmp_path, text, name="task.yaml"):
    path = tmp_path / name
    path.write_text(text)
    return path


MINIMAL = """\
name: minimal
critical_configurations:
  - {p: [0.4, 0, 0.3], euler_zyx: [0, 0, 0]}
  - {p: [0.5, 0, 0.3], euler_zyx: [0, 0, 0]}
"""


def refused(tmp_path, text):
    """The InputError a task file text raises; fails the test if it loads."""
    path = write(tmp_path, text)
    with pytest.raises(InputError) as info:
        mut.load_task(path)
    message = str(info.value)
    assert str(path) in message
    assert "\n" not in message
    return message


# ------------------------------------------------------------------------ the paper


def test_table7_transferring_loads_as_written():
    task = mut.load_task(DATA / "table7_transferring.yaml")
    assert task.name == "transferring"
    assert len(task) == 4
    positions = [(-0.5, 0, 0.3), (-0.4, 0.2, None), (0, 0.2, None), (0.1, 0, 0.3)]
    for con, expected in zip(task.critical_configurations, positions):
        np.testing.assert_array_equal(con.euler_zyx_lower, [0, -PI / 2, 0])
        np.testing.assert_array_equal(con.euler_zyx_upper, [0, -PI / 2, 0])
        for axis, value in enumerate(expected):
            if value is None:
                assert con.p_variables[axis] == "z"
                assert (con.p_lower[axis], con.p_upper[axis]) == (0.1, 0.5)
            else:
                assert con.p_lower[axis] == con.p_upper[axis] == value
    assert task.variables == {"z": (0.1, 0.5)}
    (obstacle,) = task.obstacles
    (shell,) = task.safety_shells
    np.testing.assert_array_equal(obstacle.centre, [-0.3, -0.1, 0.2])
    np.testing.assert_array_equal(obstacle.size, [0.2, 0.2, 0.2])
    np.testing.assert_array_equal(shell.size, [0.4, 0.4, 0.4])
    (constraint,) = task.path_constraints
    assert (constraint.kind, constraint.con_from, constraint.con_to) == ("orientation", 1, 4)
    assert constraint.tolerance_rad == pytest.approx(math.radians(10))
    # Table 7's single z: con_2 and con_3 always share it.
    for seed in range(20):
        trial = tasks.draw_trial(task, seed)
        z2, z3 = trial.positions[1, 2], trial.positions[2, 2]
        assert z2 == z3
        assert 0.1 <= z2 <= 0.5
        assert trial.variable_values == {"z": z2}
        np.testing.assert_array_equal(trial.positions[0], [-0.5, 0, 0.3])


def test_table8_filling_pouring_shares_cup_position_and_frees_gamma():
    task = mut.load_task(DATA / "table8_filling_pouring.yaml")
    assert len(task) == 5
    trial = tasks.draw_trial(task, 7)
    p4, p5 = trial.positions[3], trial.positions[4]
    np.testing.assert_array_equal(p4[:2], p5[:2])
    assert (p4[2], p5[2]) == (0.1, 0.0)
    assert -0.5 <= p4[0] <= 0.7 and -0.2 <= p4[1] <= 0.0
    cons = trial.critical_configurations
    assert cons[0].is_orientation_fixed and cons[4].is_orientation_fixed
    np.testing.assert_array_equal(cons[0].euler_zyx, [0, -PI, 0])
    np.testing.assert_array_equal(cons[4].euler_zyx, [PI / 2, 0, -PI / 2])
    for con in cons[1:4]:
        assert not con.is_orientation_fixed
        candidates = tasks.angle_candidates(con)
        # gamma on a 15 deg grid over [-pi, pi], bounds included: 25 values.
        assert candidates.shape == (25, 3)
        np.testing.assert_array_equal(candidates[:, :2], np.tile([0, -PI / 2], (25, 1)))
        assert candidates[0, 2] == -PI and candidates[-1, 2] == PI
        np.testing.assert_allclose(np.diff(candidates[:, 2]), math.radians(15))
        with pytest.raises(ValueError):
            con.euler_zyx


def test_table9_assembling_is_fixed():
    task = mut.load_task(DATA / "table9_assembling.yaml")
    trial = tasks.draw_trial(task, 0)
    expected_p = [(0, 0.5, 0.6), (0.1, 0.5, 0.6), (0.5, 0.1, 0.6), (0.5, 0, 0.6)]
    expected_euler = [(-PI / 2, 0, PI / 2), (0, -PI / 2, 0), (0, -PI / 2, PI / 2), (PI, 0, -PI / 2)]
    np.testing.assert_array_equal(trial.positions, expected_p)
    for con, euler in zip(trial.critical_configurations, expected_euler):
        np.testing.assert_array_equal(con.euler_zyx, euler)
        assert tasks.angle_candidates(con).shape == (1, 3)
    assert task.obstacles == () and task.path_constraints == ()
    assert np.array_equal(task.X_WB.GetAsMatrix4(), np.eye(4))
    assert np.array_equal(task.X_tool0_E.GetAsMatrix4(), np.eye(4))


def test_full_schema_every_value_form():
    task = mut.load_task(DATA / "task_full_schema.yaml")
    expected_X_WB = RigidTransform(RollPitchYaw(0, 0, PI / 2), [0.1, -0.2, 0.05])
    np.testing.assert_allclose(task.X_WB.GetAsMatrix4(), expected_X_WB.GetAsMatrix4(), atol=1e-15)
    np.testing.assert_allclose(task.X_tool0_E.translation(), [0, 0, 0.15])
    assert task.angle_grid_deg == 30
    first, second, third = task.critical_configurations
    assert first.p_variables == (None, None, "h")
    np.testing.assert_array_equal(first.p_lower, [0.4, -0.1, 0.2])
    np.testing.assert_array_equal(first.p_upper, [0.4, 0.1, 0.4])
    np.testing.assert_array_equal(first.euler_zyx_lower, [0, -PI / 2, 0])  # YAML alias
    np.testing.assert_allclose(second.euler_zyx_lower, [PI / 2, -PI / 4, 0.25])
    np.testing.assert_allclose(second.euler_zyx_upper, [PI / 2, PI / 4, 0.25])
    np.testing.assert_array_equal(third.p_lower, [0.6, 1e-3, 0.3])  # PyYAML reads 1e-3 as text
    np.testing.assert_allclose(third.euler_zyx_lower, [3 * PI / 4, 0, -PI / 2])
    trial = tasks.draw_trial(task, 3)
    candidates = tasks.angle_candidates(trial.critical_configurations[1])
    # pitch over [-45, 45] deg on a 30 deg grid: 4 samples 30 deg apart, bounds included
    np.testing.assert_allclose(candidates[:, 1], np.linspace(-PI / 4, PI / 4, 4))
    assert trial.positions[0, 2] == trial.positions[1, 2]
    assert [box.name for box in trial.obstacles + trial.safety_shells] == ["table", "table_shell"]
    assert task.path_constraints[0].max_deviation == tasks.DeviationBound(0.05, np.radians(5.0))
    assert task.refinement == tasks.RefinementBounds(tasks.DeviationBound(0.1, np.radians(20.0)),
                                                     (tasks.DeviationBound(0.02, None, 2, 3),))
    assert trial.refinement is task.refinement


# ----------------------------------------------------------------------- refusals


def test_unknown_key_is_refused_naming_it(tmp_path):
    message = refused(tmp_path, MINIMAL + "colour: red\n")
    assert "colour" in message and "unknown key" in message
    nested = MINIMAL.replace("euler_zyx: [0, 0, 0]}\n  - {p: [0.5", "euler_zyx: [0, 0, 0], speed: 1}\n  - {p: [0.5")
    message = refused(tmp_path, nested)
    assert "critical_configurations[0].speed" in message


def test_nan_is_refused_naming_the_coordinate(tmp_path):
    message = refused(tmp_path, MINIMAL.replace("[0.5, 0, 0.3]", "[0.5, 0, .nan]"))
    assert "critical_configurations[1].p[2]" in message and "finite" in message


def test_lower_above_upper_is_refused(tmp_path):
    message = refused(tmp_path, MINIMAL.replace("[0.5, 0, 0.3]", "[0.5, [0.2, -0.2], 0.3]"))
    assert "critical_configurations[1].p[1]" in message and "lower" in message
    message = refused(tmp_path, MINIMAL.replace("euler_zyx: [0, 0, 0]}\n  - {p: [0.5", "euler_zyx: [0, [pi, 0], 0]}\n  - {p: [0.5"))
    assert "critical_configurations[0].euler_zyx[1]" in message
    message = refused(tmp_path, MINIMAL + "variables: {z: [0.5, 0.1]}\n")
    assert "variables.z" in message


def test_one_critical_configuration_is_refused(tmp_path):
    text = "critical_configurations:\n  - {p: [0.4, 0, 0.3], euler_zyx: [0, 0, 0]}\n"
    message = refused(tmp_path, text)
    assert "critical_configurations" in message and "at least 2" in message


@pytest.mark.parametrize(
    "replace, expected",
    [
        (("[0.5, 0, 0.3]", "[0.5, w, 0.3]"), "unknown variable 'w'"),
        (("[0.5, 0, 0.3]", "[0.5, 0]"), "critical_configurations[1].p"),
        (("[0.5, 0, 0.3]", "[0.5, true, 0.3]"), "critical_configurations[1].p[1]"),
        (("[0.5, 0, 0.3]", "[0.5, {a: 1}, 0.3]"), "critical_configurations[1].p[1]"),
        (("[0.5, 0, 0.3]", "[0.5, [0.1, 0.2, 0.3], 0.3]"), "[lower, upper]"),
        (("[0.5, 0, 0.3]", "[0.5, 0, 0.3], p: [1, 2, 3]"), "twice"),
        (("[0.5, 0, 0.3]", "[0.5, 0, [0.3"), "not valid YAML"),
    ],
)
def test_malformed_positions_are_refused(tmp_path, replace, expected):
    assert expected in refused(tmp_path, MINIMAL.replace(*replace))


def test_missing_and_malformed_fields_are_refused(tmp_path):
    text = MINIMAL.replace("{p: [0.5, 0, 0.3], euler_zyx: [0, 0, 0]}", "{p: [0.5, 0, 0.3]}")
    assert "critical_configurations[1].euler_zyx: missing" in refused(tmp_path, text)
    assert "not an angle" in refused(tmp_path, MINIMAL.replace("[0, 0, 0]}\n  - {p: [0.5", "[0, quarter, 0]}\n  - {p: [0.5"))
    assert "variables are for positions" in refused(
        tmp_path, MINIMAL.replace("[0, 0, 0]}\n  - {p: [0.5", "[0, g, 0]}\n  - {p: [0.5") + "variables: {g: [0, 1]}\n"
    )
    message = refused(tmp_path, MINIMAL.replace("[0, 0, 0]}\n  - {p: [0.5", "[0, yes, 0]}\n  - {p: [0.5"))
    assert "critical_configurations[0].euler_zyx[1]: expected an angle or a [lower, upper] list" in message
    assert "the task file is empty" in refused(tmp_path, "")
    assert "boolean" in refused(tmp_path, MINIMAL + "variables: {on: [0, 1]}\n")


def test_boxes_and_constraints_are_checked(tmp_path):
    box = "obstacles:\n  - {name: a, centre: [0, 0, 0], size: [0.1, 0, 0.1]}\n"
    assert "obstacles[0].size[1]" in refused(tmp_path, MINIMAL + box)
    twice = "obstacles:\n  - {name: a, centre: [0, 0, 0], size: [1, 1, 1]}\nsafety_shells:\n  - {name: a, centre: [0, 0, 0], size: [2, 2, 2]}\n"
    assert "safety_shells[0].name" in refused(tmp_path, MINIMAL + twice)
    constraint = "path_constraints:\n  - {kind: orientation, between: [1, 3], euler_zyx: [0, 0, 0], tolerance_deg: 10}\n"
    assert "path_constraints[0].between" in refused(tmp_path, MINIMAL + constraint)
    zero_based = constraint.replace("[1, 3]", "[0, 1]")
    assert "start at 1" in refused(tmp_path, MINIMAL + zero_based)
    kind = constraint.replace("orientation", "speed").replace("[1, 3]", "[1, 2]")
    assert "path_constraints[0].kind" in refused(tmp_path, MINIMAL + kind)


# -------------------------------------------------------------------------- trials


def test_draw_trial_is_reproducible_and_within_ranges(tmp_path):
    text = MINIMAL.replace("[0.5, 0, 0.3]", "[[0.4, 0.6], [-0.1, 0.1], h]") + "variables: {h: [0.2, 0.3]}\n"
    task = mut.load_task(write(tmp_path, text))
    first = tasks.draw_trial(task, 11)
    again = tasks.draw_trial(task, 11)
    np.testing.assert_array_equal(first.positions, again.positions)
    assert first.seed == 11
    draws = np.array([tasks.draw_trial(task, seed).positions[1] for seed in range(200)])
    assert np.all(draws >= [0.4, -0.1, 0.2]) and np.all(draws <= [0.6, 0.1, 0.3])
    # The ranges are really used: the draws spread over most of each range.
    assert np.all(draws.max(axis=0) - draws.min(axis=0) > [0.15, 0.15, 0.07])
    assert len({tuple(row) for row in draws}) == 200
    with pytest.raises(InputError, match="seed"):
        tasks.draw_trial(task, -1)


def test_angle_grid_includes_bounds_within_step():
    step = math.radians(15)
    grid = tasks.angle_grid(-1.0, 1.0, step)
    assert grid[0] == -1.0 and grid[-1] == 1.0
    assert np.all(np.diff(grid) <= step + 1e-12)
    assert len(grid) == math.ceil(2.0 / step) + 1
    np.testing.assert_array_equal(tasks.angle_grid(0.3, 0.3, step), [0.3])


@pytest.mark.parametrize(
    "text, value",
    [("pi", PI), ("-pi/2", -PI / 2), ("3*pi/4", 3 * PI / 4), ("0.5pi", PI / 2), ("-90deg", -PI / 2),
     ("1.25", 1.25), ("+pi", PI), ("2 * pi / 3", 2 * PI / 3)],
)
def test_angle_text(text, value):
    assert angle_from_text(text) == pytest.approx(value, abs=1e-15)


@pytest.mark.parametrize("text", ["pie", "pi/0", "90 degrees", "x", ""])
def test_angle_text_refused(text):
    assert angle_from_text(text) is None


def test_euler_zyx_is_rz_ry_rx():
    yaw, pitch, roll = 0.3, -0.7, 1.1
    X = tasks.rigid_transform_from_euler_zyx([1, 2, 3], [yaw, pitch, roll])
    R = (
        RotationMatrix.MakeZRotation(yaw) @ RotationMatrix.MakeYRotation(pitch) @ RotationMatrix.MakeXRotation(roll)
    )
    np.testing.assert_allclose(X.rotation().matrix(), R.matrix(), atol=1e-15)
    np.testing.assert_array_equal(X.translation(), [1, 2, 3])


def test_concrete_task_from_fixed():
    positions = np.array([[0.4, 0, 0.3], [0.5, 0.1, 0.2]])
    euler = np.array([[0, PI / 2, 0], [PI, 0, 0]])
    task = tasks.ConcreteTask.from_fixed("random", positions, euler)
    np.testing.assert_array_equal(task.positions, positions)
    assert len(task) == 2
    np.testing.assert_array_equal(task.critical_configurations[1].euler_zyx, euler[1])
    with pytest.raises(ValueError):
        task.critical_configurations[0].p[0] = 1.0  # read-only


def test_the_tool_direction_table_of_task_files_rst():
    """Every entry of docs/task_files.rst's tool-down / tool-horizontal table, checked with
    the UR5e's kinematics: inverse kinematics of E at that orientation, then tool0's z
    axis (out of the flange) by forward kinematics points the stated way."""
    import re

    from drake_lfd.io.yaml_values import angle_from_text
    from drake_lfd.robot.initial_ik import initial_configuration_candidates
    from drake_lfd.robot.kinematics import UR5eKinematics

    text = (Path(__file__).parents[1] / "docs" / "task_files.rst").read_text()
    rows = re.findall(r"^\s*(?:down|horizontal), along ([+-][xyz]) of W\s+``\[(.*?)\]``\s+``\[(.*?)\]``\s*$",
                      text, re.MULTILINE)
    assert len(rows) == 5
    frames = [tasks.rigid_transform_from_euler_zyx([0, 0, 0.2], [0, math.pi / 2, 0]), RigidTransform()]
    for direction, *eulers in rows:
        expected = np.zeros(3)
        expected["xyz".index(direction[1])] = 1.0 if direction[0] == "+" else -1.0
        for X_tool0_E, euler in zip(frames, eulers):
            angles = [angle_from_text(a) for a in euler.split(",")]
            X_WE = tasks.rigid_transform_from_euler_zyx([0.45, 0.1, 0.35], angles)
            (best, *_) = initial_configuration_candidates(X_WE, X_tool0_E=X_tool0_E)
            kinematics = UR5eKinematics(X_tool0_E=X_tool0_E)
            np.testing.assert_allclose(kinematics.X_WE(best.q).GetAsMatrix4(), X_WE.GetAsMatrix4(), atol=1e-4)
            z_tool0 = kinematics.X_Wtool0(best.q).rotation().matrix()[:, 2]
            np.testing.assert_allclose(z_tool0, expected, atol=1e-4, err_msg=f"{direction} {euler}")  # IK: 1e-5 rad


def _task_with_boxes(path, group, count):
    boxes = "\n".join(f"  - {{name: b{i}, centre: [2, {i / 100:.2f}, 0], size: [0.01, 0.01, 0.01]}}" for i in range(count))
    path.write_text("critical_configurations:\n  - {p: [0.4, -0.2, 0.2], euler_zyx: [0, 0, 0]}\n"
                    f"  - {{p: [0.4, 0.0, 0.3], euler_zyx: [0, 0, 0]}}\n{group}:\n{boxes}\n")
    return path


@pytest.mark.parametrize("group", ["obstacles", "safety_shells"])
def test_a_task_with_more_boxes_than_the_limit_is_refused_naming_the_block(tmp_path, group):
    path = _task_with_boxes(tmp_path / "many.yaml", group, mut.MAX_BOXES + 1)
    with pytest.raises(InputError, match=f"at most {mut.MAX_BOXES}") as refused:
        mut.load_task(path)
    assert str(refused.value).startswith(f"{path}: {group}: ")
    at_the_limit = mut.load_task(_task_with_boxes(tmp_path / "limit.yaml", group, mut.MAX_BOXES))
    assert len(getattr(at_the_limit, group)) == mut.MAX_BOXES


def test_a_tool_with_more_shapes_than_the_limit_is_refused(tmp_path):
    shapes = "\n".join(f"  - {{name: s{i}, box: [0.01, 0.01, 0.01], p: [0, 0, 0.05]}}" for i in range(21))
    path = tmp_path / "tool.yaml"
    path.write_text("critical_configurations:\n  - {p: [0.4, -0.2, 0.2], euler_zyx: [0, 0, 0]}\n"
                    f"  - {{p: [0.4, 0.0, 0.3], euler_zyx: [0, 0, 0]}}\ntool:\n{shapes}\n")
    with pytest.raises(InputError, match=f"at most {mut.MAX_TOOL_SHAPES} shapes"):
        mut.load_task(path)
