"""A task-independent key for a planning state, so one Q-table serves unseen tasks.

The paper trains one Q-table on 20 random tasks and applies it to new ones (Section
6.2-6.3); a table keyed by task-specific states cannot do that (docs/method.rst,
"Planning"). The key of a
state ``(k, a_k)`` describes what remains to be done from it, in terms that recur across
tasks:

* how many segments remain (capped at 3), or ``goal`` at the last con;
* the relative rotation to the next critical configuration, ``r_k* r_(k+1)`` (in con_k's
  frame, so the key is invariant to rigid motions of the whole task; the next con's
  nominal candidate, the middle of its grid, when its angles are bounded), as the
  nearest of the 24 rotations of the cube. The relative rotations of the paper's random
  tasks (Euler angles multiples of pi/2) are exactly these, and which demonstrations can
  cover a segment depends mostly on its rotation (beta >= -0.9 rejects only translations
  nearly opposite).

Finer keys were measured worse: adding how far the rotation is from the cube's (< 10,
< 30 deg, more) and the translation direction (26 bins) split 40 training tasks over too
many keys, and the greedy walk's mean cost on 100 held-out chained tasks rose from 2.9 %
to 6.8 % above the optimum (``benchmarks/bench_planners.py``).

Not for: deciding legality (always recomputed from similarity), memoising keys (the
MDP does, ``mdp.CompositionMDP.state_key``) or learning.
"""

from __future__ import annotations

import itertools

import numpy as np

from drake_lfd.planning.composition import CompositionProblem
from drake_lfd.core.dual_quaternion import dual_quaternion_relative
from drake_lfd.core.quaternion import quaternion_from_rotation_matrices

__all__ = ["GOAL_KEY", "MAX_REMAINING", "CUBE_ROTATIONS", "motion_key", "state_key"]

GOAL_KEY = "goal"
MAX_REMAINING = 3


def _cube_rotations() -> np.ndarray:
    """Unit quaternions of the 24 proper rotations of a cube, shape (24, 4)."""
    matrices = []
    for perm in itertools.permutations(range(3)):
        for signs in itertools.product((1.0, -1.0), repeat=3):
            R = np.zeros((3, 3))
            for row, (col, sign) in enumerate(zip(perm, signs)):
                R[row, col] = sign
            if np.linalg.det(R) > 0:
                matrices.append(R)
    return quaternion_from_rotation_matrices(np.array(matrices))


CUBE_ROTATIONS = _cube_rotations()


def motion_key(relative_pose: np.ndarray) -> str:
    """Key of a relative pose (8,): the index of the nearest cube rotation."""
    return f"R{int(np.argmax(np.abs(CUBE_ROTATIONS @ relative_pose[:4])))}"


def state_key(problem: CompositionProblem, k: int, a_k: int) -> str:
    """Task-independent key of state (k, a_k) of ``problem``."""
    n = problem.num_cons
    if k == n - 1:
        return GOAL_KEY
    remaining = min(n - 1 - k, MAX_REMAINING)
    next_candidates = problem.candidate_poses[k + 1]
    nominal = next_candidates[len(next_candidates) // 2]
    relative = dual_quaternion_relative(problem.candidate_poses[k][a_k], nominal)
    return f"n{remaining}|{motion_key(relative)}"
