"""Refinement by trajectory optimization beside the unrefined plan and the plain optimizer.

Run: ``python benchmarks/bench_refinement.py [--pick-and-place 10] [--seeds 20] [--cost fidelity]
[--no-closed-loop] [--tasks NAME ...]``.

The plain optimizer here is the independent peer of the acceptance figures: Drake's
``KinematicTrajectoryOptimization`` through the same critical configurations, without
demonstrations or tube, under the full UR5e limits (pi rad/s, 8 rad/s^2, 1.5 m/s tool;
no slow passage of the critical configurations), solved with SNOPT
(``plain_plan`` with :data:`PLAIN_OPTIONS`). The refinement keeps to the task's
``timing:`` limits at their 0.9 share, as the composed plan's timing does.

1. Over ``--seeds`` trial seeds of each paper task (transferring and
   filling-and-pouring with ``paper5``, assembling with ``paper6``), as ``drake-lfd plan
   --refine`` does (exact planner, plan-time joint-space check, then the refinement):
   how many plans are refined, each other plan's reason (counted), the refinement's time
   per plan (median and largest; the solver's share beside it; wall time, so inflated on
   a loaded machine; and the process's CPU time, which a busy machine inflates less) and
   its work (SNOPT's evaluations of the program: the same on any
   machine), and the refined motion's duration against the plain optimizer's on the same
   plan (median and largest ratio; target: the median at most 1.2), and that ratio in two
   factors: the plain optimizer under the refinement's own limits (0.9 of them, the slow
   passage of the inner critical configurations) against the full limits (the handicap
   the task's limits set), and the refined motion against that plain optimizer (what
   the tube and the demonstrations cost). The scene (one per
   paper task, as a worker's planner keeps one) remembers the programs it solved by their
   exact inputs, so a trial whose programs were all solved before (every assembling trial
   after the first: the task has no variables) is answered from memory with the same
   bits; the count of those, the first plan's CPU time and the median of the plans
   solved afresh are printed too. Then the same on
   ``--pick-and-place`` random pick-and-place tasks (one trial each, ``paper5``).
2. At trial seed 0 of each paper task and on each pick-and-place task, the three plans
   (unrefined, refined, plain) run once closed loop (a pipeline Diagram with the plan
   given, from the start of its checked joint path), side by side: planning time,
   executed duration (con_1 to the last critical configuration), closed-loop success
   (``diagrams/judging.py``), and the deviation from the demonstrated shape, two
   ways: the tube's own measure (the largest distance and angle of an executed pose from
   the composed path at the same path fraction; tube 150 mm, 30 deg) and the largest
   distance (and angle) from an executed pose to the nearest pose of the composed path,
   as a set. ``--no-closed-loop`` skips this part.

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
from drake_lfd.diagrams.judging import judge_run
from drake_lfd.experiments.pick_and_place import write_pick_and_place_tasks
from drake_lfd.io.library import Library, library_features
from drake_lfd.io.task_files import load_task
from drake_lfd.planning.options import PlanningOptions
from drake_lfd.planning.planner import plan_composition
from drake_lfd.planning.refinement import refine_plan
from drake_lfd.planning.refinement_options import RefinementOptions
from drake_lfd.planning.refinement_tube import path_fractions_of, shape_deviation, tube_deviation
from drake_lfd.planning.plain_optimizer import plain_plan
from drake_lfd.robot.kinematics import UR5eKinematics
from drake_lfd.robot.trajectory_optimization import OptimizationScene, TrajectoryLimits
from drake_lfd.robot.workcell import Workcell

METHODS = ("unrefined", "refined", "plain")
TUBE_POSITION_M = RefinementOptions().tube_position_m
TUBE_ROTATION_RAD = RefinementOptions().tube_rotation_rad
PAPER_TASKS = (("transferring", "paper5"), ("filling_pouring", "paper5"), ("assembling", "paper6"))
#: The plain optimizer of the acceptance figures: the full UR5e limits, no slow passage.
PLAIN_OPTIONS = RefinementOptions(limits=TrajectoryLimits(joint_speed_rad_s=math.pi, acceleration_rad_s2=8.0,
                                                          tool_speed_m_s=1.5), pass_speed_m_s=None)


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
    checker, the composed plan and the time ``plan_composition`` took."""
    concrete = draw_trial(task, seed)
    workcell = Workcell.of(concrete)
    checker = joint_path_checker(workcell, task.simulation)
    start = time.perf_counter()
    composed = plan_composition(concrete, features, PlanningOptions(cost=cost), seed=seed,
                                floor_z=workcell.planner_floor, checker=checker)
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
            if method == "refined":
                result = refine_plan(composed, checker, scene=scene)
            else:
                result = plain_plan(composed, checker, scene=scene, options=PLAIN_OPTIONS)
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
            lines.append(f"{task}: refined / plain executed duration {refined['executed_s'] / plain['executed_s']:.2f}; "
                         f"refined executed path {'inside' if inside else 'OUTSIDE'} the tube "
                         f"({1000 * refined['tube_m']:.0f} mm, {math.degrees(refined['tube_rad']):.1f} deg; plain "
                         f"{1000 * plain['tube_m']:.0f} mm, {math.degrees(plain['tube_rad']):.1f} deg)")
    for row in rows:
        if row.get("reason"):
            lines.append(f"{row['task']} {row['method']}: {row['reason']}")
        for failure in row.get("failures", []):
            lines.append(f"{row['task']} {row['method']}: closed loop: {failure}")
    return lines


