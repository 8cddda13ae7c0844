"""Refinement by trajectory optimization beside the unrefined plan and the plain optimizer.

Run: ``python benchmarks/bench_refinement.py [--pick-and-place 10] [--cost fidelity]``.

On the paper's three tasks (transferring and filling-and-pouring with ``paper5``,
assembling with ``paper6``; trial seed 0) and on ``--pick-and-place`` random
pick-and-place tasks (:mod:`drake_lfd.experiments.pick_and_place`, library ``paper5``),
plans each with drake-lfd (the exact planner and the plan-time joint-space check, as
``drake-lfd plan`` does), then refines it (``planning/refinement.py``) and runs the plain
optimizer from the same start and goal configurations, and runs each of the three
plans once closed loop (a pipeline Diagram with the plan given, from the start of its
checked joint path). Prints, side by side:

- planning time (the plain optimizer's: its own optimization and check, given the start
  and goal configurations and the critical configurations' path fractions of the plan);
- executed duration: closed loop, from con_1 to the last critical configuration;
- success in closed loop (``experiments/judging.py``; a given plan's critical
  configurations are its poses at its critical indices: for an optimized plan within
  1.2 mm and 0.3 deg of the task's, by the program's constraints);
- deviation from the demonstrated shape, two ways: the tube's own measure (the largest
  distance and angle of an executed pose from the composed demonstration path at the
  same path fraction; the refinement's tube is 150 mm and 30 deg), and the largest
  distance (and angle) from an executed pose to the nearest pose of the composed path,
  as a set. The second pairs poses without regard to progress along the path, so it
  can pair a pose with the wrong turn of a screw motion and read a large angle.

Then the planning time of ``--refine`` (composition, check and refinement, as
``drake-lfd plan --refine`` does) over ``--seeds`` trial seeds of each paper task, with
both action costs: median and largest (target: under 3 s).

A refinement or plain optimization that fails leaves the unrefined plan; its row then
says ``failed`` with the reason below the table.
"""

from __future__ import annotations

import argparse
import math
import tempfile
import time
from pathlib import Path

import numpy as np

from drake_lfd.core.resources import scenarios_directory
from drake_lfd.core.tasks import draw_trial
from drake_lfd.diagrams.closed_loop import ClosedLoopRunner
from drake_lfd.diagrams.pipeline import build_pipeline, joint_path_checker
from drake_lfd.experiments.judging import judge_run
from drake_lfd.experiments.pick_and_place import write_pick_and_place_tasks
from drake_lfd.io.library import Library, library_features
from drake_lfd.io.task_files import load_task
from drake_lfd.planning.planner import plan_task
from drake_lfd.planning.refinement import (
    OptimizationScene,
    RefinementOptions,
    path_fractions_of,
    plain_plan,
    refine_plan,
    shape_deviation,
    tube_deviation,
)
from drake_lfd.robot.kinematics import UR5eKinematics
from drake_lfd.robot.workcell import Workcell

METHODS = ("unrefined", "refined", "plain")
TUBE_POSITION_M = RefinementOptions().tube_position_m
TUBE_ROTATION_RAD = RefinementOptions().tube_rotation_rad
PAPER_TASKS = (("transferring", "paper5"), ("filling_pouring", "paper5"), ("assembling", "paper6"))


def _executed(run, kinematics) -> tuple[float, np.ndarray, list]:
    """Closed-loop duration from con_1 to the last critical configuration, and the
    times and E's logged poses over it (every fifth sample)."""
    t_first, t_last = run.critical_errors[0].time_s, run.critical_errors[-1].time_s
    window = (run.t >= t_first - 1e-9) & (run.t <= t_last + 1e-9)
    return float(t_last - t_first), run.t[window][::5], [kinematics.X_WE(q) for q in run.q[window][::5]]


def _executed_tube_deviation(composed, result, run, times, poses) -> tuple[float, float]:
    """The tube's measure on an executed run: each logged pose against the composed path
    at the path fraction its plan time has (the plan's samples carry their fractions)."""
    if result.refinement is not None and result.refinement.refined:
        fractions = result.refinement.path_fractions
    else:
        fractions = path_fractions_of(composed.timed)
    s = np.interp(times - run.plan_start_time_s, result.timed.times, fractions)
    return tube_deviation(composed.timed, s, poses)


