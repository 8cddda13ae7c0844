"""Refinement bounded by the task (issue 34, items 1 and 2): the task file's ``refinement:``
block and a path constraint's ``max_deviation`` say how far ``--refine`` may move E from
the composed path, span by span; a path constraint always bounds it where it applies; and
a refined plan never breaks a path constraint or a bound (the composed plan, which the
search checked, stands instead).

The machine-tending task (``tests/data/machine_tending.yaml``) pulls a part 14 cm straight
out of a fixture (con_6 -> con_7) within 3 deg: without a bound the refinement may turn
the part during that lift by anything the default tube allows.
"""

import json
import math
from pathlib import Path

import numpy as np
import pytest

from cli_subprocess import run_cli
from drake_lfd.core.errors import InputError
from drake_lfd.core.tasks import DeviationBound, RefinementBounds, draw_trial
from drake_lfd.diagrams.pipeline import joint_path_checker
from drake_lfd.io.library import Library, library_features
from drake_lfd.io.task_files import load_task, task_from_spec, task_spec_from_text
from drake_lfd.planning.options import PlanningOptions
from drake_lfd.planning.planner import plan_composition
from drake_lfd.planning.refinement import refine_plan
from drake_lfd.planning.refinement_bounds import allowed_deviations
from drake_lfd.planning.refinement_options import RefinementOptions
from drake_lfd.planning.refinement_tube import tube_deviation
from drake_lfd.robot.workcell import Workcell
from drake_lfd.robot.kinematics import UR5eKinematics
from drake_lfd.robot.trajectory_optimization import OptimizationScene
from drake_lfd.robot.path_constraints import (
    allowed_deviation,
    constraint_rotation,
    constraint_window,
    orientation_deviations,
)

TENDING = Path(__file__).parent / "data" / "machine_tending.yaml"

THREE_CONS = """
critical_configurations:
  - {p: [0.40, -0.30, 0.35], euler_zyx: [0, -pi/2, 0]}
  - {p: [0.45, 0.20, 0.35], euler_zyx: [0, -pi/2, 0]}
  - {p: [0.45, 0.20, 0.21], euler_zyx: [0, -pi/2, 0]}
  - {p: [0.45, 0.20, 0.35], euler_zyx: [0, -pi/2, 0]}
"""


def _task(text):
    return task_from_spec(task_spec_from_text(THREE_CONS + text, file="t.yaml"), file="t.yaml")


# ----------------------------------------------------------------------------- parsing


def test_no_refinement_block_means_the_documented_default_tube():
    task = _task("")
    assert task.refinement is None
    position, rotation = allowed_deviations(task)
    np.testing.assert_array_equal(position, [0.15] * 3)
    np.testing.assert_allclose(rotation, [math.radians(30)] * 3)
    options = RefinementOptions()
    assert (options.tube_position_m, options.tube_rotation_rad) == (0.15, math.radians(30.0))


def test_the_whole_task_spans_and_path_constraints_bound_the_refinement():
    task = _task("""
refinement:
  max_deviation: {position_m: 0.1}
  spans:
    - {between: [1, 2], position_m: 0.2}          # a span may be let wider
    - {between: [2, 4], rotation_deg: 10}
    - {between: [3, 4], position_m: 0.03, rotation_deg: 20}   # overlapping: the tighter
path_constraints:
  - {kind: orientation, between: [1, 3], euler_zyx: [0, -pi/2, 0], tolerance_deg: 5}
  - {kind: orientation, between: [3, 4], euler_zyx: [0, -pi/2, 0], tolerance_deg: 40,
     max_deviation: {position_m: 0.02}}
""")
    assert task.refinement == RefinementBounds(
        max_deviation=DeviationBound(position_m=0.1),
        spans=(DeviationBound(position_m=0.2, con_from=1, con_to=2),
               DeviationBound(rotation_rad=math.radians(10), con_from=2, con_to=4),
               DeviationBound(position_m=0.03, rotation_rad=math.radians(20), con_from=3, con_to=4)))
    assert task.path_constraints[0].max_deviation is None
    assert task.path_constraints[1].max_deviation == DeviationBound(position_m=0.02)
    position, rotation = allowed_deviations(task)
    np.testing.assert_allclose(position, [0.2, 0.1, 0.02])
    # Span 1: the default 30 deg, but the first constraint (5 deg) covers it; span 2: the
    # span's 10 deg and that constraint; span 3: the tighter of 10 and 20 deg (the second
    # constraint's 40 deg tolerance does not widen it).
    np.testing.assert_allclose(np.degrees(rotation), [5.0, 5.0, 10.0])
    # Every trial carries the block.
    assert draw_trial(task, 0).refinement is task.refinement


