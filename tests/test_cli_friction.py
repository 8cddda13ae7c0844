"""A new user's first hour, replayed as commands: console trial lines carry every failure
reason and describe the scene, output folders are created, every option's --help says
what it does and its default, training says when its curve never settles."""

import argparse
import contextlib
import io
import json

import numpy as np
import pytest

import drake_lfd.cli as cli
from drake_lfd.cli.app import HelpFormatter, build_parser
from drake_lfd.cli.argument_checks import prepare_output
from drake_lfd.cli.train import training_title
from drake_lfd.core.errors import InputError
from drake_lfd.experiments.simulation import (
    SUMMARY_REASON_CHARACTERS,
    TrialOutcome,
    shorten_reason,
    trial_summary_line,
)
from drake_lfd.io.library import bundled_library_names
from drake_lfd.planning.options import PlanningOptions
from drake_lfd.planning.q_learning import episodes_to_steady, never_steady

# The transferring scene (paper5's tool frame and base) with two path constraints the
# tool's orientation breaks: planned without the plan-time joint check (which now reads
# path constraints and would refuse it), a closed-loop run with two failure reasons, the
# second of which used to be dropped from the console line.
TASK_HEAD = """\
X_WB: {p: [-0.2, 0.7, 0.0], euler_zyx: [0, 0, 0]}
X_tool0_E: {p: [0, 0, 0.2], euler_zyx: [0, pi/2, 0]}
critical_configurations:
  - {p: [CON1_X, 0, 0.3], euler_zyx: [0, -pi/2, 0]}
  - {p: [-0.4, 0.2, 0.3], euler_zyx: [0, -pi/2, 0]}
  - {p: [0, 0.2, 0.3], euler_zyx: [0, -pi/2, 0]}
  - {p: [0.1, 0, 0.3], euler_zyx: [0, -pi/2, 0]}
obstacles:
  - {name: block, centre: [0.3, -0.3, 0.05], size: [0.06, 0.06, 0.06]}
safety_shells:
  - {name: box_shell, centre: [0.3, -0.3, 0.05], size: [0.1, 0.1, 0.1]}
path_constraints:
  - {kind: orientation, between: [1, 2], euler_zyx: [0, 0, 0], tolerance_deg: 10}
  - {kind: orientation, between: [3, 4], euler_zyx: [0, 0, 0], tolerance_deg: 10}
"""


def write_task(path, name, con1_x=-0.5):
    path.write_text(f"name: {name}\n" + TASK_HEAD.replace("CON1_X", repr(con1_x)))
    return path


def trial_lines(text):
    return [line for line in text.splitlines() if line.startswith("trial ")]


# ------------------------------------------------------------- 3. console trial lines


@pytest.fixture(scope="module")
def failed_trial(tmp_path_factory):
    """One trial of the shell-on-path task planned without the joint check (the plan
    breaks both path constraints) and run closed loop: (task, outcome)."""
    from drake_lfd.experiments.simulation import run_trials
    from drake_lfd.io.library import Library, library_features
    from drake_lfd.io.task_files import load_task

    root = tmp_path_factory.mktemp("friction")
    task = load_task(write_task(root / "shell_on_path.yaml", "shell_on_path"))
    (outcome,), _ = run_trials(task, library_features(Library.open("paper5")), trials=1,
                               options=PlanningOptions(joint_check=False))
    return task, outcome


@pytest.mark.slow
def test_a_failed_trial_line_carries_every_failure_reason(failed_trial):
    task, outcome = failed_trial
    failures = [str(f) for f in outcome.failures]
    assert not outcome.success and len(failures) >= 2
    kinds = [f.split(":")[0] for f in failures]
    assert "path constraint con_1..con_2" in kinds and "path constraint con_3..con_4" in kinds
    line = trial_summary_line(outcome, task)
    assert "FAILED: " in line
    for reason in failures:  # each one, whole when short enough, the JSON keeps it whole
        assert shorten_reason(reason) in line
        if len(reason) <= SUMMARY_REASON_CHARACTERS:
            assert reason in line
    assert "min distance " in line  # the clearance, in cm


