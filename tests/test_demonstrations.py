"""Joint logs: exact round trip, real UR RTDE logs, every kind of damage refused with
one message naming line and column, a log cut off mid-line kept with a warning."""

import math

import numpy as np
import pytest

import drake_lfd.io.demonstration_logs as mut
from drake_lfd.core.demonstrations import Demonstration, check_demonstration
from drake_lfd.core.errors import InputError
from drake_lfd.robot.kinematics import UR5eKinematics, dual_quaternions_from_demonstration, poses_from_demonstration
from helpers import Q_HOME, joint_log_text


def joint_motion(m=30, t0=12.5, duration=1.5, seed=0):
    """Timestamps (m,) at irregular intervals and joint angles (m, 6) moving with them
    (well inside the UR5e's speed limit), with many significant digits."""
    rng = np.random.default_rng(seed)
    t = t0 + np.sort(rng.uniform(0.0, duration, m))
    progress = (t - t0) / duration
    q = Q_HOME + np.outer(progress, rng.uniform(-0.5, 0.5, 6)) + rng.normal(0, 1e-5, (m, 6))
    return t, q


# UR's record.py writes space-separated columns in the order of its recipe; a typical
# recipe records targets, actuals, currents, TCP pose, modes and the program state.
REAL_COLUMNS = (
    ["timestamp"]
    + [f"target_q_{i}" for i in range(6)]
    + [f"target_qd_{i}" for i in range(6)]
    + [f"actual_q_{i}" for i in range(6)]
    + [f"actual_qd_{i}" for i in range(6)]
    + [f"actual_current_{i}" for i in range(6)]
    + [f"actual_TCP_pose_{i}" for i in range(6)]
    + ["robot_mode"]
    + [f"joint_mode_{i}" for i in range(6)]
    + ["safety_mode", "runtime_state", "speed_scaling"]
)


def real_format_log(t, q, runtime_state=None, delimiter=" "):
    """Text of a log in UR record.py's layout; the actual joint columns hold ``q``."""
    m = len(t)
    runtime_state = np.full(m, 2) if runtime_state is None else np.asarray(runtime_state)
    rng = np.random.default_rng(1)
    lines = [delimiter.join(REAL_COLUMNS)]
    for k in range(m):
        values = (
            [repr(float(t[k]))]
            + [f"{v:.6f}" for v in q[k] + 0.001]  # targets differ from actuals
            + [f"{v:.6f}" for v in rng.normal(0, 0.1, 6)]
            + [repr(float(v)) for v in q[k]]
            + [f"{v:.6f}" for v in rng.normal(0, 0.1, 6)]
            + [f"{v:.6f}" for v in rng.normal(0, 1, 6)]
            + [f"{v:.6f}" for v in rng.normal(0, 1, 6)]
            + ["7"]
            + ["253"] * 6
            + ["1", str(int(runtime_state[k])), "1"]
        )
        lines.append(delimiter.join(values))
    return "\n".join(lines) + "\n"




def refused(tmp_path, text, name="log.csv"):
    path = tmp_path / name
    path.write_text(text)
    with pytest.raises(InputError) as info:
        mut.read_rtde_csv(path)
    message = str(info.value)
    assert str(path) in message and "\n" not in message
    return message


# ----------------------------------------------------------------------- round trip


def test_round_trip_is_exact(tmp_path):
    t, q = joint_motion()
    demo = Demonstration("wave", t, q, description="a wave")
    path = tmp_path / "wave.csv"
    mut.write_rtde_csv(demo, path)
    header = path.read_text().splitlines()[0]
    assert header == "timestamp,actual_q_0,actual_q_1,actual_q_2,actual_q_3,actual_q_4,actual_q_5"
    loaded, warnings = mut.read_rtde_csv(path)
    assert warnings == ()
    assert loaded.name == "wave"
    np.testing.assert_array_equal(loaded.timestamps, t)
    np.testing.assert_array_equal(loaded.joint_positions, q)
    assert loaded.duration_s == t[-1] - t[0]
    assert loaded.num_samples == len(t)
    assert list(tmp_path.iterdir()) == [path]  # no temporary file left behind


