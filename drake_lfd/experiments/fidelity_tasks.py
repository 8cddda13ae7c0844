"""Tasks cut from library demonstrations at ordinary points, and whether a plan recovers them.

The shape-fidelity benchmark (``benchmarks/bench_fidelity.py``) and its test sample use
these (docs/method.rst, Shape fidelity):

* :func:`fidelity_task`: two or three distinct library demonstrations, each cut at two
  random points along it (real-valued sample indices, the poses ScLERPed between the two
  resampled poses around them, at least 0.2 samples from either, so never a resampling
  sample), and placed end to end: the first piece at a random pose (position in the
  training cube, uniform orientation), each next one moved rigidly so that it starts
  where the previous one ends. The critical configurations (all angles fixed) are the
  first cut point, the joins and the last end. The task's ``path`` is the constructing
  demonstrations' shape: each piece's cut poses and the resampled poses between them,
  placed. A piece ends before its demonstration does, so even the constructing
  demonstration is mapped (Eq. 22-25: a suffix, its end on the span's end) with some
  distortion, and the test is whether the planner finds which demonstrations made the
  task.
* :func:`path_distance`: the symmetric distance between two tool paths (positions): the
  largest distance of a sample of either path from the other path's polyline.
* :func:`evaluate`: plan a task in SE(3) (no joint-space check) with one cost mode and
  judge it: a success when the plan uses the constructing composition (same
  demonstrations over the same spans) or its path is within ``tolerance_m`` (2 cm) of the
  constructed one.

Not for: the planners' held-out tasks (``planning/random_tasks.py``: cut at samples) or
task files.
"""

from __future__ import annotations

import dataclasses
from typing import Mapping

import numpy as np
from pydrake.common.eigen_geometry import Quaternion
from pydrake.math import RollPitchYaw, RotationMatrix

from drake_lfd.core.dual_quaternion import (
    dual_quaternion_from_translation_rotation,
    dual_quaternion_multiply,
    dual_quaternion_relative,
    translation_from_dual_quaternion,
    translation_rotation_from_dual_quaternion,
)
from drake_lfd.core.screw_motion import dual_quaternion_sclerp
from drake_lfd.core.features import Feature
from drake_lfd.core.tasks import ConcreteTask
from drake_lfd.planning.options import PlanningOptions
from drake_lfd.planning.planner import plan_composition
from drake_lfd.planning.random_tasks import TRAINING_CUBE_CENTRE

__all__ = ["SUCCESS_TOLERANCE_M", "Piece", "FidelityTask", "Evaluation", "fidelity_task", "path_distance",
           "evaluate"]

SUCCESS_TOLERANCE_M = 0.02


@dataclasses.dataclass(frozen=True)
class Piece:
    """One demonstration's piece in a task: it covers con_from -> con_to (1-based), from
    the real-valued resampled index ``cut`` to ``end``."""

    demo: str
    con_from: int
    con_to: int
    cut: float
    end: float


@dataclasses.dataclass(frozen=True, eq=False)
class FidelityTask:
    """A task built by :func:`fidelity_task`, with its pieces and its constructed path
    (positions of E in W, shape (N, 3))."""

    task: ConcreteTask
    pieces: tuple[Piece, ...]
    path: np.ndarray

    @property
    def composition(self) -> list[tuple[str, int, int]]:
        return [(piece.demo, piece.con_from, piece.con_to) for piece in self.pieces]


@dataclasses.dataclass(frozen=True)
class Evaluation:
    """How one cost mode did on one task: ``status`` of the plan, whether it found the
    constructing composition, the path distance (m; inf without a plan), success."""

    status: str
    composition: tuple[tuple[str, int, int], ...]
    constructing: bool
    distance_m: float
    success: bool


def _pose_at(poses: np.ndarray, index: float) -> np.ndarray:
    """The pose at real-valued sample ``index`` (ScLERP between its two samples)."""
    lower = min(int(np.floor(index)), len(poses) - 2)
    return dual_quaternion_sclerp(poses[lower], poses[lower + 1], index - lower)


def _between_samples(rng: np.random.Generator, low: float, high: float) -> float:
    """A real index in [low, high] at least 0.2 samples from every integer."""
    index = rng.uniform(low, high)
    return float(np.floor(index) + 0.2 + 0.6 * (index - np.floor(index)))


def _euler_zyx(quaternion_wxyz: np.ndarray) -> np.ndarray:
    rpy = RollPitchYaw(RotationMatrix(Quaternion(quaternion_wxyz / np.linalg.norm(quaternion_wxyz)))).vector()
    return np.array([rpy[2], rpy[1], rpy[0]])


