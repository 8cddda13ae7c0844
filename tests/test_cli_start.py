"""The command line answers before it loads Drake.

``drake-lfd --version``, every ``--help``, a bad flag and every error a task file's text
holds (a missing file, invalid YAML, a typo'd key, a value of the wrong kind or out of
range: NaN, a bound's lower above its upper, a negative clearance), and a people file's
for ``simulate --people``, are answered by plain Python: pydrake (and numpy) are
imported only once a command's input has been checked and the command really runs. Each case runs ``drake-lfd`` in a fresh interpreter and
reads ``sys.modules`` as the command ends: what was imported, not how long it took.
The same messages and exit codes as after a full load (docs/cli.rst, Exit codes).
"""

import json
import subprocess
import sys

import pytest

from cli_subprocess import cli_env

# Runs the command line in this interpreter and prints, last, a JSON line with the exit
# status and whether pydrake and numpy were imported.
_PROBE = """
import json, sys
from drake_lfd.cli import main
try:
    status = main(sys.argv[1:])
except SystemExit as end:
    status = end.code
print(json.dumps({"status": status, "pydrake": "pydrake" in sys.modules, "numpy": "numpy" in sys.modules}))
"""


def _probe(*args, cwd=None):
    process = subprocess.run([sys.executable, "-c", _PROBE, *map(str, args)], capture_output=True, text=True,
                             env=cli_env(), cwd=cwd, timeout=120)
    loaded = json.loads(process.stdout.strip().splitlines()[-1])
    return loaded, process.stderr


def _typo_task(tmp_path, scenarios):
    text = (scenarios / "transferring.yaml").read_text()
    assert "\nangle_grid_deg:" in text or "critical_configurations:" in text
    path = tmp_path / "typo.yaml"
    path.write_text(text.replace("critical_configurations:", "critical_configuration:", 1))
    return path


@pytest.fixture
def scenarios():
    from drake_lfd.core.resources import scenarios_directory

    return scenarios_directory()


@pytest.mark.parametrize("args", [
    ["--version"],
    ["--help"],
    ["plan", "--help"],
    ["simulate", "--help"],
    ["sweep", "--help"],
    ["train", "--help"],
    ["library", "add", "--help"],
    ["export", "--help"],
    ["record", "--help"],
], ids=" ".join)
def test_version_and_help_do_not_import_drake(args):
    loaded, _ = _probe(*args)
    assert loaded == {"status": 0, "pydrake": False, "numpy": False}


@pytest.mark.parametrize("command", ["plan", "simulate"])
def test_a_typo_d_task_key_is_refused_before_drake_loads(tmp_path, scenarios, command):
    task = _typo_task(tmp_path, scenarios)
    loaded, err = _probe(command, task, "--library", "paper5")
    assert loaded == {"status": 2, "pydrake": False, "numpy": False}
    assert err.splitlines() == [
        f"drake-lfd {command}: error: {task}: critical_configuration: unknown key 'critical_configuration' "
        "(allowed: name, description, X_WB, X_tool0_E, angle_grid_deg, variables, critical_configurations, "
        "obstacles, safety_shells, path_constraints, simulation, timing, refinement, tool, people, collaboration)"]


def test_a_missing_task_file_and_a_bad_flag_are_refused_before_drake_loads(tmp_path, scenarios):
    loaded, err = _probe("plan", "missing.yaml", "--library", "paper5", cwd=tmp_path)
    assert loaded == {"status": 2, "pydrake": False, "numpy": False}
    assert err.splitlines() == ["drake-lfd plan: error: missing.yaml: no such file"]
    loaded, err = _probe("plan", scenarios / "transferring.yaml", "--library", "paper5", "--planner", "exakt")
    assert loaded == {"status": 2, "pydrake": False, "numpy": False}
    assert "argument --planner: invalid choice: 'exakt'" in err


def test_the_structure_check_and_the_loader_refuse_alike(tmp_path, scenarios):
    """The early check is the loader's own first half: the same message either way."""
    from drake_lfd.core.errors import InputError
    from drake_lfd.io.task_files import load_task
    from drake_lfd.io.task_schema import check_task_file

    task = _typo_task(tmp_path, scenarios)
    with pytest.raises(InputError) as early:
        check_task_file(task)
    with pytest.raises(InputError) as loaded:
        load_task(task)
    assert str(early.value) == str(loaded.value)
    check_task_file(scenarios / "transferring.yaml")  # a good file passes


def _loading_refusal(command, path):
    """The line ``drake-lfd COMMAND`` prints when loading ``path`` refuses it."""
    from drake_lfd.core.errors import InputError
    from drake_lfd.io.task_files import load_task

    with pytest.raises(InputError) as refusal:
        load_task(path)
    return f"drake-lfd {command}: error: {refusal.value}"


@pytest.mark.parametrize(("command", "old", "new"), [
    ("plan", "- {p: [-0.5, 0, 0.3]", "- {p: [-0.5, .nan, 0.3]"),
    ("plan", "- {p: [-0.4, 0.2, z], euler_zyx: [0, -pi/2, 0]}", "- {p: [-0.4, 0.2, z], euler_zyx: [0, -pi/2, [1, -1]]}"),
    ("simulate", "tool: []", "tool: []\nsimulation: {joint_check: {clearance_m: -0.01}}"),
    ("sweep", "tool: []", "tool: []\ntiming: {limit_fraction: 0}"),
], ids=["nan-coordinate", "angle-bound-lower-above-upper", "negative-clearance", "timing"])
def test_a_value_out_of_range_is_refused_before_drake_loads(tmp_path, scenarios, command, old, new):
    text = (scenarios / "transferring.yaml").read_text()
    assert old in text
    task = tmp_path / "task.yaml"
    task.write_text(text.replace(old, new, 1))
    extra = ["--out", tmp_path / "sweep"] if command == "sweep" else []
    loaded, err = _probe(command, task, "--library", "paper5", *extra)
    assert loaded == {"status": 2, "pydrake": False, "numpy": False}
    assert err.splitlines() == [_loading_refusal(command, task)]


def test_a_malformed_people_file_is_refused_before_drake_loads(tmp_path, scenarios):
    from drake_lfd.core.errors import InputError
    from drake_lfd.io.people_files import load_people_file

    people = tmp_path / "people.yaml"
    for text in ("people: [{name: a, path: [{t: 1, xy: [0, 0]}, {t: 0.5, xy: [0, 1]}]}]\n",  # time runs back
                 "people: [{name: a, path: [{t: 0, xy: [0, 0]}], speed: 2}]\n",  # a typo'd key
                 "collaboration: {intrusion_distance_m: -0.1}\n"):
        people.write_text(text)
        with pytest.raises(InputError) as refusal:
            load_people_file(people)
        loaded, err = _probe("simulate", scenarios / "transferring.yaml", "--library", "paper5", "--people", people)
        assert loaded == {"status": 2, "pydrake": False, "numpy": False}
        assert err.splitlines() == [f"drake-lfd simulate: error: {refusal.value}"]


@pytest.mark.slow
def test_a_valid_task_still_loads_drake_when_the_command_runs(scenarios):
    loaded, _ = _probe("plan", scenarios / "assembling.yaml", "--library", "paper5")
    assert loaded["pydrake"] and loaded["status"] == 3  # the paper's demonstration request
