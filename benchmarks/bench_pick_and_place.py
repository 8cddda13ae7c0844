"""Random pick-and-place workcell tasks: planned, not planned (why), planned-but-failed.

Run: ``python benchmarks/bench_pick_and_place.py [--tasks 50] [--seed 0] [--library paper5]``.

Generates the tasks (:mod:`drake_lfd.experiments.pick_and_place`: grasp, lift 25 cm,
carry, place; tool down; free yaw at the grasp; a box obstacle inside a shell between
grasp and place in most), and for each runs what ``drake-lfd plan`` and one
``drake-lfd simulate`` trial run (the same planner, joint-space check and pipeline
Diagram), then prints:

- how many got a plan, and for the others the reason (demonstration requested, or no
  executable plan with the blocking segments' causes);
- of the planned ones, how many failed in closed loop and why;
- the least ``|sin q3|`` and ``|sin q5|`` over every successful trial's logged joints
  (the target: none below 0.05).
"""

from __future__ import annotations

import argparse
import collections
import tempfile
import time
from pathlib import Path

import numpy as np

from drake_lfd.experiments.pick_and_place import write_pick_and_place_tasks
from drake_lfd.experiments.simulation import TrialRunner
from drake_lfd.io.library import Library, library_features
from drake_lfd.io.task_files import load_task
from drake_lfd.planning.options import PlanningOptions


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--tasks", type=int, default=50)
    parser.add_argument("--seed", type=int, default=0, help="seed of the first task")
    parser.add_argument("--library", default="paper5")
    parser.add_argument("--verbose", action="store_true", help="one line per task")
    parser.add_argument("--no-joint-check", action="store_true",
                        help="plan in SE(3) alone, without the plan-time joint-space check (the behaviour before it)")
    args = parser.parse_args()
    features = library_features(Library.open(args.library))
    counts = collections.Counter()
    reasons = collections.Counter()
    failures = collections.Counter()
    min_sin3, min_sin5 = np.inf, np.inf
    start = time.perf_counter()
    with tempfile.TemporaryDirectory() as directory:
        for path in write_pick_and_place_tasks(Path(directory), args.tasks, args.seed):
            task = load_task(path)
            runner = TrialRunner(task, features,
                                 options=PlanningOptions(cost="paper", joint_check=not args.no_joint_check))
            outcome = runner.run(trial=1, seed=0)
            plan = outcome.plan
            if plan is None or not plan.planned:
                status = "not planned" if plan is None else plan.status
                counts[status] += 1
                for segment in (plan.infeasible if plan is not None else ()):
                    reasons[f"{plan.status}: {segment.reason}"] += 1
                if plan is not None and plan.status == "demonstration_requested":
                    reasons["demonstration_requested"] += 1
                line = f"{path.stem}: {status}: " + "; ".join(outcome.failures)[:200]
            elif outcome.success:
                counts["planned, succeeded"] += 1
                q = outcome.run.q
                min_sin3 = min(min_sin3, float(np.abs(np.sin(q[:, 2])).min()))
                min_sin5 = min(min_sin5, float(np.abs(np.sin(q[:, 4])).min()))
                line = f"{path.stem}: planned, succeeded ({outcome.composition_label})"
            else:
                counts["planned, FAILED in closed loop"] += 1
                for failure in outcome.failures:
                    failures[failure.split(":")[0][:60]] += 1
                line = f"{path.stem}: planned, FAILED: " + "; ".join(outcome.failures)[:200]
            if args.verbose:
                print(line, flush=True)
    wall = time.perf_counter() - start
    print(f"{args.tasks} pick-and-place tasks (seeds {args.seed}..{args.seed + args.tasks - 1}), "
          f"library {args.library}, {'without' if args.no_joint_check else 'with'} the joint-space check, {wall:.0f} s")
    for key in ("planned, succeeded", "planned, FAILED in closed loop", "no_executable_plan",
                "demonstration_requested", "not planned"):
        if counts[key]:
            print(f"  {key}: {counts[key]}")
    if reasons:
        print("  why not planned (blocking segments found by the search, by cause):")
        for key, count in reasons.most_common():
            print(f"    {key}: {count}")
    if failures:
        print("  closed-loop failures:")
        for key, count in failures.most_common():
            print(f"    {key}: {count}")
    print(f"  least |sin q3| over successful trials: {min_sin3:.3f}; least |sin q5|: {min_sin5:.3f} (target >= 0.05)")


if __name__ == "__main__":
    main()
