"""Drake's network switch: ``DRAKE_ALLOW_NETWORK=none`` with an empty download cache.

Drake 1.51 refuses to construct any Parser while downloads are disabled and its remote
``drake_models`` package is not cached (every command used to die with a 41-line
traceback). drake-lfd never needs ``drake_models``: the commands work, and nothing is
downloaded or cached. A Meshcat recording needs Meshcat, which the switch disables too:
``--html`` and ``show-model`` are refused with one line saying what to set.
"""

import pytest

from cli_subprocess import run_cli, stderr_lines
from drake_lfd.core.network_policy import drake_allows, meshcat_refusal
from drake_lfd.core.resources import scenarios_directory

TRANSFERRING = scenarios_directory() / "transferring.yaml"


@pytest.fixture
def no_network(tmp_path):
    """DRAKE_ALLOW_NETWORK=none, and a HOME and cache without any Drake download."""
    home = tmp_path / "home"
    (home / ".cache").mkdir(parents=True)
    return {"DRAKE_ALLOW_NETWORK": "none", "HOME": str(home), "XDG_CACHE_HOME": str(home / ".cache")}, home


@pytest.mark.slow
def test_plan_and_simulate_work_without_network_and_download_nothing(tmp_path, no_network):
    env, home = no_network
    status, out, err, _, _ = run_cli("plan", TRANSFERRING, "--library", "paper5", env=env)
    assert status == 0, err
    assert "planned with" in out and "Traceback" not in err
    # simulate builds the station: the UR5e model is parsed (a Drake Parser) without network
    status, out, err, _, _ = run_cli("simulate", TRANSFERRING, "--library", "paper5", "--json",
                                     tmp_path / "s.json", env=env)
    assert status == 0, err
    assert "/1 trials succeeded" in out
    assert (tmp_path / "s.jsonl").exists() and (tmp_path / "s.json").exists()
    assert not (home / ".cache" / "drake" / "package_map").exists() or not any(
        (home / ".cache" / "drake" / "package_map").iterdir())


def test_meshcat_recordings_are_refused_with_one_line_when_meshcat_is_disabled(tmp_path, no_network):
    env, _ = no_network
    status, out, err, seconds, _ = run_cli("simulate", TRANSFERRING, "--library", "paper5", "--html",
                                           tmp_path / "rec.html", env=env)
    assert status == 2 and "Traceback" not in err
    (line,) = stderr_lines(err)
    assert "--html" in line and "DRAKE_ALLOW_NETWORK=none" in line and "DRAKE_ALLOW_NETWORK=meshcat" in line
    assert out == "" and not (tmp_path / "rec.html").exists()  # refused before any trial
    status, _, err, _, _ = run_cli("show-model", "--out", tmp_path / "m.html",
                                   env={**env, "DRAKE_ALLOW_NETWORK": "package_map"})
    assert status == 2 and len(stderr_lines(err)) == 1 and "DRAKE_ALLOW_NETWORK=package_map" in err


def test_the_switch_is_read_as_drake_reads_it():
    assert drake_allows("meshcat", {}) and drake_allows("meshcat", {"DRAKE_ALLOW_NETWORK": ""})
    assert not drake_allows("package_map", {"DRAKE_ALLOW_NETWORK": "none"})
    assert drake_allows("meshcat", {"DRAKE_ALLOW_NETWORK": "package_map:meshcat"})
    assert not drake_allows("meshcat", {"DRAKE_ALLOW_NETWORK": "package_map"})
    assert meshcat_refusal("--html", environ={"DRAKE_ALLOW_NETWORK": "meshcat"}) is None
