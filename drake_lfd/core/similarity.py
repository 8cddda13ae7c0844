"""Semantic similarity of a task segment and a demonstration (Eq. 19-21, SPEC 5).

``alpha`` compares rotations (Eq. 19), ``beta`` translation directions (Eq. 20), and
:func:`allocate` decides Definition 1: an order-preserving allocation of the segment's
p deltas to demo deltas ``i_1 < ... < i_p`` with every pair within tolerance, choosing
the one with least total alpha (that total is the action's cost, Eq. 31).

Not for: building features (``features.py``), choosing among demonstrations or segments
(the planners), or mapping the demo (``mapping.py``).
"""

from __future__ import annotations

import dataclasses

import numpy as np

# A translation shorter than this has no direction (SPEC 5).
MIN_TRANSLATION_M = 1e-3


def rotation_distance(q1, q2):
    """Rotation distance ``alpha = min(|q1 - q2|, |q1 + q2|)`` (Eq. 5, 19).

    For unit quaternions this is ``2 sin(angle / 4)``, ``angle`` in [0, pi] being the
    relative rotation angle, so it does not depend on the quaternions' signs.

    Parameters
    ----------
    q1, q2 : array-like, shape (..., 4)
        Leading dimensions broadcast.

    Returns
    -------
    alpha : array, shape (...)
    """
    q1 = np.asarray(q1, dtype=float)
    q2 = np.asarray(q2, dtype=float)
    return np.minimum(np.linalg.norm(q1 - q2, axis=-1), np.linalg.norm(q1 + q2, axis=-1))


def translation_cosine(t1, t2, min_length_m=MIN_TRANSLATION_M):
    """Cosine ``beta`` between translations (Eq. 20) with SPEC 5's short-vector rule.

    Two translations shorter than ``min_length_m`` are similar (beta = 1); one short and
    one long are not (beta = -1).

    Parameters
    ----------
    t1, t2 : array-like, shape (..., 3)
        Leading dimensions broadcast.
    min_length_m : float

    Returns
    -------
    beta : array, shape (...), in [-1, 1]
    """
    t1 = np.asarray(t1, dtype=float)
    t2 = np.asarray(t2, dtype=float)
    n1 = np.linalg.norm(t1, axis=-1)
    n2 = np.linalg.norm(t2, axis=-1)
    short1 = n1 < min_length_m
    short2 = n2 < min_length_m
    cosine = np.sum(t1 * t2, axis=-1) / np.where(short1 | short2, 1.0, n1 * n2)
    return _short_rule(np.clip(cosine, -1.0, 1.0), short1, short2)


def _short_rule(cosine, short1, short2):
    return np.where(short1 & short2, 1.0, np.where(short1 | short2, -1.0, cosine))


@dataclasses.dataclass(frozen=True)
class Tolerances:
    """Similarity tolerances, defaults from Table 6 (SPEC 5).

    Attributes
    ----------
    d_alpha : float
        Largest rotation distance alpha (0.5 is about 58 deg).
    d_beta : float
        Smallest translation cosine beta.
    min_translation_m : float
        Translations shorter than this have no direction.
    """

    d_alpha: float = 0.5
    d_beta: float = -0.9
    min_translation_m: float = MIN_TRANSLATION_M


@dataclasses.dataclass(frozen=True, eq=False)
class Allocation:
    """An order-preserving allocation of task deltas to demo deltas (Definition 1).

    Attributes
    ----------
    indices : array of int, shape (p,)
        Strictly increasing demo delta indices (0-based rows of the demo feature, which
        are also indices of the demo poses the feature came from).
    cost : float
        Total alpha over the p pairs, the least among valid allocations.
    alphas : array, shape (p,)
        alpha of each pair.
    """

    indices: np.ndarray
    cost: float
    alphas: np.ndarray


def alpha_beta_matrices(task_rotations, task_translations, demo_rotations, demo_translations,
                        min_length_m=MIN_TRANSLATION_M):
    """alpha and beta of every (task delta, demo delta) pair.

    Parameters
    ----------
    task_rotations : array-like, shape (p, 4)
        Unit quaternions.
    task_translations : array-like, shape (p, 3)
    demo_rotations : array-like, shape (n, 4)
        Unit quaternions.
    demo_translations : array-like, shape (n, 3)
    min_length_m : float

    Returns
    -------
    alpha, beta : arrays, shape (p, n)
    """
    alpha = _alpha_matrix(task_rotations, demo_rotations)
    dots, lengths, task_short, demo_short = _translation_products(
        task_translations, demo_translations, min_length_m)
    cosine = np.minimum(np.maximum(dots / lengths, -1.0), 1.0)
    return alpha, _short_rule(cosine, task_short[:, None], demo_short[None, :])