def test_the_same_task_with_the_joint_check_is_refused_naming_the_constraint(tmp_path, capsys):
    task = write_task(tmp_path / "shell_on_path.yaml", "shell_on_path")
    assert cli.main(["plan", str(task), "--library", "paper5"]) == 4
    (line,) = capsys.readouterr().err.strip().splitlines()
    assert "path_constraint" in line and "path constraint con_1..con_2" in line


@pytest.mark.slow
def test_simulate_creates_its_output_folders(tmp_path):
    from drake_lfd.core.resources import scenarios_directory

    out = {"json": tmp_path / "new" / "deep" / "results.json", "html": tmp_path / "recordings" / "run.html",
           "figures": tmp_path / "figs" / "first"}
    stdout = io.StringIO()
    with contextlib.redirect_stdout(stdout):
        code = cli.main(["simulate", str(scenarios_directory() / "transferring.yaml"), "--library", "paper5",
                         "--trials", "1", "--json", str(out["json"]), "--html", str(out["html"]),
                         "--figures", str(out["figures"])])
    assert code == 0
    assert out["json"].is_file() and out["html"].is_file()
    assert sorted(p.name for p in out["figures"].iterdir()) == [
        "transferring_distance.png", "transferring_joints.png", "transferring_plan.png"]


def test_a_trial_that_did_not_run_still_describes_the_scene(tmp_path, capsys):
    # con_1 out of the UR5e's reach: no executable plan, no run.
    task = write_task(tmp_path / "out_of_reach.yaml", "out_of_reach", con1_x=-2.5)
    assert cli.main(["simulate", str(task), "--library", "paper5"]) == 4
    captured = capsys.readouterr()
    (line,) = trial_lines(captured.out)
    assert "no run (1 obstacle, 1 shell)" in line and "no obstacles" not in line
    assert "FAILED: no executable plan: con_1 -> con_2: reach: con_1 at p = [-2.5" in line and line.endswith("...")


def test_summary_line_lists_all_reasons_each_shortened():
    reasons = [f"reason {i}: " + "x" * (40 * i) for i in range(1, 6)]
    outcome = TrialOutcome(trial=3, seed=7, plan=None, run=None, success=False, failures=reasons)
    line = trial_summary_line(outcome)
    assert line.startswith("trial 3 (seed 7): no plan; no run (no obstacles); FAILED: ")
    verdict = line.split("FAILED: ", 1)[1].split("; ")
    assert len(verdict) == len(reasons)
    for shown, reason in zip(verdict, reasons):
        assert len(shown) <= SUMMARY_REASON_CHARACTERS
        assert shown == reason if len(reason) <= SUMMARY_REASON_CHARACTERS else (
            shown.endswith("...") and reason.startswith(shown[:-3]))


# --------------------------------------------------------------- 4. output folders


def test_prepare_output_creates_folders_and_refuses_files(tmp_path):
    assert prepare_output(None, "--json") is None and prepare_output("-", "--json") is None
    target = tmp_path / "a" / "b" / "out.json"
    assert prepare_output(target, "--json") == target and target.parent.is_dir() and not target.exists()
    folder = tmp_path / "c" / "d"
    assert prepare_output(folder, "--figures", folder=True) == folder and folder.is_dir()
    prepare_output(folder, "--figures", folder=True)  # an existing folder is fine
    blocker = tmp_path / "file.txt"
    blocker.write_text("x")
    for path, is_folder, words in [
        (blocker, True, "exists and is not a folder"),
        (blocker / "sub", True, "is a file"),
        (blocker / "out.json", False, "is a file"),
        (folder, False, "is a folder"),
    ]:
        with pytest.raises(InputError, match=words) as error:
            prepare_output(path, "--opt", folder=is_folder)
        assert "--opt" in str(error.value) and "\n" not in str(error.value)