def test_real_rtde_log_space_separated(tmp_path):
    t, q = joint_motion(m=40)
    path = tmp_path / "record.csv"
    path.write_text(real_format_log(t, q))
    demo, warnings = mut.read_rtde_csv(path, name="demo")
    assert warnings == ()
    np.testing.assert_array_equal(demo.timestamps, t)
    np.testing.assert_array_equal(demo.joint_positions, q)  # actual_q, not target_q


def test_comma_separated_with_spaces_and_crlf(tmp_path):
    t, q = joint_motion(m=5)
    path = tmp_path / "ur_rtde.csv"
    path.write_bytes(joint_log_text(t, q, delimiter=", ").replace("\n", "\r\n").encode())
    demo, _ = mut.read_rtde_csv(path)
    np.testing.assert_array_equal(demo.joint_positions, q)


def test_runtime_state_keeps_playing_rows(tmp_path):
    t, q = joint_motion(m=20)
    state = np.full(20, 2)
    state[:3] = 1  # stopped before the program started
    state[-2:] = 0  # stopping
    path = tmp_path / "record.csv"
    path.write_text(real_format_log(t, q, state))
    demo, warnings = mut.read_rtde_csv(path)
    np.testing.assert_array_equal(demo.timestamps, t[3:-2])
    np.testing.assert_array_equal(demo.joint_positions, q[3:-2])
    assert len(warnings) == 1 and "15 of 20" in warnings[0]
    everything, _ = mut.read_rtde_csv(path, filter_runtime_state=False)
    assert everything.num_samples == 20


def test_freedrive_log_without_program_is_kept_with_warning(tmp_path):
    t, q = joint_motion(m=10)
    path = tmp_path / "record.csv"
    path.write_text(real_format_log(t, q, np.ones(10)))
    demo, warnings = mut.read_rtde_csv(path)
    assert demo.num_samples == 10
    assert len(warnings) == 1 and "PLAYING" in warnings[0]


# -------------------------------------------------------------- cut off mid-line


def test_last_line_with_missing_fields_is_dropped_with_warning(tmp_path):
    t, q = joint_motion(m=6)
    text = joint_log_text(t, q)
    cut = text[: text.rindex(",", 0, len(text) - 20)]  # last line loses its last fields
    path = tmp_path / "cut.csv"
    path.write_text(cut)
    demo, warnings = mut.read_rtde_csv(path)
    np.testing.assert_array_equal(demo.joint_positions, q[:5])
    assert len(warnings) == 1
    assert "line 7" in warnings[0] and "mid-line" in warnings[0] and str(path) in warnings[0]


def test_last_token_cut_without_newline_is_dropped_with_warning(tmp_path):
    t, q = joint_motion(m=6)
    text = joint_log_text(t, q).rstrip("\n")
    path = tmp_path / "cut.csv"
    path.write_text(text + "e")  # "0.123e": the last value was cut inside its exponent
    demo, warnings = mut.read_rtde_csv(path)
    assert demo.num_samples == 5 and len(warnings) == 1 and "line 7" in warnings[0]
    # The same damage with a newline after it is not a cut-off write: refused.
    message = refused(tmp_path, text + "e\n")
    assert "line 7, column actual_q_5" in message and "not a number" in message


def test_short_line_in_the_middle_is_an_error(tmp_path):
    t, q = joint_motion(m=6)
    lines = joint_log_text(t, q).splitlines()
    lines[3] = lines[3][: lines[3].rindex(",")]
    message = refused(tmp_path, "\n".join(lines) + "\n")
    assert "line 4" in message and "has 6 fields but the header has 7" in message


# --------------------------------------------------------------------- refusals


def test_empty_file(tmp_path):
    assert "empty" in refused(tmp_path, "")
    assert "empty" in refused(tmp_path, "\n  \n")


def test_missing_columns_are_named(tmp_path):
    message = refused(tmp_path, "time,actual_q_0,actual_q_1,actual_q_2,actual_q_3,actual_q_4,actual_q_5\n0,0,0,0,0,0,0\n")
    assert "missing column(s) timestamp" in message and "line 1" in message


def test_wrong_number_of_joints(tmp_path):
    header7 = "timestamp " + " ".join(f"actual_q_{i}" for i in range(7))
    message = refused(tmp_path, header7 + "\n" + " ".join(["0"] * 8) + "\n")
    assert "wrong number of joints" in message and "7 joints" in message
    header5 = "timestamp " + " ".join(f"actual_q_{i}" for i in range(5))
    message = refused(tmp_path, header5 + "\n" + " ".join(["0"] * 6) + "\n")
    assert "wrong number of joints" in message and "5 joints" in message


