"""Planner benchmarks (issue acceptance figures), printed, never asserted.

* training time: 20 random tasks x 100 episodes (Section 6.2) with a 5-demo library;
* exact planner: a 5-con task (the paper's Table 8, roll free on three cons, 15 deg grid)
  with 6 demonstrations: time to build the legal-action table and to solve it;
* held-out evaluation (seeds never used in training): 100 random tasks as in Section 6.2
  and 100 tasks chained from library demonstrations under random rigid placements
  (each con then perturbed by up to 15 deg and 2 cm).
  Reports how many each planner plans, the greedy Q-walk's completion rate without
  fallback, its mean cost against the optimum, and the fallback rate.

Usage: python benchmarks/bench_planners.py [--library synthetic|paper5|DIR]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from drake_lfd.planning.exact_planner import plan_exact
from drake_lfd.planning.planner import build_problem
from drake_lfd.planning.q_learning import DEFAULT_REFINE_EPISODES, greedy_walk, plan_q
from drake_lfd.planning.random_tasks import chained_task, random_training_task
from drake_lfd.core.synthetic_library import PAPER5, PAPER6, synthetic_features
from drake_lfd.core.tasks import ConcreteCriticalConfiguration, ConcreteTask
from drake_lfd.planning.training import train_on_random_tasks

__all__ = ["main"]


def load_features(name, six=False):
    if name == "synthetic":
        return synthetic_features(PAPER6 if six else PAPER5)
    from drake_lfd.io.library import Library, library_features

    if name == "paper5" and six:
        name = "paper6"
    return library_features(Library.open(name))


def table8_task():
    pi = np.pi
    free_roll = dict(euler_zyx_lower=[0, -pi / 2, -pi], euler_zyx_upper=[0, -pi / 2, pi], angle_grid_deg=15)
    cons = [
        ConcreteCriticalConfiguration.fixed([-0.4, -0.1, 0.0], [0, -pi, 0]),
        ConcreteCriticalConfiguration(p=[-0.5, 0.1, 0.1], **free_roll),
        ConcreteCriticalConfiguration(p=[-0.7, -0.1, 0.1], **free_roll),
        ConcreteCriticalConfiguration(p=[-0.3, -0.1, 0.1], **free_roll),
        ConcreteCriticalConfiguration.fixed([-0.3, -0.1, 0.0], [pi / 2, 0, -pi / 2]),
    ]
    return ConcreteTask("table8", cons)


def median_ms(function, repeats):
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        value = function()
        times.append(time.perf_counter() - start)
    return 1e3 * float(np.median(times)), value


def gap_text(cost, optimum):
    """Relative gap, or only the absolute one when the optimum is ~0 (exact copies)."""
    if not np.isfinite(optimum):
        return "n/a"
    if optimum < 1e-3:
        return f"absolute {cost - optimum:+.2e}"
    return f"{100 * (cost - optimum) / optimum:+.2f}%, absolute {cost - optimum:+.4f}"


def evaluate(problems, policy, label):
    exact_plans = [plan_exact(p) for p in problems]
    q_plans = [plan_q(p, policy) for p in problems]
    plannable = [i for i, e in enumerate(exact_plans) if e is not None]
    agree = all((exact_plans[i] is None) == (q_plans[i].steps is None) for i in range(len(problems)))
    fallbacks = sum(1 for q in q_plans if q.fallback)
    print(f"{label}: {len(problems)} tasks, exact plans {len(plannable)}, Q plans "
          f"{sum(q.steps is not None for q in q_plans)} (same tasks: {agree}); fallback rate "
          f"{fallbacks}/{len(problems)}")
    for refine in (DEFAULT_REFINE_EPISODES, 0):
        walks = [greedy_walk(problems[i], policy, refine_episodes=refine) for i in plannable]
        pairs = [(sum(s.cost for s in w), sum(s.cost for s in exact_plans[i]))
                 for i, w in zip(plannable, walks) if w is not None]
        q_cost = np.mean([a for a, _ in pairs]) if pairs else float("nan")
        optimum = np.mean([b for _, b in pairs]) if pairs else float("nan")
        how = f"after {refine} plan-time episodes" if refine else "general table alone"
        print(f"    greedy walk, {how}: completes {len(pairs)}/{len(plannable)} "
              f"({100 * len(pairs) / max(len(plannable), 1):.0f}%), mean cost {q_cost:.4f} vs optimum "
              f"{optimum:.4f} (gap {gap_text(q_cost, optimum)})")


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--library", default="synthetic")
    args = parser.parse_args()
    features5 = load_features(args.library)
    features6 = load_features(args.library, six=True)

    start = time.perf_counter()
    paper_only = train_on_random_tasks(features5, num_tasks=20, num_chained_tasks=0, episodes=100, seed=0)
    total = time.perf_counter() - start
    print(f"training, 20 random tasks x 100 episodes, {len(features5)} demos: episodes "
          f"{paper_only.wall_time_s:.3f} s, including building the 20 legal-action tables {total:.3f} s "
          f"(paper: 1927.42 s)")
    start = time.perf_counter()
    result = train_on_random_tasks(features5, num_tasks=20, num_chained_tasks=20, episodes=100, seed=0)
    total = time.perf_counter() - start
    print(f"training, 20 random + 20 chained tasks x 100 episodes: episodes "
          f"{result.wall_time_s:.3f} s, including building the tables {total:.3f} s")

    task = table8_task()
    build_ms, problem = median_ms(lambda: build_problem(task, features6), 9)
    solve_ms, steps = median_ms(lambda: plan_exact(problem), 21)
    print(f"exact planner, 5 cons (roll free on 3, 15 deg grid: {problem.num_candidates} candidates), "
          f"{len(features6)} demos: shortest-path solve {solve_ms:.2f} ms, legal-action table "
          f"{build_ms:.1f} ms (median); composition "
          f"{[(list(features6)[s.demo], s.j + 1, s.k + 1) for s in steps] if steps else None}")

    rng = np.random.default_rng(123456)
    random_problems = [build_problem(random_training_task(rng), features5) for _ in range(100)]
    # Chained tasks, each con then turned by up to 15 deg and moved by up to 2 cm, so the
    # costs are informative (an exact copy of a demo costs 0 whatever the planner).
    chained_problems = [
        build_problem(chained_task(rng, features5, perturbation_deg=15, perturbation_m=0.02)[0], features5)
        for _ in range(100)
    ]
    evaluate(random_problems, result.policy, "held-out random tasks (Section 6.2)")
    evaluate(chained_problems, result.policy, "held-out chained tasks")
    evaluate(chained_problems, paper_only.policy, "held-out chained tasks, policy from random tasks only")


if __name__ == "__main__":
    main()
