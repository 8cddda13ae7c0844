"""Markers that explain a plan in Meshcat: the planned tool path and a triad at each
critical configuration.

:func:`draw_plan` adds, under ``plan/`` in Meshcat's scene tree, the tool path of a
timed plan as a green line (E's origin at every pose) and, at each critical
configuration, a triad named ``con_1``, ``con_2``, ... (x red, y green, z blue, as
Drake draws frames), posed at the configuration. A closed-loop recording draws them
before it starts, so the HTML replay shows where the arm was meant to go beside where
it went; the scene tree lists the triads by name.

Not for: the robot, tool and boxes (the station's MeshcatVisualizer draws those).
"""

from __future__ import annotations

import numpy as np
from pydrake.geometry import Cylinder, Meshcat, Rgba
from pydrake.math import RigidTransform, RotationMatrix

from drake_lfd.core.timing import TimedPlan

__all__ = ["PATH_RGBA", "draw_plan", "draw_triad"]

PATH_RGBA = Rgba(0.1, 0.75, 0.2, 1.0)
_AXES = (
    ("x", RotationMatrix.MakeYRotation(np.pi / 2), np.array([1.0, 0.0, 0.0]), Rgba(0.9, 0.1, 0.1, 1.0)),
    ("y", RotationMatrix.MakeXRotation(-np.pi / 2), np.array([0.0, 1.0, 0.0]), Rgba(0.1, 0.8, 0.1, 1.0)),
    ("z", RotationMatrix(), np.array([0.0, 0.0, 1.0]), Rgba(0.1, 0.2, 0.9, 1.0)),
)


def draw_triad(meshcat: Meshcat, path: str, X_WF: RigidTransform, *, length: float = 0.1,
               radius: float = 0.006) -> None:
    """Three cylinders along the axes of frame F at ``X_WF``, under ``path``."""
    for name, R_FA, axis, rgba in _AXES:
        meshcat.SetObject(f"{path}/{name}", Cylinder(radius, length), rgba)
        meshcat.SetTransform(f"{path}/{name}", RigidTransform(R_FA, axis * length / 2))
    meshcat.SetTransform(path, X_WF)


def draw_plan(meshcat: Meshcat, plan: TimedPlan, *, path: str = "plan", line_width: float = 4.0) -> None:
    """The plan's tool path (``path/tool_path``) and its critical configurations
    (``path/con_1`` ...) in ``meshcat`` (replacing an earlier drawing there)."""
    meshcat.Delete(path)
    X_list = plan.X_WE_list()
    points = np.array([X.translation() for X in X_list]).T
    meshcat.SetLine(f"{path}/tool_path", points, line_width, PATH_RGBA)
    for number, index in enumerate(plan.critical_indices, start=1):
        draw_triad(meshcat, f"{path}/con_{number}", X_list[index])
