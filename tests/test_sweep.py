"""``drake-lfd sweep`` and ``--workers``: trials on dask worker processes give the rows a
single process gives, an interrupted sweep resumes to the same table, and bad arguments
are refused with one line.

Base placements used: the transferring task's own base (-0.2, 0.7) succeeds; at
(-0.1, 0.7) con_1 is out of reach, so those trials fail fast at planning time.
"""

import json
import signal
import subprocess
import sys

import pytest

from cli_subprocess import cli_command, cli_env, stderr_lines
from helpers import line_count, wait_until
from drake_lfd import cli
from drake_lfd.cli.app import build_parser
from drake_lfd.core.resources import scenarios_directory
from drake_lfd.experiments.parallel_trials import trial_cluster
from drake_lfd.experiments.sweep import parse_axis, row_key
from drake_lfd.io.json_lines import read_json_lines
from drake_lfd.planning.options import PlanningOptions

TRANSFERRING = scenarios_directory() / "transferring.yaml"
PNG_MAGIC = b"\x89PNG\r\n\x1a\n"
INPUTS = {"task", "library", "options", "policy", "base_x", "base_y", "base_z", "base_yaw_deg", "variables",
          "trial", "seed"}
TRIAL_FIELDS = {"success", "failures", "status", "critical_configurations", "composition", "critical_errors",
                "min_shell_distance_m", "max_joint_speed_fraction", "t", "q"}


def deterministic(value):
    """``value`` without wall-clock fields (they differ between runs)."""
    if isinstance(value, dict):
        return {k: deterministic(v) for k, v in value.items() if "wall" not in k}
    if isinstance(value, list):
        return [deterministic(v) for v in value]
    return value


def sweep_args(out, *extra):
    return ["sweep", str(TRANSFERRING), "--library", "paper5", "--out", str(out), *map(str, extra)]


def table(out):
    return sorted((deterministic(row) for row in read_json_lines(out / "sweep.jsonl")), key=row_key)


@pytest.mark.slow
def test_a_sweep_on_two_workers_writes_the_rows_and_figures_of_one_process(tmp_path, capsys):
    grid = ["--base-grid", "-0.2:-0.1:2", "0.7:0.7:1", "--trials", 2]
    parallel, sequential = tmp_path / "two", tmp_path / "one"
    assert cli.main(sweep_args(parallel, *grid, "--workers", 2)) == 0
    assert cli.main(sweep_args(sequential, *grid, "--workers", 1)) == 0
    out = capsys.readouterr().out
    assert "4 trials; 4 to run on 2 worker(s)" in out and "4 trials; 4 to run on 1 worker(s)" in out
    rows = read_json_lines(parallel / "sweep.jsonl")
    assert len(rows) == 4
    for row in rows:
        assert INPUTS | TRIAL_FIELDS <= set(row)
        assert row["options"]["planner"] == "exact" and row["base_y"] == 0.7 and row["base_z"] == 0.0
        assert set(row["variables"]) == {"z"} and 0.1 <= row["variables"]["z"] <= 0.5
    assert sorted((r["base_x"], r["trial"], r["seed"]) for r in rows) == [
        (-0.2, 1, 0), (-0.2, 2, 1), (-0.1, 1, 0), (-0.1, 2, 1)]
    by_base = {r["base_x"]: [] for r in rows}
    for row in rows:
        by_base[row["base_x"]].append(row)
    assert all(r["success"] for r in by_base[-0.2])
    assert not any(r["success"] for r in by_base[-0.1])
    assert all(r["failure_kinds"][0] == "no executable plan (reach)" for r in by_base[-0.1])
    # same seed, same concrete trial at every placement
    assert {r["seed"]: r["variables"] for r in by_base[-0.2]} == {r["seed"]: r["variables"] for r in by_base[-0.1]}
    assert table(parallel) == table(sequential)  # whichever process ran each trial
    summary = json.loads((parallel / "summary.json").read_text())
    assert summary["rows"] == 4 and summary["success_count"] == 2 and summary["workers"] == 2
    assert [(e["base_x"], e["successes"], e["trials"]) for e in summary["by_base"]] == [(-0.2, 2, 2), (-0.1, 0, 2)]
    assert [e["base_x"] for e in summary["best"]] == [-0.2]
    assert summary["failure_kinds"] == {"no executable plan (reach)": 2}
    assert deterministic(summary) == deterministic({**json.loads((sequential / "summary.json").read_text()),
                                                     "workers": 2})
    for name in ("success_by_base.png", "success_by_variable.png", "failure_reasons.png"):
        assert (parallel / name).read_bytes()[:8] == PNG_MAGIC, name


