"""``drake-lfd train`` and ``drake-lfd plan`` on a small library of joint-space demos."""

import json

import numpy as np
import pytest

import drake_lfd.cli as cli
from drake_lfd.core.demonstrations import Demonstration
from drake_lfd.robot.kinematics import UR5eKinematics
from drake_lfd.io.library import Library
from drake_lfd.planning.random_tasks import _euler_zyx_of
from drake_lfd.core.dual_quaternion import translation_rotation_from_dual_quaternion
from drake_lfd.core.pose_conversions import dual_quaternion_from_matrices

Q_HOME = np.array([0.3, -1.3, 1.7, -1.97, -np.pi / 2, 0.2])
# Joint-space demonstrations: wrist_3 turns the tool about its own z axis (a screw);
# shoulder_pan and the lift joints carry it along.
DEMO_MOTIONS = {
    "twist_cw": np.array([0.15, 0.0, 0.0, 0.0, 0.0, -np.pi / 2]),
    "twist_ccw": np.array([0.15, 0.0, 0.0, 0.0, 0.0, np.pi / 2]),
    "lift": np.array([0.0, -0.25, 0.1, 0.15 + np.pi / 2, 0.0, 0.0]),  # lifts and tilts 90 deg
}


def demo(name, start):
    t = np.linspace(0.0, 2.0, 400)
    s = 0.5 - 0.5 * np.cos(np.pi * t / 2.0)
    return Demonstration(name=name, timestamps=t, joint_positions=start + np.outer(s, DEMO_MOTIONS[name]))


@pytest.fixture(scope="module")
def library_dir(tmp_path_factory):
    path = tmp_path_factory.mktemp("lib") / "joint_demos"
    library = Library.create(path)
    for name in DEMO_MOTIONS:
        library.add(demo(name, Q_HOME), name)
    return path


def write_task(path, q_chain):
    """A task whose critical configurations are the FK of joint configurations."""
    kinematics = UR5eKinematics()
    D = dual_quaternion_from_matrices(kinematics.X_WE_batch(np.array(q_chain)))
    p, q = translation_rotation_from_dual_quaternion(D)
    lines = ["name: joint_chain", "critical_configurations:"]
    for pi, qi in zip(p, q):
        numbers = ", ".join(repr(float(v)) for v in pi)
        angles = ", ".join(repr(float(v)) for v in _euler_zyx_of(qi))
        lines.append(f"  - {{p: [{numbers}], euler_zyx: [{angles}]}}")
    path.write_text("\n".join(lines) + "\n")
    return path


@pytest.fixture(scope="module")
def chain_task(tmp_path_factory):
    # Start elsewhere: twist_cw, then lift, from a different home configuration.
    # q0 turns wrist_3 by +90 deg so that lift starts with the wrist as it was recorded.
    q0 = Q_HOME + np.array([-0.4, 0.1, -0.1, 0.05, 0.0, np.pi / 2])
    q1 = q0 + DEMO_MOTIONS["twist_cw"]
    q2 = q1 + DEMO_MOTIONS["lift"]
    return write_task(tmp_path_factory.mktemp("task") / "chain.yaml", [q0, q1, q2])


def test_plan_exact_writes_the_interface_json(library_dir, chain_task, tmp_path):
    out = tmp_path / "plan.json"
    assert cli.main(["plan", str(chain_task), "--library", str(library_dir), "--json", str(out)]) == 0
    plan = json.loads(out.read_text())
    assert plan["status"] == "planned" and plan["planner"] == "exact"
    assert [(c["demo"], c["from"], c["to"]) for c in plan["composition"]] == [("twist_cw", 1, 2), ("lift", 2, 3)]
    assert set(plan) >= {"task", "X_WB", "X_tool0_E", "critical_configurations", "total_cost", "poses",
                         "critical_indices", "max_correction", "uncovered"}
    assert plan["uncovered"] == []
    assert len(plan["critical_indices"]) == 3 and plan["critical_indices"][0] == 0
    times = [pose["t"] for pose in plan["poses"]]
    assert times[0] == 0.0 and all(b > a for a, b in zip(times, times[1:]))
    # The poses are E along the checked joint path, which meets each critical
    # configuration within the check's reach error (the geometric pass rests there).
    for con, index in zip(plan["critical_configurations"], plan["critical_indices"]):
        np.testing.assert_allclose(plan["poses"][index]["p"], con["p"], atol=1e-4)


def test_train_then_plan_with_the_q_policy(library_dir, chain_task, tmp_path):
    policy = tmp_path / "policy.json"
    summary = tmp_path / "train.json"
    assert cli.main(["train", "--library", str(library_dir), "--random-tasks", "5", "--episodes", "20",
                     "--seed", "1", "--out", str(policy), "--json", str(summary)]) == 0
    assert (tmp_path / "policy.curve.png").stat().st_size > 1000
    report = json.loads(summary.read_text())
    assert report["tasks"] == 5 and report["episodes"] == 20 and len(report["curve"]) == 20
    out = tmp_path / "plan.json"
    assert cli.main(["plan", str(chain_task), "--library", str(library_dir), "--planner", "q",
                     "--policy", str(policy), "--json", str(out)]) == 0
    plan = json.loads(out.read_text())
    assert plan["planner"] == "q"
    assert [c["demo"] for c in plan["composition"]] == ["twist_cw", "lift"]
    # Warm start from the saved policy.
    assert cli.main(["train", "--library", str(library_dir), "--random-tasks", "2", "--episodes", "5",
                     "--out", str(tmp_path / "p2.json"), "--warm-start", str(policy)]) == 0


def test_missing_demonstration_exits_3_and_names_the_segment(library_dir, chain_task, tmp_path, capsys):
    smaller = tmp_path / "smaller"
    library = Library.create(smaller)
    library.add(demo("twist_cw", Q_HOME), "twist_cw")
    out = tmp_path / "request.json"
    assert cli.main(["plan", str(chain_task), "--library", str(smaller), "--json", str(out)]) == 3
    request = json.loads(out.read_text())
    assert request["status"] == "demonstration_requested"
    assert [(u["from"], u["to"]) for u in request["uncovered"]] == [(2, 3)]
    assert "con_2 -> con_3" in capsys.readouterr().out


@pytest.mark.parametrize("extra, field", [
    (["--planner", "q"], "--policy"),
    (["--seed", "-1"], "--seed"),
])
def test_bad_arguments_exit_2_with_one_line(library_dir, chain_task, extra, field, capsys):
    assert cli.main(["plan", str(chain_task), "--library", str(library_dir)] + extra) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and field in err[0]


def test_corrupt_policy_and_unknown_library_exit_2(library_dir, chain_task, tmp_path, capsys):
    bad = tmp_path / "bad.json"
    bad.write_text("{not json")
    assert cli.main(["plan", str(chain_task), "--library", str(library_dir), "--planner", "q",
                     "--policy", str(bad)]) == 2
    assert "bad.json" in capsys.readouterr().err
    assert cli.main(["plan", str(chain_task), "--library", str(tmp_path / "nope")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "no such library" in err[0]
