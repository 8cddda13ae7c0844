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

Plan-time refinement (beyond the paper's Algorithm 2, in the spirit of its retraining):
before the greedy walk, ``DEFAULT_REFINE_EPISODES`` episodes of the same Q-learning run
on the task's own states, seeded by the general table. A tabular key cannot tell apart
tasks that look alike but cost differently, so the general table alone walks 5-8 %
above the optimum on 100 held-out chained tasks; after refinement 0.0 % (measured by
``benchmarks/bench_planners.py``), at a cost of a few milliseconds.

Adding a demonstration adds actions but no keys, so a saved table warm-starts retraining
(``train(..., policy=old)``). Policies are JSON files with a format version.
"""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path
from typing import Callable, Sequence

import numpy as np

from drake_lfd.io.atomic_files import atomic_write_bytes
from drake_lfd.planning.composition import CompositionProblem, Step
from drake_lfd.core.errors import InputError
from drake_lfd.planning.exact_planner import plan_exact
from drake_lfd.planning.state_abstraction import GOAL_KEY, state_key

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
    # Q of actions found illegal in training, keyed "state key|demo|span" (Eq. 31's -inf).
    illegal_values: dict[str, float] = dataclasses.field(default_factory=dict)

    def value(self, key: str) -> float:
        return 0.0 if key == GOAL_KEY else self.values.get(key, 0.0)

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
            "illegal_action_values": dict(sorted(self.illegal_values.items())),
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
            illegal = {str(k): float(v) for k, v in document.get("illegal_action_values", {}).items()}
            parameters = QLearningParameters(**document["parameters"])
            demos = [str(name) for name in document["library_demos"]]
            episodes = int(document.get("training_episodes", 0))
        except (KeyError, TypeError, ValueError, AttributeError) as error:
            raise InputError(f"malformed policy ({error})", file=str(path)) from None
        if not all(np.isfinite(v) for v in [*values.values(), *illegal.values()]):
            raise InputError("non-finite value in the table", file=str(path), field="values")
        return cls(values, parameters, demos, episodes, illegal)


@dataclasses.dataclass(frozen=True)
class TrainingResult:
    policy: QPolicy
    rewards: np.ndarray  # (episodes, tasks) accumulated reward of each (exploring) episode
    wall_time_s: float
    greedy_rewards: np.ndarray | None = None  # (episodes, tasks) greedy return after each episode

    @property
    def curve(self) -> np.ndarray:
        """Average accumulated reward per (exploring) episode over the training tasks."""
        return self.rewards.mean(axis=1)

    @property
    def greedy_curve(self) -> np.ndarray:
        """Average return of the greedy policy (epsilon 1, the paper's whole action set)
        after each episode, over the training tasks: the learning curve of Fig. 7."""
        return self.greedy_rewards.mean(axis=1)


def episodes_to_steady(curve: np.ndarray, window: int = 10, tolerance: float = 0.05) -> int:
    """Episodes before the reward is steady: the number of the last episode whose reward
    is farther than ``tolerance`` times the curve's range from the final level (the mean
    of the last ``window`` episodes); 0 if every episode is within it. Meant for the
    greedy curve, which changes only when learning changes the policy."""
    curve = np.asarray(curve, dtype=float)
    if len(curve) == 0:
        return 0
    final = curve[-window:].mean()
    band = tolerance * (curve.max() - curve.min()) + 1e-9
    outside = np.flatnonzero(np.abs(curve - final) > band)
    return 0 if len(outside) == 0 else int(outside[-1] + 1)


def cached_state_key(problem: CompositionProblem, k: int, a_k: int) -> str:
    """:func:`state_key`, memoised on the problem (episodes revisit the same states)."""
    cache = problem.__dict__.setdefault("_state_keys", {})
    key = cache.get((k, a_k))
    if key is None:
        key = cache[(k, a_k)] = state_key(problem, k, a_k)
    return key


class _GeneralValues:
    """Afterstate values read and written through the policy's abstract keys."""

    def __init__(self, policy: QPolicy):
        self.policy = policy

    def get(self, problem: CompositionProblem, k: int, a: int) -> float:
        return self.policy.value(cached_state_key(problem, k, a))

    def set(self, problem: CompositionProblem, k: int, a: int, value: float) -> None:
        self.policy.values[cached_state_key(problem, k, a)] = value


class _TaskValues:
    """Afterstate values of one task's own states (k, a_k), for plan-time refinement.

    Each state starts optimistic, at ``GENERAL_PRIOR_WEIGHT`` times the general table's
    estimate: the general table orders states the task has not tried yet, and the
    task's own episodes decide. Seeding with the general estimate itself was measured to
    mislead: a key that dead-ended in random training tasks stays pessimistic on a task
    where it does not, and 1000 episodes did not undo it (15 % above the optimum on
    Table 8 for 3 of 4 training seeds; 0 % with the optimistic start).
    """

    def __init__(self, policy: QPolicy):
        self.policy = policy
        self.values: dict[tuple[int, int], float] = {}

    def get(self, problem: CompositionProblem, k: int, a: int) -> float:
        if k == problem.num_cons - 1:
            return 0.0
        value = self.values.get((k, a))
        if value is None:
            return GENERAL_PRIOR_WEIGHT * self.policy.value(cached_state_key(problem, k, a))
        return value

    def set(self, problem: CompositionProblem, k: int, a: int, value: float) -> None:
        self.values[(k, a)] = value


def _q_values(problem, values, actions, discount) -> np.ndarray:
    return np.array([-s.cost + discount * values.get(problem, s.k, s.a_k) for s in actions])


def _start_candidate(problem, values, rng=None, epsilon=1.0) -> int:
    if rng is not None and rng.random() >= epsilon:
        return int(rng.integers(problem.num_candidates[0]))
    return int(np.argmax([values.get(problem, 0, a) for a in range(problem.num_candidates[0])]))


def _illegal_actions(problem, j, legal, max_span) -> list[tuple[int, int]]:
    """(demo, k) pairs of the paper's action set (Eq. 29-30) that are not similar here."""
    covered = {(step.demo, step.k) for step in legal}
    last = min(problem.num_cons - 1, j + max_span)
    return [(d, k) for d in range(problem.num_demos) for k in range(j + 1, last + 1) if (d, k) not in covered]


def _run_episode(problem, actions_cache, values, parameters, rng, illegal_values=None, demo_names=None,
                 learn: bool = True) -> float:
    """One episode of Algorithm 1 (epsilon-greedy, Eq. 33 on afterstates); its reward.

    With ``illegal_values`` (training), the agent chooses among the paper's whole action
    set, as Algorithm 1 does: an action that is not similar earns the penalty and ends
    the episode, and its Q is learned, so the reward curve shows the agent learning to
    avoid them (Fig. 7). Without it (plan-time refinement) only legal actions are tried.
    With ``learn=False`` and ``rng=None`` it is a greedy evaluation: nothing is updated.
    """
    p = parameters
    a = _start_candidate(problem, values, rng, p.epsilon)
    j, total = 0, 0.0
    while j < problem.num_cons - 1:
        penalty = p.penalty * (problem.num_cons - 1 - j) / (problem.num_cons - 1)
        cached = actions_cache.get((j, a))
        if cached is None:
            legal = problem.actions_from(j, a)
            illegal = [] if illegal_values is None else _illegal_actions(problem, j, legal, problem.max_span)
            cached = actions_cache[(j, a)] = (legal, illegal)
        legal, illegal = cached
        old = values.get(problem, j, a)
        q = _q_values(problem, values, legal, p.discount)
        if learn:
            # The afterstate's value is that of its best legal continuation (a dead end: penalty).
            values.set(problem, j, a, old + p.learning_rate * ((q.max() if legal else penalty) - old))
        if illegal:
            state = cached_state_key(problem, j, a)
            illegal_keys = [f"{state}|{demo_names[d]}|{k - j}" for d, k in illegal]
            q = np.concatenate([q, [illegal_values.get(key, 0.0) for key in illegal_keys]])
        if len(q) == 0:
            return total + penalty
        greedy = rng is None or rng.random() < p.epsilon
        choice = int(np.argmax(q)) if greedy else int(rng.integers(len(q)))
        if choice >= len(legal):
            key = illegal_keys[choice - len(legal)]
            if learn:
                old_q = illegal_values.get(key, 0.0)
                illegal_values[key] = old_q + p.learning_rate * (penalty - old_q)
            return total + penalty
        step = legal[choice]
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
        illegal_values=dict(policy.illegal_values) if policy else {},
    )
    caches = [dict() for _ in problems]
    values = _GeneralValues(learned)
    rewards = np.zeros((parameters.episodes, len(problems)))
    greedy = np.zeros_like(rewards)
    for episode in range(parameters.episodes):
        for t, problem in enumerate(problems):
            rewards[episode, t] = _run_episode(
                problem, caches[t], values, parameters, rng, learned.illegal_values, learned.library_demos)
            greedy[episode, t] = _run_episode(
                problem, caches[t], values, parameters, None, learned.illegal_values, learned.library_demos,
                learn=False)
        if progress:
            progress(episode + 1, parameters.episodes)
    learned.training_episodes += parameters.episodes
    return TrainingResult(learned, rewards, time.perf_counter() - start, greedy)