def test_non_numeric_cell_names_line_and_column(tmp_path):
    t, q = joint_motion(m=5)
    lines = joint_log_text(t, q).splitlines()
    cells = lines[2].split(",")
    cells[3] = "abc"
    lines[2] = ",".join(cells)
    message = refused(tmp_path, "\n".join(lines) + "\n")
    assert "line 3, column actual_q_2" in message and "'abc'" in message


@pytest.mark.parametrize("bad", ["nan", "inf", "-inf"])
def test_non_finite_values_name_line_and_column(tmp_path, bad):
    t, q = joint_motion(m=5)
    lines = joint_log_text(t, q).splitlines()
    cells = lines[4].split(",")
    cells[5] = bad
    lines[4] = ",".join(cells)
    message = refused(tmp_path, "\n".join(lines) + "\n")
    assert "line 5, column actual_q_4" in message and "finite" in message


def test_fewer_than_two_samples(tmp_path):
    t, q = joint_motion(m=1)
    assert "1 sample" in refused(tmp_path, joint_log_text(t, q))
    assert "0 sample" in refused(tmp_path, joint_log_text(t[:0], q[:0]))


def test_timestamps_must_strictly_increase(tmp_path):
    t, q = joint_motion(m=5)
    t[3] = t[2]
    message = refused(tmp_path, joint_log_text(t, q))
    assert "line 5, column timestamp" in message and "line 4" in message


def test_degrees_are_refused(tmp_path):
    t, q = joint_motion(m=5)
    message = refused(tmp_path, joint_log_text(t, np.degrees(q)))
    assert "degrees" in message and "line 2" in message


def test_duplicate_header_column(tmp_path):
    header = "timestamp,actual_q_0,actual_q_0,actual_q_1,actual_q_2,actual_q_3,actual_q_4,actual_q_5"
    assert "twice" in refused(tmp_path, header + "\n" + ",".join(["0"] * 8) + "\n")


def test_missing_file(tmp_path):
    with pytest.raises(InputError, match="no such file"):
        mut.read_rtde_csv(tmp_path / "absent.csv")


def test_check_demonstration_in_code():
    t, q = joint_motion(m=5)
    check_demonstration(Demonstration("ok", t, q))
    with pytest.raises(InputError, match="sample 2"):
        check_demonstration(Demonstration("x", t[[0, 1, 1, 3]], q[:4]))
    with pytest.raises(InputError, match="at least 2"):
        check_demonstration(Demonstration("x", t[:1], q[:1]))
    with pytest.raises(ValueError):
        Demonstration("x", t, q[:, :5])
    demo = Demonstration("x", t, q)
    with pytest.raises(ValueError):
        demo.joint_positions[0, 0] = 1.0


# -------------------------------------------------------------------- kinematics


def test_poses_and_dual_quaternions_by_forward_kinematics():
    t, q = joint_motion(m=4)
    kinematics = UR5eKinematics()
    demo = Demonstration("x", t, q)
    X = poses_from_demonstration(demo, kinematics)
    assert X.shape == (4, 4, 4)
    for k in range(4):
        np.testing.assert_allclose(X[k], kinematics.X_WE(q[k]).GetAsMatrix4(), atol=1e-15)
    D = dual_quaternions_from_demonstration(demo, kinematics)
    assert D.shape == (4, 8)
    from drake_lfd.core.pose_conversions import matrices_from_dual_quaternion

    np.testing.assert_allclose(matrices_from_dual_quaternion(D), X, atol=1e-12)


# ------------------------------------------------------- what real logs get wrong


def regular_log(m=200, rate_hz=500.0, scale=1.0, seed=3):
    """A plausible log: ``m`` samples at ``rate_hz``, timestamps multiplied by ``scale``
    (1000: milliseconds, 1e9: nanoseconds)."""
    rng = np.random.default_rng(seed)
    t = np.arange(m) / rate_hz
    q = Q_HOME + np.outer(t, rng.uniform(-0.5, 0.5, 6))  # at most 0.5 rad/s
    return t * scale, q


