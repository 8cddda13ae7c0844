"""The paper's Section 6, end to end: training, three tasks, a demonstration request,
warm-start retraining, and a report with the paper's numbers beside ours.

Steps (each printed as it runs):

1. library ``paper5``; its features beside Table 5;
2. Q-learning on 20 random tasks x 100 episodes (Section 6.2, Fig. 7);
3. transferring (Table 7) and filling-and-pouring (Table 8): N closed-loop trials each
   with the trained policy (planner ``q``); every plan here uses the paper's action cost,
   Eq. 31 (cost ``"paper"``, not the shape-fidelity cost of ``core/fidelity.py``);
4. assembling (Table 9) with ``paper5``: expected a demonstration request for
   con_2 -> con_3;
5. library ``paper6`` (adds ``span``), warm-start retraining on the assembling task with
   the random tasks (Fig. 10c), then N trials of assembling;
6. every successful trial is re-derived from its logged joint trajectory with
   independent kinematics (``rederive.py``).

Writes ``results.json`` (docs/cli.rst), ``report.md``, PNG figures and a Meshcat HTML
recording per task into the output folder; every closed-loop trial is appended to
``trials.jsonl`` there as it finishes (:mod:`drake_lfd.io.json_lines`), so an interrupt
keeps what ran. With more than one worker (or a scheduler), one cluster serves the
trials of all three tasks: it is started first and closed at the end, however the run
ends. When ``DRAKE_ALLOW_NETWORK`` disables
Meshcat, the recordings are skipped with a note (:mod:`drake_lfd.core.network_policy`).
Not for: the command line (``cli_paper.py``).
"""

from __future__ import annotations

import contextlib
import os
import platform
import time
from pathlib import Path
from typing import Callable

import numpy as np

from drake_lfd import __version__
from drake_lfd.core.resources import scenarios_directory
from drake_lfd.core.network_policy import NETWORK_VARIABLE, drake_allows
from drake_lfd.io.atomic_files import atomic_write_bytes
from drake_lfd.io.json_lines import JsonLinesFile
from drake_lfd.io.strict_json import write_json
from drake_lfd.experiments.figures import training_curve_figure
from drake_lfd.io.library import Library, library_features
from drake_lfd.io.plan_json import uncovered_json
from drake_lfd.planning.options import PlanningOptions
from drake_lfd.planning.planner import build_problem, plan_composition
from drake_lfd.io.policy_files import save_policy
from drake_lfd.planning.q_learning import episodes_to_steady
from drake_lfd.experiments.parallel_trials import run_trials_on_workers, runner_spec, trial_cluster
from drake_lfd.experiments.rederive import rederive_run
from drake_lfd.experiments.simulation import (
    composition_counts,
    run_trials,
    shorten_reason,
    trial_record,
    write_trial_figures,
)
from drake_lfd.experiments.table5 import compare as compare_table5
from drake_lfd.core.tasks import draw_trial
from drake_lfd.io.task_files import load_task
from drake_lfd.planning.training import train_on_random_tasks

__all__ = ['PAPER', 'PAPER_OPTIONS', 'run_paper', 'report_markdown']

PAPER = {
    "training_time_s": 1927.42,
    "training_machine": "Matlab, 4-core 4.0 GHz Intel Core i7",
    "episodes_to_steady": 50,
    "retraining_episodes_to_steady": 10,
    "transferring": "20/20; stacking mapped for the whole task",
    "filling_pouring": "20/20; filling (con_1-con_2), stacking (con_2-con_4), twisting (con_4-con_5)",
    "assembling_request": "request for con_2 -> con_3 (90 deg about body x)",
    "assembling": "20/20 after the new demonstration; twisting 1 (con_1-con_2), span (con_2-con_3), "
                  "twisting 2 (con_3-con_4)",
}

#: How the closed-loop trials of Section 6 are planned: with the trained Q-policy and the
#: paper's action cost (Eq. 31), joint-space checked like every closed-loop trial.
PAPER_OPTIONS = PlanningOptions(planner="q", cost="paper")


def _drake_version() -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("drake")
    except PackageNotFoundError:
        return "unknown"


def _reasons(outcome) -> str:
    """Every failure reason of a trial, each shortened for the log (results.json keeps them whole)."""
    return "; ".join(shorten_reason(reason) for reason in outcome.failures)


