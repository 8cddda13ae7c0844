"""Hand-built demonstrations with the motions of the paper's Fig. 5, as pose sequences.

The five demonstrations of the case study (and the sixth, ``span``), made directly in
SE(3) rather than recorded on the arm: for unit tests, benchmarks and held-out planner
evaluations that must not depend on recorded data. Each starts with the tool pointing
down and performs an exact body rotation (SPEC 2, 10) while translating:

* ``screw_cw`` / ``screw_ccw``: -/+90 deg about body z while moving 0.1 m along the
  start's body x (Table 5's direction for delta_1; a move along the tool axis would be
  anti-parallel to half of the screwing segments a task can ask for, e.g. Table 9's
  con_1 -> con_2 backs out along -z while con_3 -> con_4 drives in along +z);
* ``filling`` / ``pouring``: +/-90 deg about body y while moving diagonally;
* ``stacking``: up, over and down with a constant orientation;
* ``span``: +90 deg about body x (the sixth demonstration the assembling task asks for).

Not for: recorded demonstrations (``demonstrations.py``, ``kinesthetic.py``).
"""

from __future__ import annotations

import numpy as np

from drake_lfd.core.dual_quaternion import (
    dual_quaternion_from_euler_zyx,
    dual_quaternion_from_pose,
    dual_quaternion_multiply,
    quaternion_from_axis_angle,
)
from drake_lfd.core.features import Feature

X_AXIS, Y_AXIS, Z_AXIS = np.eye(3)
# Start pose of every demo: tool pointing down (body z = world -z).
START = dual_quaternion_from_euler_zyx([0.4, 0.1, 0.3], [0.0, 0.0, np.pi])
PAPER5 = ("screw_cw", "screw_ccw", "filling", "pouring", "stacking")
PAPER6 = PAPER5 + ("span",)


def turning_demo(body_axis, angle, body_translation, num=150, start=START):
    """Poses (num, 8) turning ``angle`` about a body axis while moving ``body_translation``."""
    s = np.linspace(0.0, 1.0, num)[:, None]
    rotations = quaternion_from_axis_angle(body_axis, angle * s[:, 0])
    motion = dual_quaternion_from_pose(s * np.asarray(body_translation, dtype=float), rotations)
    return dual_quaternion_multiply(start, motion)


def stacking_demo(start=START):
    """Poses (137, 8): up 0.1 m, over 0.2 m, down 0.1 m, orientation constant."""
    up = np.linspace([0, 0, 0], [0, 0, -0.1], 40)  # body -z is world up
    over = np.linspace([0, 0, -0.1], [0.2, 0, -0.1], 60)[1:]
    down = np.linspace([0.2, 0, -0.1], [0.2, 0, 0], 40)[1:]
    positions = np.concatenate([up, over, down])
    return dual_quaternion_multiply(start, dual_quaternion_from_pose(positions, [1.0, 0, 0, 0]))


def synthetic_demo_poses(name: str) -> np.ndarray:
    """Raw poses (m, 8) of one named hand-built demonstration."""
    quarter = np.pi / 2
    makers = {
        "screw_cw": lambda: turning_demo(Z_AXIS, -quarter, [0.1, 0, 0]),
        "screw_ccw": lambda: turning_demo(Z_AXIS, quarter, [0.1, 0, 0]),
        "filling": lambda: turning_demo(Y_AXIS, quarter, [0.1, 0, -0.1]),
        "pouring": lambda: turning_demo(Y_AXIS, -quarter, [-0.1, 0, 0.1]),
        "stacking": stacking_demo,
        "span": lambda: turning_demo(X_AXIS, quarter, [0.1, 0.1, 0]),
    }
    if name not in makers:
        raise KeyError(f"no synthetic demonstration {name!r}; known: {sorted(makers)}")
    return makers[name]()


def synthetic_features(names=PAPER5) -> dict[str, Feature]:
    """Features of the named hand-built demonstrations, in the given order."""
    return {name: Feature.from_poses(synthetic_demo_poses(name)) for name in names}