@pytest.mark.slow
def test_an_interrupted_sweep_resumes_to_the_table_of_an_uninterrupted_one(tmp_path):
    options = ["--trials", 8, "--workers", 2]
    interrupted = tmp_path / "interrupted"
    process = subprocess.Popen(cli_command(*sweep_args(interrupted, *options)), stdout=subprocess.PIPE,
                               stderr=subprocess.PIPE, text=True, env=cli_env())
    wait_until(lambda: line_count(interrupted / "sweep.jsonl") >= 1, timeout_s=240, while_running=process,
               interval_s=0.01)
    assert process.poll() is None, "the sweep ended before its first row was on disk"
    process.send_signal(signal.SIGINT)
    stdout, stderr = process.communicate(timeout=60)
    assert process.returncode == 1
    assert "Traceback" not in stderr and stderr_lines(stderr) == ["drake-lfd sweep: interrupted"]
    kept = read_json_lines(interrupted / "sweep.jsonl")
    assert 1 <= len(kept) < 8
    assert f"{len(kept)} of 8 trials are in" in stdout and "--resume" in stdout
    assert not (interrupted / "summary.json").exists()
    assert cli.main(sweep_args(interrupted, *options, "--resume")) == 0
    resumed = read_json_lines(interrupted / "sweep.jsonl")
    assert resumed[:len(kept)] == kept and len(resumed) == 8  # kept rows untouched, only the rest ran
    uninterrupted = tmp_path / "uninterrupted"
    assert cli.main(sweep_args(uninterrupted, "--trials", 8, "--workers", 1)) == 0
    assert table(interrupted) == table(uninterrupted)
    first = json.loads((interrupted / "summary.json").read_text())
    second = json.loads((uninterrupted / "summary.json").read_text())
    assert deterministic(first)["by_base"] == deterministic(second)["by_base"]
    # resuming a complete sweep runs nothing and rewrites the same table
    assert cli.main(sweep_args(interrupted, *options, "--resume")) == 0
    assert read_json_lines(interrupted / "sweep.jsonl") == resumed


@pytest.mark.slow
def test_simulate_on_two_workers_equals_one_process(tmp_path, capsys):
    documents = {}
    for workers in (2, 1):
        out = tmp_path / f"w{workers}" / "out.json"
        status = cli.main(["simulate", str(TRANSFERRING), "--library", "paper5", "--trials", "3", "--seed", "4",
                           "--workers", str(workers), "--json", str(out)])
        assert status in (0, 4)
        documents[workers] = json.loads(out.read_text())
        # the incremental file is in trial order too, one record per trial
        assert [r["trial"] for r in read_json_lines(out.with_suffix(".jsonl"))] == [1, 2, 3]
    assert [t["seed"] for t in documents[2]["trials"]] == [4, 5, 6]
    assert deterministic(documents[2]) == deterministic(documents[1])
    lines = [line.split(":")[0] for line in capsys.readouterr().out.splitlines() if line.startswith("trial ")]
    assert lines == ["trial 1 (seed 4)", "trial 2 (seed 5)", "trial 3 (seed 6)"] * 2


def _worker_state():
    """A worker's process id and how many TrialRunners it keeps."""
    import os

    from drake_lfd.experiments import parallel_trials

    return os.getpid(), len(parallel_trials._RUNNERS)


def _gone(pid):
    import psutil

    try:
        return psutil.Process(pid).status() == psutil.STATUS_ZOMBIE
    except psutil.NoSuchProcess:
        return True


@pytest.mark.slow
def test_a_trial_cluster_started_early_serves_two_runs_like_one_process_and_ends_with_its_block():
    from drake_lfd.experiments.parallel_trials import BasePlacement, run_trial_specs, runner_spec, trial_specs
    from drake_lfd.experiments.simulation import trial_json
    from drake_lfd.io.library import Library

    library = Library.open("paper5")
    reachable = trial_specs(runner_spec(TRANSFERRING, library), trials=2, seed=0)
    out_of_reach = trial_specs(runner_spec(TRANSFERRING, library, base=BasePlacement(-0.1, 0.7, 0.0, 0.0)),
                               trials=2, seed=0)

    def outcomes(specs, **where):
        return [deterministic(trial_json(outcome)) for outcome in run_trial_specs(specs, in_order=True, **where)]

    with trial_cluster(2) as cluster:
        first = outcomes(reachable, cluster=cluster)
        client = cluster.client()
        workers = client.run(_worker_state)
        second = outcomes(out_of_reach, cluster=cluster)
        after = client.run(_worker_state)
        assert client.status == "running"  # neither run closed it
    assert sorted(pid for pid, _ in after.values()) == sorted(pid for pid, _ in workers.values())
    assert sum(runners for _, runners in after.values()) > sum(runners for _, runners in workers.values())
    assert first == outcomes(reachable, workers=1) and [o["success"] for o in first] == [True, True]
    assert second == outcomes(out_of_reach, workers=1) and not any(o["success"] for o in second)
    pids = [pid for pid, _ in after.values()]
    assert wait_until(lambda: all(_gone(pid) for pid in pids), timeout_s=60, interval_s=0.05), \
        "a worker process outlived its trial cluster"
    with pytest.raises(RuntimeError, match="closed"):
        cluster.client()


