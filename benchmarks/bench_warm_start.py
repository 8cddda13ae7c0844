"""Warm start measured: episodes until the greedy plan is optimal after a demonstration is added.

The paper's assembling task (``sims/assembling.yaml``, the trial of ``draw_trial(task,
seed)``) needs a demonstration with library paper5 and plans with paper6, which adds
``span``. For each seed:

* warm: a policy trained on paper5 the way ``drake-lfd paper`` trains it (20 random
  tasks x 100 episodes, that seed);
* scratch: an empty policy.

Both then retrain with paper6 on that seed's 20 random tasks plus the assembling task
(as ``drake-lfd paper`` retrains). Before retraining (episode 0) and after every episode
round, two greedy policies are compared with the exact planner's optimum on the
assembling task:

* ``walk``: the greedy walk of Algorithm 2 (legal actions only, legality recomputed
  from similarity), *without* plan-time refinement: what ``plan --planner q`` would
  plan with refinement off;
* ``whole``: the greedy episode over the paper's whole action set, illegal (demo,
  span) pairs included with their learned Q (the training's greedy evaluation, the
  curve of Fig. 10c); counted from episode 1.

For each: ``first``, the first episode after which its cost equals the optimum (within
1e-9), and ``stays``, the episode from which on it always does, through the cap. Printed
per seed, then median / mean / max over the seeds. A run that never gets there counts as
cap + 1 episodes (shown as ``>cap``). Figures are printed, never asserted; see
docs/method.rst, "Planning".

Usage: python benchmarks/bench_warm_start.py [--seeds 20] [--max-episodes 300]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from drake_lfd.core.resources import scenarios_directory
from drake_lfd.core.tasks import draw_trial
from drake_lfd.io.library import Library, library_features
from drake_lfd.io.task_files import load_task
from drake_lfd.planning.exact_planner import plan_exact
from drake_lfd.planning.planner import build_problem
from drake_lfd.planning.q_learning import QPolicy, greedy_walk
from drake_lfd.planning.training import train_on_random_tasks

__all__ = ["main"]

NUM_TASKS = 20
PAPER_EPISODES = 100
COST_TOLERANCE = 1e-9


def first_and_stays(optimal, offset, cap):
    """First episode with an optimal plan and the episode from which on every one is;
    ``optimal[i]`` is episode ``offset + i``; ``cap + 1`` when never."""
    optimal = np.asarray(optimal, dtype=bool)
    never = cap + 1
    first = int(np.argmax(optimal)) + offset if optimal.any() else never
    if not optimal[-1]:
        return first, never
    not_optimal = np.flatnonzero(~optimal)
    return first, offset if len(not_optimal) == 0 else int(not_optimal[-1]) + 1 + offset


def episodes_to_optimum(features6, problem, optimum, seed, warm_start, cap):
    """((walk first, walk stays), (whole first, whole stays)); see the module docstring."""

    def walk_is_optimal(policy):
        steps = greedy_walk(problem, policy)
        return steps is not None and abs(sum(s.cost for s in steps) - optimum) <= COST_TOLERANCE

    walk = [walk_is_optimal(warm_start or QPolicy())]
    result = train_on_random_tasks(features6, num_tasks=NUM_TASKS, episodes=cap, seed=seed,
                                   warm_start=warm_start, extra_problems=[problem],
                                   after_episode=lambda done, policy: walk.append(walk_is_optimal(policy)))
    whole = np.abs(result.greedy_rewards[:, -1] + optimum) <= COST_TOLERANCE
    return first_and_stays(walk, 0, cap), first_and_stays(whole, 1, cap)


def shown(value, cap):
    return f">{cap}" if value > cap else str(value)


def summary(values, cap):
    values = np.asarray(values)
    return f"median {np.median(values):.1f}, mean {np.mean(values):.1f}, max {shown(int(values.max()), cap)}"


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=20)
    parser.add_argument("--max-episodes", type=int, default=300)
    args = parser.parse_args(argv)
    cap = args.max_episodes

    task = load_task(scenarios_directory() / "assembling.yaml")
    features5 = library_features(Library.open("paper5"))
    features6 = library_features(Library.open("paper6"))
    print(f"assembling task, {NUM_TASKS} random tasks + the assembling task per retraining, "
          f"greedy walk without refinement, cap {cap} episodes")
    rows = []
    start = time.perf_counter()
    for seed in range(args.seeds):
        trial = draw_trial(task, seed)
        if plan_exact(build_problem(trial, features5)) is not None:
            raise SystemExit(f"seed {seed}: the assembling trial should need a demonstration with paper5")
        problem = build_problem(trial, features6)
        exact = plan_exact(problem)
        if exact is None:
            raise SystemExit(f"seed {seed}: the assembling trial should plan with paper6")
        optimum = sum(s.cost for s in exact)
        trained5 = train_on_random_tasks(features5, num_tasks=NUM_TASKS, episodes=PAPER_EPISODES, seed=seed)
        warm = episodes_to_optimum(features6, problem, optimum, seed, trained5.policy, cap)
        scratch = episodes_to_optimum(features6, problem, optimum, seed, None, cap)
        rows.append({"warm": warm, "scratch": scratch})
        cells = "; ".join(
            f"{start_label} {measure} first {shown(row[0], cap):>4} stays {shown(row[1], cap):>4}"
            for start_label, result in (("warm", warm), ("scratch", scratch))
            for measure, row in zip(("walk", "whole"), result))
        print(f"seed {seed:2d} (optimum {optimum:.6f}): {cells}")
    for start_label in ("warm", "scratch"):
        for index, measure in enumerate(("walk", "whole")):
            first = [row[start_label][index][0] for row in rows]
            stays = [row[start_label][index][1] for row in rows]
            never = sum(value > cap for value in first)
            print(f"{start_label:>7} {measure}: first optimal after {summary(first, cap)} episodes; "
                  f"optimal from then on after {summary(stays, cap)}; never within {cap}: {never}/{len(rows)}")
    print(f"wall time {time.perf_counter() - start:.1f} s")


if __name__ == "__main__":
    main()
