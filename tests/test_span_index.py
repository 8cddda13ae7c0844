"""The span index and the swept legal-action table change no verdict, cost or plan.

On seeded random problems (the paper's random training tasks and chained tasks, several
candidates per configuration, span limits, both cost modes, libraries of the paper's
demonstrations, random motions and mixed lengths) the table built with the index
equals the one without it bit for bit, both give the same exact plans, and both match a
reference built the way the table was first built: one forward allocation dynamic
programme per (span, demonstration).

The comparison is exact, so one problem proves it for that problem; what more problems
add is more kinds of problem. :func:`problem_cases` names the kinds: each ingredient of
the recipe and what the index, the sweep and the planner did (and those in both cost
modes). The 240 problems the test once ran (seeds 0-239) show 60 cases; the 14 of
:data:`CASE_SEEDS` show each of them at least twice (a greedy cover of the 240's), and
the tests assert it, so no case is lost to a change of the recipe or of the seeds.
"""

from __future__ import annotations

import collections

import numpy as np
import pytest

from drake_lfd.core.dual_quaternion import (
    dual_quaternion_from_translation_rotation,
    dual_quaternion_multiply,
    dual_quaternion_relative,
    translation_from_dual_quaternion,
)
from drake_lfd.core.quaternion import quaternion_from_axis_angle
from drake_lfd.core.fidelity import action_pair_costs, feature_excursions
from drake_lfd.core.similarity import Tolerances, allocation_step
from drake_lfd.core.synthetic_library import PAPER6, random_features, synthetic_features
from drake_lfd.planning.composition import CompositionProblem
from drake_lfd.planning.exact_planner import cost_to_go, plan_exact
from drake_lfd.planning.planner import task_candidates
from drake_lfd.planning.random_tasks import chained_task, random_training_task
from drake_lfd.planning.span_index import ALPHA_MARGIN, PreparedLibrary

PAPER = synthetic_features(PAPER6)


def reference_table(problem: CompositionProblem) -> dict:
    """The legal-action table by the first implementation's method: per span end, every
    delta against every demo delta, then per (span, demo) the forward dynamic programme."""
    table = {}
    for k in range(1, problem.num_cons):
        D_k = problem.candidate_poses[k]
        for j in range(max(0, k - problem.max_span), k):
            rows, firsts = {}, {}
            for l in range(j, k):
                delta = dual_quaternion_relative(problem.candidate_poses[l][:, None, :], D_k[None]).reshape(-1, 8)
                rows[l], firsts[l] = [], []
                for feature in problem.demo_features:
                    pair, first = action_pair_costs(
                        delta[:, :4], translation_from_dual_quaternion(delta), feature.rotations,
                        feature.translations, feature_excursions(feature), problem.tolerances, problem.cost_mode,
                        problem.fidelity_weights, tie_break=False)
                    rows[l].append(pair.reshape(len(problem.candidate_poses[l]), len(D_k), -1))
                    firsts[l].append(first.reshape(rows[l][-1].shape))
            for d in range(problem.num_demos):
                current = rows[j][d] + firsts[j][d]
                for l in range(j + 1, k):
                    current = allocation_step(current, rows[l][d].min(axis=0)[None])
                total = current.min(axis=-1)
                if np.isfinite(total).any():
                    table[(j, k, d)] = total
    return table


def turned_candidates(rng, poses: list[np.ndarray], count: int) -> list[np.ndarray]:
    """Each configuration's pose and ``count - 1`` copies turned by up to 40 deg."""
    out = []
    for pose in poses:
        axes = rng.normal(size=(count - 1, 3))
        axes /= np.linalg.norm(axes, axis=1, keepdims=True)
        turns = dual_quaternion_from_translation_rotation(
            np.zeros((count - 1, 3)), quaternion_from_axis_angle(axes, np.radians(rng.uniform(0, 40, count - 1))))
        out.append(np.concatenate([pose[:1], dual_quaternion_multiply(pose[:1], turns)]))
    return out


LIBRARY_KINDS = ("paper", "random", "mixed lengths", "random and paper")


def recipe(seed: int) -> dict:
    """What :func:`random_problem` makes of ``seed``."""
    return {
        "library": LIBRARY_KINDS[seed % 4],
        "task": "training" if seed % 3 == 0 else ("chained from paper" if seed % 2 else "chained from library"),
        "turned candidates": seed % 5 == 1,
        "span limit": [None, 1, 2, 3][seed % 4 if seed % 7 else 0],
        "cost": "fidelity" if seed % 2 else "paper",
        "tolerances": "loose" if seed % 11 else "tight",
    }


