"""Fuzzed task files and joint logs through the real command line (a seeded sample).

``benchmarks/fuzz_inputs.py`` with fewer cases (150 task files, 60 logs, seed 0, two
worker processes each running ``drake_lfd.cli.main`` in-process, a 60 s watchdog per
case): no traceback, every exit code in {0, 2, 3, 4}, no hang, every refusal one stderr
line naming the file (and the field the mutation changed, where it knows one), no NaN
or Infinity in any JSON written, a library byte-identical after a refused ``library
add``, peak memory under 1 GB. Then the regressions the full-size run found, one test
each, and the generator's own promises (seeded, every mutation class in a small sample).
"""

import importlib.util
from pathlib import Path

import pytest

from drake_lfd.core.errors import InputError
from drake_lfd.core.tasks import angle_grid_count
from fuzzing import (  # tests/fuzzing.py, the generators
    LOG_MUTATIONS,
    TASK_MUTATIONS,
    log_cases,
    non_finite_json_tokens,
    task_cases,
)
from drake_lfd.io.task_files import MAX_CRITICAL_CONFIGURATIONS, task_spec_from_text, task_from_spec
from drake_lfd.io.yaml_checks import MAX_YAML_FILE_BYTES, read_text

ROOT = Path(__file__).resolve().parent.parent
SIMS = ROOT / "sims"


