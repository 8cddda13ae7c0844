"""``drake-lfd paper`` end to end (one trial per task) and ``drake-lfd simulate``."""

import json

import numpy as np
import pytest

import drake_lfd.cli as cli
import drake_lfd.experiments.rederive as rederive
from drake_lfd.robot.kinematics import UR5eKinematics
from drake_lfd.core.resources import scenarios_directory


def test_dh_kinematics_of_the_rederivation_matches_the_model(rng):
    q = rng.uniform(-np.pi, np.pi, size=(50, 6))
    kinematics = UR5eKinematics()
    np.testing.assert_allclose(rederive.dh_forward_kinematics(q), kinematics.X_Wtool0_batch(q), atol=1e-9)


@pytest.mark.slow
def test_paper_command_writes_results_and_report(tmp_path):
    out = tmp_path / "paper"
    assert cli.main(["paper", "--out", str(out), "--trials", "1"]) == 0
    results = json.loads((out / "results.json").read_text())
    assert set(results) >= {"training", "tasks", "wall_time_s"}
    assert results["training"]["tasks"] == 20 and results["training"]["episodes"] == 100
    tasks = results["tasks"]
    assert tasks["transferring"]["success_count"] == 1
    assert tasks["filling_pouring"]["success_count"] == 1
    assert set(tasks["filling_pouring"]["compositions"]) and all(
        label.startswith("filling+stacking") for label in tasks["filling_pouring"]["compositions"])
    assembling = tasks["assembling"]
    assert assembling["initial_status"] == "demonstration_requested"
    assert [(u["from"], u["to"]) for u in assembling["uncovered"]] == [(2, 3)]
    assert assembling["after_new_demo"]["success_count"] == 1
    assert all("span" in label for label in assembling["after_new_demo"]["compositions"])
    for task in ("transferring", "filling_pouring"):
        assert tasks[task]["rederived_success_count"] == tasks[task]["success_count"]
    report = (out / "report.md").read_text()
    assert "1927.42" in report and "| transferring (Table 7) |" in report
    for name in ("training_curve.png", "retraining_curve.png", "transferring.html", "assembling_plan.png"):
        assert (out / name).stat().st_size > 1000


@pytest.mark.slow
def test_simulate_json_is_re_derivable_from_q(tmp_path):
    out = tmp_path / "sim.json"
    scenario = scenarios_directory() / "transferring.yaml"
    assert cli.main(["simulate", str(scenario), "--library", "paper5", "--trials", "1", "--seed", "3",
                     "--json", str(out)]) == 0
    document = json.loads(out.read_text())
    assert document["trials_requested"] == 1 and document["success_count"] == 1
    (trial,) = document["trials"]
    assert len(trial["t"]) == len(trial["q"]) and np.all(np.diff(trial["t"]) <= 0.0100001)
    from drake_lfd.io.pose_records import rigid_transform_from_pose_json
    from drake_lfd.core.tasks import draw_trial
    from drake_lfd.io.task_files import load_task

    task = load_task(scenario)
    check = rederive.rederive_run(
        trial["t"], trial["q"], critical_times_s=trial["critical_times_s"],
        critical_configurations=trial["critical_configurations"],
        X_WB=rigid_transform_from_pose_json(document["X_WB"]),
        X_tool0_E=rigid_transform_from_pose_json(document["X_tool0_E"]),
        path_constraints=draw_trial(task, 3).path_constraints,
        obstacles=task.obstacles, safety_shells=task.safety_shells, tool=task.tool,
    )
    assert check.success, check.failures
    for (position, rotation), logged in zip(check.critical_errors, trial["critical_errors"]):
        assert position == pytest.approx(logged["position_m"], abs=2e-3)
    assert check.min_clearance_m == pytest.approx(trial["min_shell_distance_m"], abs=5e-3)
