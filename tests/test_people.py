"""People in the cell without a Diagram: bodies and paths, recorded tracks, people files,
ISO/TS 15066's protective separation distance and the speed override's maths."""

import math
import textwrap

import numpy as np
import pytest

from drake_lfd.core import people as mut
from drake_lfd.core.errors import InputError
from drake_lfd.core.resources import scenarios_directory
from drake_lfd.io import people_files
from drake_lfd.io.task_files import load_task, task_from_spec, task_spec_from_text

from cli_subprocess import run_cli, stderr_lines

# The minimal form every user can write (docs/collaboration.rst).
MINIMAL = textwrap.dedent("""\
    people:
      - name: operator
        path: [{t: 0.0, xy: [-0.2, -2.0]}, {t: 1.5, xy: [-0.2, -0.75]}, {t: 4.0, xy: [-0.2, -0.75]},
               {t: 5.5, xy: [-0.2, -2.0]}]
    collaboration: {}
""")
T_S = math.pi / 8.0  # the UR5e's joint speed limit over the default acceleration limit


def write(tmp_path, text, name="people.yaml"):
    path = tmp_path / name
    path.write_text(text)
    return path


def minimal_person(tmp_path):
    people, collaboration = people_files.load_people_file(write(tmp_path, MINIMAL))
    return people[0], collaboration


def test_the_minimal_people_file_loads_with_the_documented_defaults(tmp_path):
    person, collaboration = minimal_person(tmp_path)
    assert person.name == "operator"
    assert person.body == mut.BodySize()
    assert collaboration == mut.CollaborationParameters()
    assert collaboration.human_speed_m_s == 1.6  # ISO 13855
    assert collaboration.policy == mut.SSM_POLICY
    assert collaboration.stopping_time(math.pi, 8.0) == pytest.approx(T_S)


def test_a_scripted_person_walks_linearly_between_waypoints_and_stands_after_the_last(tmp_path):
    person, _ = minimal_person(tmp_path)
    path = person.motion
    np.testing.assert_allclose(path.xy(0.75), [-0.2, -1.375])
    np.testing.assert_allclose(path.xy(2.0), [-0.2, -0.75])
    np.testing.assert_allclose(path.xy(9.0), [-0.2, -2.0])
    np.testing.assert_allclose(path.xy(-1.0), [-0.2, -2.0])
    torso, head, left, right = person.capsules(2.0, floor_z=-0.75, face_xy=[-0.2, 0.7])
    # The torso's axis stands on the floor at the waypoint, from the floor to the shoulders.
    np.testing.assert_allclose(torso.X_WC.translation()[:2], [-0.2, -0.75])
    bottom = torso.X_WC.translation()[2] - torso.length / 2 - torso.radius
    top = torso.X_WC.translation()[2] + torso.length / 2 + torso.radius
    assert bottom == pytest.approx(-0.75) and top == pytest.approx(-0.75 + person.body.shoulder_height_m)
    head_top = head.X_WC.translation()[2] + head.length / 2 + head.radius
    assert head_top == pytest.approx(-0.75 + person.body.head_top_m)
    # Facing the robot's base (+y here): the left arm is on the -x side, arms hang down.
    assert left.X_WC.translation()[0] < -0.2 < right.X_WC.translation()[0]
    assert left.X_WC.rotation().matrix()[:, 2] @ [0, 0, 1] == pytest.approx(-1.0)


def test_a_reach_stretches_the_arms_toward_the_point_and_back():
    point = np.array([-0.2, 0.0, 0.3])
    reach = mut.Reach(point, 2.0, 3.0)
    person = mut.Person("p", mut.ScriptedPath((mut.Waypoint(0.0, [-0.2, -0.8]),), reach))

    def hand_distance(t):
        keypoints = person.keypoints(t, floor_z=-0.75, face_xy=[-0.2, 0.7])
        return np.linalg.norm(keypoints[4] - point)

    assert reach.amount(1.0) == 0.0 and reach.amount(2.5) == 1.0 and reach.amount(4.0) == 0.0
    assert hand_distance(2.5) < hand_distance(1.0) - 0.3
    assert hand_distance(4.0) == pytest.approx(hand_distance(1.0))