def _task_results(name, task, features, policy, trials, seed, out, log, finished=None, record=True,
                  workers=1, scheduler=None, library=None, policy_file=None, options=PAPER_OPTIONS, cluster=None):
    """Runs the trials of one task; figures and (``record``) a recording of the first
    trial; each finished trial is appended to ``finished`` (a JsonLinesFile). With more
    than one worker (or a scheduler) the trials run on worker processes (those of
    ``cluster``, if given), which load the task file, ``library`` (opened) and the saved
    ``policy_file`` themselves. Every trial is planned as ``options`` say."""
    recording = out / f"{name}.html"

    def progress(done, total, outcome):
        if finished is not None:
            finished.append(trial_record(task, outcome))
        log(f"  {name} trial {done}/{total}: {'success' if outcome.success else 'FAILED ' + _reasons(outcome)}")

    if workers == 1 and scheduler is None:
        outcomes, wall = run_trials(
            task, features, trials=trials, seed=seed, options=options, policy=policy,
            record_html=recording if record else None, progress=progress,
        )
    else:
        outcomes, wall = run_trials_on_workers(
            runner_spec(task.file, library, policy_file=policy_file, options=options), trials=trials,
            seed=seed,
            record_html=recording if record else None, progress=progress, workers=workers, scheduler=scheduler,
            cluster=cluster,
        )
    first = next((o for o in outcomes if o.run is not None), None)
    figures = write_trial_figures(task, first, out, name) if first is not None else {}
    rederived = 0
    for outcome in outcomes:
        if not outcome.success:
            continue
        check = rederive_run(
            outcome.run.t, outcome.run.q,
            critical_times_s=[e.time_s for e in outcome.run.critical_errors],
            critical_configurations=[{"p": con.p, "euler_zyx": outcome.plan.euler_zyx[i]}
                                     for i, con in enumerate(outcome.plan.task.critical_configurations)],
            X_WB=task.X_WB, X_tool0_E=task.X_tool0_E, path_constraints=outcome.plan.task.path_constraints,
            obstacles=task.obstacles, safety_shells=task.safety_shells, tool=task.tool,
        )
        rederived += check.success
        if not check.success:
            log(f"  {name} trial {outcome.trial}: re-derivation disagrees: {check.failures}")
    failures = {o.trial: o.failures for o in outcomes if not o.success}
    return {
        "trials": trials,
        "success_count": int(sum(o.success for o in outcomes)),
        "compositions": composition_counts(outcomes),
        "rederived_success_count": int(rederived),
        "failures": failures,
        "wall_time_s": wall,
        "sim_time_s": float(sum(o.run.sim_time_s for o in outcomes if o.run is not None)),
        "recording": recording.name if record and recording.exists() else None,
        "figures": figures,
    }


def run_paper(out: Path, *, trials: int = 20, seed: int = 0, log: Callable[[str], None] = print,
              workers: int = 1, scheduler: str | None = None, options: PlanningOptions = PAPER_OPTIONS) -> dict:
    """Runs Section 6 and writes everything into ``out``; returns the results document.
    Every closed-loop trial is appended to ``out / "trials.jsonl"`` as it finishes. The
    closed-loop trials run on ``workers`` processes (or the workers of ``scheduler``;
    :mod:`~drake_lfd.experiments.parallel_trials`; one cluster for all three tasks),
    with the same results; the training runs here.
    ``options`` plan every closed-loop trial (default :data:`PAPER_OPTIONS`: the
    Q-planner with the paper's cost, joint-space checked; ``drake-lfd paper --refine``
    adds ``refine=True``); the request with five demonstrations is planned with them
    without the joint-space check."""
    out.mkdir(parents=True, exist_ok=True)
    with JsonLinesFile(out / "trials.jsonl") as finished, _paper_cluster(workers, scheduler, trials) as cluster:
        return _run_paper(out, trials=trials, seed=seed, log=log, finished=finished, workers=workers,
                          scheduler=scheduler, options=options, cluster=cluster)


def _paper_cluster(workers: int, scheduler: str | None, trials: int):
    """The cluster all three tasks' trials run on, or a null context (no cluster) when
    they run in this process."""
    if scheduler is None and (workers <= 1 or trials <= 1):
        return contextlib.nullcontext()
    return trial_cluster(workers, scheduler)