def _refinement_row(concrete, checker, composed, scene) -> dict:
    """One plan's refinement and plain optimization: status, reason, times, work and
    the two motions' durations (the plain one's whenever SNOPT gave a motion, whether
    or not the project's checks accept it: it is the reference)."""
    misses = scene.solutions.misses
    cpu = time.process_time()
    report = refine_plan(composed, checker, scene=scene).refinement
    cpu = time.process_time() - cpu
    remembered = scene.solutions.misses == misses  # every program answered from the scene's memory
    plain = plain_plan(composed, checker, scene=scene, options=PLAIN_OPTIONS).refinement
    handicapped = plain_plan(composed, checker, scene=scene).refinement
    return {"handicapped_s": handicapped.duration_s, "status": report.status, "reason": report.reason, "total_s": report.total_time_s, "cpu_s": cpu,
            "solve_s": report.solve_time_s, "evaluations": report.evaluations, "budget_spent": report.budget_spent,
            "duration_s": report.duration_s, "plain_s": plain.duration_s, "plain_status": plain.status,
            "remembered": remembered}


def _reason_kind(reason: str) -> str:
    """A reason without its numbers, for counting (``check: collision``, ``optimizer: ...``)."""
    head = reason.split(";")[0]
    return ": ".join(head.split(": ")[:2]) if head.startswith("check") else head.split(" (")[0]


def _statistics_lines(label: str, rows: list[dict]) -> list[str]:
    refined = [r for r in rows if r["status"] == "refined"]
    reasons: dict[str, int] = {}
    for r in rows:
        if r["status"] != "refined":
            kind = _reason_kind(r["reason"])
            reasons[kind] = reasons.get(kind, 0) + 1
    ratios = [r["duration_s"] / r["plain_s"] for r in refined if math.isfinite(r["plain_s"])]
    totals = [r["total_s"] for r in rows]
    afresh = [r["cpu_s"] for r in rows[1:] if not r["remembered"]]
    lines = [f"{label}: {len(refined)}/{len(rows)} refined ({sum(r['budget_spent'] for r in refined)} of them "
             f"SNOPT's iterate at its iteration limit); refinement time median {np.median(totals):.2f} s, max "
             f"{max(totals):.2f} s (solver median {np.median([r['solve_s'] for r in rows]):.2f} s; target: median "
             f"<= 0.5 s), CPU time median {np.median([r['cpu_s'] for r in rows]):.2f} s, max "
             f"{max(r['cpu_s'] for r in rows):.2f} s; SNOPT evaluations median {np.median([r['evaluations'] for r in rows]):.0f}, max "
             f"{max(r['evaluations'] for r in rows)}",
             f"{label}: {sum(r['remembered'] for r in rows)} plans answered from the scene's memory of solved "
             f"programs (the same inputs, the same bits); the first plan's CPU time {rows[0]['cpu_s']:.2f} s, "
             + (f"the median of the others solved afresh {np.median(afresh):.2f} s" if afresh else
                "no other plan solved afresh")]
    if ratios:
        lines.append(f"{label}: refined / plain (full limits) duration over {len(ratios)} refined plans: median "
                     f"{np.median(ratios):.2f}, max {max(ratios):.2f} (target: median <= 1.2); refined mean "
                     f"{np.mean([r['duration_s'] for r in refined]):.2f} s, plain mean "
                     f"{np.mean([r['plain_s'] for r in refined if math.isfinite(r['plain_s'])]):.2f} s; plain "
                     f"optimizer without a motion: {sum(not math.isfinite(r['plain_s']) for r in rows)}")
    both = [r for r in refined if math.isfinite(r["plain_s"]) and math.isfinite(r["handicapped_s"])]
    if both:
        handicap = [r["handicapped_s"] / r["plain_s"] for r in both]
        tube = [r["duration_s"] / r["handicapped_s"] for r in both]
        lines.append(f"{label}: the ratio in two factors over {len(both)} plans: the plain optimizer under the "
                     f"refinement's own limits and slow passage / under the full limits median {np.median(handicap):.2f}, "
                     f"max {max(handicap):.2f}; refined / that plain optimizer (the tube's cost) median "
                     f"{np.median(tube):.2f}, max {max(tube):.2f}")
    lines += [f"{label}: not refined x{count}: {kind}" for kind, count in sorted(reasons.items())]
    return lines


