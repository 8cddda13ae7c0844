"""The vectorized fidelity cost equals, bit for bit, its first per-pair implementation.

``core/fidelity.py`` computes the fidelity terms on flat arrays by components (the task
side once per task delta) and the suffix excursions of many demonstrations at once. The
reference kept here is the implementation before that: the terms gathered pair by pair
with ``np.cross`` and ``np.linalg.norm``, the excursions one demonstration at a time from
its poses. Every array must be identical, not only close: the legal-action tables, costs
and plans built on them are then the same by construction, which the last test checks
on the random problems of ``test_span_index.py`` that show each of its cases twice
(``CASE_SEEDS``; among them every fact in the fidelity cost mode, where the terms and
the excursions are used): a bit-for-bit comparison proves itself problem by problem, so
more problems add only kinds of problem, and the test asserts it saw every kind.
"""

from __future__ import annotations

import collections

import numpy as np
import pytest

from drake_lfd.core import fidelity
from drake_lfd.core.dual_quaternion import IDENTITY_DUAL_QUATERNION, translation_from_dual_quaternion
from drake_lfd.core.quaternion import quaternion_conjugate, vector_rotated_by_quaternion
from drake_lfd.core.features import poses_from_deltas
from drake_lfd.core.similarity import Tolerances, alpha_beta_matrices, pair_costs, similar_pair_costs
from drake_lfd.core.synthetic_library import PAPER6, random_features, synthetic_features
from drake_lfd.planning import composition, span_index
from drake_lfd.planning.exact_planner import cost_to_go, plan_exact
from test_span_index import CASE_SEEDS, assert_each_case_twice, problem_cases, random_problem, same_table

MIN = Tolerances().min_translation_m


# -- the reference: the per-pair implementation, as it was ------------------------------
def reference_suffix_excursions(positions, min_length_m=MIN):
    p = np.asarray(positions, dtype=float)
    chord = p[-1] - p[:-1]
    length = np.linalg.norm(chord, axis=1)
    unit = chord / np.maximum(length, min_length_m)[:, None]
    offsets = p[None, :, :] - p[:-1, None, :]
    distance = np.linalg.norm(np.cross(offsets, unit[:, None, :]), axis=2)
    later = np.arange(len(p))[None, :] >= np.arange(len(p) - 1)[:, None]
    h = np.where(later, distance, 0.0).max(axis=1)
    h[length < min_length_m] = 0.0
    return h


def reference_feature_excursions(feature, min_length_m=MIN):
    poses = poses_from_deltas(feature.deltas, IDENTITY_DUAL_QUATERNION)
    return reference_suffix_excursions(translation_from_dual_quaternion(poses), min_length_m)


def reference_fidelity_terms(beta, task_q, t, demo_q, demo_t, demo_h, weights, min_length_m):
    task_length = np.linalg.norm(t, axis=-1)
    demo_length = np.linalg.norm(demo_t, axis=-1)
    log_ratio = np.log(np.maximum(task_length, min_length_m)) - np.log(np.maximum(demo_length, min_length_m))
    direction = np.arccos(np.clip(beta, -1.0, 1.0))
    pair = weights.direction_per_rad * direction + weights.log_scale * np.abs(log_ratio)
    pair[(task_length < min_length_m) & (demo_length < min_length_m)] = 0.0
    start_demo = vector_rotated_by_quaternion(quaternion_conjugate(demo_q), t)
    start_task = vector_rotated_by_quaternion(quaternion_conjugate(task_q), t)
    pair += weights.anchor_per_m * np.linalg.norm(start_demo - start_task, axis=-1)
    bend = weights.bend_per_m * 2.0 * task_length * np.sin(0.5 * direction)
    bend[(task_length < min_length_m) & (demo_length < min_length_m)] = 0.0
    pair += bend
    scale = np.where(demo_length < min_length_m, 1.0, np.exp(log_ratio))
    first = weights.excursion_per_m * np.abs(scale - 1.0) * demo_h - bend
    return pair, first


def reference_action_pair_costs(task_q, task_t, demo_q, demo_t, demo_h, tolerances=Tolerances(), cost="paper",
                                weights=fidelity.FidelityWeights(), tie_break=True, demo_terms=None):
    """``demo_terms`` (the library's prepared demo side) is ignored: everything is
    computed from the deltas themselves, as it was."""
    if cost == "paper" and not tie_break:
        alpha = pair_costs(task_q, task_t, demo_q, demo_t, tolerances)
        return alpha, np.zeros(alpha.shape)
    factor = 1.0 if cost == "fidelity" else fidelity.PAPER_TIE_WEIGHT
    task_q, task_t, demo_q, demo_t, demo_h = (np.asarray(a, dtype=float) for a in (task_q, task_t, demo_q, demo_t,
                                                                                 demo_h))
    alpha, beta = alpha_beta_matrices(task_q, task_t, demo_q, demo_t, tolerances.min_translation_m)
    pair = similar_pair_costs(alpha, beta, tolerances)
    first = np.zeros(pair.shape)
    r, c = np.nonzero(np.isfinite(pair))
    terms, first_terms = reference_fidelity_terms(beta[r, c], task_q[r], task_t[r], demo_q[c], demo_t[c], demo_h[c],
                                                  weights, tolerances.min_translation_m)
    pair[r, c] += factor * terms
    first[r, c] = factor * first_terms
    return pair, first