def _worker_signals_and_marker():
    """A worker's SIGINT and SIGTERM handlers, and whether it has the test's marker."""
    from drake_lfd.experiments import parallel_trials

    return (signal.getsignal(signal.SIGINT), signal.getsignal(signal.SIGTERM),
            getattr(parallel_trials, "_test_marker", None))


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="workers are forked on Linux only")
def test_local_cluster_workers_are_forked_copies_that_leave_interrupts_to_this_process(monkeypatch):
    from drake_lfd.experiments import parallel_trials

    assert parallel_trials.WORKER_START_METHOD == "fork"
    monkeypatch.setattr(parallel_trials, "_test_marker", "set before the cluster started", raising=False)
    with trial_cluster(2) as cluster:
        states = cluster.client().run(_worker_signals_and_marker)
    assert len(states) == 2
    for sigint, sigterm, marker in states.values():
        assert marker == "set before the cluster started"  # a copy of this process, not a fresh import
        assert sigint == signal.SIG_IGN and sigterm == signal.SIG_DFL


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="workers are forked on Linux only")
def test_output_buffered_before_the_workers_fork_is_written_once(tmp_path):
    script = ("import sys\n"
              "from drake_lfd.experiments.parallel_trials import trial_cluster\n"
              "print('written before the cluster started')\n"  # piped: block-buffered, unflushed
              "sys.stderr.write('said before the cluster started\\n')\n"
              "with trial_cluster(2) as cluster:\n"
              "    cluster.client().run(lambda: 0)\n")
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, env=cli_env(),
                          timeout=120)
    assert done.returncode == 0, done.stderr
    assert done.stdout.count("written before the cluster started") == 1
    assert done.stderr.count("said before the cluster started") == 1


def test_runners_of_one_library_share_its_features_loaded_once():
    from drake_lfd.experiments import parallel_trials
    from drake_lfd.experiments.parallel_trials import BasePlacement, runner_spec
    from drake_lfd.io.library import Library

    parallel_trials._FEATURES.clear()
    try:
        paper5, paper6 = Library.open("paper5"), Library.open("paper6")
        here, there = (runner_spec(TRANSFERRING, paper5, base=BasePlacement(x, 0.7, 0.0, 0.0)) for x in (-0.2, -0.3))
        first, second = here.build(), there.build()
        assert len(parallel_trials._FEATURES) == 1
        assert first.features is second.features and set(first.features) == set(paper5.names)
        other = runner_spec(TRANSFERRING, paper6).build()
        assert other.features is not first.features and set(other.features) == set(paper6.names)
        assert len(parallel_trials._FEATURES) == parallel_trials.FEATURE_SETS_PER_PROCESS == 2
        runner_spec(TRANSFERRING, paper5, options=PlanningOptions(cost="paper")).build()  # paper5 is the most recent again
        fresh = runner_spec(TRANSFERRING, Library.open("paper5")).build()
        assert fresh.features is first.features
    finally:
        parallel_trials._FEATURES.clear()


@pytest.mark.parametrize("grid, message", [
    (["0:1:x", "0:0:1"], '--base-grid: "0:1:x" is not X0:X1:NX'),
    (["0:1:2", "0:1"], '--base-grid: "0:1" is not Y0:Y1:NY'),
    (["0:1:0", "0:0:1"], '--base-grid: "0:1:0": NX must be at least 1, got 0'),
    (["0:1:1", "0:0:1"], '--base-grid: "0:1:1": one point needs X0 = X1'),
    (["0:1:2"], "--base-grid: expected 2 to 4 axes"),
    (["0:0:1", "0:0:1", "0:0:1", "0:0:1", "0:0:1"], "--base-grid: expected 2 to 4 axes"),
    (["-0.3:nan:2", "0:0:1"], '--base-grid: "-0.3:nan:2": X0 and X1 must be finite numbers'),
])
def test_bad_base_grids_are_refused_with_one_line(tmp_path, capsys, grid, message):
    assert cli.main(sweep_args(tmp_path / "out", "--base-grid", *grid)) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"drake-lfd sweep: error: {message}")
    assert not (tmp_path / "out" / "sweep.jsonl").exists()


