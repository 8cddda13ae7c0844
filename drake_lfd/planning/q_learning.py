"""Q-learning of a general composition policy (Algorithm 1) and the greedy walk (Algorithm 2).

The episodes run on the composition MDP of ``mdp.py`` (states ``(j, a_j)``, the paper's
action set with its illegal (demo, span) pairs, rewards, the dead-end penalty); this
module adds only the learning. See docs/method.rst, "Planning".

The Q-function is kept in the *afterstate* form (Sutton & Barto, Section 6.8)::

    Q(s, a) = r(s, a) + gamma * W(key(s'))

where ``r(s, a)`` is minus the allocation's total alpha (Eq. 31), known exactly from the
similarity test, ``s'`` the state the action leads to, ``key`` the task-independent
abstraction of ``state_abstraction.py``, and ``W`` a table learned with Eq. 33's update
applied to the afterstate: ``W(key(s')) <- (1 - lr) W + lr * max_a' Q(s', a')``, with
``W = 0`` at the goal and the MDP's penalty (the paper's minus infinity, scaled by the
fraction of the task left) when ``s'`` is a dead end. Illegal actions have their own
learned Q values (``QPolicy.illegal_values``), so the agent learns to avoid them. Keying
by abstract states is what lets one table, trained on random tasks, plan unseen ones;
legal actions always come from the similarity test, so every plan is valid even in
states never seen in training.

Parameters (Table 6 and what the paper leaves open):

* ``discount`` 0.9 as in Table 6.
* ``greedy_probability`` 0.8: Table 6's epsilon 0.8, read as the probability of taking
  the greedy action (so the agent explores with probability 0.2); pass
  ``greedy_probability=0.2`` for the other reading. Policy files written before the
  rename call it ``epsilon`` and are still read (``io/policy_files.py``).
* ``learning_rate`` 0.5: rewards are deterministic, so a large step converges in few
  episodes; the abstraction merges states, so it is kept below 1 to average them.
* ``penalty`` -10: the MDP's base penalty.
* ``W`` starts at 0 (optimistic, since rewards are <= 0), which drives exploration
  more reliably than the paper's random initialisation; the seed fixes everything.

Plan-time refinement (beyond the paper's Algorithm 2, in the spirit of its retraining):
before the greedy walk, ``DEFAULT_REFINE_EPISODES`` episodes of the same Q-learning run
on the task's own states, seeded by the general table. A tabular key cannot tell apart
tasks that look alike but cost differently, so the general table alone walks above the
optimum on held-out chained tasks, and after refinement at it
(``benchmarks/bench_planners.py``), at a small cost per plan.

Adding a demonstration adds actions but no keys, so a trained table warm-starts
retraining (``train(..., policy=old)``; measured by ``benchmarks/bench_warm_start.py``).

Not for: the MDP's definition (``mdp.py``), legality (``composition.py``), or policy
files (``io/policy_files.py``: this layer does not write files).
"""

from __future__ import annotations

import dataclasses
import time
from typing import Callable, Mapping, Sequence

import numpy as np

from drake_lfd.planning.composition import CompositionProblem, Step
from drake_lfd.planning.exact_planner import plan_exact
from drake_lfd.planning.mdp import DEFAULT_PENALTY, CompositionMDP, State
from drake_lfd.planning.state_abstraction import GOAL_KEY

__all__ = [
    "QLearningParameters",
    "QPolicy",
    "TrainingResult",
    "QPlan",
    "DEFAULT_REFINE_EPISODES",
    "Q_PLANNER_MAX_DEMOS",
    "GENERAL_PRIOR_WEIGHT",
    "episodes_to_steady",
    "never_steady",
    "train",
    "greedy_walk",
    "plan_q",
]


@dataclasses.dataclass(frozen=True)
class QLearningParameters:
    """Parameters of Algorithm 1 (see the module docstring for the choices).

    Attributes
    ----------
    discount : float
        gamma of Eq. 33.
    greedy_probability : float
        Probability of the greedy action in an exploring episode (Table 6's epsilon 0.8
        read that way); otherwise a uniformly random action of the paper's action set.
    learning_rate : float
        Step of Eq. 33's update.
    episodes : int
        Episodes per training task.
    penalty : float
        The MDP's base penalty for an illegal action or a dead end.
    """

    discount: float = 0.9
    greedy_probability: float = 0.8
    learning_rate: float = 0.5
    episodes: int = 100
    penalty: float = DEFAULT_PENALTY