@pytest.mark.parametrize("extra", [
    ["--figures", "{file}"],
    ["--figures", "{file}/sub"],
    ["--json", "{file}/sub/out.json"],
    ["--json", "{tmp}"],
    ["--html", "{file}/rec.html"],
])
def test_simulate_refuses_only_what_cannot_be_created(tmp_path, capsys, extra):
    blocker = tmp_path / "a_file"
    blocker.write_text("x")
    task = write_task(tmp_path / "shell_on_path.yaml", "shell_on_path")
    option, value = extra[0], extra[1].format(file=blocker, tmp=tmp_path)
    assert cli.main(["simulate", str(task), "--library", "paper5", option, value]) == 2
    captured = capsys.readouterr()
    assert captured.out == ""  # refused before any trial
    (line,) = captured.err.strip().splitlines()
    assert line.startswith("drake-lfd simulate: error: ") and option in line


def test_plan_and_train_create_missing_folders(tmp_path, capsys):
    plan_json = tmp_path / "plans" / "today" / "transferring.json"
    from drake_lfd.core.resources import scenarios_directory

    assert cli.main(["plan", str(scenarios_directory() / "transferring.yaml"), "--library", "paper5",
                     "--json", str(plan_json)]) == 0
    assert json.loads(plan_json.read_text())["status"] == "planned"
    policy, summary = tmp_path / "policies" / "p.json", tmp_path / "summaries" / "s.json"
    assert cli.main(["train", "--library", "paper5", "--random-tasks", "2", "--episodes", "5",
                     "--out", str(policy), "--json", str(summary)]) == 0
    assert policy.is_file() and summary.is_file() and (policy.parent / "p.curve.png").is_file()
    assert cli.main(["train", "--library", "paper5", "--episodes", "5", "--out", str(policy.parent)]) == 2
    assert "--out: is a folder" in capsys.readouterr().err


def test_paper_creates_its_folder_before_any_work(tmp_path, monkeypatch, capsys):
    import drake_lfd.experiments.paper as paper

    seen = {}

    def fake_run_paper(out, *, trials, seed, log, options):
        seen["out_is_dir"] = out.is_dir()
        seen["options"] = options
        task = {"success_count": trials}
        return {"tasks": {"transferring": task, "filling_pouring": task,
                          "assembling": {"initial_status": "demonstration_requested", "after_new_demo": task}},
                "wall_time_s": 0.0}

    monkeypatch.setattr(paper, "run_paper", fake_run_paper)
    out = tmp_path / "runs" / "paper"
    assert cli.main(["paper", "--out", str(out), "--trials", "1"]) == 0
    assert seen == {"out_is_dir": True, "options": paper.PAPER_OPTIONS}
    assert paper.PAPER_OPTIONS == PlanningOptions(planner="q", cost="paper", joint_check=True, refine=False)
    blocker = tmp_path / "a_file"
    blocker.write_text("x")
    assert cli.main(["paper", "--out", str(blocker / "paper")]) == 2
    assert "is a file" in capsys.readouterr().err


# -------------------------------------------------------------------- 5. help texts


def _parsers(parser, name="drake-lfd"):
    yield name, parser
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            listed = {choice.dest: choice.help for choice in action._choices_actions}
            for command, subparser in action.choices.items():
                assert listed.get(command), f"{name} {command} has no help line in {name} --help"
                yield from _parsers(subparser, f"{name} {command}")


def test_every_option_of_every_command_has_help_and_shows_its_default():
    parsers = dict(_parsers(build_parser()))
    assert {"drake-lfd train", "drake-lfd plan", "drake-lfd simulate", "drake-lfd paper",
            "drake-lfd library show"} <= set(parsers)
    for name, parser in parsers.items():
        assert parser.formatter_class is HelpFormatter, name
        formatter = parser._get_formatter()
        full_help = "".join(parser.format_help().split())  # wrapping may break after hyphens
        for action in parser._actions:
            if isinstance(action, (argparse._HelpAction, argparse._SubParsersAction)):
                continue
            label = f"{name} {'/'.join(action.option_strings) or action.dest}"
            assert action.help and action.help.strip(), f"{label} has no help text"
            text = formatter._expand_help(action)
            assert "".join(text.split()) in full_help, label
            if action.option_strings and action.default not in (None, False, "", argparse.SUPPRESS):
                assert str(action.default) in text, f"{label} does not show its default {action.default!r}"