def refinement_statistics(seeds: int, cost: str, pick_and_place: list, only: tuple = ()) -> list[str]:
    """Part 1 of the module docstring: over trial seeds 0..seeds-1 of each paper task,
    then one trial of each pick-and-place task file of ``pick_and_place`` (``only``:
    just those of these names, ``pick-and-place`` for those). Each job's lines are also
    printed as it finishes."""
    lines = []
    jobs = [(name, load_task(scenarios_directory() / f"{name}.yaml"), library, range(seeds))
            for name, library in PAPER_TASKS]
    jobs.append(("pick-and-place", None, "paper5", pick_and_place))
    jobs = [job for job in jobs if not only or job[0] in only]
    for name, task, library, trials in jobs:
        features = library_features(Library.open(library))
        rows, scene = [], None
        for trial in trials:
            seed = trial if task is not None else 0
            concrete, workcell, checker, composed, _ = _compose(task if task is not None else load_task(trial),
                                                                features, seed, cost)
            if not composed.planned:
                continue
            if scene is None or task is None:
                scene = OptimizationScene(workcell)
            rows.append(_refinement_row(concrete, checker, composed, scene))
        if rows:
            done = _statistics_lines(f"{name} ({library}, --cost {cost}, {len(rows)} plans)", rows)
            lines += done
            print("\n".join(done), flush=True)
    return lines


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--pick-and-place", type=int, default=10, metavar="N",
                        help="random pick-and-place tasks to add (seeds 0..N-1)")
    parser.add_argument("--cost", default="fidelity", choices=("paper", "fidelity"),
                        help="the planner's action cost (drake-lfd plan's default: fidelity)")
    parser.add_argument("--seeds", type=int, default=20, help="trial seeds of each paper task's statistics")
    parser.add_argument("--no-closed-loop", action="store_true", help="skip the closed-loop comparison")
    parser.add_argument("--tasks", nargs="+", default=(), metavar="NAME",
                        help="statistics of these jobs only (transferring, filling_pouring, assembling, "
                             "pick-and-place)")
    args = parser.parse_args()
    sims = scenarios_directory()
    libraries = {"paper5": library_features(Library.open("paper5")),
                 "paper6": library_features(Library.open("paper6"))}
    with tempfile.TemporaryDirectory() as directory:
        pick_and_place = write_pick_and_place_tasks(Path(directory), args.pick_and_place)
        statistics = refinement_statistics(args.seeds, args.cost, pick_and_place, tuple(args.tasks))
        rows = []
        if not args.no_closed_loop:
            for name, library in PAPER_TASKS:
                rows += bench_task(name, load_task(sims / f"{name}.yaml"), libraries[library], args.cost)
                print(f"{name}: closed loop done", flush=True)
            for path in pick_and_place:
                rows += bench_task(path.stem, load_task(path), libraries["paper5"], args.cost)
    if rows:
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
    print()
    for line in statistics:
        print(line)


if __name__ == "__main__":
    main()