def _run_paper(out: Path, *, trials: int, seed: int, log: Callable[[str], None], finished, workers: int,
               scheduler: str | None, options: PlanningOptions = PAPER_OPTIONS, cluster=None) -> dict:
    start = time.perf_counter()
    no_meshcat = not drake_allows("meshcat")
    if no_meshcat:
        log(f"note: {NETWORK_VARIABLE}={os.environ.get(NETWORK_VARIABLE)} disables Drake's Meshcat, so the "
            f"Meshcat recordings are skipped (add meshcat to {NETWORK_VARIABLE} to make them)")
    sims = scenarios_directory()
    tasks = {name: load_task(sims / f"{name}.yaml") for name in ("transferring", "filling_pouring", "assembling")}

    log("library paper5: features beside the paper's Table 5")
    paper5 = Library.open("paper5")
    features5 = library_features(paper5)
    table5 = compare_table5(paper5)

    log("training: 20 random tasks x 100 episodes (Section 6.2)")
    training = train_on_random_tasks(features5, num_tasks=20, episodes=100, seed=seed)
    steady = episodes_to_steady(training.greedy_curve)
    training_curve_figure(out / "training_curve.png", training.greedy_curve, steady_episode=steady,
                          exploring=training.curve, title="Training on 20 random tasks (Fig. 7)")
    save_policy(training.policy, out / "policy_paper5.json")

    results = {"training": {"tasks": 20, "episodes": 100, "wall_time_s": training.wall_time_s,
                            "episodes_to_steady": steady,
                            "final_average_reward": float(training.greedy_curve[-10:].mean())},
               "tasks": {}}
    for name in ("transferring", "filling_pouring"):
        log(f"{name}: {trials} closed-loop trials with the trained policy")
        results["tasks"][name] = _task_results(name, tasks[name], features5, training.policy, trials, seed, out, log,
                                               finished, record=not no_meshcat, workers=workers, scheduler=scheduler,
                                               library=paper5, policy_file=out / "policy_paper5.json",
                                               options=options, cluster=cluster)

    log("assembling with paper5")
    assembling = tasks["assembling"]
    first_try = plan_composition(draw_trial(assembling, seed), features5,
                                 options.replace(joint_check=False, refine=False), policy=training.policy)
    assembling_results = {"initial_status": first_try.status, "uncovered": uncovered_json(first_try)}
    for segment in first_try.uncovered:
        log(f"  demonstration requested for con_{segment.con_from} -> con_{segment.con_to}: "
            f"{np.degrees(segment.angle_rad):.0f} deg about {np.round(segment.axis, 2).tolist()}")

    log("library paper6 (adds span): warm-start retraining on the assembling task and the random tasks")
    paper6 = Library.open("paper6")
    features6 = library_features(paper6)
    retraining = train_on_random_tasks(
        features6, num_tasks=20, episodes=100, seed=seed, warm_start=training.policy,
        extra_problems=[build_problem(draw_trial(assembling, seed), features6)],
    )
    assembling_curve = retraining.greedy_rewards[:, -1]
    retrain_steady = episodes_to_steady(assembling_curve)
    training_curve_figure(out / "retraining_curve.png", assembling_curve, steady_episode=retrain_steady,
                          exploring=retraining.rewards[:, -1],
                          title="Assembling after the new demonstration (Fig. 10c)")
    save_policy(retraining.policy, out / "policy_paper6.json")
    assembling_results["retraining"] = {"episodes": 100, "episodes_to_steady": retrain_steady,
                                        "wall_time_s": retraining.wall_time_s}
    log(f"assembling: {trials} closed-loop trials with the retrained policy")
    assembling_results["after_new_demo"] = _task_results(
        "assembling", assembling, features6, retraining.policy, trials, seed, out, log, finished,
        record=not no_meshcat, workers=workers, scheduler=scheduler, library=paper6,
        policy_file=out / "policy_paper6.json", options=options, cluster=cluster)
    results["tasks"]["assembling"] = assembling_results
    results["table5"] = [
        {"demo": row.demo, "sample": row.sample, "alpha": float(row.alpha)} for row in table5
    ]
    results["wall_time_s"] = time.perf_counter() - start
    results["environment"] = {"drake_lfd": __version__, "drake": _drake_version(),
                              "python": platform.python_version(), "machine": platform.machine()}
    write_json(out / "results.json", results)
    atomic_write_bytes(out / "report.md", report_markdown(results, table5, tasks).encode("utf-8"))
    return results


def _composition_text(compositions: dict) -> str:
    return ", ".join(f"{label} ({count})" for label, count in compositions.items()) or "none"