def test_library_options_name_the_bundled_libraries():
    names = bundled_library_names()
    assert names  # paper5, paper6
    parsers = dict(_parsers(build_parser()))
    for name in ("drake-lfd train", "drake-lfd plan", "drake-lfd simulate"):
        (action,) = [a for a in parsers[name]._actions if "--library" in a.option_strings]
        assert all(n in action.help for n in names), name
    (show_lib,) = [a for a in parsers["drake-lfd library show"]._actions if a.dest == "library"]
    assert all(n in show_lib.help for n in names)


def test_help_shows_the_defaults_the_readme_used_to_require(capsys):
    for command, options in [("paper", ["--out DIR", "--trials N", "--seed S"]),
                             ("simulate", ["--trials N", "--seed S", "--library LIB"]),
                             ("train", ["--random-tasks N", "--episodes E", "--seed S"])]:
        with pytest.raises(SystemExit):
            cli.main([command, "--help"])
        text = " ".join(capsys.readouterr().out.split())
        assert "(default: " in text
        usage = text.split("positional arguments")[0].split("options:")[0]
        for option in options:
            if option == "--library LIB":
                assert option in usage and f"[{option}]" not in usage  # required
            else:
                assert f"[{option}]" in usage, (command, option)


# ------------------------------------------------------------------ training steadiness


def test_never_steady_is_the_last_episode_outside_the_band():
    settles = np.concatenate([np.linspace(-10, -1, 40), np.full(60, -1.0)])
    assert not never_steady(settles) and episodes_to_steady(settles) == 38
    flat = np.full(100, -2.0)
    assert not never_steady(flat) and not never_steady([])
    alternating = np.tile([-4.9295, -4.9286], 50)  # the warm-started curve below, in miniature
    assert never_steady(alternating) and episodes_to_steady(alternating) == 100
    still_moving = np.concatenate([np.full(50, -10.0), np.linspace(-10, -1, 50)])
    assert never_steady(still_moving)


def test_training_titles_describe_the_run():
    assert training_title(20, 0, "mylib") == "Q-learning on 20 random tasks, library mylib"
    assert training_title(20, 5, "paper5", warm_start=True) == (
        "Q-learning on 20 random + 5 chained tasks, library paper5, warm start")
    assert training_title(0, 1, "lib") == "Q-learning on 1 chained task, library lib"


def test_train_says_when_the_curve_never_settles(tmp_path, capsys, monkeypatch):
    import drake_lfd.experiments.figures as figures

    titles = []
    original = figures.training_curve_figure

    def spy(path, curve, **options):
        titles.append((options.get("title"), options.get("steady_episode")))
        return original(path, curve, **options)

    monkeypatch.setattr(figures, "training_curve_figure", spy)
    first = tmp_path / "first.json"
    assert cli.main(["train", "--library", "paper5", "--chained-tasks", "20", "--out", str(first)]) == 0
    capsys.readouterr()
    # Warm-started from its own policy, the greedy curve only alternates between two values
    # 0.0009 apart: it never settles, where it used to print "steady after 100 episodes".
    summary_path = tmp_path / "again.summary.json"
    assert cli.main(["train", "--library", "paper5", "--chained-tasks", "20", "--warm-start", str(first),
                     "--out", str(tmp_path / "again.json"), "--json", str(summary_path)]) == 0
    out = capsys.readouterr().out
    summary = json.loads(summary_path.read_text())
    assert never_steady(summary["curve"])
    assert summary["episodes_to_steady"] is None
    assert "not steady within 100 episodes" in out and "steady after" not in out
    (first_title, first_steady), (again_title, again_steady) = titles
    assert first_title == "Q-learning on 20 random + 20 chained tasks, library paper5"
    assert again_title == "Q-learning on 20 random + 20 chained tasks, library paper5, warm start"
    assert isinstance(first_steady, int) and again_steady is None  # no "steady from" line
