"""Refusals: how long ``plan`` takes to say no, and whether it says each reason once. Printed, never asserted.

Run: ``python benchmarks/bench_refusals.py [--pick-and-place 10] [--near-base 100] [--seed 0] [--after-only]
[--cli]``.

Tasks: the shelf pick-and-place task of ``tests/data/shelf_pick_place.yaml`` (a cup
carried over a boxed obstacle with a shell, ``paper5``'s tool frame) with its robot base
on a 4 x 4 grid of placements 10 cm apart around the file's, and random pick-and-place
work cells (:mod:`drake_lfd.experiments.pick_and_place`) with the base moved by up to
30 cm (seeded), so that some are out of reach, singular or crowded by their shell, and
``--near-base`` random pick-and-place tasks with a second safety shell standing beside
the robot's base (``shell_near_base``: 12-30 cm from the base axis, seeded), where the
shoulder and upper arm pass near a shell as shoulder_pan turns.
Each is planned as ``plan`` plans it (its work cell's joint-space checker, ``--cost
fidelity``, the exact planner, trial seed 0), timed from the work cell's construction
to the result, in one process.

Each task is planned twice in the same run: ``after``, as the planner does now, and
``before``, with the refusal pre-check (``planning/refusals.py``), the ruling out of
compositions that repeat a measured pan blocker and the merging of repeated reasons
switched off, which is the search as it was. Printed per task: status,
time and reason lines of both; for a task that plans, whether both give the same
composition and joint path (``same``). Then the median and largest refusal times, how
many refusals repeat a reason line, whether every planned task is unchanged, and the
slowest refusal against the median planned task and the slowest planned task (a search
that finds its plan late), planning alone in this warm process.
Absolute times depend on the machine's load (``uptime`` is printed); the before/after
ratio is measured under the same load.

``--cli``: each task is also planned as a user plans it, ``drake-lfd plan TASK --library
paper5`` in a process of its own, and that process's CPU time (start-up, library and
planning) is printed; then the slowest refusal against the median planned task in that
measure: the target (at most twice) is this ratio, the CPU time a user's ``plan`` takes,
the measure the slow refusals were first reported in. In one warm process the planning
alone is timed: a planned task whose first composition runs is then a single follow,
and the slowest planned tasks take many times that median too (printed), so no search
could hold its refusals to twice it.
"""

from __future__ import annotations

import argparse
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

import drake_lfd.planning.planner as planner_module
from drake_lfd.planning.options import PlanningOptions
from drake_lfd.core.tasks import draw_trial
from drake_lfd.diagrams.pipeline import joint_path_checker
from drake_lfd.experiments.pick_and_place import pick_and_place_yaml
from drake_lfd.io.library import Library, library_features
from drake_lfd.io.task_files import task_from_spec, task_spec_from_text
from drake_lfd.robot.workcell import Workcell

SHELF = Path(__file__).parents[1] / "tests" / "data" / "shelf_pick_place.yaml"


def tasks(pick_and_place: int, seed: int, near_base: int = 0) -> list[tuple[str, str]]:
    """(label, task file text) of every benchmark task."""
    shelf = SHELF.read_text()
    out = []
    for x in (-0.15, -0.05, 0.05, 0.15):
        for y in (-0.15, -0.05, 0.05, 0.15):
            out.append((f"shelf base ({x:+.2f}, {y:+.2f})",
                        shelf.replace("X_WB: {p: [0, 0, 0]", f"X_WB: {{p: [{x}, {y}, 0]")))
    rng = np.random.default_rng(seed)
    for number in range(pick_and_place):
        x, y = rng.uniform(-0.3, 0.3, 2)
        text = pick_and_place_yaml(seed * 1000 + number).replace(
            "X_WB: {p: [0, 0, 0]", f"X_WB: {{p: [{x:.3f}, {y:.3f}, 0]")
        out.append((f"pick_and_place_{seed * 1000 + number} base ({x:+.2f}, {y:+.2f})", text))
    for number in range(near_base):
        task_seed = seed * 1000 + number
        out.append((f"near_base_{task_seed}", pick_and_place_yaml(task_seed, shell_near_base=True)))
    return out


def plan_once(text: str, features, before: bool):
    """(result, seconds) of planning the task as ``plan`` does; ``before``: without the
    pre-check and the merging of reasons."""
    saved = planner_module.blocked_configurations, planner_module.distinct_reasons, planner_module.PoseBlockers
    if before:
        planner_module.blocked_configurations = lambda problem, checker: []
        planner_module.distinct_reasons = tuple
        planner_module.PoseBlockers = lambda checker: None
    try:
        task = task_from_spec(task_spec_from_text(text), file="bench")
        trial = draw_trial(task, 0)
        start = time.perf_counter()
        workcell = Workcell.of(trial)
        checker = joint_path_checker(workcell, task.simulation)
        result = planner_module.plan_composition(trial, features, PlanningOptions(),
                                                 floor_z=workcell.planner_floor, checker=checker)
        return result, time.perf_counter() - start
    finally:
        (planner_module.blocked_configurations, planner_module.distinct_reasons,
         planner_module.PoseBlockers) = saved