def test_capsules_keep_their_sizes_on_a_recorded_track(tmp_path):
    rows = [people_files.track_columns()]
    for t, x in ((0.0, -1.0), (1.0, 0.0)):
        keypoints = np.array([[x, -1, 0.2], [x, -1, 0.7], [x, -1, 0.95], [x - 0.2, -1, 0.65], [x - 0.2, -0.5, 0.6],
                              [x + 0.2, -1, 0.65], [x + 0.2, -1, -0.1]])
        rows.append([str(t)] + [repr(float(v)) for v in keypoints.ravel()])
    csv = tmp_path / "track.csv"
    csv.write_text("\n".join(",".join(row) for row in rows) + "\n")
    path = write(tmp_path, "people:\n  - {name: tracked, track: track.csv}\n")
    (person,), _ = people_files.load_people_file(path)
    np.testing.assert_allclose(person.motion.at(0.5)[0], [-0.5, -1, 0.2])
    np.testing.assert_allclose(person.motion.at(5.0)[0], [0.0, -1, 0.2])  # held after the last row
    lengths = person.body.capsule_lengths()
    capsules = person.capsules(0.5, floor_z=-0.75, face_xy=[0, 0])
    assert [c.length for c in capsules] == pytest.approx([lengths[0], lengths[1], lengths[2], lengths[2]])
    # The left arm points from the shoulder toward the hand (+y).
    assert capsules[2].X_WC.rotation().matrix()[:, 2] @ [0, 1, 0] > 0.9


@pytest.mark.parametrize("text, field, problem", [
    ("people:\n  - {name: a, path: [{t: 0, xy: [0, -2]}, {t: 1, xy: [0]}]}\n",
     "people[0].path[1].xy", "expected 2 values"),
    ("people:\n  - {name: a, path: [{t: 1, xy: [0, -2]}, {t: 1, xy: [0, -1]}]}\n",
     "people[0].path[1].t", "must increase"),
    ("people:\n  - {name: a, path: [{t: -1, xy: [0, -2]}]}\n", "people[0].path[0].t", ">= 0"),
    ("people:\n  - {name: a, pth: [{t: 0, xy: [0, -2]}]}\n", "people[0].pth", "unknown key"),
    ("people:\n  - {name: a}\n", "people[0]", "exactly one of path"),
    ("people:\n  - {path: [{t: 0, xy: [0, -2]}]}\n", "people[0].name", "missing"),
    ("people:\n  - {name: a, path: [{t: 0, xy: [0, -2]}]}\n  - {name: a, path: [{t: 0, xy: [0, -3]}]}\n",
     "people[1].name", "used by people[0]"),
    ("people:\n  - {name: a, path: [{t: 0, xy: [0, nan]}]}\n", "people[0].path[0].xy[1]", "not a finite number"),
    ("people:\n  - {name: a, path: [{t: 0, xy: [0, -2]}], body: {arm_radius_m: 0}}\n",
     "people[0].body.arm_radius_m", "must be > 0"),
    ("people:\n  - {name: a, track: missing.csv}\n", "missing.csv", "no such file"),
    ("collaboration: {policy: fast}\n", "collaboration.policy", "unknown policy"),
    ("collaboration: {human_speed_m_s: -1.6}\n", "collaboration.human_speed_m_s", "must be > 0"),
    ("collaboration: 3\n", "collaboration", "expected a mapping"),
    ("people: {name: a}\n", "people", "expected a list"),
])
def test_a_malformed_people_file_is_one_line_naming_file_field_and_problem(tmp_path, text, field, problem):
    path = write(tmp_path, text)
    with pytest.raises(InputError) as error:
        people_files.load_people_file(path)
    message = str(error.value)
    assert "\n" not in message
    assert field in message and problem in message
    assert message.startswith(str(path)) or "missing.csv" in message


def test_a_malformed_track_names_its_row_and_column(tmp_path):
    header = ",".join(people_files.track_columns())
    values = ",".join(["0.0"] + ["0.1"] * 21)
    csv = tmp_path / "track.csv"
    csv.write_text(f"{header}\n{values}\n{values.replace('0.1', 'x', 1)}\n")
    with pytest.raises(InputError, match=r"track\.csv: row 3, column pelvis_x: expected a number"):
        people_files.load_track_csv(csv)
    csv.write_text("t,x\n0,1\n")
    with pytest.raises(InputError, match=r"header"):
        people_files.load_track_csv(csv)


def test_a_task_file_holds_people_and_collaboration():
    text = (scenarios_directory() / "transferring.yaml").read_text() + MINIMAL.replace(
        "collaboration: {}", "collaboration: {reaction_time_s: 0.2, policy: stop_only, stop_radius_m: 2.5}")
    task = task_from_spec(task_spec_from_text(text), file="t.yaml")
    assert [p.name for p in task.people] == ["operator"]
    assert task.collaboration.reaction_time_s == 0.2 and task.collaboration.policy == mut.STOP_ONLY_POLICY
    plain = load_task(scenarios_directory() / "transferring.yaml")
    assert plain.people == () and plain.collaboration is None


