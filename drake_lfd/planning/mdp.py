"""The composition MDP of Section 4: states, the paper's action set, transitions, rewards.

The one definition of the MDP; the Q-learner (``q_learning.py``) and the Gymnasium
environment (``gym_env.py``) both run on it (see docs/method.rst, "Planning"):

* **State** ``(j, a_j)``: critical configuration con_j reached with its candidate
  orientation ``a_j`` (0-based). The episode starts at con_0 with a candidate of the
  agent's choice and ends at the last con (the goal).
* **Actions** (Eq. 29-30): every pair (demonstration d, span end k), ``j < k <= j +
  max_span``. A pair is *legal* when the similarity test accepts it for some candidate
  of con_k (legality comes from :class:`~drake_lfd.planning.composition.CompositionProblem`);
  a legal pair is taken as a :class:`~drake_lfd.planning.composition.Step`, which also
  names con_k's candidate ``a_k``, so a legal pair is one action per admissible ``a_k``.
  A pair that is not legal is an :class:`IllegalAction`.
* **Transition**: a Step moves to ``(k, a_k)``; an illegal action ends the episode.
* **Reward**: minus the allocation's total alpha for a Step (Eq. 31). For an illegal
  action, or a state with no legal action (a dead end), the episode ends with
  :meth:`CompositionMDP.penalty`: the paper's minus infinity, replaced by a finite
  ``base_penalty`` (-10 by default) scaled by the fraction of the task left undone, so
  an episode that gets further before it fails earns more. That is a learning signal
  even on training tasks that no composition covers, which with the paper's random
  tasks are most.

:class:`CompositionMDP` also owns the memo of the task-independent state keys
(``state_abstraction.state_key``) that the Q-table is read through.

Not for: computing legality or costs (``composition.py``), learning (``q_learning.py``),
the Gymnasium interface and observations (``gym_env.py``), or the exact optimum
(``exact_planner.py``).
"""

from __future__ import annotations

import dataclasses
from typing import NamedTuple, Union

import numpy as np

from drake_lfd.planning.composition import CompositionProblem, Step
from drake_lfd.planning.state_abstraction import state_key

__all__ = [
    "DEFAULT_PENALTY",
    "State",
    "IllegalAction",
    "Action",
    "Transition",
    "CompositionMDP",
]

DEFAULT_PENALTY = -10.0


class State(NamedTuple):
    """Con ``j`` (0-based) reached with candidate orientation ``candidate``."""

    j: int
    candidate: int


@dataclasses.dataclass(frozen=True)
class IllegalAction:
    """Demonstration ``demo`` asked to cover con_j .. con_k where it is not similar."""

    demo: int
    j: int
    k: int


Action = Union[Step, IllegalAction]


class Transition(NamedTuple):
    """Outcome of one action: the next state (the same one after an illegal action),
    the reward, whether the episode ended, and whether the action was legal."""

    state: State
    reward: float
    terminated: bool
    legal: bool


