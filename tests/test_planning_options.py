"""One set of planning options with one default: :class:`PlanningOptions` has the
defaults of ``drake-lfd plan``, checks itself, and ``drake_lfd.plan_task`` with them
plans exactly what the command line plans (composition, duration, joint trajectory)."""

import dataclasses
import json

import numpy as np
import pytest

import drake_lfd
from drake_lfd import cli
from drake_lfd.cli.app import build_parser
from drake_lfd.cli.plan import planning_options_of
from drake_lfd.core.errors import EXIT_DEMONSTRATION_REQUESTED
from drake_lfd.core.fidelity import FidelityWeights
from drake_lfd.core.resources import scenarios_directory
from drake_lfd.core.similarity import Tolerances
from drake_lfd.io.library import Library, library_features
from drake_lfd.io.plan_json import plan_json
from drake_lfd.io.strict_json import strict_json_text
from drake_lfd.planning.options import PLANNERS, PlanningOptions

SIMS = scenarios_directory()


def test_the_defaults_are_those_of_drake_lfd_plan():
    args = build_parser().parse_args(["plan", "task.yaml", "--library", "paper5"])
    options = PlanningOptions()
    assert (options.planner, options.cost, options.refine) == (args.planner, args.cost, args.refine)
    assert options.joint_check is True  # plan always checks (joint_path_checker)
    assert planning_options_of(args) == options
    assert options.tolerances == Tolerances() and options.fidelity_weights == FidelityWeights()
    assert options.timing is None and options.max_span is None


def test_the_flags_become_one_options_value():
    args = build_parser().parse_args(["plan", "task.yaml", "--library", "paper5", "--planner", "q",
                                      "--cost", "paper", "--refine"])
    assert planning_options_of(args) == PlanningOptions(planner="q", cost="paper", refine=True)


def test_paper_baseline_is_eq_31_without_the_joint_check():
    baseline = PlanningOptions.paper_baseline()
    assert (baseline.cost, baseline.joint_check, baseline.refine, baseline.planner) == ("paper", False, False, "exact")
    assert PlanningOptions.paper_baseline(planner="q").planner == "q"
    assert baseline != PlanningOptions()


@pytest.mark.parametrize("changes, message", [
    ({"planner": "greedy"}, "planner must be one of"),
    ({"cost": "shape"}, "cost must be one of"),
    ({"refine": True, "joint_check": False}, "refine needs joint_check"),
    ({"max_span": 0}, "max_span"),
    ({"refine_episodes": -1}, "refine_episodes"),
])
def test_bad_options_are_refused(changes, message):
    with pytest.raises(ValueError, match=message):
        PlanningOptions(**changes)
    with pytest.raises(ValueError, match=message):
        PlanningOptions().replace(**changes)


def test_options_are_frozen_and_hashable():
    options = PlanningOptions()
    with pytest.raises(dataclasses.FrozenInstanceError):
        options.cost = "paper"
    assert len({options, PlanningOptions(), PlanningOptions.paper_baseline()}) == 2
    assert PLANNERS == ("exact", "q")


def _cli_plan(tmp_path, name, library, seed=0):
    out = tmp_path / f"{name}_{library}.json"
    status = cli.main(["plan", str(SIMS / f"{name}.yaml"), "--library", library, "--seed", str(seed),
                       "--json", str(out)])
    return status, json.loads(out.read_text())


def _trial(name, seed=0):
    return drake_lfd.draw_trial(drake_lfd.load_task(SIMS / f"{name}.yaml"), seed)


@pytest.mark.parametrize("name, library", [
    ("transferring", "paper5"), ("filling_pouring", "paper5"), ("assembling", "paper6")])
def test_plan_task_plans_what_the_command_line_plans(tmp_path, name, library, capsys):
    result = drake_lfd.plan_task(_trial(name), library)
    status, document = _cli_plan(tmp_path, name, library)
    capsys.readouterr()
    assert status == 0 and result.planned
    assert [(s["demo"], s["from"], s["to"]) for s in document["composition"]] == [
        (s.demo, s.con_from, s.con_to) for s in result.composition]
    assert document["poses"][-1]["t"] == result.timed.duration
    assert np.array_equal(np.array(document["joint_trajectory"]["t"]), result.joint_path.t)
    assert np.array_equal(np.array(document["joint_trajectory"]["q"]), result.joint_path.q)
    assert result.timing == document["timing"] == "time_optimal"
    # The whole document, as the command line writes it.
    assert strict_json_text(plan_json(result, cost="fidelity")) == strict_json_text(document)


def test_plan_task_takes_the_library_in_any_form(tmp_path):
    trial = _trial("transferring")
    library = Library.open("paper5")
    by_name = drake_lfd.plan_task(trial, "paper5")
    for other in (library, library.path, str(library.path), library_features(library)):
        again = drake_lfd.plan_task(trial, other)
        assert again.composition == by_name.composition
        assert np.array_equal(again.joint_path.q, by_name.joint_path.q)
    with pytest.raises(TypeError, match="library must be"):
        drake_lfd.plan_task(trial, 5)


def test_a_request_is_the_command_lines_request(tmp_path, capsys):
    result = drake_lfd.plan_task(_trial("assembling"), "paper5")
    status, document = _cli_plan(tmp_path, "assembling", "paper5")
    capsys.readouterr()
    assert status == EXIT_DEMONSTRATION_REQUESTED
    assert result.status == document["status"] == "demonstration_requested"
    assert [(u["from"], u["to"]) for u in document["uncovered"]] == [(u.con_from, u.con_to) for u in result.uncovered]
    assert np.array_equal(np.array([u["axis"] for u in document["uncovered"]]),
                          np.array([u.axis for u in result.uncovered]))


def test_the_seed_is_the_trials_unless_given():
    trial = _trial("transferring", seed=3)
    options = PlanningOptions(joint_check=False)
    assert trial.seed == 3
    implicit = drake_lfd.plan_task(trial, "paper5", options)
    explicit = drake_lfd.plan_task(trial, "paper5", options, seed=3)
    assert implicit.composition == explicit.composition
    assert np.array_equal(implicit.timed.poses, explicit.timed.poses)


def test_the_paper_baseline_plans_unchecked():
    trial = _trial("transferring")
    baseline = drake_lfd.plan_task(trial, "paper5", PlanningOptions.paper_baseline())
    checked = drake_lfd.plan_task(trial, "paper5")
    assert baseline.planned and baseline.joint_path is None and baseline.timing == "geometric"
    assert checked.joint_path is not None
