"""Training a general policy on random tasks (Section 6.2) and warm-start retraining.

Beyond the paper, training can add tasks chained from the library's own demonstrations
(perturbed by up to 15 deg and 2 cm per configuration). With the paper's five
demonstrations none of 100 Section-6.2 random tasks is plannable (measured by
``benchmarks/bench_planners.py``), so they teach the table only about dead ends; chained
tasks teach it what completing a task costs (the general table's greedy walk on 100
held-out chained tasks: 4.0 % above the optimum with 20 chained training tasks, 10.4 %
without). The default is the paper's training set (no chained tasks): plan-time
refinement (``q_learning.greedy_walk``) closes the gap either way (0.0 %).

The policy records what it was trained with: the demonstrations' names and a hash of
each one's feature (:func:`feature_hash`), so a policy used with another library can be
told apart (``io/policy_files.check_policy_library``).

Not for: the learning rule itself (``q_learning.py``), policy files
(``io/policy_files.py``) or plotting (``experiments/figures.py``).
"""

from __future__ import annotations

import hashlib
from typing import Callable, Mapping, Sequence

import numpy as np

from drake_lfd.planning.composition import CompositionProblem
from drake_lfd.core.features import Feature
from drake_lfd.core.option_values import DEFAULT_CHAINED_TASKS
from drake_lfd.planning.planner import build_problem
from drake_lfd.planning.q_learning import QLearningParameters, QPolicy, TrainingResult, train
from drake_lfd.planning.random_tasks import chained_task, random_training_task
from drake_lfd.core.similarity import Tolerances


# Feature arrays are rounded to this many decimals before hashing, so the last bits of
# a recomputation (another machine's floating point) do not change the hash.
FEATURE_HASH_DECIMALS = 9


def feature_hash(feature: Feature) -> str:
    """The sha256 (hex) of a feature's ``rotations`` and ``translations`` arrays (shapes
    included, values rounded to :data:`FEATURE_HASH_DECIMALS` decimals, little-endian
    float64): equal for the same demonstration with the same tool frame and feature
    parameters, different when any of those changed."""
    digest = hashlib.sha256()
    for array in (feature.rotations, feature.translations):
        values = np.round(np.asarray(array, dtype=np.float64), FEATURE_HASH_DECIMALS) + 0.0  # no -0.0
        digest.update(repr(values.shape).encode())
        digest.update(values.astype("<f8").tobytes())
    return digest.hexdigest()


def feature_hashes(features: Mapping[str, Feature]) -> dict[str, str]:
    """Name -> :func:`feature_hash`, in the library's order."""
    return {name: feature_hash(feature) for name, feature in features.items()}


def random_training_problems(
    features: Mapping[str, Feature], num_tasks: int, seed: int, tolerances: Tolerances = Tolerances()
) -> list[CompositionProblem]:
    """``num_tasks`` Section 6.2 tasks (seeded) as composition problems."""
    rng = np.random.default_rng(seed)
    return [
        build_problem(random_training_task(rng, name=f"random_{i + 1}"), features, tolerances)
        for i in range(num_tasks)
    ]


__all__ = [
    "DEFAULT_CHAINED_TASKS",
    "CHAINED_PERTURBATION_DEG",
    "CHAINED_PERTURBATION_M",
    "FEATURE_HASH_DECIMALS",
    "feature_hash",
    "feature_hashes",
    "random_training_problems",
    "chained_training_problems",
    "train_on_random_tasks",
]

CHAINED_PERTURBATION_DEG = 15.0
CHAINED_PERTURBATION_M = 0.02


def chained_training_problems(
    features: Mapping[str, Feature], num_tasks: int, seed: int, tolerances: Tolerances = Tolerances()
) -> list[CompositionProblem]:
    """``num_tasks`` perturbed chained tasks (seeded) as composition problems."""
    rng = np.random.default_rng([seed, 1])
    return [
        build_problem(
            chained_task(rng, features, name=f"chained_{i + 1}", perturbation_deg=CHAINED_PERTURBATION_DEG,
                         perturbation_m=CHAINED_PERTURBATION_M)[0],
            features, tolerances,
        )
        for i in range(num_tasks)
    ]


def train_on_random_tasks(
    features: Mapping[str, Feature],
    *,
    num_tasks: int = 20,
    num_chained_tasks: int = DEFAULT_CHAINED_TASKS,
    episodes: int = 100,
    seed: int = 0,
    warm_start: QPolicy | None = None,
    parameters: QLearningParameters | None = None,
    extra_problems: Sequence[CompositionProblem] = (),
    progress: Callable[[int, int], None] | None = None,
    after_episode: Callable[[int, QPolicy], None] | None = None,
) -> TrainingResult:
    """Algorithm 1 on ``num_tasks`` random tasks and ``num_chained_tasks`` chained ones
    (plus ``extra_problems``, e.g. the task that asked for a new demonstration),
    ``episodes`` episodes each. ``progress`` and ``after_episode`` are passed to
    :func:`~drake_lfd.planning.q_learning.train`."""
    parameters = parameters or (warm_start.parameters if warm_start else QLearningParameters())
    parameters = QLearningParameters(**{**parameters.__dict__, "episodes": episodes})
    problems = (
        random_training_problems(features, num_tasks, seed)
        + chained_training_problems(features, num_chained_tasks, seed)
        + list(extra_problems)
    )
    return train(
        problems, library_demos=list(features), parameters=parameters, seed=seed,
        policy=warm_start, progress=progress, after_episode=after_episode,
        library_feature_hashes=feature_hashes(features),
    )