@pytest.mark.parametrize("text, field, problem", [
    ("refinement: {max_deviation: {position_m: -0.1}}", "refinement.max_deviation.position_m", "must be > 0"),
    ("refinement: {max_deviation: {position_m: 0}}", "refinement.max_deviation.position_m", "must be > 0"),
    ("refinement: {max_deviation: {position_m: 150}}", "refinement.max_deviation.position_m", "for millimetres"),
    ("refinement: {max_deviation: {rotation_deg: 200}}", "refinement.max_deviation.rotation_deg", "(0, 180]"),
    ("refinement: {max_deviation: {rotation_deg: .nan}}", "refinement.max_deviation.rotation_deg", "finite"),
    ("refinement: {max_deviation: {position_m: abc}}", "refinement.max_deviation.position_m", "expected a number"),
    ("refinement: {max_deviation: {speed: 1}}", "refinement.max_deviation.speed", "unknown key"),
    ("refinement: {max_deviation: 3}", "refinement.max_deviation", "expected a mapping"),
    ("refinement: {spans: [{between: [1, 2]}]}", "refinement.spans[0]", "give position_m, rotation_deg or both"),
    ("refinement: {spans: [{position_m: 0.1}]}", "refinement.spans[0].between", "missing"),
    ("refinement: {spans: [{between: [2, 2], position_m: 0.1}]}", "refinement.spans[0].between", "1 <= j < k <= 4"),
    ("refinement: {spans: [{between: [1, 5], position_m: 0.1}]}", "refinement.spans[0].between", "1 <= j < k <= 4"),
    ("refinement: {spans: [{between: [1], position_m: 0.1}]}", "refinement.spans[0].between", "expected [j, k]"),
    ("refinement: {spans: [{between: [1, 2], rotation_deg: 0}]}", "refinement.spans[0].rotation_deg", "(0, 180]"),
    ("path_constraints: [{between: [1, 2], euler_zyx: [0, 0, 0], tolerance_deg: 3, "
     "max_deviation: {rotation_deg: -1}}]", "path_constraints[0].max_deviation.rotation_deg", "(0, 180]"),
])
def test_a_bad_bound_is_refused_naming_the_file_and_the_field(text, field, problem):
    with pytest.raises(InputError) as error:
        _task(text)
    message = str(error.value)
    assert message.startswith(f"t.yaml: {field}: ") and problem in message, message


def test_a_bad_bound_exits_2_with_one_line(tmp_path):
    path = tmp_path / "bad.yaml"
    path.write_text(TENDING.read_text() + "refinement: {spans: [{between: [6, 9], position_m: 0.02}]}\n")
    status, _, stderr, _, _ = run_cli("plan", path, "--library", "paper5", "--refine")
    assert status == 2
    (line,) = stderr.strip().splitlines()
    assert f"{path}: refinement.spans[0].between: [6, 9] must satisfy 1 <= j < k <= 7" in line


# ------------------------------------------------------------- the refined plan keeps them


def _document(tmp_path, path):
    out = tmp_path / "plan.json"
    status, stdout, stderr, _, _ = run_cli("plan", path, "--library", "paper5", "--refine", "--json", out,
                                           timeout=300)
    assert status == 0, stderr
    return json.loads(out.read_text()), stdout


def _commanded(document, task):
    """The plan's commanded joint path: times, E's poses, and when each con is due."""
    kinematics = UR5eKinematics(X_WB=task.X_WB, X_tool0_E=task.X_tool0_E)
    t = np.array(document["joint_trajectory"]["t"])
    X = [kinematics.X_WE(np.array(q)) for q in document["joint_trajectory"]["q"]]
    due = [document["poses"][i]["t"] for i in document["critical_indices"]]
    return t, X, due


@pytest.mark.slow
def test_plan_refine_never_reports_a_plan_that_breaks_a_path_constraint(tmp_path):
    """On the machine-tending task, whatever the refinement does: the plan ``plan --refine``
    reports (refined or not) keeps the straight-out constraint on the joints it commands,
    with the closed loop's margin, the measure the search holds plans to."""
    task = load_task(TENDING)
    (constraint,) = task.path_constraints
    document, stdout = _document(tmp_path, TENDING)
    assert document["status"] == "planned"
    refinement = document["refinement"]
    assert refinement["status"] in ("refined", "failed")
    assert ("refined by trajectory optimization" in stdout) == (refinement["status"] == "refined")
    t, X, due = _commanded(document, task)
    inside = constraint_window(constraint, due, t)
    assert inside.sum() > 10
    angles = orientation_deviations(np.array([x.rotation().matrix() for x in np.array(X)[inside]]),
                                    constraint_rotation(constraint))
    assert angles.max() <= allowed_deviation(constraint) + 1e-9
    if refinement["status"] == "refined":
        assert document["poses"][-1]["t"] == pytest.approx(refinement["duration_s"])
        assert refinement["duration_s"] < refinement["unrefined_duration_s"]