class CompositionMDP:
    """The MDP of one composition problem.

    Parameters
    ----------
    problem : CompositionProblem
        Legal actions and their costs; its ``max_span`` bounds the action set.
    base_penalty : float
        Reward of an illegal action or a dead end at con_0; later it is scaled by the
        fraction of the task left (:meth:`penalty`). Negative.

    Notes
    -----
    Legal and illegal actions, their rewards and afterstates, and state keys are
    computed once per state and kept: episodes revisit the same states. Methods take a
    :class:`State` (a plain ``(j, a_j)`` tuple works too).
    """

    def __init__(self, problem: CompositionProblem, base_penalty: float = DEFAULT_PENALTY):
        self.problem = problem
        self.base_penalty = float(base_penalty)
        self.goal = problem.num_cons - 1  # index of the last critical configuration
        self._legal: dict[State, list[Step]] = {}
        self._illegal: dict[State, list[IllegalAction]] = {}
        self._afterstates: dict[State, tuple[list[State], np.ndarray]] = {}
        self._keys: dict[State, str] = {}
        self._starts = [State(0, a) for a in range(problem.num_candidates[0])]

    @property
    def num_cons(self) -> int:
        return self.problem.num_cons

    def start_states(self) -> list[State]:
        """The states an episode may start from: con_0 with each of its candidates."""
        return self._starts

    def is_goal(self, state: State) -> bool:
        return state[0] == self.goal

    def penalty(self, j: int) -> float:
        """Reward of failing at con_j: ``base_penalty`` times the fraction of the task
        left, ``(n - 1 - j) / (n - 1)``."""
        return self.base_penalty * (self.goal - j) / self.goal

    # -- the action set --------------------------------------------------------------------
    def legal_actions(self, state: State) -> list[Step]:
        """Legal actions from ``state``, in a deterministic order (span end, then demo,
        then con_k's candidate)."""
        actions = self._legal.get(state)
        if actions is None:
            actions = self._legal[state] = self.problem.actions_from(*state)
        return actions

    def legal_afterstates(self, state: State) -> tuple[list[State], np.ndarray]:
        """The states the legal actions lead to and their rewards (minus the costs),
        in the order of :meth:`legal_actions`."""
        cached = self._afterstates.get(state)
        if cached is None:
            legal = self.legal_actions(state)
            cached = self._afterstates[state] = (
                [State(step.k, step.a_k) for step in legal], np.array([-step.cost for step in legal]))
        return cached

    def illegal_actions(self, state: State) -> list[IllegalAction]:
        """The (demo, span end) pairs of the paper's action set (Eq. 29-30) that no
        candidate of the span's end makes similar, ordered by demo then span end."""
        actions = self._illegal.get(state)
        if actions is None:
            j = state[0]
            covered = {(step.demo, step.k) for step in self.legal_actions(state)}
            last = min(self.goal, j + self.problem.max_span)
            actions = self._illegal[state] = [
                IllegalAction(d, j, k)
                for d in range(self.problem.num_demos)
                for k in range(j + 1, last + 1)
                if (d, k) not in covered
            ]
        return actions

    def actions(self, state: State) -> list[Action]:
        """The paper's whole action set from ``state``: legal actions, then illegal ones."""
        return [*self.legal_actions(state), *self.illegal_actions(state)]

    def is_dead_end(self, state: State) -> bool:
        """True when no legal action leaves ``state`` (and it is not the goal)."""
        return not self.is_goal(state) and not self.legal_actions(state)

    def action_for(self, state: State, demo: int, k: int) -> Action:
        """The action "demo ``demo`` covers the span up to con_k": the legal Step with the
        least cost (the first such candidate of con_k on ties), or an IllegalAction when
        the pair is not similar (or not in the action set, e.g. past the last con)."""
        best = None
        for step in self.legal_actions(state):
            if step.demo == demo and step.k == k and (best is None or step.cost < best.cost):
                best = step
        return IllegalAction(demo, state[0], k) if best is None else best

    # -- dynamics --------------------------------------------------------------------------
    def reward(self, state: State, action: Action) -> float:
        """Minus the allocation's total alpha (Eq. 31), or the penalty when illegal."""
        if isinstance(action, IllegalAction):
            return self.penalty(state[0])
        return -action.cost

    def step(self, state: State, action: Action) -> Transition:
        """Applies ``action`` in ``state``. A Step must be one of
        :meth:`legal_actions` of ``state``."""
        if isinstance(action, IllegalAction):
            return Transition(State(*state), self.penalty(state[0]), True, False)
        if action.j != state[0] or action.a_j != state[1]:
            raise ValueError(f"{action} does not start from {state}")
        return Transition(State(action.k, action.a_k), -action.cost, action.k == self.goal, True)

    # -- the Q-table's keys ----------------------------------------------------------------
    def state_key(self, state: State) -> str:
        """The task-independent key of ``state`` (``state_abstraction.state_key``),
        memoised here."""
        key = self._keys.get(state)
        if key is None:
            key = self._keys[state] = state_key(self.problem, *state)
        return key