def random_problem(seed: int, use_index: bool) -> CompositionProblem:
    rng = np.random.default_rng(seed)
    made = recipe(seed)
    if made["library"] == "paper":
        library = dict(PAPER)
    elif made["library"] == "random":
        library = random_features(np.random.default_rng(seed), int(rng.integers(5, 30)))
    elif made["library"] == "mixed lengths":  # the stacks are padded
        library = {**random_features(np.random.default_rng(seed), 6, num_samples=int(rng.integers(3, 40))),
                   **dict(list(PAPER.items())[:3])}
    else:
        library = {**random_features(np.random.default_rng(seed), 8), **PAPER}
    if made["task"] == "training":
        task = random_training_task(rng, num_cons=int(rng.integers(3, 7)))
    else:
        source = PAPER if made["task"] == "chained from paper" else library
        task, _ = chained_task(rng, source, num_cons=int(rng.integers(3, 9)), perturbation_deg=20,
                               perturbation_m=0.03)
    _, poses = task_candidates(task)
    if made["turned candidates"]:
        poses = turned_candidates(rng, poses, int(rng.integers(2, 4)))
    tolerances = Tolerances(d_alpha=0.5, d_beta=-0.9) if made["tolerances"] == "loose" else Tolerances(d_alpha=0.3, d_beta=0.0)
    return CompositionProblem(poses, list(library.values()), tolerances, made["span limit"], made["cost"],
                              use_index=use_index)


# -- the cases -----------------------------------------------------------------------------
#: Facts also counted per cost mode: the cost mode switches the pair costs' whole code path.
PAIRED_WITH_COST = ("candidates", "tolerances", "short demo delta", "plan", "legal actions", "index discarded",
                    "index tested", "dropped earlier")
#: Problems showing every case of :func:`expected_cases` at least twice.
CASE_SEEDS = (0, 1, 3, 11, 22, 26, 30, 36, 61, 63, 65, 160, 165, 182)


def problem_cases(seed: int, problem: CompositionProblem, plan) -> set[str]:
    """The cases ``random_problem(seed, True)``, its table built and ``plan`` its exact
    plan, shows: the recipe's ingredients, whether a configuration has several candidate
    poses, whether a demonstration has a delta shorter than ``min_translation_m`` (the
    index's short/long rule), whether the index discarded pairs and any pair reached the
    exact test, whether a sweep dropped demonstrations, whether any action is legal and
    a plan exists; the facts of :data:`PAIRED_WITH_COST` also with the cost mode."""
    made = recipe(seed)
    library = problem.library
    short_demo = np.linalg.norm(library.translations, axis=-1)[library.valid] < problem.tolerances.min_translation_m
    facts = {
        "library": made["library"],
        "task": made["task"],
        "span limit": str(made["span limit"]),
        "cost": made["cost"],
        "tolerances": made["tolerances"],
        "candidates": "several" if max(problem.num_candidates) > 1 else "one",
        "short demo delta": str(bool(short_demo.any())),
        "plan": "found" if plan is not None else "none",
        "legal actions": "some" if problem.cost else "none",
        "index discarded": str(problem.stats.discarded_by_index > 0),
        "index tested": str(problem.stats.tested > 0),
        "dropped earlier": str(problem.stats.dropped_earlier > 0),
    }
    cases = {f"{name}={value}" for name, value in facts.items()}
    return cases | {f"{made['cost']} cost, {name}={facts[name]}" for name in PAIRED_WITH_COST}


def expected_cases() -> set[str]:
    """Every case seeds 0-239 show: each value of each fact, the facts of
    :data:`PAIRED_WITH_COST` in both cost modes; but the paper cost never meets a short
    demo delta (the seed's parity ties it to the paper's and the mixed-lengths libraries,
    which hold none)."""
    values = {
        "library": LIBRARY_KINDS,
        "task": ("training", "chained from paper", "chained from library"),
        "span limit": ("None", "1", "2", "3"),
        "cost": ("paper", "fidelity"),
        "tolerances": ("loose", "tight"),
        "candidates": ("one", "several"),
        "plan": ("found", "none"),
        "legal actions": ("some", "none"),
        **{name: ("True", "False") for name in ("short demo delta", "index discarded", "index tested",
                                                 "dropped earlier")},
    }
    cases = {f"{name}={value}" for name, options in values.items() for value in options}
    cases |= {f"{cost} cost, {name}={value}" for cost in values["cost"] for name in PAIRED_WITH_COST
              for value in values[name]}
    return cases - {"paper cost, short demo delta=True"}


def assert_each_case_twice(counts: collections.Counter) -> None:
    """``counts`` (case -> problems showing it) covers every expected case twice."""
    short = {case: counts[case] for case in sorted(expected_cases()) if counts[case] < 2}
    assert not short, f"cases shown by fewer than two problems (choose CASE_SEEDS again): {short}"