def test_last_line_without_newline_is_dropped_whatever_it_parses_to(tmp_path):
    t, q = regular_log(m=20)
    q[:, 5] += -3.6277474137027124 - q[-1, 5]  # wrist_3 ends at the value
    q[-1, 5] = -3.6277474137027124
    text = joint_log_text(t, q).rstrip("\n")
    assert text.endswith(",-3.6277474137027124")
    path = tmp_path / "cut.csv"
    path.write_text(text[: -len(".6277474137027124")])  # cut to "-3": still a number
    demo, warnings = mut.read_rtde_csv(path)
    assert demo.num_samples == 19
    np.testing.assert_array_equal(demo.joint_positions, q[:19])
    (warning,) = warnings
    assert str(path) in warning and "line 21" in warning and "'-3'" in warning and "dropped" in warning
    # The complete line, newline and all, is kept.
    path.write_text(text + "\n")
    demo, warnings = mut.read_rtde_csv(path)
    assert demo.num_samples == 20 and warnings == ()


def test_teleport_jump_is_refused_with_its_line(tmp_path):
    t, q = regular_log()
    q[120:, 1] += 2.0  # 2 rad in 2 ms: 1000 rad/s
    message = refused(tmp_path, joint_log_text(t, q))
    assert "line 122, column actual_q_1" in message and "line 121" in message
    assert "180 deg/s" in message
    # Just under twice the speed limit is a motion, not a jump.
    t, q = regular_log(m=3)
    q[2, 0] = q[1, 0] + 0.99 * mut.MAX_JOINT_SPEED_RAD_S * (t[2] - t[1])
    path = tmp_path / "fast.csv"
    path.write_text(joint_log_text(t, q))
    assert mut.read_rtde_csv(path).demonstration.num_samples == 3
    assert mut.MAX_JOINT_SPEED_RAD_S == pytest.approx(2 * np.radians(180))
    np.testing.assert_allclose(UR5eKinematics().velocity_limits(), mut.UR5E_JOINT_SPEED_LIMIT_RAD_S)


@pytest.mark.parametrize("scale, unit", [(1e3, "milliseconds"), (1e9, "nanoseconds")])
def test_timestamps_in_ms_or_ns_are_refused_with_the_line(tmp_path, scale, unit):
    t, q = regular_log(m=2101, scale=scale)  # 4.2 s at 500 Hz: "4200 s" in milliseconds
    message = refused(tmp_path, joint_log_text(t, q))
    assert "line 3, column timestamp" in message and unit in message and "seconds" in message


def test_absurd_duration_is_refused_with_the_line(tmp_path):
    t = np.arange(800.0)  # one sample a second, 799 s: a recording left running
    q = Q_HOME + np.outer(t / t[-1], [0.3, -0.2, 0.1, 0.2, 0.3, -0.4])
    message = refused(tmp_path, joint_log_text(t, q))
    # Line 2 holds t = 0; line 603 the first sample more than 600 s after it.
    assert "line 603, column timestamp" in message and "600 s" in message and "spans 799 s" in message


@pytest.mark.parametrize(
    "spelling",
    ["0_5", "\u0660.\u0665", "\u0661", "\uff11.5", "1\u00a0", "0x1p-2", "1_000.0"],
    ids=["underscore", "arabic-indic", "arabic-indic-integer", "fullwidth", "nbsp", "hex", "grouping"],
)
def test_python_only_number_spellings_are_refused(tmp_path, spelling):
    t, q = regular_log(m=5)
    lines = joint_log_text(t, q).splitlines()
    cells = lines[3].split(",")
    cells[2] = spelling
    lines[3] = ",".join(cells)
    message = refused(tmp_path, "\n".join(lines) + "\n")
    assert "line 4, column actual_q_1" in message and "is not a number" in message


@pytest.mark.parametrize("spelling", ["1", "-0.5", "+.5", "5.", "1e-3", "-2.5E+2", "12"])
def test_c_number_spellings_are_read(tmp_path, spelling):
    assert mut.parse_number(spelling) == float(spelling)
    for bad in ("", " 1", "1 ", "e5", ".", "-", "1e", "0_5", "\u0665"):
        assert mut.parse_number(bad) is None
    assert math.isnan(mut.parse_number("NaN")) and mut.parse_number("-inf") == -math.inf
