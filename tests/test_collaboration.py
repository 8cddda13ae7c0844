"""People in the cell, closed loop: without people the Diagram and its joint log are what
they always were; with a person walking up to the transferring task's table the robot
slows, stops, resumes, never moves toward the person inside S_p, and meets every critical
configuration; the recording shows the person."""

import base64
import dataclasses
import hashlib
import json
import math
import re
import textwrap

import numpy as np
import pytest

from drake_lfd.core.people import STOP_ONLY_POLICY, CollaborationParameters, Person, ScriptedPath, Waypoint
from drake_lfd.core.resources import scenarios_directory
from drake_lfd.diagrams.judging import SUCCESS_POSITION_TOLERANCE_M, SUCCESS_ROTATION_TOLERANCE_RAD
from drake_lfd.experiments.simulation import TrialRunner, trial_json
from drake_lfd.io.library import Library, library_features
from drake_lfd.io.people_files import task_with_people
from drake_lfd.io.task_files import load_task
from drake_lfd.systems import JointPathSource, JointTrajectoryController, SeparationMonitor, TimeScaledJointPathSource

from browser import CHROMIUM, screenshot
from cli_subprocess import run_cli

# The example of docs/collaboration.rst: walks up to the table, stays, leaves.
OPERATOR = textwrap.dedent("""\
    people:
      - name: operator
        path: [{t: 0.0, xy: [-0.2, -2.0]}, {t: 1.5, xy: [-0.2, -0.75]}, {t: 4.0, xy: [-0.2, -0.75]},
               {t: 5.5, xy: [-0.2, -2.0]}]
    collaboration: {}
""")
# The systems of the pipeline without people, as before people existed (base c198b31).
SYSTEMS_WITHOUT_PEOPLE = ["differential_ik", "feature_library", "joint_path_source", "joint_state_logger", "planner",
                          "shell_monitor", "station", "trial_end"]
# sha256 of the joint log (t, q, qdot as float64 bytes) of transferring, trial 1, seed 0,
# paper5, as the base commit c198b31 (before people existed) simulates it.
BASE_JOINT_LOG_SHA256 = "54f423c9f1fc822e17fe98881622804c6c5457d8bf3df7bfd10203d23bc3afef"


@pytest.fixture(scope="module")
def features():
    return library_features(Library.open("paper5"))


@pytest.fixture(scope="module")
def transferring():
    return load_task(scenarios_directory() / "transferring.yaml")


@pytest.fixture(scope="module")
def people_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("people") / "operator.yaml"
    path.write_text(OPERATOR)
    return path


def joint_log_sha256(run) -> str:
    return hashlib.sha256(b"".join(np.ascontiguousarray(a).tobytes() for a in (run.t, run.q, run.qdot))).hexdigest()


@pytest.fixture(scope="module")
def without_people(transferring, features):
    runner = TrialRunner(transferring, features)
    return runner, runner.run(trial=1, seed=0)


@pytest.fixture(scope="module")
def with_operator(transferring, features, people_file, tmp_path_factory):
    task = task_with_people(transferring, people_file)
    runner = TrialRunner(task, features)
    html = tmp_path_factory.mktemp("recording") / "operator.html"
    outcomes = [runner.run(trial=i + 1, seed=i, record_html=html if i == 0 else None) for i in range(3)]
    return runner, outcomes, html


@pytest.mark.slow
def test_without_people_the_diagram_and_its_joint_log_are_unchanged(without_people, transferring, features,
                                                                     tmp_path):
    runner, outcome = without_people
    pipeline = runner._runner.pipeline
    assert sorted(system.get_name() for system in pipeline.GetSystems()) == SYSTEMS_WITHOUT_PEOPLE
    assert isinstance(pipeline.source, JointPathSource) and isinstance(pipeline.controller, JointTrajectoryController)
    assert pipeline.station.people is None and pipeline.separation is None
    assert pipeline.trial_end.path_time_input_port is None
    assert outcome.success and outcome.run.collaboration is None
    assert "collaboration" not in trial_json(outcome)
    # Bit for bit the log the code before people simulated.
    assert joint_log_sha256(outcome.run) == BASE_JOINT_LOG_SHA256
    # A people file with no one in it, only a collaboration block, changes nothing.
    empty = tmp_path / "nobody.yaml"
    empty.write_text("collaboration: {reaction_time_s: 0.2}\n")
    task = task_with_people(transferring, empty)
    same = TrialRunner(task, features)
    assert sorted(system.get_name() for system in same._runner.pipeline.GetSystems()) == SYSTEMS_WITHOUT_PEOPLE
    assert joint_log_sha256(same.run(trial=1, seed=0).run) == BASE_JOINT_LOG_SHA256