def _compose(task, features, seed: int, cost: str):
    """As ``drake-lfd plan`` does: the trial of ``seed``, its work cell, the plan-time
    checker, the composed plan and the time ``plan_task`` took."""
    concrete = draw_trial(task, seed)
    workcell = Workcell.of(concrete)
    checker = joint_path_checker(workcell, task.simulation)
    start = time.perf_counter()
    composed = plan_task(concrete, features, seed=seed, floor_z=workcell.planner_floor, checker=checker, cost=cost)
    return concrete, workcell, checker, composed, time.perf_counter() - start


def bench_task(name: str, task, features, cost: str) -> list[dict]:
    """The three rows of one task (trial seed 0), or one ``not planned`` row."""
    kinematics = UR5eKinematics(X_WB=task.X_WB, X_tool0_E=task.X_tool0_E)
    concrete, workcell, checker, composed, plan_time = _compose(task, features, 0, cost)
    if not composed.planned:
        return [{"task": name, "method": "unrefined", "status": composed.status}]
    scene = OptimizationScene(workcell)
    rows = []
    for method in METHODS:
        if method == "unrefined":
            result, seconds = composed, plan_time
        else:
            begin = time.perf_counter()
            optimize = refine_plan if method == "refined" else plain_plan
            result = optimize(composed, checker, scene=scene)
            seconds = time.perf_counter() - begin + (plan_time if method == "refined" else 0.0)
        report = result.refinement
        row = {"task": name, "method": method, "planning_s": seconds, "planned_s": result.timed.duration,
               "status": "planned" if report is None else report.status,
               "reason": "" if report is None else report.reason}
        if report is not None and not report.refined:
            rows.append(row)
            continue
        # Each motion on a pipeline of its own with the plan given (no planner), from the
        # start of its checked joint path.
        given = ClosedLoopRunner(build_pipeline(concrete, plan=result.timed, config=task.simulation))
        _, run = given.run(q_initial=result.joint_path.q[0])
        judgement = judge_run(run, joint_limits=kinematics.position_limits(),
                              velocity_limits=kinematics.velocity_limits(),
                              path_constraints=concrete.path_constraints)
        executed, times, poses = _executed(run, kinematics)
        position, rotation = shape_deviation(composed.timed, poses)
        tube_position, tube_rotation = _executed_tube_deviation(composed, result, run, times, poses)
        row.update(executed_s=executed, success=judgement.success, failures=judgement.failures,
                   deviation_m=position, deviation_rad=rotation, tube_m=tube_position, tube_rad=tube_rotation)
        rows.append(row)
    return rows


def _table(rows: list[dict]) -> str:
    lines = [f"{'task':<22} {'method':<10} {'plan s':>7} {'planned s':>9} {'executed s':>10} {'success':>7} "
             f"{'tube dev mm':>11} {'deg':>5} {'set dev mm':>10} {'deg':>5}  status"]
    for row in rows:
        if "executed_s" in row:
            lines.append(f"{row['task']:<22} {row['method']:<10} {row['planning_s']:>7.2f} {row['planned_s']:>9.2f} "
                         f"{row['executed_s']:>10.2f} {str(row['success']):>7} {1000 * row['tube_m']:>11.0f} "
                         f"{math.degrees(row['tube_rad']):>5.1f} {1000 * row['deviation_m']:>10.0f} "
                         f"{math.degrees(row['deviation_rad']):>5.1f}  {row['status']}")
        elif "planning_s" in row:
            lines.append(f"{row['task']:<22} {row['method']:<10} {row['planning_s']:>7.2f} {'':>9} {'':>10} {'':>7} "
                         f"{'':>11} {'':>5} {'':>10} {'':>5}  {row['status']}")
        else:
            lines.append(f"{row['task']:<22} {row['method']:<10} {'':>7} {'':>9} {'':>10} {'':>7} {'':>11} {'':>5} "
                         f"{'':>10} {'':>5}  {row['status']}")
    return "\n".join(lines)


