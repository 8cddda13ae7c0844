"""Quiet batch jobs: recordings make Meshcat without its listening line; simulate's trial
line says whether ``--refine`` refined the trial's plan, or why not."""

from __future__ import annotations

import logging
from pathlib import Path

import pytest

from cli_subprocess import run_cli
from drake_lfd.core.resources import scenarios_directory
from drake_lfd.diagrams import recording_meshcat as mut


def listening_records(caplog):
    return [r for r in caplog.records if "listening for connections" in r.getMessage()]


def test_a_recording_meshcat_does_not_announce_a_viewer(caplog):
    from pydrake.geometry import Meshcat

    caplog.set_level(logging.INFO, logger="drake")
    live = Meshcat()  # the live viewer keeps Drake's line
    assert len(listening_records(caplog)) == 1
    caplog.clear()
    quiet = mut.recording_meshcat()
    assert listening_records(caplog) == []
    assert quiet.web_url() != live.web_url()  # a server of its own, as before
    assert logging.getLogger("drake").getEffectiveLevel() <= logging.INFO  # the level is restored


@pytest.mark.slow
def test_simulate_with_a_recording_prints_no_listening_line_and_says_refined(tmp_path):
    html = tmp_path / "rec.html"
    status, out, err, _, _ = run_cli("simulate", scenarios_directory() / "transferring.yaml", "--library", "paper5",
                                     "--trials", "2", "--workers", "1", "--refine", "--html", html, timeout=300)
    assert status == 0, err
    assert "listening for connections" not in out + err
    assert html.stat().st_size > 100_000 and b"<html" in html.read_bytes()[:2000].lower()
    lines = [line for line in out.splitlines() if line.startswith("trial ")]
    assert len(lines) == 2
    for line in lines:
        verdict = line.split("; ")[1]
        assert verdict == "refined" or verdict.startswith("not refined: "), line


def test_the_trial_line_says_why_a_plan_was_not_refined():
    import types

    from drake_lfd.experiments.simulation import TrialOutcome, trial_summary_line

    def outcome(refinement):
        plan = types.SimpleNamespace(planned=True, composition=(types.SimpleNamespace(demo="stacking"),),
                                     refinement=refinement, task=None)
        return TrialOutcome(trial=1, seed=0, plan=plan, run=None, success=False, failures=["x"])

    refined = types.SimpleNamespace(refined=True, reason="")
    failed = types.SimpleNamespace(refined=False, reason="optimizer: time budget spent (SNOPT stopped)")
    assert trial_summary_line(outcome(refined)).startswith("trial 1 (seed 0): stacking; refined; ")
    assert trial_summary_line(outcome(failed)).startswith(
        "trial 1 (seed 0): stacking; not refined: optimizer: time budget spent (SNOPT stopped); ")
    assert "refined" not in trial_summary_line(outcome(None))