@pytest.mark.slow
def test_a_person_at_the_table_slows_and_stops_the_robot_which_still_meets_every_critical_configuration(
        with_operator, without_people):
    runner, outcomes, _ = with_operator
    pipeline = runner._runner.pipeline
    assert isinstance(pipeline.source, TimeScaledJointPathSource)
    assert isinstance(pipeline.separation, SeparationMonitor)
    _, plain = without_people
    for outcome in outcomes:
        assert outcome.success, outcome.failures
        record = outcome.run.collaboration
        assert record.slowed and record.protective_stops >= 1
        assert record.violation_count == 0
        # Closer than S_p only while the robot did not move toward the person.
        close = record.distance_m[:, 0] < record.protective_distance_m[:, 0]
        assert close.any()
        assert np.all(record.speed_toward_m_s[close, 0] <= record.moving_toward_speed_m_s)
        assert record.min_separation_m > 0.3
        # The run took longer by what the people cost; the path was finished.
        assert record.time_lost_s > 1.0
        assert record.path_time_s[-1] <= record.t[-1] + 1e-9
        assert outcome.run.sim_time_s == pytest.approx(outcome.run.plan_start_time_s
                                                       + outcome.plan.timed.duration + record.time_lost_s, abs=0.02)
        for error in outcome.run.critical_errors:
            assert error.reached
            assert error.position_m < SUCCESS_POSITION_TOLERANCE_M
            assert error.rotation_rad < SUCCESS_ROTATION_TOLERANCE_RAD
    # The same plan and path as without people: con_1 is met at the same time (before the
    # person arrives), the others later.
    first = outcomes[0].run.critical_errors
    assert [e.con for e in first] == [e.con for e in plain.run.critical_errors]
    assert first[0].time_s == pytest.approx(plain.run.critical_errors[0].time_s, abs=0.011) or \
        first[0].time_s > plain.run.critical_errors[0].time_s
    assert all(a.time_s > b.time_s for a, b in zip(first[1:], plain.run.critical_errors[1:]))
    entry = trial_json(outcomes[0])
    assert set(entry["collaboration"]) == {"min_separation_m", "min_margin_m", "protective_stops", "time_scaled_s",
                                           "time_lost_s"}
    assert entry["collaboration"]["protective_stops"] >= 1 and entry["collaboration"]["time_lost_s"] > 1.0
    json.dumps(entry, allow_nan=False)


@pytest.mark.slow
def test_the_recording_shows_the_person_and_the_override(with_operator):
    _, _, html = with_operator
    commands = [base64.b64decode(b) for b in re.findall(r"data:application/octet-binary;base64,([A-Za-z0-9+/=]+)",
                                                        html.read_text())]
    for name in (b"operator/torso", b"operator/head", b"operator/left_arm", b"CapsuleGeometry",
                 b"speed_override/stopped", b"speed_override/slowed", b"animation"):
        assert any(name in command for command in commands), name
    animation = [command for command in commands if b"animation" in command]
    assert any(b"operator/torso" in command for command in animation)  # the person moves in the replay
    # The robot is coloured by the override: every link's amber and red skins are drawn
    # and their visibility is keyed in the replay.
    for link in (b"upper_arm_link", b"forearm_link", b"wrist_3_link"):
        skin = b"illustration/ur5e/" + link + b"/speed_override/stopped"
        assert any(skin in command for command in commands), link
        assert any(skin in command for command in animation), link