def _alpha_matrix(task_rotations, demo_rotations):
    # For unit quaternions min(|a - b|, |a + b|)^2 = 2 - 2 |a . b|: one matrix product
    # instead of (p, n, 4) temporaries. Rounding leaves alpha ~1e-8 rather than 0 for
    # equal rotations; allocate() recomputes the chosen pairs with rotation_distance.
    dots = np.abs(np.asarray(task_rotations, dtype=float) @ np.asarray(demo_rotations, dtype=float).T)
    return np.sqrt(np.maximum(2.0 - 2.0 * dots, 0.0))


def _translation_products(task_translations, demo_translations, min_length_m):
    """Dot products (p, n), products of lengths (p, n) (1 where short), short masks."""
    task_translations = np.asarray(task_translations, dtype=float)
    demo_translations = np.asarray(demo_translations, dtype=float)
    task_length = np.sqrt(np.einsum("ij,ij->i", task_translations, task_translations))
    demo_length = np.sqrt(np.einsum("ij,ij->i", demo_translations, demo_translations))
    task_short = task_length < min_length_m
    demo_short = demo_length < min_length_m
    lengths = np.outer(np.where(task_short, 1.0, task_length), np.where(demo_short, 1.0, demo_length))
    return task_translations @ demo_translations.T, lengths, task_short, demo_short


def allocate(task_rotations, task_translations, demo_rotations, demo_translations,
             tolerances=Tolerances()):
    """Least-alpha order-preserving allocation of task deltas to demo deltas (Eq. 21).

    Dynamic programme over (task delta l, demo index i): ``cost[l, i]`` is the least
    total alpha of allocating deltas 1..l with delta l at demo index i; the best
    predecessor is a prefix minimum of row l-1, so the work is O(p n) with one loop over
    p. Ties go to the earliest demo indices.

    Parameters
    ----------
    task_rotations : array-like, shape (p, 4)
    task_translations : array-like, shape (p, 3)
    demo_rotations : array-like, shape (n, 4)
    demo_translations : array-like, shape (n, 3)
    tolerances : Tolerances

    Returns
    -------
    allocation : Allocation or None
        None when no valid allocation exists (including p > n).
    """
    alpha = _alpha_matrix(task_rotations, demo_rotations)
    p, n = alpha.shape
    if p == 0 or p > n:
        return None
    dots, lengths, task_short, demo_short = _translation_products(
        task_translations, demo_translations, tolerances.min_translation_m)
    # beta >= d_beta without dividing: dots >= d_beta * |t_task| |t_demo|.
    similar = dots >= tolerances.d_beta * lengths
    if task_short.any() or demo_short.any():
        both = task_short[:, None] & demo_short[None, :]
        either = task_short[:, None] | demo_short[None, :]
        beta_short = np.where(both, 1.0, -1.0)
        similar = np.where(either, beta_short >= tolerances.d_beta, similar)
    cost = np.where(similar & (alpha <= tolerances.d_alpha), alpha, np.inf)
    for l in range(1, p):
        best_before = np.minimum.accumulate(cost[l - 1])
        cost[l, 0] = np.inf
        cost[l, 1:] += best_before[:-1]
    last = int(np.argmin(cost[p - 1]))
    if not np.isfinite(cost[p - 1, last]):
        return None
    indices = np.empty(p, dtype=int)
    indices[p - 1] = last
    for l in range(p - 2, -1, -1):
        indices[l] = int(np.argmin(cost[l, : indices[l + 1]]))
    alphas = rotation_distance(np.asarray(task_rotations, dtype=float),
                               np.asarray(demo_rotations, dtype=float)[indices])
    indices.flags.writeable = False
    alphas.flags.writeable = False
    return Allocation(indices=indices, cost=float(alphas.sum()), alphas=alphas)


def allocate_features(task_feature, demo_feature, tolerances=Tolerances()):
    """:func:`allocate` for two ``features.Feature`` objects (task segment, demo)."""
    return allocate(task_feature.rotations, task_feature.translations,
                    demo_feature.rotations, demo_feature.translations, tolerances)
