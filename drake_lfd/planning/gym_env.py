"""The composition MDP as a ``gymnasium.Env`` (optional extra ``drake-lfd[gym]``).

For users who want to try other RL algorithms on the paper's problem. The MDP itself
(states, the paper's action set, legality, transitions, rewards, the penalty) is the one
of ``mdp.py`` that drake-lfd's own Q-learner runs on; this module only encodes it for
Gymnasium (see docs/method.rst, "Planning"). One episode plans one task drawn at reset:
half the time a Section 6.2 random task, half the time a task chained from library
demonstrations (plannable by construction), so an agent sees both dead ends and
complete compositions.

* Action ``a = demo * max_span + (span - 1)`` is the MDP's (demo, span end
  ``j + span``) pair of Eq. 29-30; bounded angles of the span's end take the least-cost
  legal value (``CompositionMDP.action_for``). An action that is not semantically
  similar (or runs past the last con) ends the episode with the MDP's penalty,
  ``illegal_penalty`` scaled by the fraction of the task left (Eq. 31's minus infinity,
  Algorithm 1's ``Break``).
* Reward: minus the allocation's total alpha (Eq. 31).
* Observation (float32, 10 values): segments remaining / 3, then the relative motion to
  the next critical configuration in the current one's frame (rotation quaternion w >= 0,
  unit translation direction, translation length in metres clipped to 2), and the
  fraction of the task done.

Not for: drake-lfd's own training (``q_learning.py`` uses the tabular afterstate form
on the same MDP).
"""

from __future__ import annotations

from typing import Mapping

import gymnasium
import numpy as np
from gymnasium import spaces

from drake_lfd.core.dual_quaternion import (
    dual_quaternion_canonical,
    dual_quaternion_relative,
    translation_from_dual_quaternion,
)
from drake_lfd.core.features import Feature
from drake_lfd.planning.composition import CompositionProblem
from drake_lfd.planning.mdp import DEFAULT_PENALTY, CompositionMDP, State
from drake_lfd.planning.planner import build_problem
from drake_lfd.planning.random_tasks import chained_task, random_training_task

__all__ = ["CompositionEnv"]


class CompositionEnv(gymnasium.Env):
    """Gymnasium environment of the composition MDP (``mdp.CompositionMDP``).

    Parameters
    ----------
    features : mapping of demo name to Feature
        The library.
    num_cons : int
        Critical configurations of each task drawn at reset.
    max_span : int
        Longest span an action covers; the action space has ``len(features) * max_span``
        actions.
    illegal_penalty : float
        The MDP's base penalty (its value at con_1; later scaled by the task left).
    """

    metadata = {"render_modes": []}
    action_space: spaces.Discrete
    observation_space: spaces.Box

    def __init__(self, features: Mapping[str, Feature], *, num_cons: int = 4, max_span: int = 3,
                 illegal_penalty: float = DEFAULT_PENALTY):
        self.features = dict(features)
        self.num_cons = int(num_cons)
        self.max_span = int(max_span)
        self.illegal_penalty = float(illegal_penalty)
        self.action_space = spaces.Discrete(len(self.features) * self.max_span)
        low = np.array([0, -1, -1, -1, -1, -1, -1, -1, 0, 0], dtype=np.float32)
        high = np.array([1, 1, 1, 1, 1, 1, 1, 1, 2, 1], dtype=np.float32)
        self.observation_space = spaces.Box(low=low, high=high, dtype=np.float32)
        self.mdp: CompositionMDP | None = None
        self.state = State(0, 0)

    @property
    def problem(self) -> CompositionProblem | None:
        """The composition problem of the current episode's task."""
        return None if self.mdp is None else self.mdp.problem

    def _observation(self) -> np.ndarray:
        j, a = self.state
        problem = self.problem
        assert problem is not None  # reset() draws the episode's task before any observation
        n = problem.num_cons
        observation = np.zeros(10, dtype=np.float32)
        observation[0] = min(n - 1 - j, 3) / 3.0
        observation[9] = j / (n - 1)
        if j < n - 1:
            nxt = problem.candidate_poses[j + 1]
            relative = dual_quaternion_canonical(
                dual_quaternion_relative(problem.candidate_poses[j][a], nxt[len(nxt) // 2]))
            t = translation_from_dual_quaternion(relative)
            length = float(np.linalg.norm(t))
            observation[1:5] = relative[:4]
            observation[5:8] = t / length if length > 1e-9 else 0.0
            observation[8] = min(length, 2.0)
        return np.clip(observation, self.observation_space.low, self.observation_space.high)

    def reset(self, *, seed=None, options=None):
        super().reset(seed=seed)
        if self.np_random.random() < 0.5:
            task = random_training_task(self.np_random, self.num_cons)
        else:
            task, _ = chained_task(self.np_random, self.features, self.num_cons)
        problem = build_problem(task, self.features, max_span=self.max_span)
        self.mdp = CompositionMDP(problem, self.illegal_penalty)
        self.state = self.mdp.start_states()[0]
        return self._observation(), {"num_cons": problem.num_cons}

    def step(self, action):
        action = int(action)
        if not self.action_space.contains(action):
            raise ValueError(f"action {action} is outside {self.action_space}")
        demo, span = divmod(action, self.max_span)
        transition = self.mdp.step(self.state, self.mdp.action_for(self.state, demo, self.state.j + span + 1))
        self.state = transition.state
        return self._observation(), transition.reward, transition.terminated, False, {"legal": transition.legal}
