"""Q-learning of a general composition policy (Algorithm 1) and the greedy walk (Algorithm 2).

The Q-function is kept in the *afterstate* form (Sutton & Barto, Section 6.8)::

    Q(s, a) = r(s, a) + gamma * W(key(s'))

where ``r(s, a)`` is minus the allocation's total alpha (Eq. 31), known exactly from the
similarity test, ``s'`` the state the action leads to, ``key`` the task-independent
abstraction of ``state_abstraction.py``, and ``W`` a table learned with Eq. 33's update
applied to the afterstate: ``W(key(s')) <- (1 - lr) W + lr * max_a' Q(s', a')``, with
``W = 0`` at the goal and the episode-ending ``penalty`` (the paper's minus infinity)
when ``s'`` has no legal action, scaled by the fraction of the task left undone (so
an episode that gets further before it dead-ends earns more: a learning signal even on
training tasks no composition covers, which with the paper's random tasks are most). Keying by abstract states is what lets one table,
trained on random tasks, plan unseen ones (SPEC 7); legal actions always come from the
similarity test, so every plan is valid even in states never seen in training.

Parameters (Table 6 and what the paper leaves open):

* ``discount`` 0.9 and ``epsilon`` 0.8 as in Table 6. ``epsilon`` is used as the
  probability of taking the greedy action (exploring with probability 0.2); pass
  ``epsilon=0.2`` for the other reading.
* ``learning_rate`` 0.5: rewards are deterministic, so a large step converges in few
  episodes; the abstraction merges states, so it is kept below 1 to average them.
* ``W`` starts at 0 (optimistic, since rewards are <= 0), which drives exploration
  more reliably than the paper's random initialisation; the seed fixes everything.

Adding a demonstration adds actions but no keys, so a saved table warm-starts retraining
(``train(..., policy=old)``). Policies are JSON files with a format version.
"""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path
from typing import Callable, Sequence

import numpy as np

from drake_lfd.atomic_files import atomic_write_bytes
from drake_lfd.composition import CompositionProblem, Step
from drake_lfd.errors import InputError
from drake_lfd.exact_planner import plan_exact
from drake_lfd.state_abstraction import GOAL_KEY, state_key

POLICY_FORMAT_VERSION = 1


@dataclasses.dataclass(frozen=True)
class QLearningParameters:
    discount: float = 0.9
    epsilon: float = 0.8  # probability of the greedy action
    learning_rate: float = 0.5
    episodes: int = 100
    penalty: float = -10.0


@dataclasses.dataclass
class QPolicy:
    """The learned afterstate table and what it was trained with."""

    values: dict[str, float] = dataclasses.field(default_factory=dict)
    parameters: QLearningParameters = dataclasses.field(default_factory=QLearningParameters)
    library_demos: list[str] = dataclasses.field(default_factory=list)
    training_episodes: int = 0

    def value(self, key: str) -> float:
        return 0.0 if key == GOAL_KEY else self.values.get(key, 0.0)

    def q_value(self, problem: CompositionProblem, step: Step) -> float:
        return -step.cost + self.parameters.discount * self.value(cached_state_key(problem, step.k, step.a_k))

    # -- files ------------------------------------------------------------------------------
    def save(self, path: str | Path) -> None:
        """Writes the policy atomically (temporary file, fsync, rename)."""
        path = Path(path)
        document = {
            "format_version": POLICY_FORMAT_VERSION,
            "kind": "drake-lfd afterstate Q-table",
            "parameters": dataclasses.asdict(self.parameters),
            "library_demos": self.library_demos,
            "training_episodes": self.training_episodes,
            "values": dict(sorted(self.values.items())),
        }
        atomic_write_bytes(path, (json.dumps(document, indent=1) + "\n").encode())

    @classmethod
    def load(cls, path: str | Path) -> "QPolicy":
        path = Path(path)
        try:
            document = json.loads(path.read_text())
        except FileNotFoundError:
            raise InputError("no such policy file", file=str(path)) from None
        except (json.JSONDecodeError, UnicodeDecodeError) as error:
            raise InputError(f"not a JSON policy ({error})", file=str(path)) from None
        if not isinstance(document, dict) or document.get("format_version") != POLICY_FORMAT_VERSION:
            raise InputError(
                f"unsupported policy format (expected format_version {POLICY_FORMAT_VERSION})",
                file=str(path), field="format_version",
            )
        try:
            values = {str(k): float(v) for k, v in document["values"].items()}
            parameters = QLearningParameters(**document["parameters"])
            demos = [str(name) for name in document["library_demos"]]
            episodes = int(document.get("training_episodes", 0))
        except (KeyError, TypeError, ValueError, AttributeError) as error:
            raise InputError(f"malformed policy ({error})", file=str(path)) from None
        if not all(np.isfinite(v) for v in values.values()):
            raise InputError("non-finite value in the table", file=str(path), field="values")
        return cls(values, parameters, demos, episodes)