@pytest.mark.slow
def test_a_person_far_away_leaves_the_path_and_its_times_as_without_people(transferring, features, without_people):
    far = Person("far", ScriptedPath((Waypoint(0.0, [-0.2, -20.0]),)))
    task = dataclasses.replace(transferring, people=(far,))
    outcome = TrialRunner(task, features).run(trial=1, seed=0)
    _, plain = without_people
    record = outcome.run.collaboration
    assert not record.slowed and record.time_lost_s == pytest.approx(0.0, abs=1e-9)
    np.testing.assert_allclose(record.path_time_s, record.t, atol=1e-9)
    for a, b in zip(outcome.run.critical_errors, plain.run.critical_errors):
        assert a.time_s == pytest.approx(b.time_s, abs=1e-9)
    # The same law as the compiled controller, in Python: the same motion to well below
    # a micrometre.
    np.testing.assert_allclose(outcome.run.q, plain.run.q, atol=1e-6)


@pytest.mark.slow
def test_the_stop_only_policy_stops_while_anyone_is_inside_its_radius(transferring, features):
    # Leaves far beyond the radius (about 2.3 m), so the robot resumes.
    walker = Person("walker", ScriptedPath(tuple(Waypoint(t, xy) for t, xy in (
        (0.0, [-0.2, -4.0]), (2.0, [-0.2, -0.75]), (3.0, [-0.2, -0.75]), (5.0, [-0.2, -4.0])))))
    task = dataclasses.replace(transferring, people=(walker,),
                               collaboration=CollaborationParameters(policy=STOP_ONLY_POLICY))
    runner = TrialRunner(task, features)
    outcome = runner.run(trial=1, seed=0)
    assert outcome.success, outcome.failures
    record = outcome.run.collaboration
    radius = runner._runner.pipeline.source.stop_radius_m
    # Stopped (override falling or 0) whenever the person was inside the radius; only
    # 1 or 0 are asked for, the ramp between.
    inside = record.distance_m[:, 0] < radius
    assert inside.any() and record.protective_stops >= 1
    assert record.violation_count == 0


@pytest.mark.slow
def test_simulate_with_people_reports_the_collaboration_per_trial(tmp_path, people_file):
    out = tmp_path / "out.json"
    status, stdout, err, _, _ = run_cli("simulate", scenarios_directory() / "transferring.yaml", "--library",
                                        "paper5", "--people", people_file, "--trials", "1", "--workers", "1",
                                        "--json", out, timeout=300)
    assert status == 0, err
    assert re.search(r"people cost \d+\.\d s \(slowed \d+\.\d s, 1 protective stop, closest 0\.\d\d m\); success",
                     stdout), stdout
    document = json.loads(out.read_text())
    collaboration = document["trials"][0]["collaboration"]
    assert collaboration["time_lost_s"] > 1.0 and math.isfinite(collaboration["min_margin_m"])


@pytest.mark.slow
def test_a_trial_run_again_on_the_same_diagram_gives_the_same_run(with_operator):
    # Everything the override needs lives in the Context: nothing carries over a run.
    runner, outcomes, _ = with_operator
    again = runner.run(trial=1, seed=0)
    first = outcomes[0].run
    np.testing.assert_array_equal(again.run.collaboration.override, first.collaboration.override)
    np.testing.assert_array_equal(again.run.q, first.q)
    assert again.run.collaboration.protective_stops == first.collaboration.protective_stops


@pytest.mark.slow
@pytest.mark.skipif(CHROMIUM is None, reason="needs Debian's chromium (installed by .ci/run)")
def test_the_recording_shows_the_orange_person(with_operator, tmp_path):
    _, _, html = with_operator

    def orange(image):
        red, green, blue = image[:, :, 0], image[:, :, 1], image[:, :, 2]
        return float(np.mean((red > 0.7) & (green > 0.2) & (green < 0.6) & (blue < 0.3)))

    image = screenshot(html, tmp_path / "people.png")
    if orange(image) <= 0.002:  # a loaded machine can starve the renderer: once more, longer
        image = screenshot(html, tmp_path / "people_again.png", budget_ms=9000)
    assert orange(image) > 0.002