# -- the comparisons -------------------------------------------------------------------
def mixed_library():
    """Random motions of 3 to 60 samples and the paper's demonstrations (99 deltas)."""
    features = []
    for seed, samples in enumerate((3, 4, 7, 12, 25, 60)):
        features += list(random_features(np.random.default_rng(seed), 3, num_samples=samples).values())
    return features + list(synthetic_features(PAPER6).values())


def test_excursions_equal_the_reference():
    features = mixed_library()
    for feature in features:
        assert np.array_equal(fidelity.feature_excursions(feature), reference_feature_excursions(feature))
    prepared = span_index.PreparedLibrary(features, Tolerances())
    order = np.random.default_rng(0).permutation(len(features))
    padded = prepared.excursions(order[:7])  # some first, then the rest (and the first again)
    padded = np.concatenate([padded, prepared.excursions(order)])
    for row, d in enumerate(np.concatenate([order[:7], order])):
        n = len(features[d])
        assert np.array_equal(padded[row, :n], reference_feature_excursions(features[d])), d
        assert not padded[row, n:].any()


@pytest.mark.parametrize("seed", range(6))
def test_pair_costs_equal_the_reference(seed):
    rng = np.random.default_rng(seed)
    features = mixed_library()
    for trial in range(40):
        demo = features[rng.integers(len(features))]
        source = features[rng.integers(len(features))]
        p = int(rng.choice([1, 1, 2, 9]))
        picked = rng.integers(0, len(source), p)
        task_q = source.rotations[picked] * rng.choice([-1.0, 1.0], (p, 1))
        task_t = source.translations[picked] * rng.uniform(0.3, 3.0, (p, 1))
        task_t[rng.random(p) < 0.25] *= 1e-4  # short task translations
        demo_t = demo.translations.copy()
        demo_t[rng.random(len(demo_t)) < 0.1] *= 1e-4  # and short demo ones
        demo_h = reference_feature_excursions(demo)
        tolerances = Tolerances(d_alpha=float(rng.choice([0.2, 0.5, 1.5])), d_beta=float(rng.choice([-1.0, -0.9, 0.0])))
        for cost in fidelity.COST_MODES:
            for tie_break in (True, False):
                args = (task_q, task_t, demo.rotations, demo_t, demo_h, tolerances, cost, fidelity.FidelityWeights(),
                        tie_break)
                new, old = fidelity.action_pair_costs(*args), reference_action_pair_costs(*args)
                assert np.array_equal(new[0], old[0]) and np.array_equal(new[1], old[1]), (seed, trial, cost)
                # With the demo side prepared once (as a library keeps it): the same bits.
                terms = fidelity.demo_delta_terms(demo_t, tolerances.min_translation_m)
                prepared = fidelity.action_pair_costs(*args, demo_terms=terms)
                assert np.array_equal(prepared[0], old[0]) and np.array_equal(prepared[1], old[1]), (seed, trial)


def test_elementwise_terms_equal_the_reference():
    """``fidelity_terms`` pair by pair (its documented elementwise use) and broadcast."""
    rng = np.random.default_rng(7)
    demo = mixed_library()[-1]
    picked = rng.integers(0, len(demo), len(demo))
    task_q, task_t = demo.rotations[picked], demo.translations[picked] * rng.uniform(0.5, 2.0, (len(demo), 1))
    beta = rng.uniform(-1.0, 1.0, len(demo))
    h = reference_feature_excursions(demo)
    weights = fidelity.FidelityWeights()
    new = fidelity.fidelity_terms(beta, task_q, task_t, demo.rotations, demo.translations, h, weights, MIN)
    old = reference_fidelity_terms(beta, task_q, task_t, demo.rotations, demo.translations, h, weights, MIN)
    assert np.array_equal(new[0], old[0]) and np.array_equal(new[1], old[1])
    # Every task delta against every demo delta at once, as the pairs one by one.
    square = np.broadcast_to(beta[:, None], (len(demo), len(demo)))
    grid = fidelity.fidelity_terms(square, task_q[:, None], task_t[:, None], demo.rotations[None],
                                   demo.translations[None], h[None], weights, MIN)
    rows, columns = np.indices(square.shape).reshape(2, -1)
    pairs = reference_fidelity_terms(square.reshape(-1), task_q[rows], task_t[rows], demo.rotations[columns],
                                     demo.translations[columns], h[columns], weights, MIN)
    assert np.array_equal(grid[0].reshape(-1), pairs[0]) and np.array_equal(grid[1].reshape(-1), pairs[1])


def test_tables_and_plans_equal_the_reference_in_every_case(monkeypatch):
    def reference_excursions(self, demos):
        out = np.zeros((len(demos), self.rotations.shape[1]))
        for row, d in enumerate(demos.tolist()):
            out[row, :self.lengths[d]] = reference_feature_excursions(self.features[d])
        return out

    cases = collections.Counter()
    for seed in CASE_SEEDS:
        problem = random_problem(seed, True)
        table, plan, values = problem.cost, plan_exact(problem), cost_to_go(problem)
        with monkeypatch.context() as patch:
            patch.setattr(composition, "action_pair_costs", reference_action_pair_costs)
            patch.setattr(span_index.PreparedLibrary, "excursions", reference_excursions)
            reference = random_problem(seed, True)
            reference_table, reference_plan = reference.cost, plan_exact(reference)
            reference_values = cost_to_go(reference)
        assert same_table(table, reference_table), seed
        assert plan == reference_plan, seed
        assert all(np.array_equal(a, b) for a, b in zip(values, reference_values)), seed
        cases.update(problem_cases(seed, problem, plan))
    assert_each_case_twice(cases)