DEFAULT_REFINE_EPISODES = 100
GENERAL_PRIOR_WEIGHT = 1e-4


@dataclasses.dataclass(frozen=True)
class QPlan:
    steps: list[Step] | None
    greedy_completed: bool  # the greedy walk alone reached the last con
    fallback: str | None  # "exact" when the exact planner had to finish the job
    refine_episodes: int = 0


def greedy_walk(problem: CompositionProblem, policy: QPolicy, *, refine_episodes: int = 0,
                seed: int = 0) -> list[Step] | None:
    """Algorithm 2: greedy on Q over legal actions; None if it reaches a dead end.

    With ``refine_episodes`` > 0, that many episodes of Algorithm 1 are first run on this
    task's own states, seeded by the policy's values (the policy itself is not changed),
    undiscounted: on one task the objective is its total cost, as for the exact planner.
    """
    parameters = policy.parameters
    if refine_episodes > 0:
        # On one task the objective is its total cost, undiscounted, as the exact planner's.
        parameters = dataclasses.replace(parameters, discount=1.0)
        values = _TaskValues(policy)
        rng = np.random.default_rng(seed)
        cache: dict = {}
        for _ in range(refine_episodes):
            _run_episode(problem, cache, values, parameters, rng)
    else:
        values = _GeneralValues(policy)
    a = _start_candidate(problem, values)
    j, steps = 0, []
    while j < problem.num_cons - 1:
        actions = problem.actions_from(j, a)
        if not actions:
            return None
        step = actions[int(np.argmax(_q_values(problem, values, actions, parameters.discount)))]
        steps.append(step)
        j, a = step.k, step.a_k
    return steps


def plan_q(problem: CompositionProblem, policy: QPolicy, *,
           refine_episodes: int = DEFAULT_REFINE_EPISODES, seed: int = 0) -> QPlan:
    """Greedy walk (after plan-time refinement); if it dead-ends while a composition
    exists, the exact planner finishes, so the Q-planner never fails a task the library
    can cover."""
    steps = greedy_walk(problem, policy, refine_episodes=refine_episodes, seed=seed)
    if steps is not None:
        return QPlan(steps, True, None, refine_episodes)
    exact = plan_exact(problem)
    return QPlan(exact, False, "exact" if exact is not None else None, refine_episodes)
