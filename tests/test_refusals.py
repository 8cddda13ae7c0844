"""Refusals no choice can change (planning/refusals.py) and the distinct reasons of a refusal."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from cli_subprocess import run_cli, stderr_lines
from drake_lfd.core.tasks import draw_trial
from drake_lfd.diagrams.pipeline import joint_path_checker
from drake_lfd.io.library import Library, library_features
from drake_lfd.io.task_files import task_from_spec, task_spec_from_text
from drake_lfd.planning import refusals as mut
from drake_lfd.planning.executable import InfeasibleSegment
from drake_lfd.planning.options import PlanningOptions
from drake_lfd.planning.planner import build_problem, plan_composition
from drake_lfd.robot.workcell import Workcell

DATA = Path(__file__).parent / "data"


def shelf_text(x=0.0, y=0.0):
    """The shelf task with its robot base moved to (x, y)."""
    text = (DATA / "shelf_pick_place.yaml").read_text()
    return text.replace("X_WB: {p: [0, 0, 0]", f"X_WB: {{p: [{x}, {y}, 0]")


def plan_shelf(x, y):
    task = task_from_spec(task_spec_from_text(shelf_text(x, y)), file="shelf.yaml")
    trial = draw_trial(task, 0)
    workcell = Workcell.of(trial)
    checker = joint_path_checker(workcell, task.simulation)
    features = library_features(Library.open("paper5"))
    result = plan_composition(trial, features, PlanningOptions(), floor_z=workcell.planner_floor, checker=checker)
    return result, trial, checker, features


def test_a_configuration_blocked_on_every_branch_is_refused_before_any_alternative():
    """Base 15 cm too far back: con_2 has the elbow straight on every branch (the search
    used to forbid 22 actions, 8-32 s, one line each); now one segment per such
    configuration, found with the first composition."""
    result, trial, checker, features = plan_shelf(-0.15, 0.15)
    assert result.status == "no_executable_plan"
    assert result.search_rounds == 1
    (segment,) = result.infeasible
    assert segment.con_to == 2 and segment.reason == "reach"
    assert "at con_2" in segment.detail and "no inverse-kinematics solution" in segment.detail
    problem = build_problem(trial, features, cost="fidelity")
    assert segment.blocked_alternatives == sum(
        int(np.isfinite(m).sum()) for (j, k, _), m in problem.cost.items() if j <= 1 <= k)
    result, *_ = plan_shelf(-0.15, -0.15)
    assert [s.con_to for s in result.infeasible] == [2, 3]
    singular = result.infeasible[0]
    assert singular.reason == "singularity" and "elbow straight (|sin q3| = 0." in singular.detail
    assert "on every inverse-kinematics branch" in singular.detail and "< 0.06) on " in singular.detail


def test_a_task_that_plans_is_not_refused():
    result, *_ = plan_shelf(0.05, 0.05)
    assert result.planned and result.search_rounds == 1


def test_the_refusal_is_one_line_per_reason_and_the_json_counts_alternatives(tmp_path):
    task = tmp_path / "shelf.yaml"
    task.write_text(shelf_text(-0.15, -0.15))
    out = tmp_path / "plan.json"
    status, _, err, _, _ = run_cli("plan", task, "--library", "paper5", "--json", out)
    assert status == 4, err
    lines = stderr_lines(err)
    assert len(lines) == 2 and len(set(lines)) == 2, lines
    assert "Traceback" not in err
    infeasible = json.loads(out.read_text())["infeasible"]
    assert [e["to"] for e in infeasible] == [2, 3]
    assert all(e["blocked_alternatives"] > 1 and e["demo"] == "" for e in infeasible)


def test_distinct_reasons_merge_what_differs_only_in_numbers():
    a = InfeasibleSegment(1, 2, "singularity", "elbow straight (|sin q3| = 0.057 < 0.06)", "stacking")
    b = InfeasibleSegment(2, 3, "singularity", "elbow straight (|sin q3| = 0.031 < 0.06)", "pouring")
    c = InfeasibleSegment(2, 3, "collision", "collision with safety shell 's': upper_arm_link/x passes 9.9 mm "
                          "from safety shell 's' (clearance 10 mm)", "stacking")
    d = InfeasibleSegment(2, 4, "collision", "collision with safety shell 's': forearm_link/y passes 9.9 mm "
                          "from safety shell 's' (clearance 10 mm)", "stacking")
    merged = mut.distinct_reasons([a, c, b, d, c])
    assert [(s.con_from, s.con_to, s.reason) for s in merged] == [(1, 2, "singularity"), (2, 3, "collision"),
                                                                   (2, 4, "collision")]
    assert [s.blocked_alternatives for s in merged] == [2, 2, 1]
    assert merged[0].demo == "" and merged[1].demo == "stacking"
    assert merged[0].detail == a.detail
    assert "[blocks 2 alternatives]" in merged[0].describe() and "blocks" not in merged[2].describe()


def test_the_pan_sweep_takes_the_better_way_round():
    pans = np.linspace(0.0, 2 * np.pi, 360, endpoint=False)
    least = np.full(360, 0.1)
    least[90] = 0.005  # a pan-only shape near a shell at 90 deg
    a, b = np.radians([0.0, 10.0]), np.radians([180.0])
    worst = mut._sweep_minimum(least, pans, a, b)
    assert worst.shape == (2, 1)
    np.testing.assert_allclose(worst, 0.1)  # the way round through 270 deg is clear
    least[270] = 0.002  # blocked both ways
    np.testing.assert_allclose(mut._sweep_minimum(least, pans, a, b), 0.005)
    # A pan at its own end is the configuration's business, not the sweep's.
    np.testing.assert_allclose(mut._sweep_minimum(least, pans, np.radians([90.0]), np.radians([100.0])), 0.1)


def test_a_configuration_only_other_branches_reach_is_refused_at_once():
    """Base 15 cm forward: con_3 keeps the margins only on branches con_1 and con_2 do
    not have; the arm cannot change branch without crossing a singularity, so the search
    (20 rounds, 22-50 s, six lines before) is not needed."""
    result, *_ = plan_shelf(0.15, 0.05)
    assert result.status == "no_executable_plan" and result.search_rounds == 1
    (segment,) = result.infeasible
    assert (segment.con_from, segment.con_to, segment.reason) == (2, 3, "collision")
    assert "at con_3" in segment.detail and "changing branch crosses a singularity" in segment.detail
    assert "upper_arm_link/" in segment.detail and "box_shell" in segment.detail


def test_a_branch_is_the_side_of_each_singularity():
    q = np.array([0.3, -1.2, 1.6, -1.97, -np.pi / 2, 0.0])
    elbow, wrist, shoulder = mut.branch_signature(q)
    assert (elbow, wrist) == (1, -1) and shoulder in (-1, 1)
    flipped = q.copy()
    flipped[2] = -q[2]
    assert mut.branch_signature(flipped)[0] == -1
    turned = q + 2 * np.pi * np.array([1, 0, 1, 1, 1, 1])  # windings change no branch
    assert mut.branch_signature(turned) == mut.branch_signature(q)
