"""A task-independent key for a planning state, so one Q-table serves unseen tasks.

The paper trains one Q-table on 20 random tasks and applies it to new ones (Section
6.2-6.3); a table keyed by task-specific states cannot do that (SPEC 7). The key of a
state ``(k, a_k)`` describes what remains to be done from it, in terms that recur across
tasks:

* how many segments remain (capped at 3), or ``goal`` at the last con;
* the relative motion to the next critical configuration ``D_k* (x) D_(k+1)`` expressed in
  con_k's frame (so the key is invariant to rigid motions of the whole task), with the
  next con's nominal candidate (the middle of its grid) when its angles are bounded:
  its rotation as the nearest of the 24 rotations of the cube (the relative rotations
  of the paper's random tasks, whose Euler angles are multiples of pi/2, are exactly
  these) plus how far it is from it (< 10 deg, < 30 deg, more), and its translation
  direction as the nearest of the 26 directions of a 3x3x3 grid (``short`` under 1 mm).

Not for: deciding legality (always recomputed from similarity) or learning.
"""

from __future__ import annotations

import itertools

import numpy as np

from drake_lfd.composition import CompositionProblem
from drake_lfd.dual_quaternion import (
    dual_quaternion_relative,
    quaternion_from_rotation_matrices,
    translation_from_dual_quaternion,
)

GOAL_KEY = "goal"
MAX_REMAINING = 3
_ROTATION_BUCKETS_RAD = np.radians([10.0, 30.0])
_SHORT_M = 1e-3


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


def _grid_directions() -> np.ndarray:
    directions = [d for d in itertools.product((-1.0, 0.0, 1.0), repeat=3) if any(d)]
    directions = np.array(directions)
    return directions / np.linalg.norm(directions, axis=1, keepdims=True)


CUBE_ROTATIONS = _cube_rotations()
GRID_DIRECTIONS = _grid_directions()


def motion_key(relative_pose: np.ndarray) -> str:
    """Key of a relative pose (8,): nearest cube rotation, bucket, translation direction."""
    r = relative_pose[:4]
    dots = np.abs(CUBE_ROTATIONS @ r)
    nearest = int(np.argmax(dots))
    angle_off = 2.0 * np.arccos(np.clip(dots[nearest], -1.0, 1.0))
    bucket = int(np.searchsorted(_ROTATION_BUCKETS_RAD, angle_off))
    t = translation_from_dual_quaternion(relative_pose)
    length = np.linalg.norm(t)
    direction = "short" if length < _SHORT_M else str(int(np.argmax(GRID_DIRECTIONS @ (t / length))))
    return f"R{nearest}.{bucket}|t{direction}"


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
