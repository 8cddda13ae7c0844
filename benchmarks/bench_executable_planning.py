"""Planning time before and after the joint-space check (executable plans), printed.

Run: ``python benchmarks/bench_executable_planning.py [--trials 5]``.

For the paper's three tasks (transferring and filling-and-pouring with ``paper5``,
assembling with ``paper6``; trials 0..N-1 drawn as ``simulate`` draws them) and for a
20-configuration task chained from a 30-demonstration library (the five paper
demonstrations, each in six versions whose translations are stretched by 0-25 %, so no
two features are equal), prints the median and the largest wall time of
``plan_composition`` (the paper's cost) without the check ("before") and with it ("after": lazy search over
compositions, the joint path of each checked one followed at the controller's 10 ms),
with the rounds of the search and the status; "after" also gives its median CPU time
(``time.process_time``, which load inflates less). The check is built once per scene, as
``plan``, ``simulate`` and the planner system do, so a trial reuses what earlier trials
of the task computed (a follow resumed where two plans part, a timed piece of joint path
remembered by its exact inputs; the plans are the same either way): "first" is the
first trial's time, when nothing was there to reuse. ``--fresh`` plans every trial as
in a new process (a new check, the timed pieces forgotten).
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from drake_lfd.core.dual_quaternion import (
    dual_quaternion_from_translation_rotation,
    translation_rotation_from_dual_quaternion,
)
from drake_lfd.core.features import Feature
from drake_lfd.core.resources import scenarios_directory
from drake_lfd.core.tasks import draw_trial
from drake_lfd.io.library import Library, library_features
from drake_lfd.io.task_files import load_task
from drake_lfd.planning.options import PlanningOptions
from drake_lfd.planning.planner import plan_composition

# The paper's cost, without and with the check (figures in benchmarks/RESULTS.md).
UNCHECKED = PlanningOptions.paper_baseline()
CHECKED = PlanningOptions(cost="paper")
from drake_lfd.planning.random_tasks import chained_task
from drake_lfd.robot import path_timing
from drake_lfd.robot.joint_path import JointPathChecker
from drake_lfd.robot.scene import KinematicScene, table_under_robot


def checker_for(task) -> tuple[JointPathChecker, float]:
    table = table_under_robot(task.X_WB)
    scene = KinematicScene(X_WB=task.X_WB, X_tool0_E=task.X_tool0_E, obstacles=task.obstacles,
                           safety_shells=task.safety_shells, table=table, tool=getattr(task, "tool", None))
    checker = JointPathChecker(scene, X_WB=task.X_WB, table_geometry_ids=[scene.geometry.table_geometry_id])
    return checker, float(table.centre[2] + table.size[2] / 2)


def timed(function):
    """``(value, wall s, CPU s)`` of ``function()``."""
    start, cpu = time.perf_counter(), time.process_time()
    value = function()
    return value, time.perf_counter() - start, time.process_time() - cpu


def report(label, before, after, after_cpu, results):
    rounds = [r.search_rounds for r in results]
    statuses = sorted({r.status for r in results})
    print(f"{label:34s} before: median {1000 * np.median(before):6.0f} ms, max {1000 * max(before):6.0f} ms | "
          f"after: median {1000 * np.median(after):6.0f} ms (CPU {1000 * np.median(after_cpu):4.0f} ms), "
          f"max {1000 * max(after):6.0f} ms, first {1000 * after[0]:6.0f} ms | "
          f"rounds {min(rounds)}-{max(rounds)}, {', '.join(statuses)}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--trials", type=int, default=5)
    parser.add_argument("--fresh", action="store_true",
                        help="plan each trial as in a new process: nothing reused from the trials before")
    args = parser.parse_args()

    def check_for(task):
        """The scene's check, new for every trial with --fresh."""
        if args.fresh:
            path_timing.forget_timed_pieces()
            return checker_for(task)
        return shared
    for name, library in (("transferring", "paper5"), ("filling_pouring", "paper5"), ("assembling", "paper6")):
        task = load_task(scenarios_directory() / f"{name}.yaml")
        features = library_features(Library.open(library))
        shared = checker_for(task)
        floor = shared[1]
        path_timing.forget_timed_pieces()
        before, after, after_cpu, results = [], [], [], []
        for seed in range(args.trials):
            concrete = draw_trial(task, seed)
            before.append(timed(lambda: plan_composition(concrete, features, UNCHECKED, floor_z=floor))[1])
            checker = check_for(task)[0]
            result, seconds, cpu = timed(lambda: plan_composition(concrete, features, CHECKED, floor_z=floor,
                                                                        checker=checker))
            after.append(seconds)
            after_cpu.append(cpu)
            results.append(result)
        report(f"{name} ({library}, {args.trials} trials)", before, after, after_cpu, results)

    paper5 = library_features(Library.open("paper5"))
    library30 = {}
    for copy in range(6):
        for name, feature in paper5.items():
            p, r = translation_rotation_from_dual_quaternion(feature.poses)
            stretched = dual_quaternion_from_translation_rotation(p[0] + (1.0 + 0.05 * copy) * (p - p[0]), r)
            library30[f"{name}_{copy}"] = Feature.from_poses(stretched)
    transferring = load_task(scenarios_directory() / "transferring.yaml")
    shared = checker_for(transferring)
    path_timing.forget_timed_pieces()
    before, after, after_cpu, results = [], [], [], []
    for seed in range(args.trials):
        task, _ = chained_task(np.random.default_rng(seed), library30, num_cons=20, name="chained20")
        before.append(timed(lambda: plan_composition(task, library30, UNCHECKED))[1])
        checker = check_for(transferring)[0]
        result, seconds, cpu = timed(lambda: plan_composition(task, library30, CHECKED, checker=checker))
        after.append(seconds)
        after_cpu.append(cpu)
        results.append(result)
    report(f"20 cons, 30 demos ({args.trials} tasks)", before, after, after_cpu, results)


if __name__ == "__main__":
    main()
