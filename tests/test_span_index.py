"""The span index and the swept legal-action table change no verdict, cost or plan.

On 240 seeded random problems (the paper's random training tasks and chained tasks,
several candidates per configuration, span limits, both cost modes, libraries of the
paper's demonstrations, random motions and mixed lengths) the table built with the index
equals the one without it bit for bit, both give the same exact plans, and both match a
reference built the way the table was first built: one forward allocation dynamic
programme per (span, demonstration).
"""

from __future__ import annotations

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


def random_problem(seed: int, use_index: bool) -> CompositionProblem:
    rng = np.random.default_rng(seed)
    kind = seed % 4
    if kind == 0:
        library = dict(PAPER)
    elif kind == 1:
        library = random_features(np.random.default_rng(seed), int(rng.integers(5, 30)))
    elif kind == 2:  # mixed lengths: the stacks are padded
        library = {**random_features(np.random.default_rng(seed), 6, num_samples=int(rng.integers(3, 40))),
                   **dict(list(PAPER.items())[:3])}
    else:
        library = {**random_features(np.random.default_rng(seed), 8), **PAPER}
    if seed % 3 == 0:
        task = random_training_task(rng, num_cons=int(rng.integers(3, 7)))
    else:
        source = PAPER if seed % 2 else library
        task, _ = chained_task(rng, source, num_cons=int(rng.integers(3, 9)), perturbation_deg=20,
                               perturbation_m=0.03)
    _, poses = task_candidates(task)
    if seed % 5 == 1:
        poses = turned_candidates(rng, poses, int(rng.integers(2, 4)))
    max_span = [None, 1, 2, 3][seed % 4 if seed % 7 else 0]
    cost = "fidelity" if seed % 2 else "paper"
    tolerances = Tolerances(d_alpha=0.5, d_beta=-0.9) if seed % 11 else Tolerances(d_alpha=0.3, d_beta=0.0)
    return CompositionProblem(poses, list(library.values()), tolerances, max_span, cost, use_index=use_index)


def same_table(a: dict, b: dict) -> bool:
    return list(a) == list(b) and all(np.array_equal(a[key], b[key]) for key in a)


@pytest.mark.slow
def test_the_index_changes_no_verdict_cost_or_plan_on_240_random_problems():
    discarded = 0
    tested = 0
    for seed in range(240):
        indexed, plain = random_problem(seed, True), random_problem(seed, False)
        assert same_table(indexed.cost, plain.cost), seed
        assert plan_exact(indexed) == plan_exact(plain), seed
        for left, right in zip(cost_to_go(indexed), cost_to_go(plain)):
            assert np.array_equal(left, right), seed
        discarded += indexed.stats.discarded_by_index
        tested += indexed.stats.tested
        if seed % 4 == 0:  # the reference is slow: every fourth problem
            reference = reference_table(plain)
            assert sorted(reference) == sorted(plain.cost), seed
            for key, matrix in reference.items():
                np.testing.assert_allclose(plain.cost[key], matrix, rtol=1e-12, atol=1e-12, err_msg=str(seed))
    assert discarded > 0.2 * (discarded + tested)  # the index did discard pairs


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
