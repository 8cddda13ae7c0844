"""Training a general policy on random tasks (Section 6.2) and warm-start retraining.

Not for: the learning rule itself (``q_learning.py``) or plotting (``figures.py``).
"""

from __future__ import annotations

from typing import Callable, Mapping

import numpy as np

from drake_lfd.composition import CompositionProblem
from drake_lfd.features import Feature
from drake_lfd.planning import build_problem
from drake_lfd.q_learning import QLearningParameters, QPolicy, TrainingResult, train
from drake_lfd.random_tasks import random_training_task
from drake_lfd.similarity import Tolerances


def random_training_problems(
    features: Mapping[str, Feature], num_tasks: int, seed: int, tolerances: Tolerances = Tolerances()
) -> list[CompositionProblem]:
    """``num_tasks`` Section 6.2 tasks (seeded) as composition problems."""
    rng = np.random.default_rng(seed)
    return [
        build_problem(random_training_task(rng, name=f"random_{i + 1}"), features, tolerances)
        for i in range(num_tasks)
    ]


def train_on_random_tasks(
    features: Mapping[str, Feature],
    *,
    num_tasks: int = 20,
    episodes: int = 100,
    seed: int = 0,
    warm_start: QPolicy | None = None,
    parameters: QLearningParameters | None = None,
    extra_problems: list[CompositionProblem] = (),
    progress: Callable[[int, int], None] | None = None,
) -> TrainingResult:
    """Algorithm 1 on ``num_tasks`` random tasks (plus ``extra_problems``, e.g. the task
    that asked for a new demonstration), ``episodes`` episodes each."""
    parameters = parameters or (warm_start.parameters if warm_start else QLearningParameters())
    parameters = QLearningParameters(**{**parameters.__dict__, "episodes": episodes})
    problems = random_training_problems(features, num_tasks, seed) + list(extra_problems)
    return train(
        problems, library_demos=list(features), parameters=parameters, seed=seed,
        policy=warm_start, progress=progress,
    )