def _benchmark():
    spec = importlib.util.spec_from_file_location("fuzz_inputs", ROOT / "benchmarks" / "fuzz_inputs.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.mark.slow
def test_a_seeded_sample_of_fuzzed_inputs_never_gives_a_traceback():
    fuzz = _benchmark()
    cases = list(task_cases(150, seed=0)) + list(log_cases(60, seed=0))
    report = fuzz.run_cases(cases, workers=2, timeout=60.0)
    assert report["cases"] == 210
    assert report["problems"] == {}, {kind: items[:3] for kind, items in report["problems"].items()}
    assert report["peak_memory_bytes"] < 2**30
    codes = {code for per_class in report["codes"].values() for code in per_class}
    assert codes <= {"0", "2", "3", "4"}
    assert {"0", "2"} <= codes  # the sample holds accepted inputs, not only refusals


def test_the_generator_is_seeded_and_covers_every_class():
    first = [(case.mutation, case.data) for case in task_cases(60, seed=3)]
    assert first == [(case.mutation, case.data) for case in task_cases(60, seed=3)]
    assert first != [(case.mutation, case.data) for case in task_cases(60, seed=4)]
    assert {case.mutation.split("+")[0] for case in task_cases(len(TASK_MUTATIONS), seed=0)} == set(TASK_MUTATIONS)
    logs = list(log_cases(len(LOG_MUTATIONS), seed=0))
    assert {case.mutation.split("+")[0] for case in logs} == set(LOG_MUTATIONS)
    assert [case.data for case in logs] == [case.data for case in log_cases(len(LOG_MUTATIONS), seed=0)]


def test_non_finite_json_tokens_are_counted():
    assert non_finite_json_tokens('{"a": [NaN, Infinity, -Infinity, "NaN"]}') == 3
    assert non_finite_json_tokens('{"a": null}') == 0
    assert non_finite_json_tokens("{") == -1


def test_the_harness_sees_a_library_changed_by_a_refusal(tmp_path):
    fuzz = _benchmark()
    (tmp_path / "demos").mkdir()
    (tmp_path / "library.json").write_text("{}")
    before = fuzz.library_snapshot(tmp_path)
    (tmp_path / "demos" / "x.csv").write_text("debris")
    assert fuzz.library_snapshot(tmp_path) != before
    assert fuzz.library_snapshot(tmp_path / "missing") is None


# -------------------------------------------------- regressions found by the fuzz run

def _task(text, tmp_path):
    path = tmp_path / "task.yaml"
    path.write_text(text)
    return path


BASE = (
    "name: t\nX_tool0_E: {p: [0, 0, 0.2], euler_zyx: [0, pi/2, 0]}\ncritical_configurations:\n"
    "  - {p: [-0.5, 0, 0.3], euler_zyx: [0, -pi/2, 0]}\n  - {p: [0.1, 0.2, 0.3], euler_zyx: [0, -pi/2, VALUE]}\n"
)


def _refusal(text, tmp_path):
    with pytest.raises(InputError) as caught:
        path = _task(text, tmp_path)
        task_from_spec(task_spec_from_text(read_text(path), file=path), file=path)
    message = str(caught.value)
    assert "\n" not in message and str(tmp_path / "task.yaml") in message
    return message


@pytest.mark.parametrize("tagged", ["!!map [1, 2]", "!!bool maybe", "!!float", "!!set [a]", "!!timestamp yesterday"])
def test_yaml_tags_that_pyyaml_builds_lazily_or_with_lookups_are_one_line(tmp_path, tagged):
    # Were internal errors: TypeError (a !!map on a list), KeyError ('maybe'), IndexError (''),
    # AttributeError (a timestamp that is none).
    assert "not valid YAML" in _refusal(BASE.replace("VALUE", tagged), tmp_path)


@pytest.mark.parametrize("number", ["0_5", "1_000", "0x10", "05", "1:30", "1_0.5"])
def test_numbers_only_yaml_1_1_spells_are_refused(tmp_path, number):
    # 0_5 was read as the integer 5, 1:30 as 90, 0x10 as 16.
    assert "decimal digits" in _refusal(BASE.replace("VALUE", number), tmp_path)


@pytest.mark.parametrize("number", ["'0_5'", "'٠.٥'", "'０.5'", "'-pi/٢'", "'٩0deg'"])
def test_python_only_number_spellings_are_refused_in_task_files(tmp_path, number):
    # Python's float() reads all of these as numbers; they were accepted as 0.5, ...
    assert "critical_configurations[1].euler_zyx[2]" in _refusal(BASE.replace("VALUE", number), tmp_path)


def test_an_integer_too_large_for_a_float_is_one_line(tmp_path):
    # Was OverflowError: int too large to convert to float.
    message = _refusal(BASE.replace("VALUE", "9" * 400), tmp_path)
    assert "critical_configurations[1].euler_zyx[2]" in message and "too large" in message


@pytest.mark.parametrize("grid", ["5e-324", "1e-300", "0.0001"])
def test_an_angle_grid_finer_than_the_minimum_is_refused(tmp_path, grid):
    # 5e-324 deg is 0 rad: was ZeroDivisionError in the candidate count.
    text = BASE.replace("VALUE", "[-pi, pi]") + f"angle_grid_deg: {grid}\n"
    assert "angle_grid_deg" in _refusal(text, tmp_path)


def test_angle_counts_of_bounds_near_the_float_limit_are_exact():
    assert angle_grid_count(-1e308, 1e308, 1.0) == 2 * int(1e308) + 1  # exact, where span / step is inf
    with pytest.raises(ValueError):
        angle_grid_count(0.0, 1.0, 0.0)


def test_too_many_critical_configurations_are_refused_before_planning(tmp_path):
    # 200 configurations planned for minutes (a hang in the fuzz run), 3000 took 26 s to refuse.
    con = "  - {p: [-0.5, 0, 0.3], euler_zyx: [0, -pi/2, 0]}\n"
    text = BASE.replace("VALUE", "0") + con * (MAX_CRITICAL_CONFIGURATIONS - 1)
    message = _refusal(text, tmp_path)
    assert f"at most {MAX_CRITICAL_CONFIGURATIONS}" in message and "critical_configurations" in message


def test_a_yaml_file_larger_than_the_limit_is_refused_unread(tmp_path):
    path = tmp_path / "task.yaml"
    path.write_text("name: t\n" + "# padding\n" * (MAX_YAML_FILE_BYTES // 10 + 1))
    with pytest.raises(InputError, match="larger than 1 MiB"):
        read_text(path)


def test_a_bound_near_the_float_limit_is_one_line_from_the_size_check(tmp_path, capsys):
    # Was OverflowError: int too large to convert to float, in the size check's message.
    from drake_lfd.cli import main

    path = _task(BASE.replace("VALUE", "[-1e300, 1e300]"), tmp_path)
    assert main(["plan", str(path), "--library", "paper5"]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and str(path) in lines[0] and "critical_configurations[1].euler_zyx" in lines[0]


def test_a_control_character_is_one_line_naming_where(tmp_path):
    # PyYAML's reader error was two lines ('  in "<unicode string>", position 0').
    message = _refusal("name: x\x11\n", tmp_path)
    assert "character 8" in message and "U+0011" in message


def test_an_integer_too_large_for_a_float_in_a_float_field_names_the_field(tmp_path):
    # Was "cannot load: int too large to convert to float" from the typed loader, no field.
    text = BASE.replace("VALUE", "0") + "safety_shells:\n  - {name: s, centre: [0, 0, " + "9" * 400 + "], size: [1, 1, 1]}\n"
    assert "safety_shells[0].centre[2]" in _refusal(text, tmp_path)


def test_an_input_error_over_several_lines_is_printed_as_one(capsys, monkeypatch):
    from drake_lfd.cli import app
    from drake_lfd.cli import library as library_command

    def refuse(args):
        raise InputError("first line\nsecond line", file="f.csv")

    monkeypatch.setattr(library_command, "run_show", refuse)
    assert app.main(["library", "show", "paper5"]) == 2
    assert capsys.readouterr().err == "drake-lfd library: error: f.csv: first line second line\n"