def same_table(a: dict, b: dict) -> bool:
    return list(a) == list(b) and all(np.array_equal(a[key], b[key]) for key in a)


def test_the_index_changes_no_verdict_cost_or_plan_in_any_case():
    """On :data:`CASE_SEEDS`, every case twice (module docstring): the same table, plan
    and values with and without the index, and the same table as the first method's."""
    discarded = 0
    tested = 0
    cases: collections.Counter = collections.Counter()
    for seed in CASE_SEEDS:
        indexed, plain = random_problem(seed, True), random_problem(seed, False)
        assert same_table(indexed.cost, plain.cost), seed
        plan = plan_exact(indexed)
        assert plan == plan_exact(plain), seed
        for left, right in zip(cost_to_go(indexed), cost_to_go(plain)):
            assert np.array_equal(left, right), seed
        discarded += indexed.stats.discarded_by_index
        tested += indexed.stats.tested
        reference = reference_table(plain)
        assert sorted(reference) == sorted(plain.cost), seed
        for key, matrix in reference.items():
            np.testing.assert_allclose(plain.cost[key], matrix, rtol=1e-12, atol=1e-12, err_msg=str(seed))
        cases.update(problem_cases(seed, indexed, plan))
    assert_each_case_twice(cases)
    assert discarded > 0.2 * (discarded + tested)  # the index did discard pairs


@pytest.mark.slow
def test_the_cases_are_those_of_the_240_problems_the_tests_ran_before():
    """The case list is what seeds 0-239 show, no more and no less (so CASE_SEEDS,
    which shows each twice, stands for them)."""
    shown = set()
    for seed in range(240):
        problem = random_problem(seed, True)
        shown |= problem_cases(seed, problem, plan_exact(problem))
    assert shown == expected_cases()


def test_rows_built_on_demand_equal_the_whole_table():
    for seed in (1, 2, 5, 13):
        lazy, whole = random_problem(seed, True), random_problem(seed, True)
        whole.cost  # noqa: B018 (builds every row)
        for j in range(lazy.num_cons - 2, -1, -1):
            for a_j in range(lazy.num_candidates[j]):
                assert lazy.actions_from(j, a_j) == whole.actions_from(j, a_j), (seed, j)
        assert same_table(lazy.cost, whole.cost)


def test_forbidding_before_the_table_is_whole_forbids_only_that_action():
    problem = random_problem(1, True)
    step = problem.actions_from(0, 0)[0]
    problem.forbid(step)
    assert step not in problem.actions_from(0, 0)
    reference = random_problem(1, True)
    matrix = reference.cost[(step.j, step.k, step.demo)].copy()
    matrix[step.a_j, step.a_k] = np.inf
    assert np.array_equal(problem.cost.get((step.j, step.k, step.demo), np.full_like(matrix, np.inf)), matrix)


def test_the_index_bound_holds_for_every_delta_it_discards():
    """Brute force: wherever some demo delta passes the rotation and short-translation
    tests, the index admits the demonstration."""
    rng = np.random.default_rng(3)
    features = list(random_features(rng, 40).values()) + list(PAPER.values())
    tolerances = Tolerances()
    library = PreparedLibrary(features, tolerances)
    q = rng.normal(size=(300, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    short = rng.random(300) < 0.2
    mask = library.index.candidates(q, short)
    assert 0 < mask.mean() < 1
    for d, feature in enumerate(features):
        alpha = np.minimum(np.linalg.norm(q[:, None] - feature.rotations[None], axis=-1),
                           np.linalg.norm(q[:, None] + feature.rotations[None], axis=-1))
        demo_short = np.linalg.norm(feature.translations, axis=-1) < tolerances.min_translation_m
        passes = (alpha <= tolerances.d_alpha + ALPHA_MARGIN) & (short[:, None] == demo_short[None])
        assert not (passes.any(axis=1) & ~mask[:, d]).any(), d


def test_the_walk_picks_what_a_scan_over_every_action_picks():
    """plan_exact's record scan against the scan over ``actions_from`` it replaced."""
    from drake_lfd.planning.exact_planner import TIE_BREAK_PER_STEP

    for seed in range(0, 240, 6):
        problem = random_problem(seed, True)
        value = cost_to_go(problem)
        steps = plan_exact(problem)
        if steps is None:
            assert not np.isfinite(value[0]).any()
            continue
        a = int(np.argmin(value[0]))
        for step in steps:
            best = None
            for candidate in problem.actions_from(step.j, a):
                total = candidate.cost + TIE_BREAK_PER_STEP + value[candidate.k][candidate.a_k]
                if best is None or total < best[0] - 1e-12:
                    best = (total, candidate)
            assert best[1] == step, seed
            a = step.a_k