@dataclasses.dataclass
class QPolicy:
    """The learned afterstate table and what it was trained with (no file I/O here:
    ``io/policy_files.py`` saves and loads it)."""

    values: dict[str, float] = dataclasses.field(default_factory=dict)
    parameters: QLearningParameters = dataclasses.field(default_factory=QLearningParameters)
    library_demos: list[str] = dataclasses.field(default_factory=list)
    training_episodes: int = 0
    # Q of actions found illegal in training, keyed "state key|demo|span" (Eq. 31's -inf).
    illegal_values: dict[str, float] = dataclasses.field(default_factory=dict)
    # Demonstration name -> hash of the feature it was trained with
    # (training.feature_hash); None when unknown (policy files written before it was kept).
    library_feature_hashes: dict[str, str] | None = None

    def value(self, key: str) -> float:
        return 0.0 if key == GOAL_KEY else self.values.get(key, 0.0)


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
        """Average return of the greedy policy (greedy probability 1, the paper's whole action set)
        after each episode, over the training tasks: the learning curve of Fig. 7."""
        assert self.greedy_rewards is not None  # train() records them
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


def never_steady(curve: np.ndarray, window: int = 10, tolerance: float = 0.05) -> bool:
    """Whether the curve never settles within its episodes: its final episode is itself
    the last one outside the band of :func:`episodes_to_steady` (farther than
    ``tolerance`` times the range from the mean of the last ``window`` episodes), so
    :func:`episodes_to_steady` would equal the number of episodes. A curve that keeps
    changing to its end, or that alternates between values at the end, is never steady
    (however small the values' differences); an empty curve is steady."""
    curve = np.asarray(curve, dtype=float)
    return len(curve) > 0 and episodes_to_steady(curve, window, tolerance) == len(curve)


class _GeneralValues:
    """Afterstate values read and written through the policy's abstract keys."""

    def __init__(self, policy: QPolicy):
        self.policy = policy

    def get(self, mdp: CompositionMDP, state: State) -> float:
        return self.policy.value(mdp.state_key(state))

    def set(self, mdp: CompositionMDP, state: State, value: float) -> None:
        self.policy.values[mdp.state_key(state)] = value


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
        self.values: dict[State, float] = {}

    def get(self, mdp: CompositionMDP, state: State) -> float:
        if mdp.is_goal(state):
            return 0.0
        value = self.values.get(state)
        if value is None:
            return GENERAL_PRIOR_WEIGHT * self.policy.value(mdp.state_key(state))
        return value

    def set(self, mdp: CompositionMDP, state: State, value: float) -> None:
        self.values[state] = value


def _q_values(mdp: CompositionMDP, values, state: State, discount: float) -> np.ndarray:
    """Afterstate Q of the legal actions from ``state``: reward plus the discounted value
    of where they lead."""
    afterstates, rewards = mdp.legal_afterstates(state)
    return rewards + discount * np.array([values.get(mdp, after) for after in afterstates])


def _start_state(mdp: CompositionMDP, values, rng=None, greedy_probability: float = 1.0) -> State:
    starts = mdp.start_states()
    if rng is not None and rng.random() >= greedy_probability:
        return starts[int(rng.integers(len(starts)))]
    return starts[int(np.argmax([values.get(mdp, s) for s in starts]))]


class _IllegalKeys:
    """Keys of the illegal actions' Q values, "state key|demo name|span", per state of
    one MDP (memoised: episodes revisit the same states)."""

    def __init__(self, mdp: CompositionMDP, demo_names: Sequence[str]):
        self.mdp = mdp
        self.demo_names = list(demo_names)
        self._keys: dict[State, list[str]] = {}

    def __call__(self, state: State) -> list[str]:
        keys = self._keys.get(state)
        if keys is None:
            prefix = self.mdp.state_key(state)
            keys = self._keys[state] = [f"{prefix}|{self.demo_names[a.demo]}|{a.k - a.j}"
                                        for a in self.mdp.illegal_actions(state)]
        return keys


