"""Finished trials are on disk as they finish: an interrupt keeps what ran.

``simulate --json OUT.json`` appends each finished trial to ``OUT.jsonl`` (flushed and
fsynced); ``paper --out DIR`` to ``DIR/trials.jsonl``. SIGINT once two of twenty trials are
on disk leaves exactly the trials that finished (two, or a few more that finished before the
signal arrived: a trial takes about 0.2 s), in order and whole; the command says how many,
and ends with one line, exit 1.
"""

import os
import signal
import subprocess

import pytest

from cli_subprocess import cli_command, cli_env, stderr_lines
from helpers import line_count, wait_until
from drake_lfd.core.resources import scenarios_directory
from drake_lfd.io.json_lines import JsonLinesFile, json_lines_path_for, read_json_lines


@pytest.mark.slow
def test_sigint_after_the_second_trial_keeps_the_finished_ones_on_disk(tmp_path):
    trials = 20
    out = tmp_path / "results" / "out.json"
    lines_path = tmp_path / "results" / "out.jsonl"
    process = subprocess.Popen(
        cli_command("simulate", scenarios_directory() / "transferring.yaml", "--library", "paper5",
                    "--trials", trials, "--json", out),
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=cli_env())
    wait_until(lambda: line_count(lines_path) >= 2, timeout_s=240, while_running=process, interval_s=0.01)
    assert process.poll() is None, "the run ended before its second trial was on disk"
    process.send_signal(signal.SIGINT)
    stdout, stderr = process.communicate(timeout=60)
    assert process.returncode == 1
    assert "Traceback" not in stderr and stderr_lines(stderr) == ["drake-lfd simulate: interrupted"]
    records = read_json_lines(lines_path)
    kept = len(records)
    assert 2 <= kept < trials  # what finished before the signal, not one trial more or fewer
    # In trial order; on two workers (the default) a later trial may have finished while
    # an earlier one still ran, and an interrupt keeps it too: ascending, not always 1..kept.
    numbers = [r["trial"] for r in records]
    assert numbers[:2] == [1, 2] and numbers == sorted(set(numbers))
    assert [r["seed"] for r in records] == [n - 1 for n in numbers]
    for record in records:  # each line is a whole trial, as in the final JSON's "trials"
        assert record["task"] == "transferring" and len(record["t"]) == len(record["q"]) > 100
        assert {"success", "failures", "composition", "critical_errors"} <= set(record)
    assert not out.exists()  # the final document is written only when every trial ran
    assert f"{kept} finished trial(s) of {trials} are in {lines_path}" in stdout
    assert [line.split(" (")[0] for line in stdout.splitlines() if line.startswith("trial ")] == [
        f"trial {n}" for n in numbers]


def test_json_lines_are_strict_whole_and_beside_the_json(tmp_path):
    assert json_lines_path_for(tmp_path / "out.json") == tmp_path / "out.jsonl"
    assert json_lines_path_for(tmp_path / "results") == tmp_path / "results.jsonl"
    path = tmp_path / "trials.jsonl"
    path.write_text("left from an earlier run\n")
    with JsonLinesFile(path) as lines:
        lines.append({"trial": 1, "min_shell_distance_m": float("inf")})
        assert read_json_lines(path) == [{"trial": 1, "min_shell_distance_m": None}]  # on disk already
        lines.append({"trial": 2, "x": float("nan")})
    text = path.read_text()
    assert "NaN" not in text and "Infinity" not in text and text.count("\n") == 2
    with open(path, "a") as file:  # a last line cut by a power loss is skipped
        file.write('{"trial": 3, "t"')
    assert [r["trial"] for r in read_json_lines(path)] == [1, 2]
    os.remove(path)


@pytest.mark.slow
def test_a_trial_printed_as_finished_is_on_disk_when_the_interrupt_comes_during_its_write(tmp_path, monkeypatch,
                                                                                         capsys):
    """Ctrl-C while the second trial's record is being written: the lines printed on the
    way out are those of the trials on disk, not one more."""
    import drake_lfd.cli.simulate as simulate_module
    from drake_lfd.cli import main

    out = tmp_path / "run.json"
    original = JsonLinesFile.append
    calls = []

    def interrupted(self, record):
        calls.append(record)
        if len(calls) == 2:
            raise KeyboardInterrupt
        return original(self, record)

    monkeypatch.setattr(simulate_module.JsonLinesFile, "append", interrupted)
    status = main(["simulate", str(scenarios_directory() / "transferring.yaml"), "--library", "paper5",
                   "--trials", "3", "--json", str(out)])
    captured = capsys.readouterr()
    assert status == 1 and captured.err.splitlines()[-1] == "drake-lfd simulate: interrupted"
    printed = [line for line in captured.out.splitlines() if line.startswith("trial ")]
    on_disk = read_json_lines(json_lines_path_for(out))
    # Trials run on parallel workers (one per core): which ones finish before the
    # interrupt varies from run to run, and on the way out every trial that finished is
    # still delivered (written, then printed). Whatever ran, the trials printed are the
    # trials on disk, and the one whose write was interrupted is neither.
    printed_trials = [int(line.split(" (")[0].split()[1]) for line in printed]
    assert on_disk and printed_trials == [record["trial"] for record in on_disk]
    assert calls[1]["trial"] not in printed_trials
