"""Hand-built demonstrations with the motions of the paper's Fig. 5, as pose sequences.

The five demonstrations of the case study (and the sixth, ``span``), made directly in
SE(3) rather than recorded on the arm: for unit tests, benchmarks and held-out planner
evaluations that must not depend on recorded data. Each starts with the tool pointing
down and performs an exact body rotation (about an axis of the tool frame, in the
conventions of ``docs/method.rst``, *Conventions*) while translating:

* ``screw_cw`` / ``screw_ccw``: -/+90 deg about body z while moving 0.1 m along the
  start's body x (Table 5's direction for delta_1; a move along the tool axis would be
  anti-parallel to half of the screwing segments a task can ask for, e.g. Table 9's
  con_1 -> con_2 backs out along -z while con_3 -> con_4 drives in along +z);
* ``filling`` / ``pouring``: +/-90 deg about body y while moving diagonally;
* ``stacking``: up, over and down with a constant orientation;
* ``span``: +90 deg about body x (the sixth demonstration the assembling task asks for).

:func:`random_demo_poses` / :func:`random_features` make demonstrations with random
motions, for generated libraries of any size (``benchmarks/bench_library_scale.py``).

Not for: recorded demonstrations (``demonstrations.py``, ``kinesthetic.py``).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from drake_lfd.core.dual_quaternion import dual_quaternion_from_translation_rotation, dual_quaternion_multiply
from drake_lfd.core.pose_conversions import dual_quaternion_from_euler_zyx
from drake_lfd.core.quaternion import quaternion_from_axis_angle
from drake_lfd.core.features import Feature

__all__ = [
    "START",
    "PAPER5",
    "PAPER6",
    "turning_demo",
    "stacking_demo",
    "synthetic_demo_poses",
    "synthetic_features",
    "random_demo_poses",
    "random_features",
]

_X_AXIS, _Y_AXIS, _Z_AXIS = np.eye(3)
#: Start pose of every demo, shape (8,), read-only: tool pointing down (body z = world -z).
START = dual_quaternion_from_euler_zyx([0.4, 0.1, 0.3], [0.0, 0.0, np.pi])
for _constant in (_X_AXIS, _Y_AXIS, _Z_AXIS, START):
    _constant.flags.writeable = False
del _constant
#: Names of the paper's five demonstrations (Fig. 5), in the paper's order.
PAPER5 = ("screw_cw", "screw_ccw", "filling", "pouring", "stacking")
#: The five and the sixth demonstration the assembling task asks for.
PAPER6 = PAPER5 + ("span",)


def turning_demo(
    body_axis: ArrayLike,
    angle: float,
    body_translation: ArrayLike,
    num: int = 150,
    start: ArrayLike = START,
) -> NDArray[np.float64]:
    """Poses turning ``angle`` about a body axis while moving ``body_translation``.

    Parameters
    ----------
    body_axis : array-like, shape (3,)
        Unit rotation axis in the start pose's frame.
    angle : float
        Total rotation (rad).
    body_translation : array-like, shape (3,)
        Total translation in the start pose's frame (m).
    num : int
        Number of poses.
    start : array-like, shape (8,)
        First pose (a unit dual quaternion).

    Returns
    -------
    D : array, shape (num, 8)
        A new array; rotation and translation both advance linearly.
    """
    s = np.linspace(0.0, 1.0, num)[:, None]
    rotations = quaternion_from_axis_angle(body_axis, angle * s[:, 0])
    translations = s * np.asarray(body_translation, dtype=float)
    motion = dual_quaternion_from_translation_rotation(translations, rotations)
    return dual_quaternion_multiply(start, motion)


def stacking_demo(start: ArrayLike = START) -> NDArray[np.float64]:
    """Poses up 0.1 m, over 0.2 m, down 0.1 m with a constant orientation.

    Parameters
    ----------
    start : array-like, shape (8,)
        First pose (a unit dual quaternion).

    Returns
    -------
    D : array, shape (137, 8)
    """
    up = np.linspace([0, 0, 0], [0, 0, -0.1], 40)  # body -z is world up
    over = np.linspace([0, 0, -0.1], [0.2, 0, -0.1], 60)[1:]
    down = np.linspace([0.2, 0, -0.1], [0.2, 0, 0], 40)[1:]
    positions = np.concatenate([up, over, down])
    motion = dual_quaternion_from_translation_rotation(positions, [1.0, 0, 0, 0])
    return dual_quaternion_multiply(start, motion)


def synthetic_demo_poses(name: str) -> NDArray[np.float64]:
    """Raw poses of one named hand-built demonstration.

    Parameters
    ----------
    name : str
        One of :data:`PAPER6`.

    Returns
    -------
    D : array, shape (m, 8)
        A new array.

    Raises
    ------
    KeyError
        For an unknown name.
    """
    quarter = np.pi / 2
    makers = {
        "screw_cw": lambda: turning_demo(_Z_AXIS, -quarter, [0.1, 0, 0]),
        "screw_ccw": lambda: turning_demo(_Z_AXIS, quarter, [0.1, 0, 0]),
        "filling": lambda: turning_demo(_Y_AXIS, quarter, [0.1, 0, -0.1]),
        "pouring": lambda: turning_demo(_Y_AXIS, -quarter, [-0.1, 0, 0.1]),
        "stacking": stacking_demo,
        "span": lambda: turning_demo(_X_AXIS, quarter, [0.1, 0.1, 0]),
    }
    if name not in makers:
        raise KeyError(f"no synthetic demonstration {name!r}; known: {sorted(makers)}")
    return makers[name]()


def synthetic_features(names: Sequence[str] = PAPER5) -> dict[str, Feature]:
    """Features of the named hand-built demonstrations, in the given order.

    Parameters
    ----------
    names : sequence of str
        Names from :data:`PAPER6`.

    Returns
    -------
    features : dict of str to Feature
        Built with :meth:`Feature.from_poses` and its defaults.
    """
    return {name: Feature.from_poses(synthetic_demo_poses(name)) for name in names}


def random_demo_poses(rng: np.random.Generator, num: int = 120) -> NDArray[np.float64]:
    """Raw poses of a random demonstration with its own motion, for generated libraries.

    It turns by an angle drawn uniformly in [-pi, pi] about a random body axis while it
    moves 5-30 cm in a random body direction, bulging off the straight line by up to
    half that length (a lift-over-lower when large), from a random start pose.

    Parameters
    ----------
    rng : numpy.random.Generator
    num : int
        Number of poses.

    Returns
    -------
    D : array, shape (num, 8)
    """
    axis = rng.normal(size=3)
    axis /= np.linalg.norm(axis)
    direction = rng.normal(size=3)
    direction *= rng.uniform(0.05, 0.3) / np.linalg.norm(direction)
    bulge = rng.normal(size=3)
    bulge *= rng.uniform(0.0, 0.5) * np.linalg.norm(direction) / np.linalg.norm(bulge)
    s = np.linspace(0.0, 1.0, num)[:, None]
    translations = s * direction + np.sin(np.pi * s) * bulge
    rotations = quaternion_from_axis_angle(axis, rng.uniform(-np.pi, np.pi) * s[:, 0])
    start_axis = rng.normal(size=3)
    start = dual_quaternion_from_translation_rotation(
        rng.uniform(-0.2, 0.2, 3) + [0.4, 0.0, 0.3],
        quaternion_from_axis_angle(start_axis / np.linalg.norm(start_axis), rng.uniform(0.0, np.pi)))
    return dual_quaternion_multiply(start, dual_quaternion_from_translation_rotation(translations, rotations))


def random_features(rng: np.random.Generator, count: int, num_samples: int | None = None) -> dict[str, Feature]:
    """Features of ``count`` :func:`random_demo_poses` demonstrations, named
    ``random_0`` .. (with ``num_samples``, resampled to that many samples instead of
    :meth:`Feature.from_poses`' default)."""
    extra = {} if num_samples is None else {"num_samples": num_samples}
    return {f"random_{i}": Feature.from_poses(random_demo_poses(rng), **extra) for i in range(count)}