def fidelity_task(rng: np.random.Generator, features: Mapping[str, Feature], *, num_pieces: int | None = None,
                  name: str = "fidelity", first_cut_fraction: float = 0.5,
                  min_piece_fraction: float = 0.3) -> FidelityTask:
    """A task of 2 or 3 (``num_pieces``; random when None) pieces of distinct
    demonstrations, each cut at two ordinary points (module docstring).

    Parameters
    ----------
    rng : numpy Generator
        Draws everything (demonstrations, cuts, placement).
    features : mapping of name to Feature
        The library (at least ``num_pieces`` demonstrations).
    num_pieces : int, optional
    name : str
    first_cut_fraction : float
        A piece starts in the first ``first_cut_fraction`` of its demonstration's samples.
    min_piece_fraction : float
        and ends at least this fraction of the rest later, before the last sample.
    """
    names = list(features)
    count = int(rng.integers(2, 4)) if num_pieces is None else int(num_pieces)
    if not 1 <= count <= len(names):
        raise ValueError(f"num_pieces must be in [1, {len(names)}], got {count}")
    demos = [names[i] for i in rng.choice(len(names), size=count, replace=False)]
    q = rng.normal(size=4)
    start = dual_quaternion_from_translation_rotation(TRAINING_CUBE_CENTRE + rng.uniform(-0.25, 0.25, 3),
                                                      q / np.linalg.norm(q))
    cons, path, pieces = [start], [], []
    for demo in demos:
        poses = features[demo].poses
        last = len(poses) - 1
        cut = _between_samples(rng, 0.0, first_cut_fraction * last)
        end = _between_samples(rng, cut + min_piece_fraction * (last - cut), last - 1.0)
        first = _pose_at(poses, cut)
        placed = [dual_quaternion_multiply(cons[-1], dual_quaternion_relative(first, pose))
                  for pose in [first, *poses[int(np.ceil(cut)):int(np.floor(end)) + 1], _pose_at(poses, end)]]
        path.extend(translation_from_dual_quaternion(np.array(placed)))
        cons.append(placed[-1])
        pieces.append(Piece(demo, len(cons) - 1, len(cons), cut, end))
    positions, quaternions = translation_rotation_from_dual_quaternion(np.array(cons))
    euler = np.array([_euler_zyx(qi) for qi in quaternions])
    return FidelityTask(ConcreteTask.from_fixed(name, positions, euler), tuple(pieces), np.array(path))


def _distance_to_polyline(points: np.ndarray, polyline: np.ndarray) -> np.ndarray:
    """Distance of each point (P, 3) to the polyline (S + 1, 3), shape (P,)."""
    a, b = polyline[:-1], polyline[1:]
    ab = b - a
    length2 = np.maximum(np.einsum("ij,ij->i", ab, ab), 1e-18)
    t = np.clip(np.einsum("pij,ij->pi", points[:, None, :] - a[None], ab) / length2, 0.0, 1.0)
    closest = a[None] + t[..., None] * ab[None]
    return np.linalg.norm(points[:, None, :] - closest, axis=2).min(axis=1)


def path_distance(path_a: np.ndarray, path_b: np.ndarray) -> float:
    """Symmetric path distance (m): the largest distance of a sample of either path from
    the other path's polyline (a Hausdorff distance between the polylines, measured at
    the samples). Paths are positions, shape (N, 3), N >= 2."""
    path_a, path_b = np.asarray(path_a, dtype=float), np.asarray(path_b, dtype=float)
    return float(max(_distance_to_polyline(path_a, path_b).max(), _distance_to_polyline(path_b, path_a).max()))


def evaluate(case: FidelityTask, features: Mapping[str, Feature], cost: str, *,
             tolerance_m: float = SUCCESS_TOLERANCE_M) -> Evaluation:
    """Plans ``case`` with the exact planner in SE(3) (no joint-space check) in cost mode
    ``cost`` and judges it (module docstring)."""
    result = plan_composition(case.task, features, PlanningOptions(cost=cost, joint_check=False))
    if not result.planned:
        return Evaluation(result.status, (), False, float("inf"), False)
    composition = tuple((s.demo, s.con_from, s.con_to) for s in result.composition)
    constructing = list(composition) == case.composition
    distance = path_distance(case.path, translation_from_dual_quaternion(result.timed.poses))
    return Evaluation(result.status, composition, constructing, distance,
                      constructing or distance <= tolerance_m)
