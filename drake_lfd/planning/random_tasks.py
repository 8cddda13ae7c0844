"""Random tasks: the paper's training distribution (Section 6.2) and chained test tasks.

* :func:`random_training_task`: 4 critical configurations, positions uniform in a 50 cm
  cube inside the UR5e's reach, each Euler angle drawn from {-pi, -pi/2, 0, pi/2, pi}.
* :func:`chained_task`: a task made by chaining randomly chosen library demonstrations
  under a random rigid placement, so it is plannable by construction (held-out
  evaluation of the planners).

Not for: task files (``io/task_files.py``) or turning tasks into composition problems
(``planner.build_problem``).
"""

from __future__ import annotations

from typing import Mapping

import numpy as np
from pydrake.math import RollPitchYaw, RotationMatrix

from drake_lfd.core.dual_quaternion import (
    dual_quaternion_from_translation_rotation,
    dual_quaternion_multiply,
    dual_quaternion_relative,
    translation_rotation_from_dual_quaternion,
)
from drake_lfd.core.quaternion import quaternion_from_axis_angle
from drake_lfd.core.features import Feature
from drake_lfd.core.tasks import ConcreteTask

__all__ = ["TRAINING_CUBE_CENTRE", "TRAINING_CUBE_SIZE", "TRAINING_ANGLES", "random_training_task",
           "chained_task"]

# A 50 cm cube inside the UR5e's reach (base frame = world frame), in front of the robot.
TRAINING_CUBE_CENTRE = np.array([0.45, 0.0, 0.35])
TRAINING_CUBE_SIZE = 0.5
TRAINING_ANGLES = np.array([-np.pi, -np.pi / 2, 0.0, np.pi / 2, np.pi])


def random_training_task(rng: np.random.Generator, num_cons: int = 4, name: str = "random") -> ConcreteTask:
    """A Section 6.2 training task (all angles fixed)."""
    positions = TRAINING_CUBE_CENTRE + rng.uniform(-0.5, 0.5, size=(num_cons, 3)) * TRAINING_CUBE_SIZE
    euler_zyx = rng.choice(TRAINING_ANGLES, size=(num_cons, 3))
    return ConcreteTask.from_fixed(name, positions, euler_zyx)


def _euler_zyx_of(q_wxyz: np.ndarray) -> np.ndarray:
    from pydrake.common.eigen_geometry import Quaternion

    rpy = RollPitchYaw(RotationMatrix(Quaternion(q_wxyz / np.linalg.norm(q_wxyz)))).vector()
    return np.array([rpy[2], rpy[1], rpy[0]])


def chained_task(
    rng: np.random.Generator,
    features: Mapping[str, Feature],
    num_cons: int = 4,
    name: str = "chained",
    perturbation_deg: float = 0.0,
    perturbation_m: float = 0.0,
) -> tuple[ConcreteTask, list[str]]:
    """A task whose segments are pieces of randomly chosen demonstrations, placed rigidly.

    The gaps con_1 -> con_n are split into runs of 1 or 2 segments; each run is covered
    by one randomly chosen demo (a 2-segment run passes through one of the demo's middle
    samples). The first con is placed at a random pose in the training cube; each run
    starts where the previous one ended. With ``perturbation_deg`` / ``perturbation_m``,
    every con after the first is then turned about a random axis by up to that angle and
    moved by up to that distance, so the task is similar to the demos without being an
    exact copy (costs become informative). Returns the task and the demo names used.
    """
    names = list(features)
    start = dual_quaternion_from_translation_rotation(
        TRAINING_CUBE_CENTRE + rng.uniform(-0.25, 0.25, 3),
        _random_quaternion(rng),
    )
    chain = [start]
    used = []
    gaps = num_cons - 1
    while gaps > 0:
        run = 1 if gaps == 1 else int(rng.integers(1, 3))
        demo = names[int(rng.integers(len(names)))]
        demo_poses = features[demo].poses
        if demo_poses is None:
            raise ValueError(f"demonstration {demo!r} has no poses to chain")
        m = len(demo_poses)
        samples = [0, int(rng.integers(m // 3, 2 * m // 3)), m - 1] if run == 2 else [0, m - 1]
        relative = dual_quaternion_relative(demo_poses[0], demo_poses[samples])
        chain.extend(dual_quaternion_multiply(chain[-1], relative[1:]))
        used.append(demo)
        gaps -= run
    poses = np.array(chain)
    if perturbation_deg > 0.0 or perturbation_m > 0.0:
        count = len(poses) - 1
        angles = np.radians(perturbation_deg) * rng.uniform(0.0, 1.0, count)
        axes = rng.normal(size=(count, 3))
        axes /= np.linalg.norm(axes, axis=1, keepdims=True)
        shifts = rng.normal(size=(count, 3))
        shifts *= perturbation_m * rng.uniform(0.0, 1.0, (count, 1)) / np.linalg.norm(shifts, axis=1, keepdims=True)
        poses[1:] = dual_quaternion_multiply(
            poses[1:],
            dual_quaternion_from_translation_rotation(shifts, quaternion_from_axis_angle(axes, angles)))
    positions, quaternions = translation_rotation_from_dual_quaternion(poses)
    euler = np.array([_euler_zyx_of(q) for q in quaternions])
    return ConcreteTask.from_fixed(name, positions, euler), used


def _random_quaternion(rng: np.random.Generator) -> np.ndarray:
    q = rng.normal(size=4)
    return q / np.linalg.norm(q)
