"""Finished trials are on disk as they finish: an interrupt keeps what ran.

``simulate --json OUT.json`` appends each finished trial to ``OUT.jsonl`` (flushed and
fsynced); ``paper --out DIR`` to ``DIR/trials.jsonl``. SIGINT after the 2nd of 5 trials
leaves exactly those 2 trials on disk, and the command ends with one line, exit 1.
"""

import os
import signal
import subprocess
import time

from cli_subprocess import cli_command, cli_env, stderr_lines
from drake_lfd.core.resources import scenarios_directory
from drake_lfd.io.json_lines import JsonLinesFile, json_lines_path_for, read_json_lines


def finished_lines(path):
    return path.read_text().count("\n") if path.exists() else 0


def test_sigint_after_the_second_of_five_trials_keeps_the_two_on_disk(tmp_path):
    out = tmp_path / "results" / "out.json"
    lines_path = tmp_path / "results" / "out.jsonl"
    process = subprocess.Popen(
        cli_command("simulate", scenarios_directory() / "transferring.yaml", "--library", "paper5",
                    "--trials", 5, "--json", out),
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=cli_env())
    deadline = time.monotonic() + 90
    while finished_lines(lines_path) < 2 and process.poll() is None and time.monotonic() < deadline:
        time.sleep(0.01)
    assert process.poll() is None, "the run ended before its second trial was on disk"
    process.send_signal(signal.SIGINT)  # a trial takes about 2 s: this is during the third
    stdout, stderr = process.communicate(timeout=60)
    assert process.returncode == 1
    assert "Traceback" not in stderr and stderr_lines(stderr) == ["drake-lfd simulate: interrupted"]
    records = read_json_lines(lines_path)
    assert [r["trial"] for r in records] == [1, 2] and [r["seed"] for r in records] == [0, 1]
    for record in records:  # each line is a whole trial, as in the final JSON's "trials"
        assert record["task"] == "transferring" and len(record["t"]) == len(record["q"]) > 100
        assert {"success", "failures", "composition", "critical_errors"} <= set(record)
    assert not out.exists()  # the final document is written only when every trial ran
    assert f"2 finished trial(s) of 5 are in {lines_path}" in stdout
    assert [line.split(" (")[0] for line in stdout.splitlines() if line.startswith("trial ")] == [
        "trial 1", "trial 2"]


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