def test_a_people_file_replaces_the_tasks_people_and_keeps_its_collaboration_unless_given(tmp_path):
    task = load_task(scenarios_directory() / "transferring.yaml")
    with_people = people_files.task_with_people(task, write(tmp_path, MINIMAL))
    assert len(with_people.people) == 1 and with_people.collaboration == mut.CollaborationParameters()
    only_block = people_files.task_with_people(with_people, write(tmp_path, "collaboration: {reaction_time_s: 0.3}\n",
                                                                  "c.yaml"))
    assert only_block.people == with_people.people and only_block.collaboration.reaction_time_s == 0.3


def test_the_protective_separation_distance_is_iso_ts_15066s_sum():
    p = mut.CollaborationParameters()
    standing = 1.6 * (0.1 + T_S) + 0.208 + 0.1 + 0.01
    assert mut.protective_separation_distance(0.0, p, T_S) == pytest.approx(standing)
    # v_r T_r + S_s, S_s = v_r T_s / 2.
    assert mut.protective_separation_distance(0.5, p, T_S) == pytest.approx(standing + 0.5 * 0.1 + 0.5 * T_S / 2)
    # Moving away counts as standing.
    assert mut.protective_separation_distance(-0.5, p, T_S) == pytest.approx(standing)
    np.testing.assert_allclose(mut.protective_separation_distance(np.array([0.0, 0.5]), p, T_S),
                               [standing, standing + 0.05 + 0.25 * T_S])


def test_the_override_is_full_when_far_zero_when_too_close_and_falls_no_faster_than_the_ramp():
    p, dt = mut.CollaborationParameters(), 0.01
    standing = p.standstill_distance_m(T_S)
    assert mut.separation_override(5.0, 1.0, p, T_S, dt) == 1.0
    assert mut.separation_override(standing, 0.0, p, T_S, dt) == 0.0
    distances = np.linspace(standing, 3.0, 400)
    overrides = np.array([mut.separation_override(d, 1.2, p, T_S, dt) for d in distances])
    assert np.all(np.diff(overrides) >= 0.0) and 0.0 < overrides[len(overrides) // 2] <= 1.0
    # A person closing in at v_h lowers the allowed override at most dt / T_s a period,
    # which the rate limit follows.
    step = p.human_speed_m_s * dt
    drops = [mut.separation_override(d, u, p, T_S, dt) - mut.separation_override(d - step, u, p, T_S, dt)
             for d in distances[1:] for u in (0.0, 0.5, 1.5)]
    assert max(drops) <= dt / T_S + 1e-12
    # Wherever the robot may move, d keeps S_p at its speed plus the approach while it stops.
    for d in distances:
        o = mut.separation_override(d, 1.2, p, T_S, dt)
        if o > 0.0:
            assert d - p.human_speed_m_s * (p.reaction_time_s + o * T_S) >= \
                mut.protective_separation_distance(o * 1.2, p, T_S) - 1e-9
    assert mut.rate_limited(0.0, 1.0, 0.1) == pytest.approx(0.9)
    assert mut.rate_limited(2.0, 0.95, 0.1) == 1.0


def test_the_stop_only_radius_is_where_ssm_starts_slowing_at_top_speed():
    p, dt = mut.CollaborationParameters(policy=mut.STOP_ONLY_POLICY), 0.01
    radius = mut.stop_only_radius_m(p, T_S, dt)
    assert mut.separation_override(radius, p.max_speed_m_s, p, T_S, dt) == pytest.approx(1.0)
    assert mut.separation_override(radius - 0.05, p.max_speed_m_s, p, T_S, dt) < 1.0
    assert mut.stop_only_override(radius - 0.01, radius) == 0.0 and mut.stop_only_override(radius, radius) == 1.0
    assert mut.stop_only_radius_m(mut.CollaborationParameters(stop_radius_m=1.0), T_S, dt) == 1.0


def test_simulate_with_a_malformed_people_file_says_one_line_and_exits_2(tmp_path):
    path = write(tmp_path, "people:\n  - {name: a, path: [{t: 0, xy: [0, -2]}, {t: 1, xy: [0]}]}\n")
    status, out, err, _, _ = run_cli("simulate", scenarios_directory() / "transferring.yaml", "--library", "paper5",
                                     "--people", path)
    assert status == 2
    lines = stderr_lines(err)
    assert len(lines) == 1 and "people[0].path[1].xy" in lines[0] and str(path) in lines[0], err
    assert "Traceback" not in err
