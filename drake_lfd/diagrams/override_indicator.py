"""The speed override shown in Meshcat: the robot coloured by it, and a traffic light.

A Meshcat recording replays the transforms and the visibility of the scene's objects,
not changes of colour (a keyed ``color`` property does not play back), so colour is
shown by visibility keyed per frame of the recording:

- the robot: every link carries an amber and a red skin (its collision shapes, a few
  millimetres larger, half transparent) under ``<link>/speed_override/``, moving with
  the link; the amber one shows while the robot is slowed, the red one during a
  protective stop, neither at full speed (:func:`draw_robot_skins`);
- a traffic light: under ``speed_override/`` three spheres at one spot above the robot's
  base, green, amber and red, one visible at a time (:func:`draw_override_indicator`).

:func:`record_override` keys both from a run's
:class:`~drake_lfd.diagrams.collaboration_result.CollaborationRecord`. The people
themselves are SceneGraph geometry (``systems/people.py``) and need nothing here.

Not for: the plan's markers (``plan_markers.py``), the people's geometry.
"""

from __future__ import annotations

import numpy as np
from pydrake.geometry import Box as BoxShape, Capsule, Cylinder, Meshcat, MeshcatAnimation, Rgba, Sphere
from pydrake.math import RigidTransform
from pydrake.multibody.tree import BodyIndex

__all__ = ["INDICATOR_PATH", "INDICATOR_STATES", "SKIN_STATES", "draw_override_indicator", "draw_robot_skins",
           "record_override", "override_state"]

INDICATOR_PATH = "speed_override"
#: The indicator's states and colours: full speed, slowed, protective stop.
INDICATOR_STATES = {"full_speed": Rgba(0.1, 0.8, 0.2, 1.0), "slowed": Rgba(1.0, 0.7, 0.0, 1.0),
                    "stopped": Rgba(0.9, 0.1, 0.1, 1.0)}
#: The robot's skins: slowed and protective stop (none at full speed).
SKIN_STATES = {"slowed": Rgba(1.0, 0.7, 0.0, 0.55), "stopped": Rgba(0.9, 0.1, 0.1, 0.55)}
# How much larger than the link's collision shapes a skin is, m (so it shows over them).
_SKIN_MARGIN_M = 0.006
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


def _inflated(shape):
    """``shape`` a margin larger all round (None for a shape without a closed form here)."""
    margin = _SKIN_MARGIN_M
    if isinstance(shape, Cylinder):
        return Cylinder(shape.radius() + margin, shape.length() + 2 * margin)
    if isinstance(shape, Sphere):
        return Sphere(shape.radius() + margin)
    if isinstance(shape, Capsule):
        return Capsule(shape.radius() + margin, shape.length())
    if isinstance(shape, BoxShape):
        return BoxShape(shape.width() + 2 * margin, shape.depth() + 2 * margin, shape.height() + 2 * margin)
    return None


def draw_robot_skins(meshcat: Meshcat, plant, scene_graph, prefix: str = "/drake/illustration") -> list[str]:
    """The amber and red skins on every body of ``plant`` but the world (the robot and its
    tool), under the illustration visualizer's frame paths (``prefix``), hidden; returns
    the skin folders, one per body. Drawn after the visualizer's initialization (which
    clears its folder)."""
    inspector = scene_graph.model_inspector()
    folders = []
    for index in range(1, plant.num_bodies()):
        body = plant.get_body(BodyIndex(index))
        geometries = plant.GetCollisionGeometriesForBody(body)
        if not geometries:
            continue
        frame_path = f"{prefix}/" + inspector.GetName(plant.GetBodyFrameIdOrThrow(body.index())).replace("::", "/")
        folder = f"{frame_path}/{INDICATOR_PATH}"
        for state, rgba in SKIN_STATES.items():
            for number, geometry in enumerate(geometries):
                shape = _inflated(inspector.GetShape(geometry))
                if shape is None:
                    continue
                path = f"{folder}/{state}/{number}"
                meshcat.SetObject(path, shape, rgba)
                meshcat.SetTransform(path, inspector.GetPoseInFrame(geometry))
            meshcat.SetProperty(f"{folder}/{state}", "visible", False)
        folders.append(folder)
    return folders


def record_override(animation: MeshcatAnimation, t: np.ndarray, override: np.ndarray,
                    skins: list[str] = ()) -> int:
    """Keys the indicator's and the robot's skins' visibility (``skins``: the folders
    :func:`draw_robot_skins` returned) into ``animation`` at every change of state of
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
        for folder in skins:
            for name in SKIN_STATES:
                animation.SetProperty(frame, f"{folder}/{name}", "visible", name == state)
        changes += previous is not None
        previous = state
    return changes