@pytest.mark.slow
def test_a_refined_plan_keeps_a_tight_span_bound_or_the_composed_plan_stands(tmp_path):
    """A bound of 5 mm and 1 deg over the lift (con_6 -> con_7), where the constraint alone
    would allow 3 deg: measured on the followed (commanded) motion, the lift within 5 mm
    of the composed lift's path and within 1 deg of the composed rotation at the same path
    fraction, the rest within the default tube; or the refinement failed and the composed
    plan stands."""
    path = tmp_path / "tight.yaml"
    path.write_text(TENDING.read_text() + "refinement:\n  spans:\n"
                    "    - {between: [6, 7], position_m: 0.005, rotation_deg: 1}\n")
    task, workcell, checker, composed = _composed_trial(path)
    assert composed.planned
    result = refine_plan(composed, checker, scene=OptimizationScene(workcell))
    report = result.refinement
    if not report.refined:
        assert report.reason and result.timed is composed.timed and result.joint_path is composed.joint_path
        return
    followed, timed = result.joint_path, result.timed
    kinematics = UR5eKinematics(X_WB=task.X_WB, X_tool0_E=task.X_tool0_E)
    s = np.interp(np.minimum(followed.t, timed.duration), timed.times, report.path_fractions)
    X = [kinematics.X_WE(q) for q in followed.q]
    due = [timed.times[i] for i in timed.critical_indices]
    lift = (followed.t >= due[5] - 1e-9) & (followed.t <= due[6] + 1e-9)
    assert lift.sum() > 10
    poses = [x for x, w in zip(X, lift) if w]
    first, last = composed.timed.critical_indices[5], composed.timed.critical_indices[6]
    composed_lift = np.array([x.translation() for x in composed.timed.X_WE_list()[first:last + 1]])
    assert max(_distance_to_polyline(x.translation(), composed_lift) for x in poses) <= 0.005
    _, rotation = tube_deviation(composed.timed, s[lift], poses)
    assert rotation <= math.radians(1.0)
    position, rotation = tube_deviation(composed.timed, s, X)
    assert position <= 0.15 and rotation <= math.radians(30.0)


def _composed_trial(path):
    """The task file at ``path``, trial seed 0: its work cell, checker and composed plan
    (``paper5``), as ``plan`` makes them."""
    task = load_task(path)
    trial = draw_trial(task, 0)
    workcell = Workcell.of(trial)
    checker = joint_path_checker(workcell, task.simulation)
    composed = plan_composition(trial, library_features(Library.open("paper5")), PlanningOptions(),
                                floor_z=workcell.planner_floor, checker=checker)
    return task, workcell, checker, composed


def _distance_to_polyline(p, points):
    start, step = points[:-1], np.diff(points, axis=0)
    u = np.clip(np.einsum("ij,ij->i", p - start, step) / np.maximum(np.einsum("ij,ij->i", step, step), 1e-300),
                0.0, 1.0)
    return float(np.min(np.linalg.norm(start + u[:, None] * step - p, axis=1)))


@pytest.mark.slow
def test_a_refined_motion_that_breaks_a_path_constraint_is_refused(tmp_path, monkeypatch):
    """The program made to turn the part 8 deg in the middle of the lift (its own path
    constraint bounds replaced by that; the constraint lets the refinement turn it as far
    as it likes from the composed path): every motion the program gives breaks the
    constraint, the check refuses each for it, and the composed plan stands."""
    import drake_lfd.planning.refinement as refinement_module
    from pydrake.math import RotationMatrix
    from drake_lfd.robot.optimization_records import PoseBound

    path = tmp_path / "free.yaml"
    path.write_text(TENDING.read_text().replace("tolerance_deg: 3}",
                                                "tolerance_deg: 3, max_deviation: {rotation_deg: 180}}"))
    task, workcell, checker, composed = _composed_trial(path)
    (constraint,) = task.path_constraints

    def turned(result, fractions, options):
        R = RotationMatrix(constraint_rotation(constraint)).multiply(RotationMatrix.MakeXRotation(math.radians(8)))
        return [PoseBound(float(0.5 * (fractions[5] + fractions[6])), R_WE=R, angle_rad=math.radians(1))]

    monkeypatch.setattr(refinement_module, "path_constraint_bounds", turned)
    result = refine_plan(composed, checker, scene=OptimizationScene(workcell))
    report = result.refinement
    assert report.status == "failed"
    assert result.timed is composed.timed and result.joint_path is composed.joint_path
    assert report.reason.startswith("check: path_constraint: the tool turns ")
    assert "path constraint con_6..con_7 allows a plan 1.5 deg" in report.reason
