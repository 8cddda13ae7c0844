"""The speed override shown in Meshcat: a traffic light above the robot's base.

A Meshcat recording replays the transforms of the scene's frames, not changes of colour,
so the speed override is shown by an indicator whose visibility is keyed per frame of the
recording: under ``speed_override/`` three spheres at one spot above the robot's base,
green while the robot runs at full speed, amber while it is slowed and red during a
protective stop; only one is visible at a time. :func:`draw_override_indicator` puts
them in Meshcat (green showing) and :func:`record_override` keys the recording from a
run's :class:`~drake_lfd.diagrams.collaboration_result.CollaborationRecord`. The people
themselves are SceneGraph geometry (``systems/people.py``) and need nothing here.

Not for: the plan's markers (``plan_markers.py``), the people's geometry.
"""

from __future__ import annotations

import numpy as np
from pydrake.geometry import Meshcat, MeshcatAnimation, Rgba, Sphere
from pydrake.math import RigidTransform

__all__ = ["INDICATOR_PATH", "INDICATOR_STATES", "draw_override_indicator", "record_override", "override_state"]

INDICATOR_PATH = "speed_override"
#: The indicator's states and colours: full speed, slowed, protective stop.
INDICATOR_STATES = {"full_speed": Rgba(0.1, 0.8, 0.2, 1.0), "slowed": Rgba(1.0, 0.7, 0.0, 1.0),
                    "stopped": Rgba(0.9, 0.1, 0.1, 1.0)}
# How high above the base the light sits, m, and its radius.
_HEIGHT_M = 1.1
_RADIUS_M = 0.06


def override_state(override: float) -> str:
    """``full_speed`` (override 1), ``stopped`` (0) or ``slowed``."""
    if override >= 1.0 - 1e-9:
        return "full_speed"
    return "stopped" if override <= 1e-9 else "slowed"


def draw_override_indicator(meshcat: Meshcat, X_WB: RigidTransform) -> None:
    """The three spheres above the base at ``X_WB``, the green one showing."""
    meshcat.Delete(INDICATOR_PATH)
    for name, rgba in INDICATOR_STATES.items():
        meshcat.SetObject(f"{INDICATOR_PATH}/{name}", Sphere(_RADIUS_M), rgba)
        meshcat.SetProperty(f"{INDICATOR_PATH}/{name}", "visible", name == "full_speed")
    meshcat.SetTransform(INDICATOR_PATH, RigidTransform(X_WB.translation() + np.array([0.0, 0.0, _HEIGHT_M])))


def record_override(animation: MeshcatAnimation, t: np.ndarray, override: np.ndarray) -> int:
    """Keys the indicator's visibility into ``animation`` at every change of state of
    ``override`` (times ``t``, s); returns how many changes there were."""
    changes = 0
    previous = None
    for time_s, value in zip(np.asarray(t, dtype=float), np.asarray(override, dtype=float)):
        state = override_state(value)
        if state == previous:
            continue
        frame = animation.frame(float(time_s))
        for name in INDICATOR_STATES:
            animation.SetProperty(frame, f"/drake/{INDICATOR_PATH}/{name}", "visible", name == state)
        changes += previous is not None
        previous = state
    return changes