def plan_command_cpu(text: str) -> tuple[int, float]:
    """(exit status, CPU seconds) of ``drake-lfd plan`` on the task in a process of its own."""
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "task.yaml"
        path.write_text(text)
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        done = subprocess.run([sys.executable, "-m", "drake_lfd", "plan", str(path), "--library", "paper5"],
                              capture_output=True, text=True)
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return done.returncode, (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def reason_lines(result) -> list[str]:
    return [segment.describe() for segment in result.infeasible] if result.status == "no_executable_plan" else []


def same_plan(a, b) -> bool:
    return (a.composition == b.composition and a.joint_path is not None and b.joint_path is not None
            and np.array_equal(a.joint_path.q, b.joint_path.q))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--pick-and-place", type=int, default=10)
    parser.add_argument("--near-base", type=int, default=100,
                        help="random pick-and-place tasks with a shell beside the base")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--after-only", action="store_true", help="skip the 'before' runs (minutes)")
    parser.add_argument("--cli", action="store_true", help="also time each task as a `drake-lfd plan` process")
    args = parser.parse_args()
    features = library_features(Library.open("paper5"))
    print(f"load before: {os.getloadavg()[0]:.2f}")
    refusal_times, before_times, repeated, planned_same, planned = [], [], 0, 0, 0
    planned_times, slowest, slowest_planned = [], ("", 0.0), ("", 0.0)
    cli_planned, cli_refused = [], []
    for label, text in tasks(args.pick_and_place, args.seed, args.near_base):
        after, after_s = plan_once(text, features, before=False)
        lines = reason_lines(after)
        line = f"{label:<40} {after.status:<19} {after_s:6.2f} s, {len(lines)} reason line(s)"
        if not args.after_only:
            before, before_s = plan_once(text, features, before=True)
            line += f" | before: {before.status:<19} {before_s:6.2f} s, {len(reason_lines(before))} line(s)"
            if after.planned:
                planned += 1
                planned_same += same_plan(after, before)
                line += f" | same: {'yes' if same_plan(after, before) else 'NO'}"
            elif after.status == "no_executable_plan":
                before_times.append(before_s)
        if args.cli:
            status, cpu = plan_command_cpu(text)
            line += f" | plan command: exit {status}, {cpu:.2f} s CPU"
            if status == 0:
                cli_planned.append(cpu)
            elif status == 4:
                cli_refused.append((cpu, label))
        if after.planned:
            planned_times.append(after_s)
            slowest_planned = max(slowest_planned, (label, after_s), key=lambda item: item[1])
        if after.status == "no_executable_plan":
            refusal_times.append(after_s)
            slowest = max(slowest, (label, after_s), key=lambda item: item[1])
            repeated += len(lines) != len(set(lines))
        print(line, flush=True)
        for reason in lines:
            print(f"    {reason[:220]}")
    print()
    print(f"load after: {os.getloadavg()[0]:.2f}")
    if refusal_times:
        print(f"refusals: {len(refusal_times)}, median {np.median(refusal_times):.2f} s, "
              f"max {max(refusal_times):.2f} s; refusals repeating a reason line: {repeated}")
    if before_times:
        print(f"before (same tasks, same run): median {np.median(before_times):.2f} s, max {max(before_times):.2f} s")
    if not args.after_only:
        print(f"planned tasks: {planned}, same composition and joint path before and after: {planned_same}")
    if refusal_times and planned_times:
        median = float(np.median(planned_times))
        print(f"slowest refusal {slowest[1]:.2f} s ({slowest[0]}) against the median planned task {median:.2f} s "
              f"({len(planned_times)} planned): {slowest[1] / median:.1f} times, planning alone in one warm process "
              f"(the slowest planned task {slowest_planned[1]:.2f} s, {slowest_planned[0]}; the target is measured as "
              f"`plan` processes: --cli)")
    if cli_planned and cli_refused:
        median = float(np.median(cli_planned))
        cpu, label = max(cli_refused)
        print(f"as `drake-lfd plan` processes (CPU): slowest refusal {cpu:.2f} s ({label}) against the median "
              f"planned task {median:.2f} s: {cpu / median:.1f} times (target: at most 2)")


if __name__ == "__main__":
    main()