def report_markdown(results: dict, table5_rows, tasks) -> str:
    """The report: the paper's numbers beside ours, figures embedded."""
    t = results["tasks"]
    tr, fp, asm = t["transferring"], t["filling_pouring"], t["assembling"]
    after = asm["after_new_demo"]
    request = ", ".join(
        f"con_{u['from']} -> con_{u['to']} ({np.degrees(u['angle_rad']):.0f} deg about "
        f"[{', '.join(f'{a:.2f}' for a in u['axis'])}])" for u in asm["uncovered"]) or "none (planned)"
    matched = sum(r.alpha <= 0.15 for r in table5_rows)
    lines = [
        "# drake-lfd: Yu & Chang, Section 6, reproduced",
        "",
        f"drake-lfd {results['environment']['drake_lfd']}, Drake {results['environment']['drake']}, "
        f"Python {results['environment']['python']}; whole run {results['wall_time_s']:.0f} s.",
        "",
        "## Results beside the paper",
        "",
        "| result | paper | drake-lfd |",
        "|---|---|---|",
        f"| Table 5 rotation parts within alpha 0.15 | (reference) | {matched} of {len(table5_rows)} |",
        f"| training time, 20 tasks x 100 episodes | {PAPER['training_time_s']} s ({PAPER['training_machine']}) "
        f"| {results['training']['wall_time_s']:.2f} s |",
        f"| episodes until the reward is steady (Fig. 7) | about {PAPER['episodes_to_steady']} "
        f"| {results['training']['episodes_to_steady']} |",
        f"| transferring (Table 7) | {PAPER['transferring']} | {tr['success_count']}/{tr['trials']}; "
        f"{_composition_text(tr['compositions'])} |",
        f"| filling and pouring (Table 8) | {PAPER['filling_pouring']} | {fp['success_count']}/{fp['trials']}; "
        f"{_composition_text(fp['compositions'])} |",
        f"| assembling (Table 9), 5 demonstrations | {PAPER['assembling_request']} | {asm['initial_status']}: "
        f"{request} |",
        f"| retraining after the new demonstration (Fig. 10c) | steady after about "
        f"{PAPER['retraining_episodes_to_steady']} iterations | steady after "
        f"{asm['retraining']['episodes_to_steady']} episodes ({asm['retraining']['wall_time_s']:.2f} s) |",
        f"| assembling, 6 demonstrations | {PAPER['assembling']} | {after['success_count']}/{after['trials']}; "
        f"{_composition_text(after['compositions'])} |",
        "",
        "Every success was re-derived from its logged joint trajectory with independent kinematics "
        "(UR's DH table in numpy, speeds by finite differences, clearances re-queried): "
        f"transferring {tr['rederived_success_count']}/{tr['success_count']}, filling and pouring "
        f"{fp['rederived_success_count']}/{fp['success_count']}, assembling "
        f"{after['rederived_success_count']}/{after['success_count']}.",
        "",
    ]
    failed = {name: r.get("failures") or r.get("after_new_demo", {}).get("failures")
              for name, r in (("transferring", tr), ("filling_pouring", fp), ("assembling", after))}
    if any(failed.values()):
        lines += ["### Failed trials", ""]
        for name, failures in failed.items():
            for trial, reasons in (failures or {}).items():
                lines.append(f"- {name} trial {trial}: {'; '.join(reasons)}")
        lines.append("")
    lines += [
        "## Training (Fig. 7 and Fig. 10c)",
        "",
        "![training](training_curve.png) ![retraining](retraining_curve.png)",
        "",
        "The paper's random tasks (Euler angles drawn from multiples of pi/2) are rarely covered by five "
        "demonstrations: an episode mostly ends at the first dead end. The agent chooses among the paper's "
        "whole action set (Eq. 29-30) and learns to avoid actions that are not similar. The curves show "
        "the greedy policy's accumulated reward after each episode (averaged over the tasks; in grey, "
        "the exploring episodes themselves, epsilon 0.8). Before each plan, 100 episodes "
        "of the same Q-learning refine the table on the task itself (docs/method.rst, Planning).",
        "",
        "## The tasks",
        "",
    ]
    for name, result in (("transferring", tr), ("filling_pouring", fp), ("assembling", after)):
        figures = result.get("figures", {})
        lines.append(f"### {name}")
        lines.append("")
        for key in ("plan", "joints", "distance"):
            if key in figures:
                lines.append(f"![{name} {key}]({figures[key]})")
        if result.get("recording"):
            lines.append(f"Meshcat recording of the first trial: [{result['recording']}]({result['recording']})")
        lines.append("")
    lines += [
        "## Choices that make the paper's tasks feasible for a UR5e",
        "",
        "The paper never defines the end-effector frame or where the robot stands. Each "
        "scenario file in `sims/` keeps the paper's numbers and explains its choices:",
        "",
    ]
    for name, task in tasks.items():
        lines.append(f"- **{name}** (`sims/{name}.yaml`): robot base at "
                     f"{np.round(task.X_WB.translation(), 3).tolist()}; {task.description}.")
    lines += [
        "- The tool frame E sits 0.2 m out along the flange axis, turned +90 deg about the flange's y "
        "axis (shared by every scenario and both bundled libraries).",
        "- Filling and pouring: cup 2 is drawn from the 20 x 20 cm area x in [-0.3, -0.1], y in [-0.2, 0] "
        "(the paper's range crosses the robot's base).",
        "",
        "## Table 5",
        "",
        "| demo | sample | alpha to the paper's rotation |",
        "|---|---|---|",
    ]
    for row in table5_rows:
        lines.append(f"| {row.demo} | {row.sample} | {row.alpha:.3f} |")
    lines += ["", "See `docs/table5.md` for the full comparison, translation directions included.", ""]
    return "\n".join(lines)