def _run_episode(mdp: CompositionMDP, values, parameters: QLearningParameters, rng, illegal_values=None,
                 illegal_keys: _IllegalKeys | None = None, learn: bool = True) -> float:
    """One episode of Algorithm 1 (epsilon-greedy, Eq. 33 on afterstates); its return.

    With ``illegal_values`` (training; ``illegal_keys`` names their entries), the agent
    chooses among the paper's whole action set, as Algorithm 1 does: an illegal action
    earns the MDP's penalty and ends the episode, and its Q is learned, so the reward
    curve shows the agent learning to avoid them (Fig. 7). Without it (plan-time
    refinement) only legal actions are tried. With ``learn=False`` and ``rng=None`` it
    is a greedy evaluation: nothing is updated.
    """
    p = parameters
    state = _start_state(mdp, values, rng, p.greedy_probability)
    total = 0.0
    while not mdp.is_goal(state):
        penalty = mdp.penalty(state.j)
        legal = mdp.legal_actions(state)
        illegal = [] if illegal_values is None else mdp.illegal_actions(state)
        old = values.get(mdp, state)
        q = _q_values(mdp, values, state, p.discount)
        if learn:
            # The afterstate's value is that of its best legal continuation (a dead end: penalty).
            values.set(mdp, state, old + p.learning_rate * ((q.max() if legal else penalty) - old))
        if illegal:
            assert illegal_keys is not None  # given with illegal_values, in training
            keys = illegal_keys(state)
            q = np.concatenate([q, [illegal_values.get(key, 0.0) for key in keys]])
        if len(q) == 0:
            return total + penalty
        greedy = rng is None or rng.random() < p.greedy_probability
        choice = int(np.argmax(q)) if greedy else int(rng.integers(len(q)))
        if choice >= len(legal):
            key = keys[choice - len(legal)]
            transition = mdp.step(state, illegal[choice - len(legal)])
            if learn:
                old_q = illegal_values.get(key, 0.0)
                illegal_values[key] = old_q + p.learning_rate * (transition.reward - old_q)
            return total + transition.reward
        transition = mdp.step(state, legal[choice])
        total += transition.reward
        state = transition.state
    return total


def train(
    problems: Sequence[CompositionProblem],
    *,
    library_demos: Sequence[str],
    parameters: QLearningParameters = QLearningParameters(),
    seed: int = 0,
    policy: QPolicy | None = None,
    progress: Callable[[int, int], None] | None = None,
    after_episode: Callable[[int, QPolicy], None] | None = None,
    library_feature_hashes: Mapping[str, str] | None = None,
) -> TrainingResult:
    """Algorithm 1 on several tasks, episodes interleaved across tasks.

    ``library_demos`` (and ``library_feature_hashes``, name -> feature hash, if known)
    record in the policy what it was trained with.
    ``policy`` warm-starts from a trained table (its values are copied, not modified).
    ``progress(done, total)`` is called after each episode round;
    ``after_episode(done, policy)`` too, with the policy being learned (to evaluate it;
    it must not be modified).
    """
    start = time.perf_counter()
    rng = np.random.default_rng(seed)
    learned = QPolicy(
        values=dict(policy.values) if policy else {},
        parameters=parameters,
        library_demos=list(library_demos),
        training_episodes=(policy.training_episodes if policy else 0),
        illegal_values=dict(policy.illegal_values) if policy else {},
        library_feature_hashes=None if library_feature_hashes is None else dict(library_feature_hashes),
    )
    mdps = [CompositionMDP(problem, parameters.penalty) for problem in problems]
    keys = [_IllegalKeys(mdp, learned.library_demos) for mdp in mdps]
    values = _GeneralValues(learned)
    rewards = np.zeros((parameters.episodes, len(problems)))
    greedy = np.zeros_like(rewards)
    for episode in range(parameters.episodes):
        for t, mdp in enumerate(mdps):
            rewards[episode, t] = _run_episode(mdp, values, parameters, rng, learned.illegal_values, keys[t])
            greedy[episode, t] = _run_episode(mdp, values, parameters, None, learned.illegal_values, keys[t],
                                              learn=False)
        if progress:
            progress(episode + 1, parameters.episodes)
        if after_episode:
            after_episode(episode + 1, learned)
    learned.training_episodes += parameters.episodes
    return TrainingResult(learned, rewards, time.perf_counter() - start, greedy)


DEFAULT_REFINE_EPISODES = 100
#: Largest library the Q planner serves (``plan --planner q`` refuses larger ones and
#: names the exact planner). Training and plan-time refinement scan every action of a
#: visited state, illegal ones included (h times the spans), so both grow linearly with
#: the library; measured by ``benchmarks/bench_library_scale.py --section q`` (docs/method.rst,
#: "Cost of planning").
Q_PLANNER_MAX_DEMOS = 3000
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
    mdp = CompositionMDP(problem, parameters.penalty)
    values: _TaskValues | _GeneralValues
    if refine_episodes > 0:
        parameters = dataclasses.replace(parameters, discount=1.0)
        values = _TaskValues(policy)
        rng = np.random.default_rng(seed)
        for _ in range(refine_episodes):
            _run_episode(mdp, values, parameters, rng)
    else:
        values = _GeneralValues(policy)
    state = _start_state(mdp, values)
    steps = []
    while not mdp.is_goal(state):
        actions = mdp.legal_actions(state)
        if not actions:
            return None
        step = actions[int(np.argmax(_q_values(mdp, values, state, parameters.discount)))]
        steps.append(step)
        state = mdp.step(state, step).state
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