@dataclasses.dataclass(frozen=True)
class TrainingResult:
    policy: QPolicy
    rewards: np.ndarray  # (episodes, tasks) accumulated reward of each episode
    wall_time_s: float

    @property
    def curve(self) -> np.ndarray:
        """Average accumulated reward per episode over the training tasks (Fig. 7)."""
        return self.rewards.mean(axis=1)


def episodes_to_steady(curve: np.ndarray, window: int = 10, tolerance: float = 0.05) -> int:
    """First episode from which the ``window``-episode moving average stays within
    ``tolerance`` (relative to the final level, at least 0.05 absolute) of the final level."""
    curve = np.asarray(curve, dtype=float)
    if len(curve) < window:
        return len(curve)
    moving = np.convolve(curve, np.ones(window) / window, mode="valid")
    final = moving[-1]
    band = max(tolerance * abs(final), 0.05)
    outside = np.flatnonzero(np.abs(moving - final) > band)
    return 0 if len(outside) == 0 else int(outside[-1] + 1)


def cached_state_key(problem: CompositionProblem, k: int, a_k: int) -> str:
    """:func:`state_key`, memoised on the problem (episodes revisit the same states)."""
    cache = problem.__dict__.setdefault("_state_keys", {})
    key = cache.get((k, a_k))
    if key is None:
        key = cache[(k, a_k)] = state_key(problem, k, a_k)
    return key


def _start_candidates(problem: CompositionProblem, policy: QPolicy) -> np.ndarray:
    return np.array([policy.value(cached_state_key(problem, 0, a)) for a in range(problem.num_candidates[0])])


def _run_episode(problem, actions_cache, policy, rng, learn: bool) -> float:
    p = policy.parameters
    start_values = _start_candidates(problem, policy)
    if rng.random() < p.epsilon:
        a = int(np.argmax(start_values))
    else:
        a = int(rng.integers(len(start_values)))
    j, total = 0, 0.0
    while j < problem.num_cons - 1:
        key = cached_state_key(problem, j, a)
        actions = actions_cache.setdefault((j, a), problem.actions_from(j, a))
        if not actions:
            penalty = p.penalty * (problem.num_cons - 1 - j) / (problem.num_cons - 1)
            if learn:
                policy.values[key] = policy.value(key) + p.learning_rate * (penalty - policy.value(key))
            return total + penalty
        q = np.array([policy.q_value(problem, s) for s in actions])
        if learn:
            policy.values[key] = policy.value(key) + p.learning_rate * (q.max() - policy.value(key))
        choice = int(np.argmax(q)) if rng.random() < p.epsilon else int(rng.integers(len(actions)))
        step = actions[choice]
        total -= step.cost
        j, a = step.k, step.a_k
    return total


def train(
    problems: Sequence[CompositionProblem],
    *,
    library_demos: Sequence[str],
    parameters: QLearningParameters = QLearningParameters(),
    seed: int = 0,
    policy: QPolicy | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> TrainingResult:
    """Algorithm 1 on several tasks, episodes interleaved across tasks.

    ``policy`` warm-starts from a saved table (its values are copied, not modified).
    ``progress(done, total)`` is called after each episode round.
    """
    import time

    start = time.perf_counter()
    rng = np.random.default_rng(seed)
    learned = QPolicy(
        values=dict(policy.values) if policy else {},
        parameters=parameters,
        library_demos=list(library_demos),
        training_episodes=(policy.training_episodes if policy else 0),
    )
    caches = [dict() for _ in problems]
    rewards = np.zeros((parameters.episodes, len(problems)))
    for episode in range(parameters.episodes):
        for t, problem in enumerate(problems):
            rewards[episode, t] = _run_episode(problem, caches[t], learned, rng, learn=True)
        if progress:
            progress(episode + 1, parameters.episodes)
    learned.training_episodes += parameters.episodes
    return TrainingResult(learned, rewards, time.perf_counter() - start)


@dataclasses.dataclass(frozen=True)
class QPlan:
    steps: list[Step] | None
    greedy_completed: bool  # the greedy walk alone reached the last con
    fallback: str | None  # "exact" when the exact planner had to finish the job


def greedy_walk(problem: CompositionProblem, policy: QPolicy) -> list[Step] | None:
    """Algorithm 2: greedy on Q over legal actions; None if it reaches a dead end."""
    a = int(np.argmax(_start_candidates(problem, policy)))
    j, steps = 0, []
    while j < problem.num_cons - 1:
        actions = problem.actions_from(j, a)
        if not actions:
            return None
        q = [policy.q_value(problem, s) for s in actions]
        step = actions[int(np.argmax(q))]
        steps.append(step)
        j, a = step.k, step.a_k
    return steps


def plan_q(problem: CompositionProblem, policy: QPolicy) -> QPlan:
    """Greedy walk; if it dead-ends while a composition exists, the exact planner finishes,
    so the Q-planner never fails a task the library can cover."""
    steps = greedy_walk(problem, policy)
    if steps is not None:
        return QPlan(steps, True, None)
    exact = plan_exact(problem)
    return QPlan(exact, False, "exact" if exact is not None else None)