@pytest.mark.parametrize("args, message", [
    (["sweep", str(TRANSFERRING), "--library", "paper5", "--out", "OUT", "--workers", "0"],
     "--workers: must be at least 1, got 0"),
    (["simulate", str(TRANSFERRING), "--library", "paper5", "--workers", "0"], "--workers: must be at least 1, got 0"),
    (["simulate", str(TRANSFERRING), "--library", "paper5", "--meshcat", "--workers", "2"],
     "--meshcat: shows the trials one after another in one viewer: it needs --workers 1"),
    (["paper", "--out", "OUT", "--workers", "0"], "--workers: must be at least 1, got 0"),
])
def test_bad_worker_counts_are_refused_with_one_line(tmp_path, capsys, args, message):
    args = [str(tmp_path / "out") if a == "OUT" else a for a in args]
    assert cli.main(args) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"drake-lfd {args[0]}: error: {message}"]


def test_negative_axes_are_values_not_options():
    assert parse_axis("-0.3:-0.1:3") == pytest.approx((-0.3, -0.2, -0.1))
    args = build_parser().parse_args(sweep_args("OUT", "--base-grid", "-0.3:-0.1:3", "-1e-1:0:2", "0:0:1",
                                                    "-90:90:3"))
    assert args.base_grid == ["-0.3:-0.1:3", "-1e-1:0:2", "0:0:1", "-90:90:3"]


def test_failure_kinds_group_by_the_records_kind_not_their_text():
    """A row's failures are counted by the kinds their records carry: rewording a line moves
    no figure; a row written before rows carried kinds counts as ``other``."""
    from drake_lfd.core.failures import FAILURE_KINDS, Failure, failure_labels
    from drake_lfd.experiments.sweep import failure_kinds_of

    refused = Failure("no_executable_plan", "any wording at all", configuration=1, cause="reach")
    moved = Failure("position_error", "con_3 missed by a lot", configuration=3)
    assert failure_labels([refused, moved, "a plain old line"]) == [
        "no executable plan (reach)", "critical configuration position error", "other"]
    assert failure_kinds_of({"failures": ["x", "y"], "failure_kinds": failure_labels([refused, moved])}) == [
        "no executable plan (reach)", "critical configuration position error"]
    assert failure_kinds_of({"failures": ["written by an older drake-lfd"]}) == ["other"]
    with pytest.raises(ValueError):
        Failure("typo_kind", "x")
    assert set(FAILURE_KINDS) >= {"path_constraint", "penetration", "separation", "no_executable_plan"}


@pytest.mark.slow
def test_the_sweeps_failure_kinds_do_not_move_when_every_message_is_reworded(tmp_path, monkeypatch):
    """``bench_sweep``'s sweep (transferring, ``paper5``, its 2 x 2 base grid), two trials a
    placement, run as ``drake-lfd sweep`` runs it and again with every failure line
    reworded at its source (each ``Failure`` built with another text): the failure kinds
    per trial and the summary's counts by kind are the same; only the lines differ."""
    from drake_lfd.cli import main
    from drake_lfd.core import failures
    from drake_lfd.core.resources import scenarios_directory
    from drake_lfd.experiments.sweep import row_key
    from drake_lfd.io.json_lines import read_json_lines

    def sweep(out):
        status = main(["sweep", str(scenarios_directory() / "transferring.yaml"), "--library", "paper5",
                       "--trials", "2", "--base-grid", "-0.3:-0.2:2", "0.6:0.7:2", "--workers", "1",
                       "--out", str(out)])
        assert status == 0
        rows = sorted(read_json_lines(out / "sweep.jsonl"), key=lambda row: repr(row_key(row)))
        return rows, json.loads((out / "summary.json").read_text())

    rows, summary = sweep(tmp_path / "plain")
    original_new = failures.Failure.__new__

    def reworded(cls, kind, detail, **fields):
        return original_new(cls, kind, f"reworded: {detail[::-1]}", **fields)

    monkeypatch.setattr(failures.Failure, "__new__", reworded)
    reworded_rows, reworded_summary = sweep(tmp_path / "reworded")
    assert summary["failure_kinds"] and summary["failure_kinds"] == reworded_summary["failure_kinds"]
    assert [row["failure_kinds"] for row in rows] == [row["failure_kinds"] for row in reworded_rows]
    lines = [line for row in reworded_rows for line in row["failures"]]
    assert lines and all(line.startswith("reworded: ") for line in lines)