def _summary(rows: list[dict]) -> list[str]:
    lines = []
    by_task: dict[str, dict] = {}
    for row in rows:
        by_task.setdefault(row["task"], {})[row["method"]] = row
    for task, methods in by_task.items():
        refined, plain = methods.get("refined", {}), methods.get("plain", {})
        if "executed_s" in refined and "executed_s" in plain:
            inside = refined["tube_m"] <= TUBE_POSITION_M and refined["tube_rad"] <= TUBE_ROTATION_RAD
            lines.append(f"{task}: refined / plain executed duration {refined['executed_s'] / plain['executed_s']:.2f} "
                         f"(target <= 1.5); refined executed path {'inside' if inside else 'OUTSIDE'} the tube "
                         f"({1000 * refined['tube_m']:.0f} mm, {math.degrees(refined['tube_rad']):.1f} deg; plain "
                         f"{1000 * plain['tube_m']:.0f} mm, {math.degrees(plain['tube_rad']):.1f} deg)")
    for row in rows:
        if row.get("reason"):
            lines.append(f"{row['task']} {row['method']}: {row['reason']}")
        for failure in row.get("failures", []):
            lines.append(f"{row['task']} {row['method']}: closed loop: {failure}")
    return lines


def planning_times(seeds: int) -> list[str]:
    """``--refine``'s planning time (composition with the joint-space check, then the
    refinement) of each paper task over trial seeds 0..seeds-1, with each action cost."""
    lines = []
    for name, library in PAPER_TASKS:
        task = load_task(scenarios_directory() / f"{name}.yaml")
        features = library_features(Library.open(library))
        for cost in ("fidelity", "paper"):
            times, refined = [], 0
            for seed in range(seeds):
                start = time.perf_counter()
                _, _, checker, result, _ = _compose(task, features, seed, cost)
                if result.planned:
                    result = refine_plan(result, checker)
                    refined += result.refinement.refined
                times.append(time.perf_counter() - start)
            lines.append(f"{name} ({library}, --cost {cost}): planning with --refine over {seeds} seeds median "
                         f"{np.median(times):.2f} s, max {max(times):.2f} s (target < 3 s); {refined} refined")
    return lines


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--pick-and-place", type=int, default=10, metavar="N",
                        help="random pick-and-place tasks to add (seeds 0..N-1)")
    parser.add_argument("--cost", default="fidelity", choices=("paper", "fidelity"),
                        help="the planner's action cost (drake-lfd plan's default: fidelity)")
    parser.add_argument("--seeds", type=int, default=10, help="trial seeds of the planning-time measurement")
    args = parser.parse_args()
    sims = scenarios_directory()
    paper5 = library_features(Library.open("paper5"))
    paper6 = library_features(Library.open("paper6"))
    rows = []
    libraries = {"paper5": paper5, "paper6": paper6}
    for name, library in PAPER_TASKS:
        rows += bench_task(name, load_task(sims / f"{name}.yaml"), libraries[library], args.cost)
        print(f"{name}: done", flush=True)
    with tempfile.TemporaryDirectory() as directory:
        for path in write_pick_and_place_tasks(Path(directory), args.pick_and_place):
            rows += bench_task(path.stem, load_task(path), paper5, args.cost)
    print()
    print(_table(rows))
    print()
    for line in _summary(rows):
        print(line)
    executed = {m: [r["executed_s"] for r in rows if r["method"] == m and "executed_s" in r] for m in METHODS}
    for method in METHODS:
        values = executed[method]
        successes = sum(1 for r in rows if r["method"] == method and r.get("success"))
        print(f"{method}: {successes} successes of {len(values)} runs; mean executed duration "
              f"{np.mean(values) if values else float('nan'):.2f} s")
    if args.seeds > 0:
        print()
        for line in planning_times(args.seeds):
            print(line, flush=True)


if __name__ == "__main__":
    main()
